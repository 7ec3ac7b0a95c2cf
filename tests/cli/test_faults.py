"""Faults: a worker process killed mid-design does not end a sweep.

The local pool: the design whose worker died is run again on a rebuilt pool; one that kills its
worker every time is recorded failed with the reason, and the designs that were only pending in
the broken pools finish normally. A sweep through such a fault completes with every design
exactly once, and its resume has nothing left to do.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from designlab.optimize.executors import LocalExecutor

KILLER = 2  # the task index whose worker dies


def _die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def kill_once(task):
    """Kills its own worker the first time it runs task KILLER (a marker file remembers)."""
    marker = Path(task["marker"])
    if task["i"] == KILLER and not marker.exists():
        marker.write_text("died once")
        _die()
    return task["i"] ** 2


def kill_always(task):
    if task["i"] == KILLER:
        _die()
    return task["i"] ** 2


def _run(fn, tmp_path, n=6):
    tasks = [{"i": i, "marker": str(tmp_path / "marker")} for i in range(n)]
    return list(LocalExecutor(2).run(fn, tasks))


def test_a_worker_killed_once_is_retried_and_every_design_comes_back_once(tmp_path):
    out = _run(kill_once, tmp_path)
    assert (tmp_path / "marker").exists()               # the worker did die
    assert sorted(i for i, _, _ in out) == list(range(6))
    assert all(err is None and res == i ** 2 for i, res, err in out), out


def test_a_design_that_always_kills_its_worker_is_recorded_failed_the_rest_run(tmp_path):
    out = _run(kill_always, tmp_path)
    assert sorted(i for i, _, _ in out) == list(range(6))
    by = {i: (res, err) for i, res, err in out}
    res, err = by.pop(KILLER)
    assert res is None and "worker process died while running this design" in err
    assert "\n" not in err
    assert all(e is None and r == i ** 2 for i, (r, e) in by.items()), by


def sweep_kill_once(task):
    """A sweep evaluator (sweep_fixtures.quadratic) whose worker dies once at h=2, r=8."""
    from sweep_fixtures import quadratic

    p = task["params"]
    marker = Path(os.environ["DESIGNLAB_TEST_MARKER"])
    if p["h"] == 2.0 and p["r"] == 8.0 and not marker.exists():
        marker.write_text("died once")
        _die()
    return quadratic(task)


@pytest.mark.slow
def test_a_sweep_survives_a_killed_worker_and_its_store_stays_consistent(tmp_path, monkeypatch):
    import pyarrow.parquet as pq

    from designlab.optimize.space import sweep_config
    from designlab.optimize.sweep import run_sweep

    monkeypatch.setenv("DESIGNLAB_TEST_MARKER", str(tmp_path / "marker"))
    cfg = sweep_config({"part": "fingertip", "method": "grid",
                        "parameters": {"h": {"range": [0.0, 4.0], "levels": 3},
                                       "r": {"values": [6.0, 8.0]}},
                        "objectives": {"condition_number": "min"}})
    r = run_sweep(cfg, tmp_path / "out", evaluator=sweep_kill_once, executor=LocalExecutor(2))
    assert (tmp_path / "marker").exists()
    assert r.new == 6 and r.failed == 2                  # h=4 fails by design (quadratic)
    status = {(row["param.h"], row["param.r"]): row["status"] for row in r.rows}
    assert status[(2.0, 8.0)] == "ok" and sum(s == "ok" for s in status.values()) == 4
    keys = pq.read_table(tmp_path / "out" / "results.parquet").column("key").to_pylist()
    assert len(keys) == 6 == len(set(keys))
    again = run_sweep(cfg, tmp_path / "out", evaluator=sweep_kill_once,
                      executor=LocalExecutor(2))
    assert again.new == 0 and again.reused == 6


def test_recover_removes_temp_rows_of_the_old_naming(tmp_path):
    """``results/.KEY.RAND.tmp.parquet`` (the naming before temp names carried the writer's PID)
    left by a killed run: removed on recover, never read as a row."""
    from designlab.optimize.store import ResultStore

    store = ResultStore(tmp_path)
    store.rows_dir.mkdir(parents=True)
    old = store.rows_dir / ".0123456789abcdef0123.k3x9.tmp.parquet"
    old.write_bytes(b"")                                 # killed right after creating it
    assert store.recover()["temporary_files"] == 1
    assert not old.exists() and store.keys() == set()
