"""Faults on Dask: a worker process killed mid-design.

A real ``LocalCluster`` (worker processes, 2 workers of 1 thread) runs a flexure sweep in which
one design's evaluation SIGKILLs its own worker process every time it runs. The design is run
once more (``MAX_RETRIES``) on a new worker, then recorded failed with a reason naming the
workers that died; the other designs come back exactly once, the store holds one row per
design, a resume runs nothing again, and no process is left alive after the cluster closes.
"""

from __future__ import annotations

import os
import signal

import pytest

from designlab.optimize.sweep import default_evaluator

KILLER = 1.0     # the wire radius whose evaluation kills its worker


def killing_evaluator(task):
    """The sweep's own evaluator, except that the design with wire_radius == KILLER writes
    its process id to the marker file and SIGKILLs its own (worker) process."""
    if task["params"]["wire_radius"] == KILLER:
        with open(os.environ["DESIGNLAB_TEST_KILL_MARKER"], "a") as f:
            f.write(f"{os.getpid()}\n")
        os.kill(os.getpid(), signal.SIGKILL)
    return default_evaluator(task)


CFG = {"part": "flexure", "method": "grid",
       "parameters": {"wire_radius": {"values": [0.9, KILLER, 1.1, 1.2]}},
       "fixed": {"disc_radius": 18.0, "mean_diameter": 26.0, "active_coils": 2.0},
       "settings": {"K_f_target_N_per_m": 4000.0,
                    "model": {"truth": "chain", "working_load_N": 10.0}},
       "objectives": {"K_f_target_error": "min"}}


@pytest.mark.slow
def test_a_design_that_kills_its_dask_worker_is_retried_once_then_recorded_failed(
        tmp_path, monkeypatch):
    import psutil
    import pyarrow.parquet as pq
    from distributed import LocalCluster

    from designlab.optimize.executors import MAX_RETRIES, DaskExecutor
    from designlab.optimize.space import sweep_config
    from designlab.optimize.sweep import run_sweep

    marker = tmp_path / "killed"
    monkeypatch.setenv("DESIGNLAB_TEST_KILL_MARKER", str(marker))
    cfg = sweep_config(CFG)
    me = psutil.Process()
    before = {p.pid for p in me.children(recursive=True)}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        ex = DaskExecutor(cluster.scheduler_address)
        r = run_sweep(cfg, tmp_path / "out", evaluator=killing_evaluator, executor=ex)
        deaths = marker.read_text().split()
        assert len(deaths) == 1 + MAX_RETRIES == len(set(deaths))  # each on its own worker
        assert r.new == 4 and r.reused == 0 and r.failed == 1
        by_r = {row["param.wire_radius"]: row for row in r.rows}
        bad = by_r.pop(KILLER)
        assert bad["status"] == "error"
        assert "worker" in bad["error"] and "died" in bad["error"]
        assert "tcp://" in bad["error"]                 # names the lost worker(s)
        assert "\n" not in bad["error"]
        assert all(row["status"] == "ok" and row["K_f_target_error"] is not None
                   for row in by_r.values()), by_r
        keys = pq.read_table(tmp_path / "out" / "results.parquet").column("key").to_pylist()
        assert len(keys) == 4 == len(set(keys))
        assert not list((tmp_path / "out").rglob("*.tmp*"))
        again = run_sweep(cfg, tmp_path / "out", evaluator=killing_evaluator, executor=ex)
        assert again.new == 0 and again.reused == 4
        assert marker.read_text().split() == deaths     # the resume ran nothing again
    psutil.wait_procs([p for p in me.children(recursive=True) if p.pid not in before],
                      timeout=10)
    # every worker and nanny ended; multiprocessing's resource tracker is this (test)
    # process's own helper, started with the first spawned child: it ends with this process
    left = [p for p in me.children(recursive=True) if p.pid not in before and p.is_running()
            and p.status() != psutil.STATUS_ZOMBIE
            and "multiprocessing.resource_tracker" not in " ".join(p.cmdline())]
    assert not left, [p.cmdline() for p in left]
    for pid in map(int, deaths):
        assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
