"""Test protocols as data (TOML-configurable); the papers' values are the defaults. Details:
docs/models/sensors_shared.md.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.params import at_least, did_you_mean, load_toml, rng, validate

G_ACC = 9.81  #: m/s^2, grams -> newtons: F = m_g * 1e-3 * G_ACC

TABLE_II_WEIGHTS_G = (0.0, 5.0, 15.0, 35.0, 55.0, 105.0, 132.0, 232.0)
TABLE_III_WEIGHTS_G = (0.0, 5.0, 15.0, 35.0, 55.0, 82.0, 109.0, 136.0, 163.0, 213.0)
FSS015_RANGE_N = 15.0       #: Honeywell FSS015WNSX force sensing range (seed 001 Table I)
FSS015_OVERFORCE_N = 45.0   #: safety overforce (seed 001 Table I)
#: most samples in one load history (a 1e-6 s step over a 150 s test would be 1.5e8 samples,
#: over 2 GB once the FEM responses are stacked)
MAX_TIME_STEPS = 200_000


def _check_steps(steps: int, dt_s: float, dt_min: float, duration_s: float) -> None:
    """At most :data:`MAX_TIME_STEPS` samples: else name ``dt_s`` with the smallest allowed."""
    if steps > MAX_TIME_STEPS:
        at_least("dt_s", dt_s, dt_min, f"at most {MAX_TIME_STEPS} time steps over the "
                 f"{duration_s:.6g} s test", unit="s")


@dataclass(frozen=True)
class HangingWeightTest:
    """Seed 001 hanging-weight hysteresis test (defaults: Table II)."""

    weights_g: tuple[float, ...] = TABLE_II_WEIGHTS_G
    tray_g: float = field(default=5.0, metadata=rng(0, 1000, unit="g"))
    hold_s: float = field(default=10.0, metadata=rng(0, 3600, lo_open=True, unit="s",
                          doc="time each weight hangs before the next is added/removed"))
    read_window_s: float = field(default=3.0, metadata=rng(0, 3600, lo_open=True, unit="s"))
    dt_s: float = field(default=0.5, metadata=rng(0, 60, lo_open=True, unit="s"))
    g1_locations: tuple[str, ...] = tuple(f"h{i}" for i in range(1, 10))
    g2_locations: tuple[str, ...] = tuple(f"r{i}" for i in range(1, 6))
    rotations: int = field(default=6, metadata=rng(1, 72))
    sensor_range_N: float = field(default=FSS015_RANGE_N, metadata=rng(0, None, lo_open=True, unit="N"))
    sensor_overforce_N: float = field(default=FSS015_OVERFORCE_N, metadata=rng(0, None, lo_open=True, unit="N"))

    def __post_init__(self):
        validate(self)
        w = np.asarray(self.weights_g, object)
        if w.ndim == 1 and all(isinstance(x, (int, float, np.integer, np.floating))
                               and not isinstance(x, bool) for x in w):
            w = w.astype(float)
        if w.dtype != float or w.ndim != 1 or len(w) < 3 or not np.all(np.isfinite(w)) \
                or np.any(np.diff(w) <= 0) or w[0] < 0:
            raise ParameterError("weights_g", list(self.weights_g),
                                 "at least 3 finite, non-negative, strictly increasing masses "
                                 "in g")
        if self.read_window_s > self.hold_s:
            raise ParameterError("read_window_s", self.read_window_s,
                                 f"<= hold_s ({self.hold_s:g} s)")
        for name in ("g1_locations", "g2_locations"):
            locs = getattr(self, name)
            if len(set(locs)) != len(locs):
                raise ParameterError(name, list(locs), "distinct load-point names")
        n_loads = 2 * len(w) - 1
        if n_loads + 1 > MAX_TIME_STEPS // 10:
            raise ParameterError("weights_g", f"{len(w)} masses",
                                 f"at most {(MAX_TIME_STEPS // 10 - 2) // 2 + 1} masses")
        n_per = max(1, int(round(self.hold_s / self.dt_s)))
        _check_steps(n_loads * n_per + 1, self.dt_s,
                     n_loads * self.hold_s / (MAX_TIME_STEPS - 1 - n_loads),
                     n_loads * self.hold_s)

    @classmethod
    def preset(cls, name: str) -> "HangingWeightTest":
        """``"tested"`` (Table II) or ``"optimized"`` (Table III: 0..213 g, h1..h6, r1..r6)."""
        if name == "tested":
            return cls()
        if name == "optimized":
            return cls(weights_g=TABLE_III_WEIGHTS_G,
                       g1_locations=tuple(f"h{i}" for i in range(1, 7)),
                       g2_locations=tuple(f"r{i}" for i in range(1, 7)))
        raise ParameterError("preset", name, "one of tested, optimized"
                             + did_you_mean(name, ("tested", "optimized")))

    @property
    def sequence_g(self) -> np.ndarray:
        """Added mass at each step: up through the weights, then down in reverse (2n-1 steps)."""
        w = np.asarray(self.weights_g, float)
        return np.concatenate([w, w[-2::-1]])

    @property
    def loads_N(self) -> np.ndarray:
        """Hanging load (tray + weight) at each step, N."""
        return (self.sequence_g + self.tray_g) * 1e-3 * G_ACC

    @property
    def max_load_N(self) -> float:
        return float(self.loads_N.max())

    def time_history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, load(t), step index(t)): piecewise-constant load, each step held ``hold_s``."""
        n_per = max(1, int(round(self.hold_s / self.dt_s)))
        loads = self.loads_N
        t = np.arange(len(loads) * n_per + 1) * self.dt_s
        step = np.minimum(np.arange(len(t)) // n_per, len(loads) - 1)
        step[0] = 0
        return t, loads[step], step

    def read_masks(self, t: np.ndarray, step: np.ndarray) -> list[np.ndarray]:
        """Per step, the samples in the ``read_window_s`` after its marker (the end of the
        settling part of the hold: the paper marks the time once the weight has stabilised)."""
        starts = np.array([t[step == k][0] for k in range(step.max() + 1)])
        ends = starts + self.hold_s
        marker = ends - self.read_window_s
        return [(step == k) & (t >= marker[k] - 1e-9) & (t <= ends[k] + 1e-9)
                for k in range(len(starts))]

    def check_sensor_range(self, peak_sensor_force_N: float, sensor: str = "sensor") -> None:
        """Error above the overforce, warning above the sensing range."""
        if peak_sensor_force_N > self.sensor_overforce_N:
            raise ParameterError("weights_g", max(self.weights_g),
                                 f"loads keeping every {sensor} under its safety overforce "
                                 f"{self.sensor_overforce_N:g} N (peak {peak_sensor_force_N:.1f} N)")
        if peak_sensor_force_N > self.sensor_range_N:
            warnings.warn(f"{sensor} force {peak_sensor_force_N:.2f} N exceeds its sensing range "
                          f"{self.sensor_range_N:g} N", stacklevel=2)


@dataclass(frozen=True)
class StrapLoadTest:
    """Seed 000 fingertip loads on the strap: steps and grasp-like cycles (N, s).

    The paper gives no absolute amplitudes, only that normal forces are about one order of
    magnitude above shear (Figs. 7-8); the defaults (5 N normal, 0.5 N shear) follow that ratio
    at a pinch force typical of lifting its 346 g object.
    """

    normal_N: float = field(default=5.0, metadata=rng(0, 100, lo_open=True, unit="N"))
    shear_N: float = field(default=0.5, metadata=rng(0, 100, unit="N"))
    step_hold_s: float = field(default=5.0, metadata=rng(0, 600, lo_open=True, unit="s"))
    cycle_period_s: float = field(default=2.0, metadata=rng(0, 600, lo_open=True, unit="s"))
    cycles: int = field(default=3, metadata=rng(0, 1000))
    n_steps: int = field(default=4, metadata=rng(1, 100))
    dt_s: float = field(default=0.1, metadata=rng(0, 10, lo_open=True, unit="s"))

    def __post_init__(self):
        validate(self)
        n_stair = 2 * self.n_steps + 1
        n_hold = max(1, int(round(self.step_hold_s / self.dt_s)))
        n_cyc = int(round(self.cycles * self.cycle_period_s / self.dt_s))
        duration = n_stair * self.step_hold_s + self.cycles * self.cycle_period_s
        _check_steps(n_stair * n_hold + n_cyc + 1, self.dt_s,
                     duration / (MAX_TIME_STEPS - 2 - n_stair), duration)

    def time_history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, F_n(t), F_x(t)): staircase up and down in normal force (shear at its ratio), then
        ``cycles`` grasp cycles (raised cosine in F_n, sine in F_x)."""
        levels = np.linspace(0, 1, self.n_steps + 1)
        stair = np.concatenate([levels, levels[-2::-1]])
        n_hold = max(1, int(round(self.step_hold_s / self.dt_s)))
        a = np.repeat(stair, n_hold)
        n_cyc = int(round(self.cycles * self.cycle_period_s / self.dt_s))
        tc = np.arange(n_cyc) * self.dt_s
        grasp = 0.5 * (1 - np.cos(2 * np.pi * tc / self.cycle_period_s))
        fn = self.normal_N * np.concatenate([a, grasp, [0.0]])
        fx = self.shear_N * np.concatenate([a, np.sin(2 * np.pi * tc / self.cycle_period_s),
                                            [0.0]])
        t = np.arange(len(fn)) * self.dt_s
        return t, fn, fx


@dataclass(frozen=True)
class FlexureWrenchTest:
    """Seed 002: static wrenches at the fingertip, up to ``max_force_N`` (10 N in the paper) and
    ``max_moment_Nmm`` about each axis, in ``steps`` increments each way."""

    max_force_N: float = field(default=10.0, metadata=rng(0, 1000, lo_open=True, unit="N"))
    max_moment_Nmm: float = field(default=100.0, metadata=rng(0, 1e5, lo_open=True, unit="N mm"))
    steps: int = field(default=5, metadata=rng(1, 100))

    def __post_init__(self):
        validate(self)

    def wrenches(self) -> np.ndarray:
        """(n, 6) wrenches (m_x, m_y, m_z [N mm], f_x, f_y, f_z [N]) along each axis, +/-."""
        amp = np.array([self.max_moment_Nmm] * 3 + [self.max_force_N] * 3)
        levels = np.linspace(-1, 1, 2 * self.steps + 1)
        levels = levels[levels != 0]
        out = [np.eye(6)[i] * amp[i] * s for i in range(6) for s in levels]
        return np.array(out)


def _coerce(cls, values: dict[str, Any]) -> dict[str, Any]:
    names = {f.name: f for f in fields(cls)}
    out = {}
    for k, v in values.items():
        if k not in names:
            raise ParameterError(k, v, f"a parameter of {cls.__name__}: " + ", ".join(sorted(names))
                                 + did_you_mean(k, names))
        out[k] = tuple(v) if isinstance(v, list) else v
    return out


def _file_values(path: str | Path) -> Any:
    """A protocol file's keys: its ``[protocol]`` table, else its top-level keys."""
    data = load_toml(path)
    return data.get("protocol", data)


