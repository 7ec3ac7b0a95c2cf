"""What every effect shares: signal helpers, the :class:`Effect` base class and its registry,
the fitted effect (:class:`Fitted`, its JSON form) and the fit itself.

An effect is an additive correction ``y += F(data, yhat; theta) @ beta`` whose regressors ``F``
depend on the data (and, for some, on the prediction ``yhat`` made before the effect) through a
few nonlinear settings ``theta`` (time constants, thresholds, a delay), found by a small grid
search, while ``beta`` follows by linear least squares. Every fit also refits the base's affine
part (intercept and the gains of the inputs the base uses: the *nuisance* columns), so an effect
and the base are fitted jointly. Settings are chosen by AIC on the rows being fitted.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from designlab.atomic import jsonable
from designlab.errors import ModelError
from designlab.measured.dataset import Dataset

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
    from scipy import signal               # imported here: 0.5 s that predict does not need

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
    """``y(t - delay)`` (``delay`` in s) by linear interpolation within each run (edges held)."""
    out = np.empty_like(y, dtype=float)
    for s in _segments(segment):
        out[s] = np.interp(t[s] - delay, t[s], y[s])
    return out


def play(x: np.ndarray, widths: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """Play (backlash) operators of half-widths ``widths``: the slider position ``w`` of each
    Maxwell-slip element; returns ``x - w`` (n, m), bounded by +-width. Units of ``x``."""
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
    """The 1-99 % percentile range of ``x`` (units of ``x``; at least 1e-12)."""
    lo, hi = np.percentile(x, [1, 99])
    return float(max(hi - lo, 1e-12))


def drive_inputs(data: Dataset) -> list[str]:
    """The inputs of kind ``drive`` (what was applied), in the data's order."""
    return [n for n in data.inputs if data.kinds.get(n, "drive") == "drive"]


def varying_drives(data: Dataset) -> list[str]:
    """The drive inputs that are not constant in ``data``."""
    return [n for n in drive_inputs(data) if np.ptp(data.inputs[n]) != 0]


# --------------------------------------------------------------------------- the base class


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
    per_run: bool = False   # one intercept per training run in every fit (>= 2 runs)
    tare: bool = True       # a new run's intercept: tared on its start (else the runs' mean)
    pred_cache: dict = field(default_factory=dict)  # regressors of this yhat


#: every effect class by its ``name``, filled by :meth:`Effect.__init_subclass__`
EFFECTS: dict[str, type[Effect]] = {}


