"""Single-objective optimisation (surrogate on the sweep, or differential evolution) and the
multi-objective choice from the Pareto front.

* ``surrogate``: run the sweep, fit a radial-basis-function surrogate (scipy
  ``RBFInterpolator``, thin-plate spline, on parameters scaled to the unit cube) of the objective
  over the feasible designs, minimise it with differential evolution, then evaluate the
  surrogate's optimum for real; the better of it and the best sweep design is chosen.
* ``de``: scipy ``differential_evolution`` calling the evaluator directly (every evaluation cached
  in the sweep store; costly: ``maxiter x popsize x dims`` predictions).
* ``pareto`` (several objectives): the non-dominated designs of the sweep; the chosen one is
  closest to the ideal point after scaling each objective over the front.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.optimize import differential_evolution

from designlab.errors import OutputError, ParameterError
from designlab.optimize.executors import LocalExecutor
from designlab.optimize.failures import error_text, is_write_failure, write_failure_message
from designlab.optimize.space import Dimension, SweepConfig, objective_value
from designlab.optimize.store import ResultStore, design_key
from designlab.optimize.sweep import (SweepResult, _row, default_evaluator, materials_fingerprint,
                                      run_sweep)

METHODS = ("auto", "surrogate", "de", "pareto")


@dataclass
class OptimizeResult:
    method: str
    sweep: SweepResult
    chosen: dict[str, Any]               # the chosen design's table row
    chosen_params: dict[str, float]
    surrogate: dict[str, Any] | None = None
    history: list[dict[str, Any]] | None = None


def _evaluate_one(config: SweepConfig, params: dict[str, float], evaluator, store: ResultStore
                  ) -> dict[str, Any]:
    full = {**config.fixed, **params}
    key = design_key(config.part, full, config.settings, config.protocol,
                     {"materials": materials_fingerprint()})
    task = {"part": config.part, "params": full, "swept": params, "settings": config.settings,
            "protocol": config.protocol, "key": key}
    if store.has_row(key):
        return store.rows([key])[0]
    import time

    t0 = time.perf_counter()
    try:
        metrics = evaluator(task)
        err = None
    except Exception as exc:
        metrics, err = {}, error_text(exc)
        if is_write_failure(err):     # a full disk: not the design's failure, nothing stored
            raise OutputError(write_failure_message(err)) from None
    elapsed = time.perf_counter() - t0
    row = _row(task, metrics, err, elapsed, config)
    store.put(key, row, {"metrics": metrics, "elapsed_s": elapsed} if err is None else None)
    return row


def _penalised(row: dict[str, Any], name: str, spec: Any) -> float:
    if row.get("status") != "ok" or not row.get("feasible") or row.get(name) is None:
        return 1e12
    return objective_value(row[name], spec)


def _unit(dims: tuple[Dimension, ...], x: np.ndarray) -> np.ndarray:
    lo = np.array([d.lo for d in dims])
    hi = np.array([d.hi for d in dims])
    return (x - lo) / np.where(hi > lo, hi - lo, 1.0)


def check_method(method: str, config: SweepConfig) -> str:
    """The method ``optimize`` runs for ``config`` (``auto`` resolved), or a one-line
    :class:`ParameterError` when the config cannot use it: no objective, several objectives
    for a single-objective method, value lists for a continuous one. Callers check this
    before anything is written."""
    if method not in METHODS:
        raise ParameterError("method", method, "one of " + ", ".join(METHODS))
    names = list(config.objectives)
    if not names:
        raise ParameterError("objectives", {}, "at least one objective (metric = \"min\"...)")
    if method == "auto":
        method = "pareto" if len(names) > 1 else "surrogate"
    if method in ("surrogate", "de") and len(names) != 1:
        raise ParameterError("objectives", names, f"exactly one objective for method {method}")
    if any(d.values for d in config.dimensions) and method in ("surrogate", "de"):
        raise ParameterError("parameters", [d.name for d in config.dimensions if d.values][0],
                             "ranges (not value lists) for continuous optimisation")
    return method


def optimize(config: SweepConfig, out: str | Path, *, method: str = "auto",
             evaluator: Callable | None = None, executor=None, maxiter: int = 10,
             popsize: int = 6, seed: int = 0, progress=None, files=None) -> OptimizeResult:
    """Optimise ``config.objectives`` over ``config.dimensions`` (see module docstring).
    ``files`` (a :class:`~designlab.atomic.FileSet`): the table ``results.parquet`` is staged
    with it (the CLI commits it with the report)."""
    method = check_method(method, config)
    names = list(config.objectives)
    evaluator = evaluator or default_evaluator
    executor = executor or LocalExecutor()
    store = ResultStore(out)
    sweep = run_sweep(config, out, evaluator=evaluator, executor=executor, progress=progress,
                      files=files)
    dims = config.dimensions
    keyed = {r["key"]: r for r in sweep.rows}

    if method == "pareto":
        if sweep.best_key is None:
            raise ParameterError("constraints", config.constraints,
                                 "constraints that at least one design of the sweep satisfies")
        chosen = keyed[sweep.best_key]
        return OptimizeResult("pareto", sweep, chosen, _params(chosen, dims))

    name, spec = names[0], config.objectives[names[0]]
    bounds = [(d.lo, d.hi) for d in dims]
    if method == "de":
        history = []

        def f(x):
            row = _evaluate_one(config, dict(zip([d.name for d in dims], map(float, x))),
                                evaluator, store)
            history.append(row)
            if progress:
                progress(len(history), None, row)
            return _penalised(row, name, spec)

        res = differential_evolution(f, bounds, maxiter=maxiter, popsize=popsize, seed=seed,
                                     polish=False, tol=1e-6)
        best = min(history, key=lambda r: _penalised(r, name, spec))
        store.consolidate(files=files)      # with the designs the evolution added
        return OptimizeResult("de", sweep, best, _params(best, dims),
                              {"nfev": int(res.nfev), "fun": float(res.fun)}, history)

    # surrogate on the sweep
    X, y = [], []
    for r in sweep.rows:
        v = _penalised(r, name, spec)
        if v < 1e12:
            X.append([r[f"param.{d.name}"] for d in dims])
            y.append(v)
    if len(y) < len(dims) + 2:
        raise ParameterError("samples", len(y),
                             f">= {len(dims) + 2} feasible sweep designs to fit a surrogate")
    X = np.array(X, float)
    y = np.array(y, float)
    rbf = RBFInterpolator(_unit(dims, X), y, kernel="thin_plate_spline", degree=1)
    res = differential_evolution(lambda u: float(rbf(u[None])[0]), [(0.0, 1.0)] * len(dims),
                                 seed=seed, tol=1e-8, maxiter=200)
    x_opt = np.array([d.lo + u * (d.hi - d.lo) for d, u in zip(dims, res.x)])
    row_opt = _evaluate_one(config, dict(zip([d.name for d in dims], map(float, x_opt))),
                            evaluator, store)
    best_sweep = min(sweep.rows, key=lambda r: _penalised(r, name, spec))
    chosen = min([row_opt, best_sweep], key=lambda r: _penalised(r, name, spec))
    store.consolidate(files=files)
    return OptimizeResult("surrogate", sweep, chosen, _params(chosen, dims),
                          {"predicted": float(res.fun), "actual": _penalised(row_opt, name, spec),
                           "x": x_opt.tolist(), "n_train": len(y)})


def _params(row: dict[str, Any], dims) -> dict[str, float]:
    return {d.name: row[f"param.{d.name}"] for d in dims}