def load_protocol(cls: type, path: str | Path | None = None) -> Any:
    """A protocol of class ``cls`` (a sensor's ``Sensor.protocol``) from a TOML file (top-level
    keys or a ``[protocol]`` table; ``preset = "optimized"`` selects Table III of the hanging
    weight test); the defaults when ``path`` is None."""
    if path is None:
        return cls()
    data = _file_values(path)
    preset = data.pop("preset", None) if isinstance(data, dict) else None
    base = cls.preset(preset) if preset is not None and hasattr(cls, "preset") else None
    if preset is not None and base is None:
        raise ParameterError("preset", preset, f"no presets for {cls.__name__}")
    kwargs = _coerce(cls, data)
    if base is not None:
        from dataclasses import replace
        return replace(base, **kwargs)
    return cls(**kwargs)


def protocol_for(cls: type, path: str | Path | None = None, values: dict[str, Any] | None = None,
                 design=None, design_protocol=None) -> Any:
    """A sensor's protocol: the paper's defaults (``cls()``), made to fit ``design`` by
    ``design_protocol(protocol, design, values)`` (a file without ``preset`` is read as
    overrides of those defaults), a TOML file, and/or a dict of overrides (sweeps; ``preset`` selects a preset first). An unknown key is a one-line
    error naming ``protocol.<key>`` (:func:`_coerce`'s, as for a TOML file)."""
    from dataclasses import replace

    if path is not None and design is not None and design_protocol is not None:
        data = _file_values(path)
        if isinstance(data, dict) and "preset" not in data:   # the file's keys on the design's
            path, values = None, {**data, **(values or {})}   # defaults, as overrides
    proto = load_protocol(cls, path)
    if path is None and design is not None and design_protocol is not None:
        proto = design_protocol(proto, design, values)
    if values:
        data = dict(values)
        preset = data.pop("preset", None)
        if preset is not None:
            proto = type(proto).preset(preset)
        try:
            data = _coerce(type(proto), data)
        except ParameterError as exc:
            raise ParameterError(f"protocol.{exc.name}", exc.value, exc.allowed) from None
        proto = replace(proto, **data)
    return proto
