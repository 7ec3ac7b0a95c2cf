"""Optuna studies over the sweep store: a study interrupted (an exception, kill -9) and started
again resumes with no design evaluated twice; the storage opens with Optuna's own API (as
optuna-dashboard opens it); designs the mesh error bars cannot separate stay not
distinguishable; bad input is refused in one line, exit 2, nothing written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.study import STUDY_FILE, STUDY_NAME, run_study, violations

CFG = {"part": "fingertip", "samples": 12,
       "parameters": {"h": [0.0, 5.0], "r": [6.0, 9.0]},
       "objectives": {"condition_number": "min"},
       "constraints": {"printable": True, "min_safety_factor": {"min": 2.0}}}


class Counting:
    """A bowl with its minimum at h=2, r=8 (infeasible where h > 4.5); appends each evaluated
    design to a file; raises KeyboardInterrupt (or kills its process) at the ``stop``-th call."""

    def __init__(self, log: Path, stop: int = 0, kill: bool = False, bar: float = 0.0):
        self.log, self.stop, self.kill, self.bar = str(log), stop, kill, bar

    def __call__(self, task):
        with open(self.log, "a") as f:
            f.write(task["key"] + "\n")
        n = len(Path(self.log).read_text().split())
        if self.stop and n == self.stop:
            if self.kill:
                os.kill(os.getpid(), signal.SIGKILL)
            raise KeyboardInterrupt
        p = task["params"]
        v = 1.0 + (p["h"] - 2.0) ** 2 + (p["r"] - 8.0) ** 2
        return {"condition_number": v, "printable": True,
                "min_safety_factor": 1.0 if p["h"] > 4.5 else 3.0, "printed_volume_mm3": p["r"],
                "mesh_convergence": {"condition_number": {"coarse": v + self.bar}}}


@pytest.fixture(scope="module", autouse=True)
def _imported():
    """Optuna, the part and the material library imported once (setup, not the tests' own
    time)."""
    import optuna  # noqa: F401

    from designlab.optimize.sweep import materials_fingerprint

    materials_fingerprint()
    sweep_config(CFG)


def _evaluated(log: Path) -> list[str]:
    return log.read_text().split() if log.exists() else []


def _once_but_the_interrupted(keys: list[str], stop: int) -> bool:
    """Every design evaluated once, except the one whose evaluation was interrupted (it never
    finished: evaluated again, once)."""
    return all(keys.count(k) == 1 or (k == keys[stop - 1] and keys.count(k) == 2) for k in keys)


def test_an_interrupted_study_resumes_with_no_design_evaluated_twice(tmp_path):
    import optuna

    cfg, log, out = sweep_config(CFG), tmp_path / "calls.txt", tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_study(cfg, out, "tpe", trials=12, batch=3, executor=LocalExecutor(1),
                  evaluator=Counting(log, stop=5))
    res = run_study(cfg, out, "tpe", trials=12, batch=3, executor=LocalExecutor(1),
                    evaluator=Counting(log))
    keys = _evaluated(log)
    assert _once_but_the_interrupted(keys, 5)
    assert res.trials == 12 and len(res.sweep.rows) == len(set(keys))
    study = optuna.load_study(study_name=STUDY_NAME, storage=optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(out / STUDY_FILE))))
    done = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) == 12 and not [t for t in study.trials
                                    if t.state == optuna.trial.TrialState.RUNNING]
    assert all("design_key" in t.user_attrs and len(t.constraints) == 2 for t in done)
    # the best trial is feasible and is the study's chosen design
    best = min((t for t in done if max(t.constraints.values()) <= 0), key=lambda t: t.value)
    assert best.user_attrs["design_key"] == res.sweep.best_key
    # run again with the budget reached: nothing asked, nothing evaluated
    again = run_study(cfg, out, "tpe", trials=12, executor=LocalExecutor(1),
                      evaluator=Counting(log))
    assert again.asked == 0 and _evaluated(log) == keys


def test_a_multi_objective_study_and_its_pareto_set(tmp_path):
    cfg = sweep_config({**CFG, "objectives": {"condition_number": "min",
                                              "printed_volume_mm3": "max"}})
    res = run_study(cfg, tmp_path, "nsga2", trials=8, batch=4, executor=LocalExecutor(1),
                    evaluator=Counting(tmp_path / "c.txt"))
    assert res.trials == 8 and res.sweep.pareto_keys and res.sweep.best_key in res.sweep.pareto_keys


def test_designs_within_the_error_bars_are_not_distinguishable(tmp_path):
    cfg = sweep_config({**CFG, "method": "grid",
                        "parameters": {"h": {"range": [1.5, 2.5], "levels": 3}, "r": [7.5, 8.5]},
                        "constraints": {}})
    res = run_study(cfg, tmp_path, "grid", trials=9, executor=LocalExecutor(1),
                    evaluator=Counting(tmp_path / "c.txt", bar=10.0))
    assert res.sweep.best_key and len(res.sweep.tie_keys) == 8     # every other design
    narrow = run_study(cfg, tmp_path / "b", "grid", trials=9, executor=LocalExecutor(1),
                       evaluator=Counting(tmp_path / "d.txt", bar=0.0))
    assert narrow.sweep.tie_keys == []


def test_constraint_violations():
    c = {"printable": True, "min_safety_factor": {"min": 2.0}, "k": {"min": 1, "max": 3}}
    assert violations({"printable": True, "min_safety_factor": 2.5, "k": 2}, c) == [0.0, -0.5, -1]
    assert violations({"printable": False, "k": 5}, c) == [1.0, 1.0, 2]


@pytest.mark.parametrize("args, says", [
    (["--method", "tpee"], "--method"),
    (["--method", "tpe", "--trials", "0"], "--trials"),
    (["--method", "gp"], "pip install 'designlab[gp]'"),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, monkeypatch, args, says):
    from designlab.cli import main

    monkeypatch.setitem(sys.modules, "torch", None)     # as if torch were not installed
    cfg = tmp_path / "s.toml"
    cfg.write_text('part = "fingertip"\n[parameters]\nh = [0.0, 5.0]\n'
                   '[objectives]\ncondition_number = "min"\n')
    with pytest.raises(SystemExit) as e:
        main(["optimize", str(cfg), "--out", str(tmp_path / "o"), *args])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and says in err and len(err.splitlines()) <= 2
    assert not (tmp_path / "o").exists()


def test_a_constraint_on_a_metric_no_prediction_has(tmp_path, capsys):
    from designlab.cli import main

    cfg = tmp_path / "s.toml"
    cfg.write_text('part = "fingertip"\n[parameters]\nh = [0.0, 5.0]\n'
                   '[objectives]\ncondition_number = "min"\n'
                   '[constraints]\nresistance_ohm = { min = 100 }\n')
    with pytest.raises(SystemExit) as e:
        main(["optimize", str(cfg), "--out", str(tmp_path / "o"), "--method", "tpe"])
    assert e.value.code == 2 and "resistance_ohm" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


SCRIPT = """
import sys
sys.path.insert(0, {here!r})
from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.study import run_study
from test_study import CFG, Counting
run_study(sweep_config(CFG), {out!r}, "tpe", trials=12, batch=3, executor=LocalExecutor(1),
          evaluator=Counting(__import__("pathlib").Path({log!r}), stop={stop}, kill=True))
