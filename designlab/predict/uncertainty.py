"""Monte Carlo of a design's prediction: N virtual builds with scattered inputs, the readout
noise of each, and what drives the spread.

Each sensor brings its own Monte Carlo model in its record (``Sensor.uncertainty``, a
:class:`MonteCarloModel`: uncertain inputs with default distributions and sources, metrics, FEM
stage, one virtual build, the paper's numbers); this module names no sensor.

``[uncertainty]`` in a predict (or robust sweep) TOML gives each uncertain input a distribution;
inputs left out keep their default; ``samples`` and ``seed`` may sit in the table::

    [uncertainty]
    samples = 1000
    seed = 0
    sensitivity = "rank"          # or "sobol" (SALib: Saltelli sampling, N (2d + 2) builds)
    printed_modulus_scale = { dist = "uniform", lo = 0.84, hi = 1.0 }
    bolt_preload_N = { dist = "normal", mean = 20.0, std = 3.0, lo = 5.0 }
    fss015_sensitivity = { dist = "uniform", lo = 2.2, hi = 2.6 }
    friction_coefficient = { dist = "lognormal", mean = 0.23, std = 0.02 }
    pose_noise_mm = { dist = "fixed", value = 0.025 }

Distributions: ``normal`` (mean, std), ``lognormal`` (mean, std of the variable itself),
``uniform`` (lo, hi), ``fixed`` (value); normal and lognormal take optional bounds ``lo``/``hi``
(truncation by inverse CDF: every draw inside, no rejection). A negative spread, bounds that
exclude the mean, or a name the sensor does not have -> one-line :class:`ParameterError` naming
it and listing the allowed names.

Every draw comes from ``numpy.random.SeedSequence(seed)``: the inputs are drawn in the parent
before any work is sent out, each build's readout noise from its sample index, so local
processes, a Dask cluster and a resumed run give identical numbers. The FEM of a design is
computed once (the parent, before dispatch) into ``OUT/fem`` and every worker reads it; a
sampled modulus scale of the single printed material is applied to the condensed stiffness
(exact, :mod:`designlab.sensors.fingertip.calibration`), the FSS015 gain, preload and friction
need no FEM. Samples are written to ``OUT/samples/<batch>.json`` as they finish (atomic; a
rerun of the same command skips them); a failed build is recorded with its error and counted.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.params import check_keys, did_you_mean
from designlab.sensors.distributions import (
    _KEYS, DISTRIBUTIONS, Distribution, Input, MonteCarloModel)

TABLE_KEYS = ("samples", "seed", "sensitivity", "batch")
#: a design's build count is bounded: 10^6 virtual builds is a cluster's day
MAX_SAMPLES = 1_000_000


def model_of(sensor: str) -> MonteCarloModel:
    """The Monte Carlo model of ``sensor`` (its ``Sensor.uncertainty``), or a one-line error
    listing the sensors that have one."""
    from designlab.sensors.registry import SENSORS, get_sensor

    m = get_sensor(sensor).uncertainty
    if m is None:
        have = sorted(n for n, s in SENSORS.items() if s.uncertainty is not None)
        raise ParameterError("part", sensor, "a sensor with an uncertainty model: "
                             + ", ".join(have))
    return m


def sensor_inputs(sensor: str) -> tuple[Input, ...]:
    """The uncertain inputs of ``sensor``."""
    return tuple(model_of(sensor).inputs)


def mc_metrics(sensor: str) -> tuple[str, ...]:
    """The Monte Carlo metrics of ``sensor`` (empty when it has no uncertainty model)."""
    from designlab.sensors.registry import SENSORS

    s = SENSORS.get(sensor)
    return tuple(s.uncertainty.metrics) if s is not None and s.uncertainty is not None else ()


# ---------------------------------------------------------------------------------- the spec

@dataclass(frozen=True)
class UncertaintySpec:
    """A checked ``[uncertainty]`` table of one sensor."""

    sensor: str
    inputs: dict[str, Distribution]
    samples: int = 200
    seed: int = 0
    sensitivity: str = "rank"
    batch: int = 25

    def columns(self) -> list[str]:
        """Sampled variables (an input with ``per_build`` k > 1 gives ``name.1 .. name.k``)."""
        per = {i.name: i.per_build for i in sensor_inputs(self.sensor)}
        out = []
        for n, d in self.inputs.items():
            if d.dist == "fixed" or (d.std == 0 and d.dist in ("normal", "lognormal")) or (
                    d.dist == "uniform" and d.lo == d.hi):
                continue
            out += [n] if per[n] == 1 else [f"{n}.{k + 1}" for k in range(per[n])]
        return out

    def to_json(self) -> dict[str, Any]:
        return {"sensor": self.sensor, "samples": self.samples, "seed": self.seed,
                "sensitivity": self.sensitivity,
                "inputs": {k: v.to_json() for k, v in self.inputs.items()}}


def input_range(sensor: str, inp: Input) -> dict[str, Any] | None:
    """The values a build of ``sensor`` accepts for input ``inp`` (a field's lo/hi metadata):
    the input's own ``allowed``, else the sensor's model setting, part parameter or protocol
    field of the same name (the build passes the value through it), else for a ``*_scale``
    input a positive number (a scale of a modulus, a gain, a width); None: no range known."""
    import dataclasses

    if inp.allowed is not None:
        return dict(inp.allowed)
    from designlab.sensors.registry import get_sensor

    s = get_sensor(sensor)
    for cls in (s.settings, s.part, s.protocol):
        try:
            fields = {f.name: f for f in dataclasses.fields(cls)}
        except TypeError:
            continue
        meta = fields[inp.name].metadata if inp.name in fields else None
        if meta and (meta.get("lo") is not None or meta.get("hi") is not None):
            return dict(meta)
    if inp.name.endswith("_scale"):
        return {"lo": 0.0, "lo_open": True}
    return None


def _int(name: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise ParameterError(name, v, f"an integer, {lo} <= value <= {hi}")
    return v


def parse_uncertainty(sensor: str, table: dict[str, Any] | None, *, samples: int | None = None
                      ) -> UncertaintySpec:
    """The checked spec: defaults for every input of ``sensor``, replaced by the table's."""
    table = dict(table or {})
    inputs = {i.name: i for i in sensor_inputs(sensor)}
    names = sorted(inputs)
    opts = {k: table.pop(k) for k in TABLE_KEYS if k in table}
    for k in table:
        if k not in inputs:
            raise ParameterError(f"uncertainty.{k}", table[k], f"an input of the {sensor}: "
                                 + ", ".join(names) + did_you_mean(k, names)
                                 + f" (or {', '.join(TABLE_KEYS)})")
    dists = {}
    for n, inp in inputs.items():
        if n not in table:
            dists[n] = inp.default
            continue
        v = table[n]
        if not isinstance(v, dict):
            raise ParameterError(f"uncertainty.{n}", v, "a table { dist = \"normal\", mean = "
                                 "..., std = ... } (or uniform lo/hi, lognormal, fixed value)")
        kind = v.get("dist")
        if kind not in DISTRIBUTIONS:
            raise ParameterError(f"uncertainty.{n}.dist", kind, "one of "
                                 + ", ".join(DISTRIBUTIONS) + did_you_mean(str(kind), DISTRIBUTIONS))
        check_keys(v, ("dist", "source", *_KEYS[kind]), f"uncertainty.{n}")
        src = v.get("source", "user ([uncertainty] table)")
        if not isinstance(src, str):
            raise ParameterError(f"uncertainty.{n}.source", src, "text")
        dists[n] = Distribution(kind, **{k: v[k] for k in _KEYS[kind] if k in v},
                                source=src).check(n)
        meta = input_range(sensor, inp)
        if meta is not None:
            dists[n].check_within(n, meta, dists[n].short())
    n_samples = samples if samples is not None else opts.get("samples", 200)
    n_samples = _int("--samples" if samples is not None else "uncertainty.samples", n_samples,
                     2, MAX_SAMPLES)
    seed = _int("uncertainty.seed", opts.get("seed", 0), 0, 2 ** 32 - 1)
    sens = opts.get("sensitivity", "rank")
    if sens not in ("rank", "sobol"):
        raise ParameterError("uncertainty.sensitivity", sens, "rank or sobol")
    batch = _int("uncertainty.batch", opts.get("batch", 25), 1, 10000)
    return UncertaintySpec(sensor, dists, n_samples, seed, sens, batch)


def load_uncertainty(sensor: str, path: str | Path | None, *, samples: int | None = None
                     ) -> UncertaintySpec:
    """``[uncertainty]`` of a TOML file (or its top level), or the defaults when None."""
    from designlab.params import load_toml

    table = None
    if path is None:
        return parse_uncertainty(sensor, table, samples=samples)
    data = load_toml(path, "--uncertainty")
    table = data.get("uncertainty", data)
    if not isinstance(table, dict):
        raise ParameterError(f"{path}: uncertainty", table, "a TOML table")
    try:
        return parse_uncertainty(sensor, table, samples=samples)
    except ParameterError as exc:      # the line names the file that holds the key
        if not str(exc.name).startswith("uncertainty"):
            raise
        raise ParameterError(f"{path}: {exc.name}", exc.value, exc.allowed) from None


# ----------------------------------------------------------------------------------- drawing

def draw(spec: UncertaintySpec) -> tuple[list[str], np.ndarray]:
    """(columns, values (n_builds, n_columns)): plain Monte Carlo from ``SeedSequence(seed)``,
    or SALib's Saltelli design for Sobol indices (then n_builds = samples (2 d + 2))."""
    cols = spec.columns()
    per = {i.name: i.per_build for i in sensor_inputs(spec.sensor)}
    dist_of = {}
    for n, d in spec.inputs.items():
        for c in ([n] if per[n] == 1 else [f"{n}.{k + 1}" for k in range(per[n])]):
            dist_of[c] = d
    if spec.sensitivity == "sobol" and cols:
        from SALib.sample import sobol as sobol_sample

        problem = {"num_vars": len(cols), "names": cols, "bounds": [[0.0, 1.0]] * len(cols)}
        U = sobol_sample.sample(problem, _pow2(spec.samples), calc_second_order=True,
                                seed=spec.seed)
        U = np.clip(U, 1e-12, 1 - 1e-12)
    else:
        U = np.random.default_rng(np.random.SeedSequence(spec.seed)).random(
            (spec.samples, len(cols)))
    V = np.column_stack([dist_of[c].ppf(U[:, j]) for j, c in enumerate(cols)]) if cols \
        else np.zeros((len(U), 0))
    return cols, V


def _pow2(n: int) -> int:
    return 1 << max(1, int(math.ceil(math.log2(max(n, 2)))))


def build_values(spec: UncertaintySpec, cols: list[str], row: np.ndarray) -> dict[str, Any]:
    """One build's input values by input name (per-build inputs as lists)."""
    per = {i.name: i.per_build for i in sensor_inputs(spec.sensor)}
    vals = dict(zip(cols, map(float, row)))
    out = {}
    for n, d in spec.inputs.items():
        if per[n] == 1:
            out[n] = vals.get(n, d.center)
        else:
            out[n] = [vals.get(f"{n}.{k + 1}", d.center) for k in range(per[n])]
    return out


# ------------------------------------------------------------------------- one build, a batch

def build_seed(seed: int, index: int) -> int:
    """The readout-noise seed of build ``index`` (independent of batching and scheduling)."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def _fem_stage(sensor: str, params: dict, settings: dict | None, protocol: dict | None,
               fem_dir: str | None):
    """(context, fem misses): the design's FEM stage through the cache."""
    from designlab.fem.cache import FEMCache
    from designlab.geometry.parts import make_part

    part = make_part(sensor, params)
    cache = FEMCache(fem_dir)
    ctx = model_of(sensor).fem_stage(part, settings, protocol, cache)
    return ctx, cache.misses


def run_batch(task: dict[str, Any]) -> dict[str, Any]:
    """Evaluate builds ``task["indices"]`` (values in ``task["values"]``). Picklable, top level:
    the executors' unit of work. Failed builds are returned with their error."""
    sensor = task["sensor"]
    t0 = time.perf_counter()
    model = model_of(sensor)
    ctx, misses = _fem_stage(sensor, task["params"], task.get("settings"),
                             task.get("protocol"), task.get("fem_cache"))
    rows = []
    for idx, values in zip(task["indices"], task["values"]):
        seed = build_seed(task["seed"], idx)
        try:
            m = model.build(ctx, values, seed)
            bad = [k for k, v in m.items() if v is not None and not np.isfinite(v)]
            if bad:
                raise FloatingPointError(f"non-finite {bad[0]}")
            rows.append({"index": idx, "status": "ok", "metrics": m})
        except Exception as exc:   # recorded and counted, never dropped
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            rows.append({"index": idx, "status": "failed",
                         "error": f"{type(exc).__name__}: {msg}"})
    return {"rows": rows, "fem_solves": misses, "elapsed_s": time.perf_counter() - t0}


# ------------------------------------------------------------------------------ the summary

def summarize(spec: UncertaintySpec, cols: list[str], V: np.ndarray, rows: list[dict]
              ) -> dict[str, Any]:
    """Per metric: mean, std, 5/50/95 % quantiles over the successful builds, and the inputs
    that drive it (Spearman rank correlation, or SALib Sobol S1/ST with ``sensitivity =
    "sobol"``); the failed builds counted with their errors."""
    ok = [i for i, r in enumerate(rows) if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    names = sorted({k for i in ok for k in rows[i]["metrics"]})
    metrics = {}
    for m in names:
        idx = [i for i in ok if rows[i]["metrics"].get(m) is not None]
        y = np.array([rows[i]["metrics"][m] for i in idx], float)
        if len(y):
            metrics[m] = {**_spread(y), "drivers": _drivers(spec, cols, V, idx, y)}
    errors: dict[str, int] = {}
    for r in failed:
        errors[r.get("error", "?")] = errors.get(r.get("error", "?"), 0) + 1
    return {"sensor": spec.sensor, "builds": len(rows), "ok": len(ok), "failed": len(failed),
            "failed_errors": errors, "failed_indices": [r["index"] for r in failed][:100],
            "sensitivity_method": ("Sobol indices (SALib, Saltelli design)"
                                   if spec.sensitivity == "sobol"
                                   else "Spearman rank correlation"),
            "spec": spec.to_json(), "inputs_sampled": cols, "metrics": metrics,
            "paper": model_of(spec.sensor).paper}


def _spread(y: np.ndarray) -> dict[str, Any]:
    """Mean, standard deviation (0 for one build), 5/50/95 % quantiles and count of ``y``."""
    q5, q50, q95 = np.quantile(y, [0.05, 0.5, 0.95])
    return {"mean": float(y.mean()), "std": float(y.std(ddof=1)) if len(y) > 1 else 0.0,
            "p5": float(q5), "p50": float(q50), "p95": float(q95), "n": int(len(y))}


def _drivers(spec: UncertaintySpec, cols: list[str], V: np.ndarray, idx: list[int],
             y: np.ndarray) -> dict[str, Any]:
    """The inputs that drive one metric ``y`` (builds ``idx`` of the samples ``V``), strongest
    first: Sobol S1/ST (``sensitivity = "sobol"``, every build succeeded) or Spearman's rho;
    none for fewer than three builds or a constant metric."""
    if not (cols and len(y) > 2 and np.ptp(y) > 0):
        return {}
    if spec.sensitivity == "sobol" and len(y) == len(V):
        from SALib.analyze import sobol as sobol_analyze

        problem = {"num_vars": len(cols), "names": cols, "bounds": [[0.0, 1.0]] * len(cols)}
        Si = sobol_analyze.analyze(problem, y, calc_second_order=True, seed=spec.seed)
        drivers = {c: {"S1": float(Si["S1"][j]), "ST": float(Si["ST"][j])}
                   for j, c in enumerate(cols)}
        return dict(sorted(drivers.items(), key=lambda kv: -kv[1]["ST"]))
    from scipy.stats import spearmanr

    X = V[idx]
    rho = {}
    for j, c in enumerate(cols):
        if np.ptp(X[:, j]) > 0:
            r = spearmanr(X[:, j], y).statistic
            rho[c] = float(r) if np.isfinite(r) else 0.0
    return dict(sorted(rho.items(), key=lambda kv: -abs(kv[1])))


def summary_rows(summary: dict[str, Any], drivers: int = 2) -> list[tuple[str, str, str, str, str]]:
    """(metric, mean, p5, p95, strongest drivers) as text, for the CLI's table."""
    out = []
    for m, e in summary["metrics"].items():
        d = e.get("drivers") or {}
        if d and isinstance(next(iter(d.values())), dict):
            txt = ", ".join(f"{k} (ST {v['ST']:.2f})" for k, v in list(d.items())[:drivers])
        else:
            txt = ", ".join(f"{k} ({v:+.2f})" for k, v in list(d.items())[:drivers])
        out.append((m, f"{e['mean']:.4g}", f"{e['p5']:.4g}", f"{e['p95']:.4g}", txt))
    return out
