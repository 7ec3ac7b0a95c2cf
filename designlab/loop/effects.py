"""The effect library: physical mechanisms that can be added to a sensor model.

Each effect is an additive correction ``y += F(data, yhat; theta) @ beta`` whose regressors
``F`` depend on the data (and, for some, on the prediction ``yhat`` made before the effect)
through a few nonlinear settings ``theta`` (time constants, thresholds, a delay), found by a
small grid search, while ``beta`` follows by linear least squares. Every fit also refits the
base's affine part (intercept and the gains of the inputs the base uses: the *nuisance*
columns), so an effect and the base are fitted jointly. Settings are chosen by AIC on the rows
being fitted.

Mechanisms (name: regressors):

- ``relaxation``: viscoelastic relaxation/creep, Prony terms on the input history,
  ``h_i = highpass(x, tau_i)`` (exact exponential recursion, ramp-invariant); mechanical outputs.
- ``piezo_relaxation``: the same form on the predicted resistance/voltage (electrical outputs).
- ``drift``: baseline drift in the time since the run started: linear, quadratic, or an
  exponential settling ``exp(-t / tau_d)`` (warm-up, conditioning; extrapolates flat).
- ``thermal``: temperature through a TCR, ``(T - T_m) * yhat`` and ``(T - T_m)``.
- ``hysteresis``: direction-dependent friction: Coulomb ``tanh(xdot / v0)``, Dahl, or
  Maxwell-slip (parallel elasto-slide elements = play operators).
- ``nonlinearity``: load nonlinearity, polynomial in the normalised input (order 2 or 3).
- ``moment_arm``: output scales with a location input, ``(loc - loc_m) * yhat``.
- ``parallel_path``: a parallel load path that steals sensitivity above an engagement level,
  ``max(x - x_s, 0)``.
- ``run_offset``: one offset per run (re-donning, preload); runs not seen in training are
  tared on their first ``tare_s`` seconds of residual.
- ``lag``: channel lag; a fractional time shift of the prediction estimated by
  cross-correlation.
- ``cross_axis``: the output depends on an input the base does not use.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from scipy import signal

from designlab.measured.dataset import ELECTRICAL, Dataset
from designlab.errors import ModelError

# --------------------------------------------------------------------------- signal helpers


def _segments(segment: np.ndarray) -> list[slice]:
    """Contiguous runs of equal segment id as slices."""
    if segment.size == 0:
        return []
    cut = np.flatnonzero(np.diff(segment)) + 1
    edges = np.r_[0, cut, segment.size]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def highpass(x: np.ndarray, tau: float, dt: float, segment: np.ndarray) -> np.ndarray:
    """``h = int exp(-(t-s)/tau) dx(s)``: first-order high-pass of ``x`` with time constant
    ``tau`` (s), exact for a piecewise-linear input on a uniform step ``dt``, restarted at 0 at
    the start of every run. Units of ``x``."""
    a = math.exp(-dt / tau)
    c = tau * (1.0 - a) / dt
    out = np.empty_like(x, dtype=float)
    for s in _segments(segment):
        xs = x[s]
        out[s], _ = signal.lfilter([c, -c], [1.0, -a], xs, zi=[-c * xs[0]])
    return out


def rate(x: np.ndarray, dt: float, segment: np.ndarray) -> np.ndarray:
    """Time derivative (units of x per s), central differences within each run."""
    out = np.zeros_like(x, dtype=float)
    for s in _segments(segment):
        if s.stop - s.start > 1:
            out[s] = np.gradient(x[s], dt)
    return out


def shift(y: np.ndarray, delay: float, t: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """``y(t - delay)`` by linear interpolation within each run (edges held)."""
    out = np.empty_like(y, dtype=float)
    for s in _segments(segment):
        out[s] = np.interp(t[s] - delay, t[s], y[s])
    return out


def play(x: np.ndarray, widths: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """Play (backlash) operators of half-widths ``widths``: the slider position ``w`` of each
    Maxwell-slip element; returns ``x - w`` (n, m), bounded by +-width."""
    widths = np.asarray(widths, float)
    out = np.empty((x.size, widths.size))
    for s in _segments(segment):
        w = np.full(widths.size, x[s.start])
        for k in range(s.start, s.stop):
            w = np.minimum(np.maximum(w, x[k] - widths), x[k] + widths)
            out[k] = x[k] - w
    return out


def dahl(x: np.ndarray, xc: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """Normalised Dahl friction state ``z`` in [-1, 1] (n, m): ``dz/dx = (1 - z sgn(dx)) / xc``,
    integrated exactly per step (``z -> s + (z - s) exp(-|dx| / xc)``)."""
    xc = np.asarray(xc, float)
    out = np.empty((x.size, xc.size))
    for s in _segments(segment):
        xs = x[s]
        dx = np.diff(xs, prepend=xs[0])
        e = np.exp(-np.abs(dx)[:, None] / xc[None, :])
        sg = np.sign(dx)
        z = np.zeros(xc.size)
        block = out[s]
        for k in range(xs.size):
            if sg[k] != 0.0:
                z = sg[k] + (z - sg[k]) * e[k]
            block[k] = z
    return out


def robust_range(x: np.ndarray) -> float:
    lo, hi = np.percentile(x, [1, 99])
    return float(max(hi - lo, 1e-12))


# --------------------------------------------------------------------------- the library


@dataclass
class Context:
    """What an effect sees: the data, the output's name, the prediction before the effect and
    (when known) the measured output, and the inputs the base uses (nuisance columns)."""

    data: Dataset
    output: str
    yhat: np.ndarray
    base_inputs: tuple[str, ...]
    measured: np.ndarray | None = None
    cache: dict = field(default_factory=dict)       # regressors of the data alone
    pred_cache: dict = field(default_factory=dict)  # regressors of this yhat


@dataclass(frozen=True)
class Effect:
    """One mechanism acting on one channel (``channel`` is None for time/run effects)."""

    name: str
    channel: str | None = None
    uses_prediction: bool = False
    fixed_coefficients: bool = False   # regressors enter with coefficient 1 (lag)
    intercept: bool = True             # nuisance intercept (off when regressors hold offsets)
    doc: str = ""

    @property
    def key(self) -> str:
        return f"{self.name}[{self.channel}]" if self.channel else self.name

    # the three hooks, dispatched on name
    def grid(self, ctx: Context) -> list[dict]:
        return GRIDS[self.name](self, ctx)

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        if not self.uses_prediction:
            ck = (id(ctx.data), self.key, repr(sorted(theta.items())))
            hit = ctx.cache.get(ck)
            if hit is not None:
                return hit
        f = np.asarray(FEATURES[self.name](self, ctx, theta), float)
        f = f.reshape(f.shape[0], -1)
        if not self.uses_prediction:
            ctx.cache[ck] = f
        return f


def _drive_inputs(data: Dataset) -> list[str]:
    return [n for n in data.inputs if data.kinds.get(n, "drive") == "drive"]


def library(train: Dataset, output: str, base_inputs: tuple[str, ...]) -> tuple[list[Effect], dict]:
    """The candidate effects that apply to ``output`` of this data, and why others do not."""
    q = train.quantities.get(output, "")
    electrical = q in ELECTRICAL
    drives = _drive_inputs(train)
    kinds = train.kinds
    out: list[Effect] = []
    skipped: dict[str, str] = {}
    for x in drives:
        if np.ptp(train.inputs[x]) == 0:
            skipped[f"*[{x}]"] = "input is constant in the training data"
            continue
        if electrical:
            skipped[f"relaxation[{x}]"] = "electrical output: see piezo_relaxation"
        else:
            out.append(Effect("relaxation", x))
        out.append(Effect("hysteresis", x))
        out.append(Effect("nonlinearity", x))
        out.append(Effect("parallel_path", x))
        if x not in base_inputs:
            out.append(Effect("cross_axis", x))
    if electrical:
        out.append(Effect("piezo_relaxation", None, uses_prediction=True))
    else:
        skipped["piezo_relaxation"] = "output is not electrical (resistance/voltage/current)"
    out.append(Effect("drift"))
    temps = [n for n in train.inputs if kinds.get(n) == "temperature"]
    locs = [n for n in train.inputs if kinds.get(n) == "location"]
    for T in temps:
        out.append(Effect("thermal", T, uses_prediction=True))
    if not temps:
        skipped["thermal"] = "no temperature input"
    for loc in locs:
        out.append(Effect("moment_arm", loc, uses_prediction=True))
    if not locs:
        skipped["moment_arm"] = "no location input"
    if np.unique(train.segment).size >= 2:
        out.append(Effect("run_offset", intercept=False))
    else:
        skipped["run_offset"] = "one training run: per-run offsets cannot be tested"
    out.append(Effect("lag", None, uses_prediction=True, fixed_coefficients=True))
    return out, skipped


# grids: nonlinear settings from the training data ------------------------------------------


def _tau_grid(ctx: Context) -> list[float]:
    d = ctx.data
    dur = min(float(np.max(d.time_in_run())), 600.0)
    lo, hi = 3 * d.dt, max(dur / 4, 6 * d.dt)
    return [float(v) for v in np.geomspace(lo, hi, 8)]


def _grid_relax(e: Effect, ctx: Context) -> list[dict]:
    taus = _tau_grid(ctx)
    single = [{"tau": (t,)} for t in taus]
    pairs = [{"tau": (a, b)} for a, b in itertools.combinations(taus, 2)]
    return single + pairs


def _grid_hyst(e: Effect, ctx: Context) -> list[dict]:
    x = ctx.data.inputs[e.channel]
    R = robust_range(x)
    v = rate(x, ctx.data.dt, ctx.data.segment)
    vs = float(np.std(v)) or 1.0
    g = [{"variant": "coulomb", "v0": f * vs} for f in (0.03, 0.1, 0.3)]
    g += [{"variant": "dahl", "xc": f * R} for f in (0.01, 0.03, 0.1, 0.3)]
    g += [{"variant": "maxwell_slip", "widths": tuple(f * R for f in (0.01, 0.03, 0.1, 0.3))}]
    return g


def _center_scale(x: np.ndarray) -> tuple[float, float]:
    lo, hi = np.percentile(x, [1, 99])
    return float((lo + hi) / 2), float(max((hi - lo) / 2, 1e-12))


def _grid_nonlin(e: Effect, ctx: Context) -> list[dict]:
    c, s = _center_scale(ctx.data.inputs[e.channel])
    return [{"order": o, "center": c, "scale": s} for o in (2, 3)]


def _grid_parallel(e: Effect, ctx: Context) -> list[dict]:
    x = ctx.data.inputs[e.channel]
    s = robust_range(x)
    return [{"engage": float(np.quantile(x, q)), "scale": s} for q in (0.3, 0.5, 0.7, 0.85)]


def _grid_drift(e: Effect, ctx: Context) -> list[dict]:
    T = float(max(np.max(ctx.data.time_in_run()), 1e-9))
    return ([{"variant": "polynomial", "order": 1, "duration_s": T},
             {"variant": "polynomial", "order": 2, "duration_s": T}]
            + [{"variant": "settling", "tau_s": f * T} for f in (0.03, 0.1, 0.3, 1.0)])


def _grid_mean(e: Effect, ctx: Context) -> list[dict]:
    return [{"reference": float(np.mean(ctx.data.inputs[e.channel]))}]


def _grid_none(e: Effect, ctx: Context) -> list[dict]:
    return [{}]


def _grid_offset(e: Effect, ctx: Context) -> list[dict]:
    rows = ctx.cache.get("rows", np.ones(len(ctx.data), bool))
    paths = [ctx.data.segments[s]["path"] for s in np.unique(ctx.data.segment[rows])]
    return [{"runs": tuple(paths), "tare_s": 1.0}]


def _grid_lag(e: Effect, ctx: Context) -> list[dict]:
    """The delay maximising the correlation of the measured output with the shifted
    prediction (coarse grid of one sample, then a parabola through the peak)."""
    d = ctx.data
    y = ctx.measured
    rows = ctx.cache.get("rows", np.ones(len(d), bool))
    dt = d.dt
    max_lag = min(2.0, 0.05 * float(np.max(d.time_in_run())))
    lags = np.arange(-math.floor(max_lag / dt), math.floor(max_lag / dt) + 1) * dt
    if lags.size < 3:
        return [{"delay": 0.0}]
    cc = np.array([np.corrcoef(y[rows], shift(ctx.yhat, L, d.t, d.segment)[rows])[0, 1]
                   for L in lags])
    cc = np.nan_to_num(cc, nan=-1.0)
    i = int(np.argmax(cc))
    delay = float(lags[i])
    if 0 < i < lags.size - 1:
        a, b, c = cc[i - 1], cc[i], cc[i + 1]
        den = a - 2 * b + c
        if den < 0:
            delay += 0.5 * (a - c) / den * dt
    return [{"delay": delay, "max_lag_s": float(max_lag)}]


GRIDS: dict[str, Callable] = {
    "relaxation": _grid_relax, "piezo_relaxation": _grid_relax, "hysteresis": _grid_hyst,
    "nonlinearity": _grid_nonlin, "parallel_path": _grid_parallel, "drift": _grid_drift,
    "thermal": _grid_mean, "moment_arm": _grid_mean, "cross_axis": _grid_mean,
    "run_offset": _grid_offset, "lag": _grid_lag,
}

# features ----------------------------------------------------------------------------------


def _hp_cached(ctx: Context, key: str, x: np.ndarray, tau: float, cache: bool) -> np.ndarray:
    ck = (id(ctx.data), "hp", key, tau)
    if cache and ck in ctx.cache:
        return ctx.cache[ck]
    h = highpass(x, tau, ctx.data.dt, ctx.data.segment)
    if cache:
        ctx.cache[ck] = h
    return h


def _f_relax(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    x = ctx.data.inputs[e.channel]
    return np.column_stack([_hp_cached(ctx, e.channel, x, t, True) for t in th["tau"]])


def _f_piezo(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    cols = []
    for t in th["tau"]:
        if t not in ctx.pred_cache:
            ctx.pred_cache[t] = highpass(ctx.yhat, t, ctx.data.dt, ctx.data.segment)
        cols.append(ctx.pred_cache[t])
    return np.column_stack(cols)


def _f_hyst(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    d = ctx.data
    x = d.inputs[e.channel]
    if th["variant"] == "coulomb":
        return np.tanh(rate(x, d.dt, d.segment) / th["v0"])
    if th["variant"] == "dahl":
        return dahl(x, np.array([th["xc"]]), d.segment)
    return play(x, np.array(th["widths"]), d.segment)


def _f_nonlin(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    u = (ctx.data.inputs[e.channel] - th["center"]) / th["scale"]
    return np.column_stack([u ** k for k in range(2, th["order"] + 1)])


def _f_parallel(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    x = ctx.data.inputs[e.channel]
    return np.maximum(x - th["engage"], 0.0) / th["scale"]


def _f_drift(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    if th["variant"] == "settling":
        return np.exp(-ctx.data.time_in_run() / th["tau_s"])
    s = ctx.data.time_in_run() / th["duration_s"]
    return np.column_stack([s ** k for k in range(1, th["order"] + 1)])


def _f_thermal(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    dT = ctx.data.inputs[e.channel] - th["reference"]
    return np.column_stack([dT * ctx.yhat, dT])


_f_moment = _f_thermal


def _f_cross(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    return ctx.data.inputs[e.channel] - th["reference"]


def _f_offset(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    d = ctx.data
    paths = [d.segments[s]["path"] for s in d.segment]
    return np.column_stack([np.array([p == r for p in paths], float) for r in th["runs"]])


def _f_lag(e: Effect, ctx: Context, th: dict) -> np.ndarray:
    d = ctx.data
    return shift(ctx.yhat, th["delay"], d.t, d.segment) - ctx.yhat


FEATURES: dict[str, Callable] = {
    "relaxation": _f_relax, "piezo_relaxation": _f_piezo, "hysteresis": _f_hyst,
    "nonlinearity": _f_nonlin, "parallel_path": _f_parallel, "drift": _f_drift,
    "thermal": _f_thermal, "moment_arm": _f_moment, "cross_axis": _f_cross,
    "run_offset": _f_offset, "lag": _f_lag,
}

# --------------------------------------------------------------------------- fitting


@dataclass(frozen=True)
class Fitted:
    """An effect with its settings ``theta``, coefficients ``beta`` (one per regressor) and
    nuisance refit ``alpha`` (intercept first when the effect has one, then the base inputs)."""

    effect: Effect
    theta: dict
    beta: tuple[float, ...]
    alpha: tuple[float, ...]
    nuisance: tuple[str, ...]
    sse: float = float("nan")

    def to_json(self) -> dict:
        return {"name": self.effect.name, "channel": self.effect.channel,
                "theta": _jsonable(self.theta), "beta": list(self.beta),
                "alpha": list(self.alpha), "nuisance": list(self.nuisance),
                "parameters": describe(self)}

    @staticmethod
    def from_json(d: dict) -> "Fitted":
        name = d["name"]
        if name not in FEATURES:
            raise ModelError(f"model effect name={name!r} is not known; allowed: "
                             f"{', '.join(FEATURES)}")
        eff = Effect(name, d.get("channel"),
                     uses_prediction=name in ("piezo_relaxation", "thermal", "moment_arm", "lag"),
                     fixed_coefficients=name == "lag", intercept=name != "run_offset")
        th = {k: tuple(v) if isinstance(v, list) else v for k, v in d["theta"].items()}
        return Fitted(eff, th, tuple(d["beta"]), tuple(d["alpha"]), tuple(d["nuisance"]))


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def nuisance_columns(data: Dataset, base_inputs: tuple[str, ...], intercept: bool) -> np.ndarray:
    cols = ([np.ones(len(data))] if intercept else []) + [data.inputs[n] for n in base_inputs]
    return np.column_stack(cols) if cols else np.zeros((len(data), 0))


def fit(effect: Effect, ctx: Context, residual: np.ndarray, rows: np.ndarray,
        thetas: list[dict] | None = None) -> Fitted:
    """Best settings (AIC over the grid) and least-squares coefficients on ``rows``."""
    N = nuisance_columns(ctx.data, ctx.base_inputs, effect.intercept)
    r = residual[rows]
    n = int(rows.sum())
    best = None
    ctx.cache["rows"] = rows
    for th in (thetas if thetas is not None else effect.grid(ctx)):
        F = effect.features(ctx, th)
        if effect.fixed_coefficients:
            X, target = N[rows], r - F[rows].sum(1)
        else:
            X, target = np.column_stack([F[rows], N[rows]]), r
        if X.shape[1]:
            coef, *_ = np.linalg.lstsq(X, target, rcond=None)
            sse = float(np.sum((target - X @ coef) ** 2))
        else:
            coef, sse = np.zeros(0), float(np.sum(target ** 2))
        p = X.shape[1] + (0 if not effect.fixed_coefficients else len(th))
        aic = n * math.log(max(sse, 1e-300) / n) + 2 * p
        if best is None or aic < best[0]:
            nb = 0 if effect.fixed_coefficients else F.shape[1]
            beta = (1.0,) * F.shape[1] if effect.fixed_coefficients else tuple(coef[:nb])
            best = (aic, th, beta, tuple(coef[nb:]), sse)
    ctx.cache.pop("rows", None)
    _, th, beta, alpha, sse = best
    return Fitted(effect, th, tuple(map(float, beta)), tuple(map(float, alpha)),
                  tuple(ctx.base_inputs), sse)


def contribution(f: Fitted, ctx: Context) -> np.ndarray:
    """What the fitted effect adds to the prediction ``ctx.yhat`` on ``ctx.data``."""
    F = f.effect.features(ctx, f.theta)
    N = nuisance_columns(ctx.data, f.nuisance, f.effect.intercept)
    out = F @ np.asarray(f.beta) + (N @ np.asarray(f.alpha) if N.shape[1] else 0.0)
    if f.effect.name == "run_offset":
        out = out + _tare_unseen(f, ctx, out)
    return out


def _tare_unseen(f: Fitted, ctx: Context, partial: np.ndarray) -> np.ndarray:
    """Offsets of runs not seen in training: the mean residual over each run's first
    ``tare_s`` seconds when the measured output is known, else the mean trained offset."""
    d = ctx.data
    extra = np.zeros(len(d))
    tin = d.time_in_run()
    for s in np.unique(d.segment):
        if d.segments[s]["path"] in f.theta["runs"]:
            continue
        m = d.segment == s
        if ctx.measured is not None:
            w = m & (tin <= f.theta["tare_s"])
            extra[m] = float(np.mean((ctx.measured - ctx.yhat - partial)[w]))
        else:
            extra[m] = float(np.mean(f.beta)) if f.beta else 0.0
    return extra


def describe(f: Fitted) -> dict:
    """Parameters of a fitted effect under their physical names."""
    e, th, b = f.effect, f.theta, list(f.beta)
    out: dict[str, Any] = {}
    if e.name in ("relaxation", "piezo_relaxation"):
        out = {"tau_s": list(th["tau"]), "g": b,
               "g_unit": "output unit per input unit" if e.name == "relaxation" else
               "relative (of the predicted output's high-pass)"}
    elif e.name == "hysteresis":
        out = {"variant": th["variant"], **{k: v for k, v in th.items() if k != "variant"}}
        out["amplitude" if len(b) == 1 else "stiffness"] = b[0] if len(b) == 1 else b
    elif e.name == "nonlinearity":
        out = {"order": th["order"], "center": th["center"], "scale": th["scale"],
               "coefficients": b, "form": "sum_k c_k ((x - center)/scale)^k, k >= 2"}
    elif e.name == "parallel_path":
        out = {"engage": th["engage"], "gain_change": b[0] / th["scale"],
               "form": "gain_change * max(x - engage, 0)"}
    elif e.name == "drift" and th["variant"] == "settling":
        out = {"variant": "settling", "amplitude": b[0], "tau_s": th["tau_s"],
               "form": "amplitude * exp(-t_run / tau)"}
    elif e.name == "drift":
        out = {"variant": "polynomial", "order": th["order"], "coefficients": b,
               "duration_s": th["duration_s"], "form": "sum_k c_k (t_run / duration)^k"}
    elif e.name == "thermal":
        out = {"tcr_per_C": b[0], "offset_per_C": b[1], "reference_C": th["reference"]}
    elif e.name == "moment_arm":
        out = {"relative_gain_per_unit": b[0], "offset_per_unit": b[1],
               "reference": th["reference"]}
    elif e.name == "cross_axis":
        out = {"coupling": b[0], "reference": th["reference"]}
    elif e.name == "run_offset":
        out = {"offsets": dict(zip(th["runs"], b)), "tare_s": th["tare_s"]}
    elif e.name == "lag":
        out = {"delay_s": th["delay"], "max_lag_s": th.get("max_lag_s")}
    if f.alpha:
        names = (["intercept"] if e.intercept else []) + [f"gain[{n}]" for n in f.nuisance]
        out["base_adjust"] = dict(zip(names, f.alpha))
    return out


def regressor(f: Fitted, ctx: Context) -> tuple[np.ndarray, str]:
    """The variable that best shows the effect (for plots): one regressor and its name."""
    e = f.effect
    d = ctx.data
    if e.name in ("relaxation", "hysteresis", "nonlinearity", "parallel_path", "cross_axis"):
        return d.inputs[e.channel], f"{e.channel} ({d.units.get(e.channel, '')})"
    if e.name in ("thermal", "moment_arm"):
        return d.inputs[e.channel], f"{e.channel} ({d.units.get(e.channel, '')})"
    if e.name == "drift":
        return d.time_in_run(), "time in run (s)"
    if e.name == "run_offset":
        return d.segment.astype(float), "run"
    if e.name == "lag":
        return rate(ctx.yhat, d.dt, d.segment), "rate of the prediction (per s)"
    return f.effect.features(ctx, f.theta) @ np.asarray(f.beta), e.key
