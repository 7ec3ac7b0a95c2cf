"""Robust design: sweep or optimise a quantile of the Monte Carlo instead of the nominal value.

A sweep TOML with an ``[uncertainty]`` table (:mod:`designlab.predict.uncertainty`) runs, for
every design, its nominal prediction plus ``samples`` virtual builds; each Monte Carlo metric
``M`` becomes the columns ``mc.M.mean``, ``mc.M.std``, ``mc.M.p5``, ``mc.M.p50``, ``mc.M.p95``
of the design's row, and ``mc.failed`` counts its failed builds. Objectives and constraints may
name them::

    [uncertainty]
    samples = 64
    hysteresis_percent = { dist = "uniform", lo = 2.0, hi = 5.0 }

    [objectives]
    "mc.force_error_std.z.p95" = "min"     # the 95th percentile of the force error

The builds of one design run in its worker, in order, from ``SeedSequence([seed, index])`` (the
numbers do not depend on the executor); the design's FEM is the sweep's shared ``OUT/fem``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from designlab.errors import ParameterError
from designlab.params import did_you_mean
from designlab.predict.uncertainty import mc_metrics

STATS = ("mean", "std", "p5", "p50", "p95")


def _check_mc_name(part: str, where: str, name: str) -> None:
    metrics = mc_metrics(part)
    allowed = [f"mc.{m}.{s}" for m in metrics for s in STATS] + ["mc.failed"]
    if name not in allowed:
        raise ParameterError(f"{where}.{name}", name, f"a Monte Carlo metric of the {part}: "
                             f"mc.<metric>.<{'|'.join(STATS)}> with <metric> one of "
                             + ", ".join(metrics) + did_you_mean(name, allowed))


def robust_config(data: dict[str, Any]):
    """(SweepConfig, the checked uncertainty spec) of a sweep TOML dict with ``[uncertainty]``;
    ``mc.*`` objectives/constraints are checked here, the rest by the sweep's own loader."""
    from designlab.optimize.space import sweep_config
    from designlab.predict.uncertainty import parse_uncertainty

    data = dict(data)
    table = data.pop("uncertainty", None)
    if not isinstance(table, dict):
        raise ParameterError("uncertainty", table, "an [uncertainty] table (robust design)")
    part = data.get("part")
    mc = {}
    for sect in ("objectives", "constraints"):
        sec = dict(data.get(sect) or {})
        mc[sect] = {k: sec.pop(k) for k in list(sec) if str(k).startswith("mc.")}
        for k in mc[sect]:
            _check_mc_name(str(part), sect, k)
        data[sect] = sec
    placeholder = not data["objectives"] and mc["objectives"]
    if placeholder:                          # the loader needs one; ours replace it
        data["objectives"] = {"condition_number": "min"}
    cfg = sweep_config(data)
    spec = parse_uncertainty(cfg.part, table)
    objectives = {**mc["objectives"], **({} if placeholder else cfg.objectives)}
    cfg = dataclasses.replace(cfg, objectives=objectives,
                              constraints={**cfg.constraints, **mc["constraints"]})
    return cfg, spec


def load_robust_config(path: str | Path):
    from designlab.optimize.space import read_sweep_toml

    return robust_config(read_sweep_toml(path))


class RobustEvaluator:
    """Picklable evaluator: the design's nominal metrics plus its Monte Carlo columns."""

    def __init__(self, spec):
        self.spec = spec

    @property
    def key_extra(self) -> dict[str, Any]:
        """Part of each design's key (:func:`designlab.optimize.sweep.tasks_of`): a nominal row
        (no ``mc.*`` columns) or another spec's row is never reused for this one."""
        return {"uncertainty": dataclasses.asdict(self.spec)}

    def __call__(self, task: dict[str, Any]) -> dict[str, Any]:
        from designlab.optimize.evaluate import evaluate_design
        from designlab.predict.uncertainty import build_values, draw, run_batch, summarize

        out = evaluate_design(task)
        spec = dataclasses.replace(self.spec, sensor=task["part"])
        cols, V = draw(spec)
        settings = (task.get("settings") or {}).get("model")
        res = run_batch({"sensor": task["part"], "params": task["params"],
                         "settings": settings, "protocol": task.get("protocol") or None,
                         "fem_cache": task.get("fem_cache"), "seed": spec.seed,
                         "indices": list(range(len(V))),
                         "values": [build_values(spec, cols, v) for v in V]})
        s = summarize(spec, cols, V, res["rows"])
        out["mc"] = {m: {k: e[k] for k in STATS} for m, e in s["metrics"].items()}
        out["mc"]["failed"] = s["failed"]
        return out


def robust_optimize(path: str | Path, out: str | Path, *, method: str = "auto", executor=None,
                    progress=None):
    """:func:`designlab.optimize.optimizer.optimize` with :class:`RobustEvaluator`; returns
    (OptimizeResult, bands): per design key, each objective's 5-95 % band."""
    from designlab.optimize.optimizer import optimize

    cfg, spec = load_robust_config(path)
    res = optimize(cfg, out, method=method, evaluator=RobustEvaluator(spec), executor=executor,
                   progress=progress)
    return res, bands(res.sweep.rows, cfg)


def bands(rows: list[dict[str, Any]], cfg) -> dict[str, dict[str, Any]]:
    """Per design key and Monte Carlo objective/constraint ``mc.M.S``: (p5, p50, p95) of M."""
    out: dict[str, dict[str, Any]] = {}
    names = {n.rsplit(".", 1)[0] for n in [*cfg.objectives, *cfg.constraints]
             if n.startswith("mc.") and n != "mc.failed"}
    for r in rows:
        out[r["key"]] = {n: tuple(r.get(f"{n}.{q}") for q in ("p5", "p50", "p95"))
                         for n in sorted(names)}
    return out


def load_sweep(path: str | Path):
    """(SweepConfig, evaluator) of a sweep/optimize TOML: with an ``[uncertainty]`` table the
    robust config and a :class:`RobustEvaluator`, else the plain config and None (the sweep's
    default evaluator). A refused objective or constraint names the file."""
    from designlab.optimize.space import read_sweep_toml, sweep_config

    data = read_sweep_toml(path)
    try:
        if "uncertainty" in data:
            cfg, spec = robust_config(data)
            return cfg, RobustEvaluator(spec)
        return sweep_config(data), None
    except ParameterError as exc:   # an objective or constraint: the line names the file
        if not str(exc.name).startswith(("objectives.", "constraints.")):
            raise
        raise ParameterError(f"{path}: {exc.name}", exc.value, exc.allowed) from None


def band_lines(rows: list[dict[str, Any]], cfg, keys: list[str] | None = None,
               limit: int = 10) -> list[str]:
    """One text line per design (``keys`` first, then the table order, at most ``limit``):
    each Monte Carlo objective/constraint's 5 / 50 / 95 % band and the failed builds."""
    b = bands(rows, cfg)
    if not any(b.values()):
        return []
    by = {r["key"]: r for r in rows}
    order = list(dict.fromkeys([*(keys or []), *(r["key"] for r in rows)]))
    out = []
    for k in order[:limit]:
        r = by.get(k)
        if r is None or r.get("status") != "ok":
            continue
        txt = "; ".join(f"{n} {lo:.4g} / {mid:.4g} / {hi:.4g}" for n, (lo, mid, hi) in b[k].items()
                        if None not in (lo, mid, hi))
        failed = r.get("mc.failed")
        out.append(f"{k[:8]}: {txt} (5 / 50 / 95 %"
                   + (f"; {int(failed)} failed builds" if failed else "") + ")")
    return out
