"""Run a design sweep: every design of a :class:`SweepConfig` through an evaluator on an
executor, caching and storing results as they finish; resumable with the same command."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from designlab.errors import ClusterError, OutputError
from designlab.optimize.executors import LocalExecutor, LostTasks, cluster_lost
from designlab.optimize.failures import is_write_failure, write_failure_message
from designlab.optimize.pareto import non_dominated
from designlab.optimize.space import SweepConfig, feasible, objective_value
from designlab.optimize.store import ResultStore, design_key, flatten_metrics

Evaluator = Callable[[dict[str, Any]], dict[str, Any]]


def default_evaluator(task: dict[str, Any]) -> dict[str, Any]:
    """Geometry metrics + the virtual-test prediction of one design (imported lazily so that
    worker processes load only what they need)."""
    from designlab.optimize.evaluate import evaluate_design

    return evaluate_design(task)


def _timed(evaluator: Evaluator, task: dict[str, Any]) -> dict[str, Any]:
    t0 = time.perf_counter()
    out = evaluator(task)
    return {"metrics": out, "elapsed_s": time.perf_counter() - t0}


class _Timed:
    """Picklable wrapper timing the evaluator inside the worker."""

    def __init__(self, evaluator: Evaluator):
        self.evaluator = evaluator

    def __call__(self, task):
        return _timed(self.evaluator, task)


@dataclass
class SweepResult:
    rows: list[dict[str, Any]]        # one per design, in config order
    new: int                          # designs evaluated in this run
    reused: int                       # designs found in the store
    failed: int
    pareto_keys: list[str]
    best_key: str | None
    table_path: Path
    warnings: list[str] = dataclasses.field(default_factory=list)
    #: designs whose difference from the best design is within the discretisation error of
    #: that difference on every objective (see :func:`compare_to_best`)
    tie_keys: list[str] = dataclasses.field(default_factory=list)
    #: designs within the bars on every objective whose bar is known, but with an unknown bar
    #: (no mesh error estimate) on another: whether they differ from the best is unknown
    unknown_keys: list[str] = dataclasses.field(default_factory=list)


def materials_fingerprint() -> str:
    """Hash of the material library (moduli, Prony terms, gauge factors): a changed material
    invalidates cached predictions."""
    import hashlib

    from designlab.fem.materials import MATERIALS

    return hashlib.sha256(repr(sorted(MATERIALS.items())).encode()).hexdigest()[:16]


def tasks_of(config: SweepConfig, evaluator: Any = None) -> list[dict[str, Any]]:
    """One task per design; its key holds what determines its row: the design, the settings,
    the protocol, the material library and what the evaluator adds (``evaluator.key_extra``,
    e.g. a robust sweep's [uncertainty] spec: its rows carry Monte Carlo columns)."""
    materials = materials_fingerprint()
    extra: dict[str, Any] = {"materials": materials}
    evaluator_extra = getattr(evaluator, "key_extra", None)
    if evaluator_extra is not None:
        extra["evaluator"] = evaluator_extra
    out = []
    for swept in config.designs():
        params = {**config.fixed, **swept}
        out.append({"part": config.part, "params": params, "swept": swept,
                    "settings": config.settings, "protocol": config.protocol,
                    "key": design_key(config.part, params, config.settings, config.protocol,
                                      extra)})
    return out


def scores(rows: list[dict[str, Any]], config: SweepConfig) -> np.ndarray:
    """(n, k) objective values to minimise; NaN for failed or infeasible designs."""
    names = list(config.objectives)
    F = np.full((len(rows), len(names)), np.nan)
    for i, r in enumerate(rows):
        if r.get("status") != "ok" or not r.get("feasible", False):
            continue
        for j, n in enumerate(names):
            v = r.get(n)
            if v is not None:
                F[i, j] = objective_value(v, config.objectives[n])
    return F


def run_sweep(config: SweepConfig, out: str | Path, *, evaluator: Evaluator | None = None,
              executor=None, progress: Callable[[int, int, dict], None] | None = None,
              retry_failed: bool = False, files=None) -> SweepResult:
    """Evaluate every design not yet in ``out``; ``progress(done, total, row)`` after each.
    One run per ``out`` at a time (:func:`designlab.atomic.out_lock`); a killed run's temporary
    files are removed first. ``files`` (a :class:`~designlab.atomic.FileSet`): the table
    ``results.parquet`` is staged with it (the CLI commits it with the report)."""
    from designlab.atomic import out_lock

    out = Path(out)
    with out_lock(out, "designlab sweep"):
        return _run_sweep(config, out, evaluator=evaluator, executor=executor,
                          progress=progress, retry_failed=retry_failed, files=files)


def _run_sweep(config: SweepConfig, out: Path, *, evaluator, executor, progress,
               retry_failed: bool, files=None) -> SweepResult:
    store = ResultStore(out)
    store.recover()
    evaluator = evaluator or default_evaluator
    executor = executor or LocalExecutor()
    tasks = tasks_of(config, evaluator)
    for t in tasks:            # one FEM per distinct model, shared by the sweep's designs
        t["fem_cache"] = str(store.fem_dir)
    reused, remaining = _pending(store, tasks, config, retry_failed)
    if progress:
        progress(reused, len(tasks), {})
    _evaluate(store, executor, evaluator, remaining, config,
              lambda n, row: progress(reused + n, len(tasks), row) if progress else None)
    rows = store.rows([t["key"] for t in tasks])
    table_path = store.consolidate(files=files)
    pareto, best = _pareto_and_best(rows, config)
    warnings = _missing_metric_warnings(rows, config)
    ties, unknown = compare_to_best(rows, config, best) if best is not None else ([], [])
    if unknown:
        warnings.append(f"{len(unknown)} design(s) have no discretisation error bar on an "
                        "objective (no mesh_convergence): whether they differ from the best "
                        "design by more than the mesh error is unknown, not zero")
    return SweepResult(rows, len(remaining), reused, sum(r.get("status") != "ok" for r in rows),
                       pareto, best, table_path, warnings, ties, unknown)


def _pending(store: ResultStore, tasks: list[dict], config: SweepConfig,
             retry_failed: bool) -> tuple[int, list[dict]]:
    """(designs reused, tasks still to evaluate): a design in the store is reused (with
    ``retry_failed``, only if it did not fail; a design whose row says the cluster was lost,
    or that a write of it was refused (a full disk), never); one cached (finished) but killed before its
    row was written gets its row now."""
    done_keys = store.keys()
    failed = [r for r in store.rows() if r.get("status") != "ok"] if done_keys else []
    # a design the cluster lost (stored so by an older run) is not done; with retry_failed
    # no failed design is
    # a design whose write the file system refused (a full disk) is not done either
    done_keys -= {r["key"] for r in failed if retry_failed or cluster_lost(r.get("error"))
                  or is_write_failure(r.get("error"))}
    todo = [t for t in tasks if t["key"] not in done_keys]
    reused = len(tasks) - len(todo)
    remaining = []
    for t in todo:
        cached = store.cached(t["key"])
        if cached is not None and not retry_failed:
            store.put(t["key"], _row(t, cached["metrics"], None, cached["elapsed_s"], config), None)
            reused += 1
        else:
            remaining.append(t)
    return reused, remaining


def _evaluate(store: ResultStore, executor, evaluator, tasks: list[dict], config: SweepConfig,
              progress: Callable[[int, dict], Any]) -> None:
    """Evaluate ``tasks`` on the executor, storing each row (and its result) as it finishes;
    ``progress(done, row)`` after each. Designs the executor lost (its cluster failed) get no
    row: :class:`~designlab.errors.ClusterError` names them after the others are stored, and
    the same command runs them again. A design whose file could not be written (a full disk,
    :func:`~designlab.optimize.failures.is_write_failure`) stops the run with a one-line
    :class:`~designlab.errors.OutputError` and gets no row either."""
    n_done = 0
    try:
        for i, res, err in executor.run(_Timed(evaluator), tasks):
            t = tasks[i]
            if is_write_failure(err):
                # the file system's failure, not the design's: nothing stored for it (a rerun
                # evaluates it); the run stops, the designs finished stay stored
                raise OutputError(write_failure_message(err))
            if err is None:
                row = _row(t, res["metrics"], None, res["elapsed_s"], config)
                store.put(t["key"], row, res)
            else:
                row = _row(t, {}, err, float("nan"), config)
                store.put(t["key"], row, None)
            n_done += 1
            progress(n_done, row)
    except LostTasks as lost:
        keys = [tasks[i]["key"][:8] for i in lost.indices]
        raise ClusterError(f"{lost.reason}: {len(keys)} of {len(tasks)} designs not run "
                           f"({', '.join(keys)}); the {n_done} finished are stored in "
                           f"{store.root}: run the same command again to run the rest"
                           ) from None


def _pareto_and_best(rows: list[dict], config: SweepConfig) -> tuple[list[str], str | None]:
    """The Pareto set's keys and the best design's: the first objective's minimum, or with
    several objectives the Pareto design closest to the ideal point (each scaled to 0..1)."""
    F = scores(rows, config)
    pareto, best = [], None
    if not (F.shape[1] and len(rows)):
        return pareto, best
    mask = non_dominated(F)
    pareto = [rows[i]["key"] for i in np.flatnonzero(mask)]
    if F.shape[1] >= 1 and np.isfinite(F[:, 0]).any():
        best = rows[int(np.nanargmin(F[:, 0]))]["key"] if len(pareto) else None
        if len(pareto) > 1:
            Fp = F[mask]
            lo, hi = Fp.min(0), Fp.max(0)
            z = (Fp - lo) / np.where(hi > lo, hi - lo, 1)
            best = pareto[int(np.argmin(np.linalg.norm(z, axis=1)))]
    return pareto, best


def _missing_metric_warnings(rows: list[dict], config: SweepConfig) -> list[str]:
    """One warning per objective or constraint no evaluated design has."""
    ok = [r for r in rows if r.get("status") == "ok"]
    return [f"no design has the metric {name!r} (objective or constraint): it cannot rank or "
            "admit any design"
            for name in [*config.objectives, *config.constraints]
            if ok and all(r.get(name) is None for r in ok)]


#: metrics of the CAD (optimize.evaluate.geometry_metrics), not of a mesh: no discretisation error
CAD_METRICS = ("printed_volume_mm3", "printable", "min_wall_mm")


def error_bar(row: dict[str, Any], name: str, config: SweepConfig | None = None) -> float:
    """Discretisation error bar of metric ``name`` of a design: |value - value on the coarser
    mesh| (0 for a metric of the CAD or when the prediction rests on no mesh, NaN when unknown:
    a metric without a coarse value, or, given the ``config``, its model settings turned
    ``mesh_convergence`` off)."""
    if name in CAD_METRICS:
        return 0.0
    model = ((config.settings or {}).get("model") or {}) if config is not None else {}
    if model.get("mesh_convergence") is False:
        return float("nan")
    v, c = row.get(name), row.get(f"mesh_convergence.{name}.coarse")
    if row.get("mesh_convergence") is None and c is None:
        return 0.0 if "mesh_convergence" in row else float("nan")
    if v is None or c is None:
        return float("nan")
    return abs(float(v) - float(c))


def difference_error(a: dict[str, Any], b: dict[str, Any], name: str,
                     config: SweepConfig | None = None) -> float:
    """Error bar of the difference ``a - b`` of metric ``name`` (NaN: unknown). Designs that
    share one FEM (same ``fem_key``) share its discretisation error: their difference is
    compared at both mesh levels, |(a - b) - (a_c - b_c)|; otherwise the bars add."""
    if name in CAD_METRICS:
        return 0.0
    fa, fb = a.get("fem_key"), b.get("fem_key")
    if fa is not None and fa == fb:
        ca, cb = a.get(f"mesh_convergence.{name}.coarse"), b.get(f"mesh_convergence.{name}.coarse")
        if None not in (ca, cb, a.get(name), b.get(name)):
            return abs((float(a[name]) - float(b[name])) - (float(ca) - float(cb)))
    return error_bar(a, name, config) + error_bar(b, name, config)


def compare_to_best(rows: list[dict[str, Any]], config: SweepConfig, best_key: str
                    ) -> tuple[list[str], list[str]]:
    """(ties, unknown) among the feasible designs other than the best. On each objective a
    design's difference from the best is *within* the error bar of that difference, *apart*
    (beyond it) or *unknown* (no bar: NaN, never read as 0). Ties: within on every objective
    (one objective: on it; a Pareto config: on all of them), so the prediction cannot tell the
    design from the best and no choice between them rests on it. Unknown: apart on none, but
    unknown on one or more: whether it differs is not known. A design apart on any objective
    is distinguishable."""
    names = list(config.objectives)
    if not names:
        return [], []
    best = next(r for r in rows if r["key"] == best_key)
    ties, unknown = [], []
    for r in rows:
        if r["key"] == best_key or r.get("status") != "ok" or not r.get("feasible", False):
            continue
        if any(r.get(n) is None or best.get(n) is None for n in names):
            continue
        states = set()
        for n in names:
            err = difference_error(r, best, n, config)
            d = abs(float(r[n]) - float(best[n]))
            states.add("unknown" if not np.isfinite(err) else "within" if d <= err else "apart")
        if states == {"within"}:
            ties.append(r["key"])
        elif "apart" not in states:
            unknown.append(r["key"])
    return ties, unknown


def indistinguishable(rows: list[dict[str, Any]], config: SweepConfig, best_key: str
                      ) -> list[str]:
    """The ties of :func:`compare_to_best`: designs within the error bars of their difference
    from the best on every objective."""
    return compare_to_best(rows, config, best_key)[0]


def _row(task: dict[str, Any], metrics: dict[str, Any], error: str | None, elapsed: float,
         config: SweepConfig) -> dict[str, Any]:
    flat = flatten_metrics(metrics)
    row = {"key": task["key"], "part": task["part"], "status": "error" if error else "ok",
           "error": error, "elapsed_s": float(elapsed)}
    row.update({f"param.{k}": float(v) if isinstance(v, (int, float)) else str(v)
                for k, v in task["params"].items()})
    row.update(flat)
    row["feasible"] = bool(error is None and feasible(flat, config.constraints))
    return row