@dataclass(frozen=True)
class Effect:
    """One mechanism acting on one channel (``channel`` is None for time/run effects).

    A mechanism is one subclass in one module of this package; defining it registers it in
    :data:`EFFECTS` under its ``name``. It sets the class attributes below and implements
    :meth:`applies`, :meth:`grid` and :meth:`features`; :meth:`describe` and
    :meth:`regressor` have generic defaults."""

    channel: str | None = None

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""          # one line, shown with an accepted effect in loop.json
    regressors_doc: ClassVar[str] = ""   # docs table: the regressors added to the prediction
    settings_doc: ClassVar[str] = "-"    # docs table: the nonlinear settings (grid)
    applies_doc: ClassVar[str] = ""      # docs table: when the library offers it
    uses_prediction: ClassVar[bool] = False   # regressors depend on yhat (not cached)
    fixed_coefficients: ClassVar[bool] = False  # regressors enter with coefficient 1 (lag)
    intercept: ClassVar[bool] = True     # nuisance intercept (off when regressors hold offsets)
    per_input: ClassVar[bool] = False    # one instance per varying drive input, offered input
    #                                      by input before the other effects
    rank: ClassVar[int] = 1000           # position in the candidate order (ties: registration
    #                                      order); the order changes the greedy selection
    first: ClassVar[bool] = False        # taken before any other passing candidate (a loaded
    #                                      model's own error, which others would absorb)
    refine: ClassVar[str] = ""           # a positive scalar setting refined between the grid's
    #                                      neighbours of the best one (AIC, log scale)

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        name = cls.__dict__.get("name")
        if name:
            if name in EFFECTS:
                raise TypeError(f"effect name {name!r} is taken by {EFFECTS[name].__qualname__}")
            EFFECTS[name] = cls

    @property
    def key(self) -> str:
        return f"{self.name}[{self.channel}]" if self.channel else self.name

    # ---- what a mechanism defines

    @classmethod
    def applies(cls, train: Dataset, output: str, base_inputs: tuple[str, ...]
                ) -> list[Effect] | str:
        """The instances that apply to ``output`` of the training data, or why none does.
        A ``per_input`` effect returns instances on :func:`varying_drives` only."""
        raise NotImplementedError

    def grid(self, ctx: Context) -> list[dict]:
        """The nonlinear settings to try, from the training data in ``ctx``."""
        raise NotImplementedError

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        """The regressors for settings ``theta``: (n,) or (n, k)."""
        raise NotImplementedError

    def width(self, theta: dict) -> int | None:
        """How many regressors :meth:`features` gives at settings ``theta`` (the length of a
        fitted ``beta``), read from the settings alone so that a model file is checked when it
        is loaded; None when only the data can tell (the check is then left to the
        prediction). A wrong or missing setting raises KeyError, TypeError or ValueError."""
        return None

    def describe(self, f: Fitted) -> dict:
        """Parameters of the fitted effect under their physical names."""
        return {"theta": dict(f.theta), "coefficients": list(f.beta)}

    def regressor(self, f: Fitted, ctx: Context) -> tuple[np.ndarray, str]:
        """The variable that best shows the effect (for plots) and its label."""
        return self.columns(ctx, f.theta) @ np.asarray(f.beta), self.key

    def solve(self, X: np.ndarray, target: np.ndarray, k: int) -> np.ndarray:
        """Coefficients of ``X`` (its first ``k`` columns are the effect's regressors, the rest
        the nuisance) for ``target``: least squares; an effect with constrained coefficients
        (a non-negative density) overrides it."""
        coef, *_ = np.linalg.lstsq(X, target, rcond=None)
        return coef

    def extra(self, f: Fitted, ctx: Context, partial: np.ndarray) -> np.ndarray | None:
        """What the effect adds beyond its fitted regressors (None: nothing)."""
        return None

    # ---- shared machinery

    def columns(self, ctx: Context, theta: dict) -> np.ndarray:
        """:meth:`features` as an (n, k) float array; cached per data set and settings unless
        they depend on the prediction."""
        if not self.uses_prediction:
            ck = (id(ctx.data), self.key, repr(sorted(theta.items())))
            hit = ctx.cache.get(ck)
            if hit is not None:
                return hit
        f = np.asarray(self.features(ctx, theta), float)
        f = f.reshape(f.shape[0], -1)
        if not self.uses_prediction:
            ctx.cache[ck] = f
        return f

    def input_axis(self, ctx: Context) -> tuple[np.ndarray, str]:
        """The effect's input channel and its label with unit (a :meth:`regressor`)."""
        d = ctx.data
        return d.inputs[self.channel], f"{self.channel} ({d.units.get(self.channel, '')})"


def count(theta: dict, key: str) -> int:
    """The length of setting ``key``, a non-empty list of numbers or names (for
    :meth:`Effect.width`); TypeError or ValueError when it is not one, KeyError when missing."""
    v = theta[key]
    if not isinstance(v, (tuple, list)) or not v:
        raise TypeError(f"{key} is not a non-empty list")
    return len(v)


def whole(theta: dict, key: str, lo: int) -> int:
    """Setting ``key``, a whole number at least ``lo`` (for :meth:`Effect.width`)."""
    v = theta[key]
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{key} is not a whole number >= {lo}")
    return v


def ordered() -> list[type[Effect]]:
    """The registered effect classes in candidate order: ``per_input`` ones by ``rank``, then
    the others by ``rank`` (ties: registration order)."""
    return sorted(EFFECTS.values(), key=lambda c: (not c.per_input, c.rank))


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
    runs: tuple[str, ...] = ()   # per-run intercepts (alpha starts with one per run)
    tare: bool = True            # a run not in ``runs`` is tared (else the runs' mean offset)

    def to_json(self) -> dict:
        return {"name": self.effect.name, "channel": self.effect.channel,
                "theta": jsonable(self.theta), "beta": list(self.beta),
                "alpha": list(self.alpha), "nuisance": list(self.nuisance),
                **({"runs": list(self.runs), "tare": self.tare} if self.runs else {}),
                "parameters": describe(self)}

    @staticmethod
    def from_json(d: dict) -> Fitted:
        name = d["name"]
        if name not in EFFECTS:
            raise ModelError(f"model effect name={name!r} is not known; allowed: "
                             f"{', '.join(c.name for c in ordered())}")
        eff = EFFECTS[name](d.get("channel"))
        th = {k: tuple(v) if isinstance(v, list) else v for k, v in d["theta"].items()}
        return Fitted(eff, th, tuple(d["beta"]), tuple(d["alpha"]), tuple(d["nuisance"]),
                      runs=tuple(str(r) for r in d.get("runs", [])),
                      tare=bool(d.get("tare", True)))


