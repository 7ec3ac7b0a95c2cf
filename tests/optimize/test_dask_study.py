"""One Optuna study whose trials two Dask workers evaluate at the same time: a real
``LocalCluster`` (two worker processes of one thread) runs a flexure study; the study asks as
many trials at a time as the cluster has worker threads, both workers evaluate designs of the
same batch at once, every design is evaluated once, the one-writer lock of ``--out`` (held by
the process that asks and tells) does not stand in the workers' way, and a resume on the same
cluster evaluates nothing."""

from __future__ import annotations

import os
import time

import pytest

from designlab.optimize.sweep import default_evaluator

pytestmark = pytest.mark.slow

CFG = {"part": "flexure",
       "parameters": {"wire_radius": [0.9, 1.3], "active_coils": [2.0, 4.0]},
       "fixed": {"disc_radius": 18.0, "mean_diameter": 26.0},
       "settings": {"K_f_target_N_per_m": 4000.0,
                    "model": {"truth": "chain", "working_load_N": 10.0}},
       "objectives": {"K_f_target_error": "min"}}


def logging_evaluator(task):
    """The sweep's own evaluator, logging the worker, the design and when it ran."""
    from distributed import get_worker

    t0 = time.time()
    out = default_evaluator(task)
    with open(os.environ["DESIGNLAB_TEST_STUDY_LOG"], "a") as f:
        f.write(f"{get_worker().address} {task['key']} {t0} {time.time()}\n")
    return out


def test_two_dask_workers_share_one_study(tmp_path, monkeypatch):
    import optuna
    from distributed import LocalCluster

    from designlab.optimize.executors import DaskExecutor
    from designlab.optimize.space import sweep_config
    from designlab.optimize.study import STUDY_FILE, STUDY_NAME, run_study

    log = tmp_path / "log.txt"
    monkeypatch.setenv("DESIGNLAB_TEST_STUDY_LOG", str(log))
    cfg, out = sweep_config(CFG), tmp_path / "out"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        ex = DaskExecutor(cluster.scheduler_address)
        res = run_study(cfg, out, "tpe", trials=6, executor=ex, evaluator=logging_evaluator)
        runs = [ln.split() for ln in log.read_text().splitlines()]
        assert res.trials == 6 and res.sweep.failed == 0, [r.get("error") for r in res.sweep.rows]
        assert len(runs) == 6 == len({key for _, key, _, _ in runs})    # each design once
        assert len({w for w, *_ in runs}) == 2                           # both workers
        # the batches are the cluster's two worker threads: three batches of two designs,
        # each pair evaluated at the same time by the two workers
        runs.sort(key=lambda r: float(r[2]))
        for a, b in zip(runs[0::2], runs[1::2]):
            assert a[0] != b[0] and float(b[2]) < float(a[3]), (a, b)
        again = run_study(cfg, out, "tpe", trials=6, executor=ex, evaluator=logging_evaluator)
        assert again.asked == 0 and len(log.read_text().splitlines()) == 6
    study = optuna.load_study(study_name=STUDY_NAME, storage=optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(out / STUDY_FILE))))
    done = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) == 6 == len(study.trials)
    assert {t.user_attrs["design_key"] for t in done} == {key for _, key, _, _ in runs}