"""


@pytest.mark.slow
@pytest.mark.parametrize("stop", [2, 7])
def test_kill_9_mid_study_resumes_with_no_design_evaluated_twice(tmp_path, stop):
    out, log = tmp_path / "out", tmp_path / "calls.txt"
    script = SCRIPT.format(here=str(Path(__file__).parent), out=str(out), log=str(log),
                           stop=stop)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert p.returncode == -signal.SIGKILL, p.stderr
    res = run_study(sweep_config(CFG), out, "tpe", trials=12, batch=3,
                    executor=LocalExecutor(1), evaluator=Counting(log))
    keys = _evaluated(log)
    assert _once_but_the_interrupted(keys, stop) and res.trials == 12
    assert json.loads(json.dumps(res.info))["trials"] == 12


def test_optuna_dashboard_serves_the_study_of_a_run(tmp_path):
    """optuna-dashboard's own storage loader and web app open ``OUT/study.log`` as it is."""
    dashboard = pytest.importorskip("optuna_dashboard")
    from optuna_dashboard._storage_url import get_storage

    cfg = sweep_config(CFG)
    run_study(cfg, tmp_path, "random", trials=3, executor=LocalExecutor(1),
              evaluator=Counting(tmp_path / "c.txt"))
    import optuna

    study = optuna.load_study(study_name=STUDY_NAME, storage=get_storage(str(tmp_path / STUDY_FILE)))
    assert len(study.trials) == 3
    app = dashboard.wsgi(str(tmp_path / STUDY_FILE))
    status = []
    body = b"".join(app({"REQUEST_METHOD": "GET", "PATH_INFO": "/api/studies",
                         "wsgi.input": None, "SERVER_NAME": "x", "SERVER_PORT": "80",
                         "wsgi.url_scheme": "http"}, lambda s, h, *a: status.append(s)))
    assert status[0].startswith("200") and STUDY_NAME in json.loads(body)["study_summaries"][0][
        "study_name"]