#: seconds at the start of a run not seen in training over which its offset is tared (5 s: over
#: 1 s the tare's noise let a start-of-run settling term pass as an effect in runs of noise)
TARE_S = 5.0


def run_paths(data: Dataset, rows: np.ndarray | None = None) -> tuple[str, ...]:
    """The paths of the runs with samples in ``rows`` (all rows by default), in run order."""
    seg = data.segment if rows is None else data.segment[rows]
    return tuple(data.segments[s]["path"] if s < len(data.segments) else f"segment {s}"
                 for s in np.unique(seg))


def _run_of_sample(data: Dataset) -> np.ndarray:
    names = np.array([s["path"] for s in data.segments] + [""], dtype=object)
    seg = np.minimum(data.segment, len(data.segments))
    out = names[seg]
    missing = data.segment >= len(data.segments)
    if np.any(missing):
        out = out.copy()
        out[missing] = [f"segment {s}" for s in data.segment[missing]]
    return out


def nuisance_columns(data: Dataset, base_inputs: tuple[str, ...], intercept: bool,
                     runs: tuple[str, ...] = ()) -> np.ndarray:
    """The base's affine part refitted with an effect: [1 or one indicator per run in
    ``runs``,] base inputs, (n, k)."""
    if intercept and runs:
        which = _run_of_sample(data)
        cols = [(which == r).astype(float) for r in runs]
    else:
        cols = [np.ones(len(data))] if intercept else []
    cols += [data.inputs[n] for n in base_inputs]
    return np.column_stack(cols) if cols else np.zeros((len(data), 0))


def fit(effect: Effect, ctx: Context, residual: np.ndarray, rows: np.ndarray,
        thetas: list[dict] | None = None) -> Fitted:
    """Best settings (AIC over the grid) and least-squares coefficients on ``rows``."""
    return fit_group([effect], ctx, residual, rows,
                     [thetas] if thetas is not None else None)[-1]


def group_member(e: Effect) -> bool:
    """Whether an effect's coefficients can be refitted jointly with others in one least
    squares: regressors of the data alone, free coefficients, nothing added beyond them."""
    t = type(e)
    return (not t.uses_prediction and not t.fixed_coefficients and t.intercept
            and t.solve is Effect.solve and t.extra is Effect.extra)


def fit_group(members: list[Effect], ctx: Context, residual: np.ndarray, rows: np.ndarray,
              thetas: list[list[dict] | None] | None = None) -> list[Fitted]:
    """Joint fit of several effects and the base's affine part: one least squares over the
    union of their regressors and the nuisance columns on ``rows``; settings by AIC over the
    product of the members' grids (``thetas[i]`` None: member i's own grid). Returns one
    :class:`Fitted` per member, in order; the nuisance refit (``alpha``, per-run intercepts when
    ``ctx.per_run``) is carried by the last member, the others get zeros. At most one member
    may have its own ``solve`` (a constrained density): its columns lead the system."""
    members = list(members)
    last = members[-1]
    intercept = all(type(m).intercept for m in members)
    runs = run_paths(ctx.data, rows) if (ctx.per_run and intercept) else ()
    N = nuisance_columns(ctx.data, ctx.base_inputs, intercept, runs)
    r = residual[rows]
    n = int(rows.sum())
    if n == 0:      # a fold with no usable samples (short runs, long lags): skip, say why
        raise ModelError(f"{last.name}: no samples left to fit in this fold")
    ctx.cache["rows"] = rows
    grids = [(thetas[i] if thetas is not None and thetas[i] is not None else m.grid(ctx))
             for i, m in enumerate(members)]
    fixed = len(members) == 1 and last.fixed_coefficients
    own = [i for i, m in enumerate(members) if type(m).solve is not Effect.solve]
    if len(own) > 1:
        raise ModelError("a joint fit takes at most one effect with its own solver")
    order = own + [i for i in range(len(members)) if i not in own]
    try:
        best, why = _best_setting(members, grids, ctx, N, r, rows, n, fixed, order)
        if best is not None:
            searched = [thetas is None or thetas[i] is None for i in range(len(members))]
            best = _refined(members, grids, searched, best, ctx, N, r, rows, n, fixed, order)
    finally:
        ctx.cache.pop("rows", None)
    if best is None:
        raise ModelError(f"effect {'+'.join(m.key for m in members)}: no setting could be "
                         f"fitted ({why})")
    return _fitted(members, *best[1:], fixed, ctx, runs)


