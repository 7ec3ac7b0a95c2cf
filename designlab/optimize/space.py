"""Sweep configuration and design-space sampling (grid, Latin hypercube, Sobol).

A sweep config (TOML)::

    part = "NAME"                 # a sensor name, or a definition "FILE.py[:Class]" (relative
                                  # to the config's folder) or "module:Class"
    method = "grid"               # grid | lhs | sobol
    samples = 16                  # lhs/sobol: number of designs (sobol rounds up to 2^m)
    seed = 0
    [parameters]                  # ranges of the swept parameters (part units: mm, rad, ...)
    h = { range = [0.0, 20.0], levels = 3 }     # levels: grid only
    r = [3.0, 9.0]                              # shorthand for a range
    coils = { values = [3.0, 3.75, 4.5] }       # explicit values (grid)
    [fixed]                       # other part parameters held fixed
    [settings]                    # analysis settings passed to the evaluator (mesh size, ...)
    [objectives]                  # metric = "min" | "max" | { target = x }
    condition_number = "min"
    [constraints]                 # metric = { max = x } / { min = x } / true (must be truthy)
    printable = true
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import qmc

from designlab.errors import ParameterError
from designlab.params import (_short, check_field, check_keys, check_tree, did_you_mean,
                              load_toml, with_overrides)

METHODS = ("grid", "lhs", "sobol")


@dataclass(frozen=True)
class Dimension:
    """One swept parameter: a range [lo, hi] with ``levels`` grid points, or explicit values."""

    name: str
    lo: float
    hi: float
    levels: int = 3
    values: tuple[float, ...] = ()

    def grid(self) -> np.ndarray:
        if self.values:
            return np.asarray(self.values, float)
        return np.linspace(self.lo, self.hi, self.levels)

    def scale(self, u: np.ndarray) -> np.ndarray:
        """Map unit-cube samples to the range (or to the nearest listed value)."""
        if self.values:
            v = np.asarray(self.values, float)
            return v[np.minimum((u * len(v)).astype(int), len(v) - 1)]
        return self.lo + u * (self.hi - self.lo)


@dataclass(frozen=True)
class SweepConfig:
    part: str
    dimensions: tuple[Dimension, ...]
    method: str = "grid"
    samples: int = 8
    seed: int = 0
    fixed: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    objectives: dict[str, Any] = field(default_factory=dict)
    constraints: dict[str, Any] = field(default_factory=dict)
    protocol: dict[str, Any] = field(default_factory=dict)

    def designs(self) -> list[dict[str, float]]:
        """Swept parameter values of every design, in a deterministic order."""
        if self.method == "grid":
            grids = [d.grid() for d in self.dimensions]
            pts = list(itertools.product(*grids))
        else:
            k = len(self.dimensions)
            if self.method == "lhs":
                u = qmc.LatinHypercube(d=k, seed=self.seed).random(self.samples)
            else:
                m = int(np.ceil(np.log2(max(self.samples, 1))))
                u = qmc.Sobol(d=k, scramble=True, seed=self.seed).random_base2(m)
            pts = np.column_stack([d.scale(u[:, i]) for i, d in enumerate(self.dimensions)])
        return [{d.name: float(v) for d, v in zip(self.dimensions, p)} for p in pts]


MAX_DESIGNS = 100_000      # designs of one sweep (grid product or samples)
MAX_LEVELS = 10_000        # grid levels or listed values of one parameter

#: metrics a design's row has (``designlab.optimize.evaluate``): exact names, and families whose
#: members depend on the sensor (``hysteresis_percent.overall``, ``sensitivity.V_per_N.z``...)
METRICS = ("printed_volume_mm3", "printable", "min_wall_mm", "condition_number",
           "geometric_condition_number", "linearity_percent_span", "k_x_N_per_m",
           "k_y_N_per_m", "k_z_N_per_m", "K_f_target_error", "axial_share_through_sensors",
           "min_safety_factor", "sensitivity_norm", "condition_number_scaled")
METRIC_FAMILIES = ("hysteresis_percent.", "sensitivity.", "timings_s.",
                   "linearity_percent_span.", "electrical.", "mesh_convergence.", "force_error.",
                   "noise_budget.", "cross_talk_percent.")
SETTINGS = ("model", "K_f_target_N_per_m")
#: largest magnitude of an objective's target: the distance |value - target| stays far below
#: the 1e12 the optimiser gives a failed or infeasible design, and a metric's differences stay
#: resolved in it (at 1e308 every distance was the same number, or overflowed to inf)
MAX_TARGET = 1e9


def _number(name: str, v: Any, allowed: str = "a finite number") -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ParameterError(name, _short(v), allowed)
    return float(v)


def _integer(name: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise ParameterError(name, _short(v), f"an integer, {lo} <= value <= {hi}")
    return v


def _table(name: str, v: Any) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise ParameterError(name, _short(v), f"a table ([{name}] or {name} = {{...}})")
    return v


def _metric(where: str, name: str) -> None:
    if name in METRICS or any(name.startswith(f) and len(name) > len(f) for f in METRIC_FAMILIES):
        return
    raise ParameterError(f"{where}.{name}", name, "a metric of a design: " + ", ".join(METRICS)
                         + " or " + ", ".join(f + "..." for f in METRIC_FAMILIES)
                         + did_you_mean(name, METRICS))


def _dimension(name: str, spec: Any, meta: Any = None) -> Dimension:
    allowed = "[lo, hi], {range = [lo, hi], levels = n} or {values = [...]}"
    where = f"parameters.{name}"
    if isinstance(spec, list) and len(spec) == 2:
        spec = {"range": spec}
    if not isinstance(spec, dict):
        raise ParameterError(where, _short(spec), allowed)
    if "values" in spec:
        check_keys(spec, ("values",), where)
        raw = spec["values"]
        if not isinstance(raw, list) or not raw or len(raw) > MAX_LEVELS:
            raise ParameterError(f"{where}.values", _short(raw),
                                 f"a non-empty list of at most {MAX_LEVELS} numbers")
        vals = tuple(_number(f"{where}.values[{i}]", v) for i, v in enumerate(raw))
        if len(set(vals)) != len(vals):
            raise ParameterError(f"{where}.values", _short(raw), "distinct values")
        ends = (min(vals), max(vals))
        dim = Dimension(name, ends[0], ends[1], len(vals), vals)
    else:
        check_keys(spec, ("range", "levels"), where)
        r = spec.get("range")
        if not (isinstance(r, list) and len(r) == 2):
            raise ParameterError(f"{where}.range", _short(r), "[lo, hi] with lo <= hi")
        lo, hi = (_number(f"{where}.range", x, "[lo, hi]: finite numbers, lo <= hi") for x in r)
        if lo > hi:
            raise ParameterError(f"{where}.range", _short(r), "[lo, hi] with lo <= hi")
        levels = _integer(f"{where}.levels", spec.get("levels", 3), 1, MAX_LEVELS)
        if lo == hi and levels > 1:
            raise ParameterError(f"{where}.levels", levels, "1 when lo == hi (or a range lo < hi)")
        ends = (lo, hi)
        dim = Dimension(name, lo, hi, levels)
    if meta is not None:  # both ends must be allowed values of the part
        for x in ends:
            try:
                check_field(name, x, meta)
            except ParameterError as exc:
                raise ParameterError(where, _short(spec.get("values", spec.get("range"))),
                                     "values within " + exc.allowed) from None
    return dim


def _direction(name: str, spec: Any) -> Any:
    _metric("objectives", name)
    if spec in ("min", "max"):
        return spec
    if isinstance(spec, dict) and set(spec) == {"target"}:
        t = spec["target"]
        allowed = (f"one finite number, |target| <= {MAX_TARGET:g} in the metric's unit (every "
                   "metric of a design is a single number)")
        if abs(_number(f"objectives.{name}.target", t, allowed)) > MAX_TARGET:
            raise ParameterError(f"objectives.{name}.target", _short(t), allowed)
        return spec
    raise ParameterError(f"objectives.{name}", _short(spec), '"min", "max" or {target = value}')


def _constraint(name: str, v: Any) -> Any:
    _metric("constraints", name)
    if v is True:
        return v
    if isinstance(v, dict) and v and set(v) <= {"min", "max"}:
        for k, x in v.items():
            _number(f"constraints.{name}.{k}", x)
        if "min" in v and "max" in v and v["min"] > v["max"]:
            raise ParameterError(f"constraints.{name}", _short(v), "min <= max")
        return v
    raise ParameterError(f"constraints.{name}", _short(v), "true, {min = x} and/or {max = x}")


def _part_of(part: Any) -> tuple[str, str]:
    """(the config's part as every worker resolves it, its registered name): a sensor name, or
    a definition spec made canonical (a file's absolute path)."""
    from designlab.geometry.parts import PARTS
    from designlab.sensors.registry import canonical, get_sensor, looks_like_definition

    if not isinstance(part, str):
        raise ParameterError("part", _short(part), "a part name: " + ", ".join(PARTS)
                             + " or a sensor definition FILE.py[:Class]")
    if looks_like_definition(part):
        part = canonical(part)
    return part, get_sensor(part).name


def sweep_config(data: dict[str, Any]) -> SweepConfig:
    """Validate a parsed config dict (see module docstring) against the part (swept and fixed
    parameters, their ranges), its protocol and model settings, and the metrics a design has
    (objectives, constraints): a config that would fail every design is an error here."""
    known = ("part", "method", "samples", "seed", "parameters", "fixed", "settings",
             "objectives", "constraints", "protocol")
    check_keys(data, known)
    check_tree(data, "config")
    from designlab.geometry.parts import PARTS

    part, name = _part_of(data.get("part"))
    method = data.get("method", "grid")
    if method not in METHODS:
        raise ParameterError("method", _short(method), "one of " + ", ".join(METHODS)
                             + did_you_mean(str(method), METHODS))
    samples = _integer("samples", data.get("samples", 8), 1, MAX_DESIGNS)
    seed = _integer("seed", data.get("seed", 0), 0, 2 ** 32 - 1)
    params = data.get("parameters", {})
    if not isinstance(params, dict) or not params:
        raise ParameterError("parameters", _short(params),
                             "a table with at least one swept parameter")
    fields = {f.name: f for f in dataclasses.fields(PARTS[name])}
    check_keys(params, fields, "parameters")
    dims = tuple(_dimension(k, v, fields[k].metadata or None) for k, v in params.items())
    if method == "grid":
        n = int(np.prod([len(d.grid()) if d.values else d.levels for d in dims], dtype=float))
        if n > MAX_DESIGNS:
            raise ParameterError("parameters", f"{n:.3g} grid designs",
                                 f"at most {MAX_DESIGNS} designs (fewer levels, or lhs/sobol)")
    elif method == "sobol" and 2 ** int(np.ceil(np.log2(samples))) > MAX_DESIGNS:
        raise ParameterError("samples", samples, f"at most {MAX_DESIGNS} designs after sobol "
                             "rounds up to a power of 2")
    fixed = dict(_table("fixed", data.get("fixed", {})))
    overlap = set(fixed) & set(params)
    if overlap:
        name = sorted(overlap)[0]
        raise ParameterError(f"fixed.{name}", _short(fixed[name]), "not also a swept parameter")
    check_keys(fixed, fields, "fixed")
    try:
        with_overrides(PARTS[name], fixed)
    except ParameterError as exc:
        raise ParameterError(f"fixed.{exc.name}", exc.value, exc.allowed) from None
    settings = dict(_table("settings", data.get("settings", {})))
    check_keys(settings, SETTINGS, "settings")
    from designlab.predict.run import model_settings, protocol_from

    if "model" in settings:
        model_settings(part, _table("settings.model", settings["model"]))
    if "K_f_target_N_per_m" in settings:
        if _number("settings.K_f_target_N_per_m", settings["K_f_target_N_per_m"],
                   "a number > 0 N/m") <= 0:
            raise ParameterError("settings.K_f_target_N_per_m", settings["K_f_target_N_per_m"],
                                 "a number > 0 N/m")
    protocol = dict(_table("protocol", data.get("protocol", {})))
    if protocol:
        try:
            protocol_from(part, None, protocol)
        except ParameterError as exc:
            name = exc.name if exc.name.startswith("protocol.") else f"protocol.{exc.name}"
            raise ParameterError(name, exc.value, exc.allowed) from None
        except (TypeError, ValueError) as exc:
            raise ParameterError("protocol", _short(protocol), f"a valid protocol ({exc})") from None
    objectives = {k: _direction(k, v)
                  for k, v in _table("objectives", data.get("objectives", {})).items()}
    constraints = {k: _constraint(k, v)
                   for k, v in _table("constraints", data.get("constraints", {})).items()}
    from designlab.optimize.metrics import check_metric_names

    check_metric_names(settings, {"objectives": list(objectives),
                                  "constraints": list(constraints)})
    return SweepConfig(part, dims, method, samples, seed, fixed, settings, objectives,
                       constraints, protocol)


def read_sweep_toml(path: str | Path) -> dict[str, Any]:
    """A sweep config file's table; a sensor definition file named by ``part`` is taken
    relative to the config's folder."""
    from designlab.sensors.registry import canonical, looks_like_definition

    data = load_toml(path, "config")
    if isinstance(data.get("part"), str) and looks_like_definition(data["part"]):
        data["part"] = canonical(data["part"], Path(path).resolve().parent)
    return data


def load_sweep_config(path: str | Path) -> SweepConfig:
    """A sweep config from a TOML file (:func:`read_sweep_toml`)."""
    return sweep_config(read_sweep_toml(path))


def objective_value(value: float, spec: Any) -> float:
    """The value to minimise for one objective (max -> negated, target -> |value - target|)."""
    if spec == "min":
        return float(value)
    if spec == "max":
        return -float(value)
    return abs(float(value) - float(spec["target"]))


def feasible(metrics: dict[str, Any], constraints: dict[str, Any]) -> bool:
    """True when every constraint holds (a missing metric counts as violated)."""
    for k, spec in constraints.items():
        v = metrics.get(k)
        if v is None or (isinstance(v, float) and np.isnan(v)):
            return False
        if spec is True:
            if not v:
                return False
            continue
        if "min" in spec and v < spec["min"]:
            return False
        if "max" in spec and v > spec["max"]:
            return False
    return True