def test_the_load_cell_example_config_loads():
    from designlab.optimize.space import load_sweep_config
    from designlab.optimize.study import check_method

    cfg = load_sweep_config(Path(__file__).parents[2] / "examples" / "optimize_load_cell.toml")
    check_method("tpe", cfg)
    assert cfg.part.endswith("load_cell.py") and list(cfg.constraints) == ["min_safety_factor"]


@pytest.mark.slow
def test_the_gp_sampler_runs_a_study_with_torch(tmp_path):
    """``--method gp`` (Optuna's Gaussian-process sampler, on torch): its trials after the
    first random ones are the sampler's own and approach the bowl's minimum."""
    pytest.importorskip("torch")
    cfg = sweep_config({**CFG, "constraints": {}})
    res = run_study(cfg, tmp_path, "gp", trials=8, batch=2, executor=LocalExecutor(1),
                    evaluator=Counting(tmp_path / "c.txt"))
    assert res.trials == 8 and len(set(_evaluated(tmp_path / "c.txt"))) == 8
    assert res.info["sampler"] == "gp" and res.sweep.best_key is not None


class Pids:
    """The bowl of :class:`Counting`, logging the process that evaluated each design."""

    def __init__(self, log: Path):
        self.log = str(log)

    def __call__(self, task):
        with open(self.log, "a") as f:
            f.write(f"{os.getpid()} {task['key']}\n")
        p = task["params"]
        return {"condition_number": 1.0 + (p["h"] - 2.0) ** 2 + (p["r"] - 8.0) ** 2}


@pytest.mark.slow
def test_a_study_keeps_one_process_pool_for_all_its_batches(tmp_path):
    """Six batches of two trials on a pool of two workers: one pool is started, and the same
    (at most two) worker processes evaluate every batch; each design once."""
    cfg = sweep_config({**CFG, "constraints": {}})
    ex = LocalExecutor(2)
    res = run_study(cfg, tmp_path, "random", trials=12, batch=2, executor=ex,
                    evaluator=Pids(tmp_path / "p.txt"))
    lines = [ln.split() for ln in (tmp_path / "p.txt").read_text().splitlines()]
    assert res.trials == 12 and len(lines) == 12 == len({k for _, k in lines})
    assert ex.pools_started == 1 and len({pid for pid, _ in lines}) <= 2
    assert ex._pool is None                  # shut down with the study
