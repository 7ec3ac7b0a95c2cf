"""Sweep configuration and design-space sampling (grid, Latin hypercube, Sobol).

A sweep config (TOML)::

    part = "NAME"                 # a sensor of designlab.sensors.SENSORS
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

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import qmc

from designlab.errors import ParameterError
from designlab.params import load_toml

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


def _dimension(name: str, spec: Any) -> Dimension:
    allowed = "[lo, hi], {range = [lo, hi], levels = n} or {values = [...]}"
    if isinstance(spec, list) and len(spec) == 2:
        spec = {"range": spec}
    if not isinstance(spec, dict):
        raise ParameterError(f"parameters.{name}", spec, allowed)
    if "values" in spec:
        vals = tuple(float(v) for v in spec["values"])
        if not vals:
            raise ParameterError(f"parameters.{name}.values", spec["values"], "a non-empty list")
        return Dimension(name, min(vals), max(vals), len(vals), vals)
    r = spec.get("range")
    if not (isinstance(r, list) and len(r) == 2 and all(isinstance(x, (int, float)) for x in r)
            and r[0] <= r[1]):
        raise ParameterError(f"parameters.{name}.range", r, "[lo, hi] with lo <= hi")
    levels = spec.get("levels", 3)
    if not isinstance(levels, int) or levels < 1:
        raise ParameterError(f"parameters.{name}.levels", levels, "an integer >= 1")
    return Dimension(name, float(r[0]), float(r[1]), levels)


def _direction(name: str, spec: Any) -> Any:
    if spec in ("min", "max"):
        return spec
    if isinstance(spec, dict) and set(spec) == {"target"}:
        t = spec["target"]
        if isinstance(t, (int, float)) or (isinstance(t, list)):
            return spec
    raise ParameterError(f"objectives.{name}", spec, '"min", "max" or {target = value}')


def sweep_config(data: dict[str, Any]) -> SweepConfig:
    """Validate a parsed config dict (see module docstring)."""
    known = {"part", "method", "samples", "seed", "parameters", "fixed", "settings",
             "objectives", "constraints", "protocol"}
    for k in data:
        if k not in known:
            raise ParameterError(k, data[k], "a sweep config key: " + ", ".join(sorted(known)))
    from designlab.sensors.registry import get_sensor

    part = data.get("part")
    get_sensor(part)
    method = data.get("method", "grid")
    if method not in METHODS:
        raise ParameterError("method", method, "one of " + ", ".join(METHODS))
    samples = data.get("samples", 8)
    if not isinstance(samples, int) or samples < 1:
        raise ParameterError("samples", samples, "an integer >= 1")
    params = data.get("parameters", {})
    if not isinstance(params, dict) or not params:
        raise ParameterError("parameters", params, "a table with at least one swept parameter")
    dims = tuple(_dimension(k, v) for k, v in params.items())
    fixed = dict(data.get("fixed", {}))
    overlap = set(fixed) & set(params)
    if overlap:
        name = sorted(overlap)[0]
        raise ParameterError(f"fixed.{name}", fixed[name], "not also a swept parameter")
    objectives = {k: _direction(k, v) for k, v in data.get("objectives", {}).items()}
    constraints = dict(data.get("constraints", {}))
    for k, v in constraints.items():
        if not (v is True or (isinstance(v, dict) and set(v) <= {"min", "max"} and v)):
            raise ParameterError(f"constraints.{k}", v, "true, {min = x} and/or {max = x}")
    return SweepConfig(part, dims, method, samples, int(data.get("seed", 0)), fixed,
                       dict(data.get("settings", {})), objectives, constraints,
                       dict(data.get("protocol", {})))


def load_sweep_config(path: str | Path) -> SweepConfig:
    return sweep_config(load_toml(path))


def objective_value(value: float, spec: Any) -> float:
    """The value to minimise for one objective (max -> negated, target -> |value - target|)."""
    if spec == "min":
        return float(value)
    if spec == "max":
        return -float(value)
    t = np.asarray(spec["target"], float)
    return float(np.linalg.norm(np.asarray(value, float) - t))


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