def _best_setting(members: list[Effect], grids: list, ctx: Context, N: np.ndarray,
                  r: np.ndarray, rows: np.ndarray, n: int, fixed: bool, order: list[int]
                  ) -> tuple[tuple | None, str]:
    """The lowest-AIC setting over the product of the grids, (aic, combo, widths, coef, sse)
    or None, and why the last setting that could not be fitted failed."""
    best = None
    why = "an empty grid"
    for combo in itertools.product(*grids):
        got = _fit_combo(members, combo, ctx, N[rows], r, rows, fixed, order)
        if isinstance(got, str):
            why = got
            continue
        widths, coef, sse, p = got
        aic = n * math.log(max(sse, 1e-300) / n) + 2 * p
        if best is None or aic < best[0]:
            best = (aic, combo, widths, coef, sse)
    return best, why


def _neighbours(grid: list[dict], theta: dict, key: str) -> tuple[float, float] | None:
    """The grid's values of setting ``key`` next to ``theta``'s (the other settings equal),
    as (lower, upper) bounds of a refinement; None when ``theta[key]`` is no positive float."""
    v = theta.get(key)
    if not isinstance(v, float) or not v > 0:
        return None
    rest = {k: repr(x) for k, x in theta.items() if k != key}
    vals = sorted({g[key] for g in grid if isinstance(g.get(key), float) and g[key] > 0
                   and {k: repr(x) for k, x in g.items() if k != key} == rest})
    if len(vals) < 2 or v not in vals:
        return None
    i = vals.index(v)
    return vals[max(i - 1, 0)], vals[min(i + 1, len(vals) - 1)]


def _refined(members: list[Effect], grids: list, searched: list[bool], best: tuple,
             ctx: Context, N: np.ndarray, r: np.ndarray, rows: np.ndarray, n: int,
             fixed: bool, order: list[int]) -> tuple:
    """``best`` (aic, combo, widths, coef, sse) with the ``refine`` setting of each member whose
    grid was searched moved to the lowest AIC between its grid neighbours (bounded scalar
    search on its logarithm, 1 % in the value): a planted time constant or width between two
    grid values is not left half explained."""
    from scipy.optimize import minimize_scalar

    for i, m in enumerate(members):
        key = type(m).refine
        bounds = _neighbours(grids[i], best[1][i], key) if key and searched[i] else None
        if bounds is None:
            continue
        found = {}

        def aic(log_v: float, i=i, key=key, found=found, start=best[1]) -> float:
            combo = list(start)
            combo[i] = {**combo[i], key: float(math.exp(log_v))}
            got = _fit_combo(members, tuple(combo), ctx, N[rows], r, rows, fixed, order)
            if isinstance(got, str):
                return math.inf
            widths, coef, sse, p = got
            a = n * math.log(max(sse, 1e-300) / n) + 2 * p
            found[log_v] = (a, tuple(combo), widths, coef, sse)
            return a

        minimize_scalar(aic, bounds=(math.log(bounds[0]), math.log(bounds[1])),
                        method="bounded", options={"xatol": 0.01})
        top = min(found.values(), key=lambda b: b[0], default=None)
        if top is not None and top[0] < best[0]:
            best = top
    return best


def _fit_combo(members: list[Effect], combo: tuple, ctx: Context, Nr: np.ndarray,
               r: np.ndarray, rows: np.ndarray, fixed: bool, order: list[int]
               ) -> tuple[list[int], np.ndarray, float, int] | str:
    """Least squares at one setting of every member: (column widths, coefficients in the
    members' order then the nuisance's, sum of squared errors, parameters counted by AIC), or
    why the setting cannot be fitted."""
    Fs = [m.columns(ctx, th) for m, th in zip(members, combo)]
    bad = next((th for F, th in zip(Fs, combo) if not np.all(np.isfinite(F))), None)
    if bad is not None:
        return f"non-finite regressors at {bad}"
    widths = [F.shape[1] for F in Fs]
    if fixed:
        X, target = Nr, r - Fs[0][rows].sum(1)
    else:   # the member with its own solver first (its columns lead in X)
        X = np.column_stack([Fs[i][rows] for i in order] + [Nr])
        target = r
    if X.shape[1]:
        coef = (np.linalg.lstsq(X, target, rcond=None)[0] if fixed
                else members[order[0]].solve(X, target, widths[order[0]]))
        sse = float(np.sum((target - X @ coef) ** 2))
        if not fixed:
            coef = _members_order(coef, order, widths)
    else:
        coef, sse = np.zeros(0), float(np.sum(target ** 2))
    return widths, coef, sse, X.shape[1] + (len(combo[0]) if fixed else 0)


