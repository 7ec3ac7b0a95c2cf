"""A Dask scheduler that dies under a sweep: the designs it finished are stored, the ones it
did not are named in one line and the run ends with exit code 3 (not 0 with them recorded
failed); a plain resume runs exactly those (rows an older run stored as "cancelled" by the
lost scheduler included), and a design that failed by itself is still not run again."""

from __future__ import annotations

import inspect
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from designlab.errors import ClusterError
from designlab.optimize.executors import DASK_FAILED, LocalExecutor, LostTasks, cluster_lost
from designlab.optimize.space import sweep_config
from designlab.optimize.store import ResultStore
from designlab.optimize.sweep import _row, run_sweep, tasks_of

CFG = {"part": "fingertip", "method": "grid",
       "parameters": {"h": {"values": [1.0, 2.0, 3.0, 4.0]}, "r": {"values": [7.0, 8.0]}},
       "objectives": {"condition_number": "min"}}


@pytest.fixture(scope="module", autouse=True)
def _imported():
    """The part and the material library loaded once (setup, not the tests' own time)."""
    from designlab.optimize.sweep import materials_fingerprint

    materials_fingerprint()
    sweep_config(CFG)


def bowl(task):
    p = task["params"]
    return {"condition_number": 1.0 + (p["h"] - 2.0) ** 2 + (p["r"] - 8.0) ** 2}


class Logged:
    """``bowl``, appending each evaluated design's key to a file; with ``kill_after`` it
    SIGKILLs the process ``$DESIGNLAB_TEST_SCHEDULER_PID`` (the scheduler) at that call."""

    def __init__(self, log, kill_after: int = 0):
        self.log, self.kill_after = str(log), kill_after

    def __call__(self, task):
        with open(self.log, "a") as f:
            f.write(task["key"] + "\n")
        n = len(open(self.log).read().split())
        if self.kill_after and n == self.kill_after:
            time.sleep(1.0)          # the designs finished before are gathered first
            os.kill(int(os.environ["DESIGNLAB_TEST_SCHEDULER_PID"]), signal.SIGKILL)
        time.sleep(0.2 if self.kill_after else 0.0)
        return bowl(task)


class LosingExecutor:
    """Runs the first ``n`` tasks, then loses the rest as a Dask client whose scheduler died."""

    def __init__(self, n: int):
        self.n = n

    def run(self, fn, tasks):
        for i, t in enumerate(tasks[:self.n]):
            yield i, fn(t), None
        raise LostTasks(list(range(self.n, len(tasks))), "the Dask scheduler at tcp://x:1 "
                        "was lost (FutureCancelledError: scheduler-connection-lost)")


def test_a_lost_scheduler_names_the_designs_not_run_and_a_resume_runs_them(tmp_path):
    cfg, out, log = sweep_config(CFG), tmp_path / "out", tmp_path / "calls.txt"
    with pytest.raises(ClusterError) as e:
        run_sweep(cfg, out, evaluator=Logged(log), executor=LosingExecutor(3))
    keys = [t["key"] for t in tasks_of(cfg, Logged(log))]
    msg = str(e.value)
    assert e.value.exit_code == 3 and "\n" not in msg and "5 of 8 designs not run" in msg
    assert all(k[:8] in msg for k in keys[3:]) and not any(k[:8] in msg for k in keys[:3])
    assert ResultStore(out).keys() == set(keys[:3])          # no row for a lost design
    res = run_sweep(cfg, out, evaluator=Logged(log), executor=LocalExecutor(1))
    assert res.new == 5 and res.reused == 3 and res.failed == 0
    assert sorted(open(log).read().split()) == sorted(keys)  # each design once


def test_rows_an_older_run_stored_as_lost_are_run_again_own_failures_are_not(tmp_path):
    cfg, out = sweep_config(CFG), tmp_path / "out"
    tasks, store = tasks_of(cfg, bowl), ResultStore(tmp_path / "out")
    lost = DASK_FAILED + ("FutureCancelledError: _dask_try-1 cancelled for reason: "
                          "scheduler-connection-lost.")
    own = DASK_FAILED + "KilledWorker: attempted to run task on 2 different workers"
    assert cluster_lost(lost) and not cluster_lost(own) and not cluster_lost("ValueError: x")
    store.put(tasks[0]["key"], _row(tasks[0], {}, lost, float("nan"), cfg), None)
    store.put(tasks[1]["key"], _row(tasks[1], {}, own, float("nan"), cfg), None)
    res = run_sweep(cfg, out, evaluator=bowl, executor=LocalExecutor(1))
    assert res.new == 7 and res.reused == 1 and res.failed == 1
    assert {r["key"]: r["status"] for r in res.rows}[tasks[0]["key"]] == "ok"


