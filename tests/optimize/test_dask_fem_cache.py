"""One FEM per distinct model on a Dask cluster: two fingertip designs of an (h, r) sweep share
one FEM; on a LocalCluster of two worker processes the real FEM stage is computed and its cache
file written once, and the other design reads that file."""

from __future__ import annotations

import pytest

from designlab.optimize.executors import DaskExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep

pytestmark = pytest.mark.slow

CFG = {"part": "fingertip", "method": "grid",
       "parameters": {"h": {"values": [3.0, 5.0]}, "r": {"values": [7.0]}},
       "fixed": {"load_table": "II"},
       "settings": {"model": {"edge_length": 4.0, "mesh_convergence": False}},
       "objectives": {"condition_number": "min"}}


def evaluate_reading_the_file(task):
    """The sweep's own evaluator, with this process's in-memory FEM layer emptied first (so a
    design finds the FEM only in the sweep's folder), reporting what the FEM cache did."""
    from designlab.fem.cache import STATS, clear_memory
    from designlab.optimize.evaluate import evaluate_design

    clear_memory()
    before = dict(STATS)
    out = evaluate_design(task)
    out["fem_cache_stats"] = {k: STATS[k] - before[k] for k in STATS}
    return out


def test_two_designs_share_one_fem_file_on_dask(tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        res = run_sweep(sweep_config(CFG), tmp_path, evaluator=evaluate_reading_the_file,
                        executor=DaskExecutor(cluster.scheduler_address))
    rows = sorted(res.rows, key=lambda r: r["param.h"])   # table rows: flat columns
    assert [r["status"] for r in rows] == ["ok", "ok"], [r.get("error") for r in rows]
    stats = [{k: r[f"fem_cache_stats.{k}"] for k in ("computed", "written", "file_reads",
                                                      "memory_hits")} for r in rows]
    # the cached stage (the design's FEM) is shared by both designs: it is computed and its
    # file written once in all, and the design that did not compute it read its file (its
    # memory layer was empty)
    files = sorted(f.name for f in (tmp_path / "fem").glob("*.npz"))
    n = len(files)
    assert n == 1 and sum(s["computed"] for s in stats) == n, (files, stats)
    assert sum(s["written"] for s in stats) == n, stats
    assert sorted(s["computed"] + s["file_reads"] for s in stats) == [1, 1], stats
    # the FEM itself: one design solved it, the other reused it (read from its file)
    assert rows[0]["fem_key"] == rows[1]["fem_key"]
    assert any(f.startswith(rows[0]["fem_key"]) for f in files)
    assert sum(r.get("timings_s.fem_cache") is not None for r in rows) == 1
    assert rows[0]["condition_number"] != rows[1]["condition_number"]
