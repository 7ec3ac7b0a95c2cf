"""Optimisation by an Optuna study, asked and told in batches: each trial's design goes through
the sweep's evaluator and result store (a design already stored is not computed again), on the
local pool or a Dask cluster. A batch holds one trial per worker (a pool's processes, a
cluster's worker threads), evaluated at the same time; one pool or client serves every batch.
The process running the study is its one writer (it asks and tells, under ``out``'s lock): the
workers only evaluate designs.

The study lives in ``OUT/study.log`` (Optuna's journal file storage: appended, it survives a
kill and ``optuna-dashboard OUT/study.log`` opens it). A run started again loads the study: the
trials a killed run left running are told from the store (or evaluated once), then new ones are
asked until the budget of finished trials is reached. Several objectives give a multi-objective
study; the config's constraints are Optuna constraints (one value per constraint, <= 0 when it
holds, as ``Trial.set_constraint`` stores them: the samplers and the dashboard read them).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from designlab.errors import ParameterError
from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import SweepConfig
from designlab.optimize.store import ResultStore, design_key
from designlab.optimize.sweep import (SweepResult, _evaluate, _pareto_and_best, _pending,
                                      compare_to_best, default_evaluator, materials_fingerprint)

#: Optuna samplers by ``--method`` name
SAMPLERS = ("tpe", "nsga2", "gp", "grid", "random", "qmc")
STUDY_FILE = "study.log"
STUDY_NAME = "designlab"
MAX_TRIALS = 100_000


@dataclass
class StudyResult:
    sweep: SweepResult                  # the study's designs, Pareto set, best and ties
    trials: int                         # finished trials in the study
    asked: int                          # trials asked in this run
    storage: Path
    info: dict[str, Any] = field(default_factory=dict)


def check_method(method: str, config: SweepConfig) -> None:
    """Refuse a sampler this config or installation cannot use (before anything is written)."""
    from designlab.params import did_you_mean

    if method not in SAMPLERS:
        raise ParameterError("--method", method, "one of " + ", ".join(SAMPLERS)
                             + did_you_mean(method, SAMPLERS))
    if not config.objectives:
        raise ParameterError("objectives", {}, "at least one objective (metric = \"min\"...)")
    if method == "gp":
        try:
            import torch  # noqa: F401  (Optuna's GP sampler runs on it)
        except ImportError:
            raise ParameterError("--method", method, "a sampler whose dependencies are "
                                 "installed (gp needs torch: pip install 'designlab[gp]')"
                                 ) from None


def _sampler(method: str, config: SweepConfig, seed: int):
    import optuna

    if method == "tpe":
        return optuna.samplers.TPESampler(multivariate=True, seed=seed)
    if method == "nsga2":
        return optuna.samplers.NSGAIISampler(population_size=8, seed=seed)
    if method == "gp":
        return optuna.samplers.GPSampler(seed=seed)
    if method == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if method == "qmc":
        return optuna.samplers.QMCSampler(seed=seed)
    return _Grid({d.name: [float(v) for v in d.grid()] for d in config.dimensions}, seed=seed)


def _grid_class():
    import optuna

    class Grid(optuna.samplers.GridSampler):
        """The grid, asked in batches: the budget (at most the grid's size) ends the study,
        not ``study.stop`` (which only an ``optimize`` loop may call)."""

        def after_trial(self, study, trial, state, values) -> None:
            pass

    return Grid


def _Grid(*args, **kw):
    return _grid_class()(*args, **kw)


def grid_size(config: SweepConfig) -> int:
    import math

    return math.prod(len(d.grid()) for d in config.dimensions)


def violations(row: dict[str, Any], constraints: dict[str, Any]) -> list[float]:
    """One value per constraint, <= 0 when it holds (a missing metric: 1, violated)."""
    out = []
    for name, spec in constraints.items():
        v = row.get(name)
        if v is None or v != v:
            out.append(1.0)
        elif spec is True:
            out.append(0.0 if v else 1.0)
        else:
            out.append(max(spec["min"] - v if "min" in spec else -1.0,
                           v - spec["max"] if "max" in spec else -1.0))
    return out


def _directions(config: SweepConfig) -> list[str]:
    return ["maximize" if s == "max" else "minimize" for s in config.objectives.values()]


def _values(row: dict[str, Any], config: SweepConfig) -> list[float] | None:
    """The trial's objective values (a target: the distance to it), None when one is missing."""
    import numpy as np

    out = []
    for name, spec in config.objectives.items():
        v = row.get(name)
        if row.get("status") != "ok" or v is None:
            return None
        out.append(float(v) if spec in ("min", "max")
                   else float(np.linalg.norm(np.asarray(v, float) - np.asarray(spec["target"]))))
    return out


def open_study(config: SweepConfig, out: Path, method: str, seed: int = 0):
    """The study of ``out`` (created, or loaded to resume) with the sampler ``method``. A
    loaded study's sampler is seeded with ``seed`` plus its number of trials: the same seed
    would ask again the random first trials of the run that created it (designs the store
    has, trials spent on nothing new)."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    out.mkdir(parents=True, exist_ok=True)
    storage = JournalStorage(JournalFileBackend(str(out / STUDY_FILE)))
    study = optuna.create_study(study_name=STUDY_NAME, storage=storage, load_if_exists=True,
                                sampler=_sampler(method, config, seed),
                                directions=_directions(config))
    n = len(study.get_trials(deepcopy=False))
    if n:
        study.sampler = _sampler(method, config, seed + n)
    return study


def _task(config: SweepConfig, swept: dict[str, float], extra: dict, fem_dir: Path) -> dict:
    params = {**config.fixed, **swept}
    return {"part": config.part, "params": params, "swept": swept, "settings": config.settings,
            "protocol": config.protocol, "fem_cache": str(fem_dir),
            "key": design_key(config.part, params, config.settings, config.protocol, extra)}


def _suggest(trial, config: SweepConfig) -> dict[str, float]:
    return {d.name: (float(trial.suggest_categorical(d.name, [float(v) for v in d.values]))
                     if d.values else trial.suggest_float(d.name, d.lo, d.hi))
            for d in config.dimensions}


def _tell(study, trial_number: int, trial_id: int, row: dict, config: SweepConfig) -> None:
    import optuna

    storage = study._storage
    storage.set_trial_user_attr(trial_id, "design_key", row["key"])
    for name, v in zip(config.constraints, violations(row, config.constraints)):
        storage.set_trial_system_attr(trial_id, f"constraints:{name}", float(v))
    values = _values(row, config)
    if values is None:
        study.tell(trial_number, state=optuna.trial.TrialState.FAIL)
    else:
        study.tell(trial_number, values)


def _extra(evaluator) -> dict[str, Any]:
    extra: dict[str, Any] = {"materials": materials_fingerprint()}
    if getattr(evaluator, "key_extra", None) is not None:
        extra["evaluator"] = evaluator.key_extra
    return extra


def _run_batch(study, store: ResultStore, batch: list[tuple[int, int, dict]], config,
               evaluator, executor, progress) -> int:
    """Evaluate (or reuse) the designs of ``batch`` ((number, id, task) per trial) and tell each
    trial its row; returns the designs evaluated."""
    unique = list({t["key"]: t for _, _, t in batch}.values())
    _, remaining = _pending(store, unique, config, False)
    _evaluate(store, executor, evaluator, remaining, config, lambda n, row: None)
    rows = {r["key"]: r for r in store.rows([t["key"] for t in unique])}
    for number, trial_id, task in batch:
        _tell(study, number, trial_id, rows[task["key"]], config)
        if progress:
            progress(rows[task["key"]])
    return len(remaining)


def run_study(config: SweepConfig, out: str | Path, method: str = "tpe", *, trials: int,
              evaluator: Callable | None = None, executor=None, batch: int | None = None,
              seed: int | None = None, progress: Callable[[int, int, dict], Any] | None = None,
              files=None) -> StudyResult:
    """Run the study of ``out`` until it holds ``trials`` finished trials (see module
    docstring); ``progress(done, total, row)`` after each told trial. ``batch`` trials are
    asked at a time (default: the executor's workers, a Dask cluster's worker threads) and
    evaluated at once, on one pool or client kept for the whole study. One run per ``out`` at
    a time (:func:`designlab.atomic.out_lock`). ``files`` (a :class:`~designlab.atomic.FileSet`):
    the table ``results.parquet`` is staged with it (the CLI commits it with the report)."""
    from designlab.atomic import out_lock

    check_method(method, config)
    if isinstance(trials, bool) or not isinstance(trials, int) or not 1 <= trials <= MAX_TRIALS:
        raise ParameterError("--trials", trials, f"an integer, 1 <= value <= {MAX_TRIALS}")
    out = Path(out)
    executor = executor or LocalExecutor()
    # one pool (or Dask client) for every batch of the study, when the executor can keep one
    keep = executor if hasattr(executor, "__enter__") else contextlib.nullcontext()
    with out_lock(out, "designlab optimize"), keep:
        return _run_study(config, out, method, trials, evaluator or default_evaluator,
                          executor, batch, config.seed if seed is None else seed, progress,
                          files)


def _run_study(config, out, method, trials, evaluator, executor, batch, seed, progress, files):
    import optuna

    store = ResultStore(out)
    store.recover()
    study = open_study(config, out, method, seed)
    extra = _extra(evaluator)
    batch = batch or getattr(executor, "workers", None) or 4
    if method == "grid":
        trials = min(trials, grid_size(config))
    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    done = len(study.get_trials(deepcopy=False, states=states))
    tell = _progress(progress, trials, done)
    evaluated = asked = 0
    # trials a killed run left running: told from the store, or evaluated once now
    stale = [(t.number, t._trial_id, _task(config, {d.name: float(t.params[d.name])
                                                     for d in config.dimensions}, extra,
                                           store.fem_dir))
             for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
             if all(d.name in t.params for d in config.dimensions)]
    if stale:
        evaluated += _run_batch(study, store, stale, config, evaluator, executor, tell)
    done = len(study.get_trials(deepcopy=False, states=states))
    while done < trials:
        new = []
        for _ in range(min(batch, trials - done)):
            trial = study.ask()
            new.append((trial.number, trial._trial_id,
                        _task(config, _suggest(trial, config), extra, store.fem_dir)))
        asked += len(new)
        evaluated += _run_batch(study, store, new, config, evaluator, executor, tell)
        done = len(study.get_trials(deepcopy=False, states=states))
    return StudyResult(_result(study, store, config, evaluated, files), done, asked, out / STUDY_FILE,
                       {"sampler": method, "trials": done, "evaluated": evaluated,
                        "storage": str(out / STUDY_FILE), "study": STUDY_NAME})


def _progress(progress, total: int, start: int):
    count = [start]

    def told(row: dict) -> None:
        count[0] += 1
        if progress:
            progress(count[0], total, row)

    return told


def _result(study, store: ResultStore, config: SweepConfig, evaluated: int,
            files=None) -> SweepResult:
    """The study's designs (trial order, each once) with their Pareto set, best and ties."""
    keys = list(dict.fromkeys(t.user_attrs["design_key"] for t in study.get_trials(deepcopy=False)
                              if "design_key" in t.user_attrs))
    rows = store.rows(keys)
    table_path = store.consolidate(files=files)
    pareto, best = _pareto_and_best(rows, config)
    ties, unknown = compare_to_best(rows, config, best) if best is not None else ([], [])
    warnings = []
    if unknown:
        warnings.append(f"{len(unknown)} design(s) have no discretisation error bar on an "
                        "objective (no mesh_convergence): whether they differ from the best "
                        "design by more than the mesh error is unknown, not zero")
    return SweepResult(rows, evaluated, len(rows) - evaluated,
                       sum(r.get("status") != "ok" for r in rows), pareto, best, table_path,
                       warnings, ties, unknown)


def best_so_far(rows: list[dict[str, Any]], config: SweepConfig) -> list[float]:
    """The best first objective (to minimise: max negated, target as distance) among the
    feasible designs of ``rows[:n]`` for n = 1..len(rows) (inf before a feasible one)."""
    from designlab.optimize.sweep import scores

    F = scores(rows, config)[:, 0]
    out, best = [], float("inf")
    for v in F:
        if v == v:
            best = min(best, float(v))
        out.append(best)
    return out