def test_the_cli_ends_a_lost_cluster_with_exit_3_and_one_line(tmp_path, monkeypatch, capsys):
    import designlab.optimize.sweep as sweep_module
    from designlab.cli import main

    def lost(*a, **kw):
        raise ClusterError("the Dask scheduler at tcp://x:1 was lost: 2 of 8 designs not run")

    monkeypatch.setattr(sweep_module, "run_sweep", lost)
    cfg = tmp_path / "s.toml"
    cfg.write_text('part = "fingertip"\n[parameters]\nh = [0.0, 5.0]\n'
                   '[objectives]\ncondition_number = "min"\n')
    with pytest.raises(SystemExit) as e:
        main(["sweep", str(cfg), "--out", str(tmp_path / "o"), "--workers", "1"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 3 and "2 of 8 designs not run" in err and len(err.splitlines()) == 1


def _start(cmd, env):
    return subprocess.Popen([sys.executable, "-m", *cmd], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env, start_new_session=True)


@pytest.mark.slow
def test_a_sweep_whose_scheduler_is_killed_resumes_the_designs_it_lost(tmp_path, monkeypatch):
    """A real scheduler process SIGKILLed by the third design's evaluation (two worker
    processes of one thread): the sweep ends with a ClusterError naming the designs without a
    row, and a plain resume on a new cluster runs exactly those."""
    from distributed import Client, LocalCluster

    from designlab.optimize.executors import DaskExecutor

    cfg, out, log = sweep_config(CFG), tmp_path / "out", tmp_path / "calls.txt"
    sched_file = tmp_path / "scheduler.json"
    # the evaluator in a module the scheduler and the workers started here import (from the
    # folder on their PYTHONPATH), as they would a user's own
    (tmp_path / "lost_eval.py").write_text("import os\nimport signal\nimport time\n\n"
                                           + inspect.getsource(bowl)
                                           + inspect.getsource(Logged))
    monkeypatch.syspath_prepend(str(tmp_path))
    from lost_eval import Logged as Killing
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    sched = _start(["distributed.cli.dask_scheduler", "--scheduler-file", str(sched_file),
                    "--no-dashboard", "--port", "0"], env)
    env = {**env, "DESIGNLAB_TEST_SCHEDULER_PID": str(sched.pid)}
    workers = None
    try:
        for _ in range(300):
            if sched_file.exists() and sched_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        workers = _start(["distributed.cli.dask_worker", "--scheduler-file", str(sched_file),
                          "--nthreads", "1", "--nworkers", "2", "--no-dashboard"], env)
        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        with pytest.raises(ClusterError) as e:
            run_sweep(cfg, out, evaluator=Killing(log, kill_after=3),
                      executor=DaskExecutor(address))
    finally:
        for p in (workers, sched):
            if p is not None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
    stored = ResultStore(out).keys()
    keys = [t["key"] for t in tasks_of(cfg, Logged(log))]
    missing = [k for k in keys if k not in stored]
    assert 0 < len(missing) < 8 and e.value.exit_code == 3
    assert f"{len(missing)} of 8 designs not run" in str(e.value)
    assert all(k[:8] in str(e.value) for k in missing)
    assert all(r["status"] == "ok" for r in ResultStore(out).rows())
    first = open(log).read().split()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        res = run_sweep(cfg, out, evaluator=Logged(log), executor=DaskExecutor(
            cluster.scheduler_address))
    assert res.failed == 0 and res.new == len(missing) and res.reused == 8 - len(missing)
    assert sorted(open(log).read().split()[len(first):]) == sorted(missing)


def test_a_study_whose_scheduler_is_lost_resumes_its_trials(tmp_path):
    """The trials of a batch the cluster lost stay running in the study; the same command
    tells the finished ones from the store and evaluates only the lost ones."""
    from designlab.optimize.study import run_study

    cfg = sweep_config({**CFG, "method": "lhs",
                        "parameters": {"h": [0.0, 5.0], "r": [6.0, 9.0]}})
    out, log = tmp_path / "out", tmp_path / "calls.txt"
    with pytest.raises(ClusterError, match="2 of 4 designs not run"):
        run_study(cfg, out, "tpe", trials=8, batch=4, executor=LosingExecutor(2),
                  evaluator=Logged(log))
    assert len(open(log).read().split()) == 2
    res = run_study(cfg, out, "tpe", trials=8, batch=4, executor=LocalExecutor(1),
                    evaluator=Logged(log))
    keys = open(log).read().split()
    assert res.trials == 8 and res.sweep.failed == 0
    assert len(keys) == 8 == len(set(keys)) == len(res.sweep.rows)