def _members_order(coef: np.ndarray, order: list[int], widths: list[int]) -> np.ndarray:
    """Coefficients solved in ``order`` back to the members' order (the nuisance's last)."""
    at, parts = 0, {}
    for i in order:
        parts[i] = coef[at:at + widths[i]]
        at += widths[i]
    return np.r_[np.concatenate([parts[i] for i in range(len(widths))]), coef[at:]]


def _fitted(members: list[Effect], combo: tuple, widths: list[int], coef: np.ndarray,
            sse: float, fixed: bool, ctx: Context, runs: tuple[str, ...]) -> list[Fitted]:
    """One :class:`Fitted` per member; the last carries the nuisance refit."""
    out, at = [], 0
    for i, (m, th) in enumerate(zip(members, combo)):
        if fixed:
            beta = (1.0,) * widths[i]
        else:
            beta = tuple(map(float, coef[at:at + widths[i]]))
            at += widths[i]
        if i == len(members) - 1:
            alpha = tuple(map(float, coef[0 if fixed else at:]))
            out.append(Fitted(m, th, beta, alpha, tuple(ctx.base_inputs), sse, runs, ctx.tare))
        else:
            k = (1 if type(m).intercept else 0) + len(ctx.base_inputs)
            out.append(Fitted(m, th, beta, (0.0,) * k, tuple(ctx.base_inputs), sse))
    return out


def contribution(f: Fitted, ctx: Context) -> np.ndarray:
    """What the fitted effect adds to the prediction ``ctx.yhat`` on ``ctx.data``. With
    per-run intercepts, a run not seen in training is tared: its offset is the mean of the
    remaining residual over its first :data:`TARE_S` seconds when the measured output is known
    (as a rig re-zeros at the start of a run) and ``f.tare``, else the mean of the trained runs'
    offsets."""
    F = f.effect.columns(ctx, f.theta)
    runs = per_run_layout(f)
    N = nuisance_columns(ctx.data, f.nuisance, f.effect.intercept, runs)
    out = F @ np.asarray(f.beta) + (N @ np.asarray(f.alpha) if N.shape[1] else 0.0)
    if runs:
        out = out + _tare(f, ctx, out)
    extra = f.effect.extra(f, ctx, out)
    return out if extra is None else out + extra


def per_run_layout(f: Fitted) -> tuple[str, ...]:
    """The runs of ``f``'s per-run intercepts, or () when its ``alpha`` has one intercept (a
    mechanism carried over to a design with its affine refit replaced, ``alpha`` zeroed)."""
    if f.runs and f.effect.intercept and len(f.alpha) == len(f.runs) + len(f.nuisance):
        return f.runs
    return ()


def _tare(f: Fitted, ctx: Context, partial: np.ndarray) -> np.ndarray:
    d = ctx.data
    off = np.zeros(len(d))
    which = _run_of_sample(d)
    tin = None
    for s in np.unique(d.segment):
        m = d.segment == s
        if which[m][0] in f.runs:
            continue
        if ctx.measured is not None and f.tare:
            tin = d.time_in_run() if tin is None else tin
            w = m & (tin <= TARE_S)
            off[m] = float(np.mean((ctx.measured - ctx.yhat - partial)[w]))
        else:
            off[m] = float(np.mean(f.alpha[:len(f.runs)]))
    return off


def describe(f: Fitted) -> dict:
    """Parameters of a fitted effect under their physical names, with the refit of the base's
    affine part (``base_adjust``)."""
    out: dict[str, Any] = f.effect.describe(f)
    if f.alpha and any(a != 0.0 for a in f.alpha):
        head = ([f"offset[{r}]" for r in f.runs] if f.runs else ["intercept"]) \
            if f.effect.intercept else []
        names = head + [f"gain[{n}]" for n in f.nuisance]
        out["base_adjust"] = dict(zip(names, f.alpha))
    elif f.alpha:
        out["base_adjust"] = "refitted jointly: carried by the last effect of its group"
    return out


def regressor(f: Fitted, ctx: Context) -> tuple[np.ndarray, str]:
    """The variable that best shows the effect (for plots): one regressor and its name."""
    return f.effect.regressor(f, ctx)
