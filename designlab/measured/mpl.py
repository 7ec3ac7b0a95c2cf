"""The modified Power-Law (mPL) hysteresis/creep model of seed 000 (Schouten, Kosmas, Krijnen).

A recurrent network analogous to an electrical circuit: each *cell* i is a sinh-law resistor
charging a capacitor (capacitance folded into ``P_S``), all cells driven by the same input u, and
a polynomial output stage g::

    ds_i/dt = P_S,i (exp((u - s_i)/P_T,i) - exp(-(u - s_i)/P_T,i))
    z       = w0 u + sum_i w_i s_i + V_b
    y       = g(z) = g_0 + g_1 z + ... + g_m z^m

Seed 000 gives this only in words (plus Table II initial values); the equations are our
reconstruction (../shared/notes/mpl_model.md), consistent with the authors' abstracts: 3N + 2
parameters for N cells besides g. Per cell the small-signal time constant is
``tau = P_T / (2 P_S)`` (s); the state lags a steady input ramp of rate r by
``P_T asinh(r tau / P_T)``: a soft play operator (local memory); several cells give global memory.

Two time updates, input held constant over each step (zero-order hold of u_k):

* ``"euler"`` -- the paper's forward Euler ``s[k+1] = s[k] + dt f(u_k - s[k])``. It is stable only
  while ``dt (2 P_S / P_T) cosh((u_k - s[k]) / P_T) < 2`` (see :func:`euler_stability`).
* ``"exact"`` (default) -- the exact solution of the cell ODE over the step,
  ``s[k+1] = u_k - 2 P_T atanh(tanh((u_k - s[k]) / (2 P_T)) exp(-dt / tau))``: it never overshoots
  (``s`` moves monotonically towards ``u_k`` and stops short of it) for any dt.

The exact update is a Moebius map of ``r_k = exp(-dt/tau) tanh((u_k - s_k)/(2 P_T))``::

    r_{k+1} = a (r_k + d_k) / (1 + d_k r_k),   a = exp(-dt/tau),  d_k = tanh((u_{k+1} - u_k)/(2 P_T))

so the whole time loop is a prefix product of 2x2 matrices ``[[a, a d_k], [d_k, 1]]``, which
:func:`cell_states` evaluates for every cell and every parameter set at once with a log2(T)-pass
parallel scan (no Python loop over time). That is what makes the batched finite-difference
Jacobian in :func:`fit` cheap.

Units: u and the states in the sensor's unit (e.g. V or ohm), P_T in the same unit, P_S in
unit/s, dt and tau in s, y in the reference unit (e.g. N).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from designlab.errors import DataError, ModelError, ParameterError
from designlab.params import rng, validate

UPDATES = ("exact", "euler")
DT_PAPER = 0.0133  # s, seed 000: 150 Hz down-sampled by 2


@dataclass(frozen=True)
class MPLParams:
    """mPL model parameters; defaults are seed 000 Table II initial values (one cell, g0..g5)."""

    w0: float = field(default=1.0, metadata=rng(doc="instantaneous input weight"))
    w: tuple[float, ...] = (-0.1,)
    V_b: float = field(default=0.1, metadata=rng(doc="offset, input unit"))
    P_T: tuple[float, ...] = (0.2,)
    P_S: tuple[float, ...] = (0.2,)
    g: tuple[float, ...] = (0.1,) * 6
    update: str = field(default="exact", metadata=rng(choices=UPDATES))

    def __post_init__(self):
        for name in ("w", "P_T", "P_S", "g"):
            val = getattr(self, name)
            try:
                tup = tuple(float(x) for x in np.atleast_1d(np.asarray(val, float)))
            except (TypeError, ValueError):
                raise ParameterError(name, val, "a sequence of numbers") from None
            if not all(np.isfinite(tup)):
                raise ParameterError(name, val, "finite numbers")
            object.__setattr__(self, name, tup)
        for name in ("w0", "V_b"):
            object.__setattr__(self, name, float(getattr(self, name)))
        validate(self)
        n = len(self.w)
        if n < 1 or len(self.P_T) != n or len(self.P_S) != n:
            raise ParameterError("w", self.w, "one weight per cell, as many as P_T and P_S (>= 1)")
        if any(p <= 0 for p in self.P_T):
            raise ParameterError("P_T", self.P_T, "each > 0 (input unit)")
        if any(p <= 0 for p in self.P_S):
            raise ParameterError("P_S", self.P_S, "each > 0 (input unit / s)")
        if len(self.g) < 1:
            raise ParameterError("g", self.g, "at least one polynomial coefficient")

    @property
    def n_cells(self) -> int:
        return len(self.w)

    @property
    def tau(self) -> tuple[float, ...]:
        """Small-signal time constant of each cell, P_T / (2 P_S), in s."""
        return tuple(pt / (2 * ps) for pt, ps in zip(self.P_T, self.P_S))

    @property
    def n_parameters(self) -> int:
        """3N + 2 circuit parameters plus the m + 1 polynomial coefficients."""
        return 3 * self.n_cells + 2 + len(self.g)

    def states(self, u, dt, *, s0=None) -> np.ndarray:
        """Cell states (n_cells, T) for input ``u`` (T,) sampled every ``dt`` s."""
        u, dt = _check_input(u, dt)
        return cell_states(u, np.array(self.P_T), np.array(self.P_S), dt, self.update,
                           s0=s0)

    def simulate(self, u, dt, *, s0=None) -> np.ndarray:
        """Model output y (T,) for input ``u`` (T,); states start at ``s0`` (default u[0], at rest).

        With ``update="euler"`` a violated stability criterion raises :class:`ModelError`.
        """
        u, dt = _check_input(u, dt)
        s = cell_states(u, np.array(self.P_T), np.array(self.P_S), dt, self.update, s0=s0)
        if self.update == "euler":
            crit = _euler_criterion(u, s, np.array(self.P_T), np.array(self.P_S), dt)
            if not crit < 2:
                raise ModelError(f"forward Euler is unstable here: max dt*(2 P_S/P_T)*cosh((u-s)/"
                                 f"P_T) = {crit:.3g} >= 2; use update='exact' or a smaller dt")
        return self.output(u, s)

    def output(self, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Output stage y = g(w0 u + sum_i w_i s_i + V_b) for input (T,) and states (N, T)."""
        z = self.w0 * u + np.tensordot(np.array(self.w), s, axes=(0, 0)) + self.V_b
        return np.polynomial.polynomial.polyval(z, np.array(self.g))


def simulate(params: MPLParams, u, dt, *, s0=None) -> np.ndarray:
    """Model output for input ``u`` (T,) every ``dt`` s; see :meth:`MPLParams.simulate`."""
    return params.simulate(u, dt, s0=s0)


def euler_stability(params: MPLParams, u, dt) -> float:
    """Largest ``dt (2 P_S / P_T) cosh((u_k - s_k) / P_T)`` along the forward-Euler trajectory.

    Forward Euler is (locally) stable while this stays below 2: the linearised update
    ``1 - dt f'(x)`` must stay inside (-1, 1). Above 1 the Euler state overshoots u_k.
    """
    u, dt = _check_input(u, dt)
    pt, ps = np.array(params.P_T), np.array(params.P_S)
    s = cell_states(u, pt, ps, dt, "euler")
    return _euler_criterion(u, s, pt, ps, dt)


def _euler_criterion(u, s, pt, ps, dt) -> float:
    with np.errstate(over="ignore", invalid="ignore"):
        x = (u[:-1] - s[:, :-1]) / pt[:, None]        # the steps actually taken
        crit = np.max(np.asarray(dt) * (2 * ps / pt)[:, None] * np.cosh(x))
    return float(crit) if np.isfinite(crit) else float("inf")


def _check_input(u, dt) -> tuple[np.ndarray, float | np.ndarray]:
    u = np.asarray(u, float)
    if u.ndim != 1 or u.size < 2:
        raise DataError(f"mPL input u must be a 1-D signal of at least 2 samples, got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise DataError("mPL input u contains NaN or infinite samples")
    dt_arr = np.asarray(dt, float)
    if dt_arr.ndim == 0:
        if not (np.isfinite(dt_arr) and dt_arr > 0):
            raise ParameterError("dt", dt, "a time step > 0 s")
        return u, float(dt_arr)
    if dt_arr.shape != (u.size - 1,) or not np.all(dt_arr > 0):
        raise ParameterError("dt", f"array of shape {dt_arr.shape}",
                             f"a step > 0 s or {u.size - 1} steps > 0 s")
    return u, dt_arr


# ----------------------------------------------------------------------------- time loop

def cell_states(u: np.ndarray, P_T: np.ndarray, P_S: np.ndarray, dt, update: str = "exact", *,
                s0=None, starts: np.ndarray | None = None) -> np.ndarray:
    """States of many independent cells driven by one input.

    ``u`` (T,); ``P_T``, ``P_S`` of any common shape S (one entry per cell and parameter set);
    ``dt`` a step in s or (T-1,) steps; ``starts`` (T,) bool marks samples where a new record
    begins (state reset to rest, s = u). Returns states of shape S + (T,).
    """
    P_T, P_S = np.broadcast_arrays(np.asarray(P_T, float), np.asarray(P_S, float))
    shape = P_T.shape
    pt, ps = P_T.reshape(-1, 1), P_S.reshape(-1, 1)
    T = u.size
    s0 = np.full((pt.shape[0], 1), u[0]) if s0 is None else np.broadcast_to(
        np.asarray(s0, float).reshape(-1, 1), (pt.shape[0], 1))
    if update == "exact":
        s = _exact_states(u, pt, ps, dt, s0, starts)
    elif update == "euler":
        s = _euler_states(u, pt, ps, dt, s0, starts)
    else:
        raise ParameterError("update", update, "one of " + ", ".join(UPDATES))
    return s.reshape(shape + (T,))


def _euler_states(u, pt, ps, dt, s0, starts):
    T = u.size
    dts = np.broadcast_to(np.asarray(dt, float), (T - 1,))
    out = np.empty((pt.shape[0], T))
    s = s0[:, 0].copy()
    pt1, ps1 = pt[:, 0], ps[:, 0]
    reset = np.zeros(T, bool) if starts is None else np.asarray(starts, bool)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(T):
            if k and reset[k]:
                s = np.full_like(s, u[k])
            out[:, k] = s
            if k < T - 1:
                x = (u[k] - s) / pt1
                s = s + dts[k] * ps1 * (np.exp(x) - np.exp(-x))
    return out


def _moebius_scan(m11, m12, m21, m22, r0):
    """Orbit r_{k+1} = (m11_k r_k + m12_k) / (m21_k r_k + m22_k) for k = 0..n-1, from r0 (B,).

    Blocked scan: the n maps (B, n) are cut into chunks of L ~ sqrt(n); the prefix products
    of 2x2 matrices inside every chunk are built by a loop over L (vectorised over all
    chunks and rows), the chunk-start values by a loop over the chunks (vectorised over rows),
    and every value is then one vectorised Moebius evaluation: O(n) work, ~2 sqrt(n) numpy
    steps instead of n. Returns r_1..r_n as (B, n).
    """
    B, n = m11.shape
    L = max(8, int(np.sqrt(n)) + 1)
    C = -(-n // L)
    pad = C * L - n

    def block(m, fill):
        if pad:
            m = np.concatenate([m, np.full((B, pad), fill)], axis=1)
        return np.ascontiguousarray(m.reshape(B, C, L).transpose(2, 0, 1))   # (L, B, C)

    p11, p12, p21, p22 = block(m11, 1.0), block(m12, 0.0), block(m21, 0.0), block(m22, 1.0)
    for l in range(1, L):       # P_l = M_l P_{l-1} inside every chunk
        a11, a12, a21, a22 = p11[l], p12[l], p21[l], p22[l]
        b11, b12, b21, b22 = p11[l - 1], p12[l - 1], p21[l - 1], p22[l - 1]
        n11 = a11 * b11 + a12 * b21
        n12 = a11 * b12 + a12 * b22
        n21 = a21 * b11 + a22 * b21
        n22 = a21 * b12 + a22 * b22
        if l % 16 == 0:         # keep the (projective) products well scaled
            nrm = np.abs(n11) + np.abs(n12) + np.abs(n21) + np.abs(n22)
            n11 /= nrm
            n12 /= nrm
            n21 /= nrm
            n22 /= nrm
        p11[l], p12[l], p21[l], p22[l] = n11, n12, n21, n22
    start = np.empty((B, C))    # r at the start of every chunk
    start[:, 0] = r0
    e11, e12, e21, e22 = p11[-1], p12[-1], p21[-1], p22[-1]
    for c in range(C - 1):
        x = start[:, c]
        start[:, c + 1] = (e11[:, c] * x + e12[:, c]) / (e21[:, c] * x + e22[:, c])
    r = (p11 * start + p12) / (p21 * start + p22)                    # (L, B, C)
    return r.transpose(1, 2, 0).reshape(B, C * L)[:, :n]


def _exact_states(u, pt, ps, dt, s0, starts):
    """Exact zero-order-hold update as a scan of Moebius maps (see :func:`_moebius_scan`)."""
    T = u.size
    B = pt.shape[0]
    out = np.empty((B, T))
    out[:, :1] = s0
    if T == 1:
        return out
    a = np.exp(-np.asarray(dt, float) * 2.0 * ps / pt)          # (B, 1) or (B, T-1)
    a = np.broadcast_to(a, (B, T - 1))
    d = np.tanh(np.diff(u)[None, :] / (2.0 * pt))                 # (B, T-1)
    np.clip(d, -1.0 + 1e-15, 1.0 - 1e-15, out=d)
    # M_k maps r_k -> r_{k+1}:  [[a, a d], [d, 1]]
    m11 = a.copy()
    m12 = a * d
    m21 = d
    m22 = np.ones((B, T - 1))
    if starts is not None:
        rs = np.asarray(starts, bool)[1:]
        if rs.any():            # r = 0 at a record start: the map becomes the constant 0
            m11[:, rs] = 0.0
            m12[:, rs] = 0.0
            m21[:, rs] = 0.0
    r0 = a[:, :1] * np.tanh((u[0] - s0) / (2.0 * pt))             # (B, 1)
    r = np.empty((B, T - 1))
    r[:, :1] = r0
    r[:, 1:] = _moebius_scan(m11, m12, m21, m22, r0[:, 0])[:, :-1]   # r_1 .. r_{T-2}
    np.clip(r, -1.0 + 1e-16, 1.0 - 1e-16, out=r)
    out[:, 1:] = u[None, :-1] - 2.0 * pt * np.arctanh(r)
    if starts is not None:
        idx = np.flatnonzero(np.asarray(starts, bool)[1:]) + 1
        out[:, idx] = u[idx]
    return out


# ----------------------------------------------------------------------------- fitting

@dataclass(frozen=True)
class MPLFitReport:
    """How a fit went: cells chosen, least-squares iterations, cost, wall time."""

    n_cells: int
    order: int
    update: str
    iterations: int            # residual evaluations of the final local fits (sum over starts)
    jacobians: int             # batched finite-difference Jacobians (sum over starts)
    starts: int                # local least-squares runs
    rmse: float                # training RMSE of the returned model, output unit
    val_rmse: float | None     # validation RMSE (given or held-out data), output unit
    history: tuple[tuple[int, float, float], ...]   # (cells, train RMSE, validation RMSE)
    time_s: float
    message: str


@dataclass
class _Problem:
    """Normalised fitting problem: u, y in [0, 1], records concatenated with reset flags."""

    u: np.ndarray
    y: np.ndarray
    dt: float
    starts: np.ndarray
    fit_mask: np.ndarray
    order: int
    update: str
    bad: float = 10.0

    def residuals(self, theta: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """Variable-projection residuals for parameter sets theta (B, 3N) -> (B, n_rows)."""
        theta = np.atleast_2d(theta)
        B, p = theta.shape
        N = p // 3
        tau, pt, w = np.exp(theta[:, :N]), np.exp(theta[:, N:2 * N]), theta[:, 2 * N:]
        ps = pt / (2.0 * tau)
        s = cell_states(self.u, pt, ps, self.dt, self.update, starts=self.starts)  # (B, N, T)
        mask = self.fit_mask if mask is None else mask
        if mask.all():
            z = self.u[None, :] + np.matmul(w[:, None, :], s)[:, 0]
            y = self.y
        else:
            z = self.u[mask][None, :] + np.matmul(w[:, None, :], s[:, :, mask])[:, 0]
            y = self.y[mask]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            # Legendre basis on z mapped to [-1, 1]: spans the same polynomials as the
            # monomials, but the normal equations stay well conditioned
            lo, hi = z.min(1, keepdims=True), z.max(1, keepdims=True)
            x = (2.0 * z - (lo + hi)) / np.maximum(hi - lo, 1e-300)
            phi = np.polynomial.legendre.legvander(x, self.order)      # (B, n, m+1)
            gram = np.matmul(phi.transpose(0, 2, 1), phi)
            rhs = np.matmul(phi.transpose(0, 2, 1), y[None, :, None])
            ok = np.all(np.isfinite(gram), axis=(1, 2)) & np.all(np.isfinite(rhs), axis=(1, 2))
            res = np.full((B, y.size), self.bad)
            if ok.any():
                g = gram[ok] + 1e-13 * np.trace(gram[ok], axis1=1, axis2=2)[:, None, None] \
                    * np.eye(self.order + 1)
                coef = np.linalg.solve(g, rhs[ok])
                res[ok] = np.matmul(phi[ok], coef)[..., 0] - y
        res[~np.isfinite(res)] = self.bad
        return res

    def coefficients(self, theta: np.ndarray) -> np.ndarray:
        """Polynomial coefficients g (normalised units, monomial basis in z) at theta."""
        N = theta.size // 3
        tau, pt, w = np.exp(theta[:N]), np.exp(theta[N:2 * N]), theta[2 * N:]
        s = cell_states(self.u, pt, pt / (2 * tau), self.dt, self.update, starts=self.starts)
        z = self.u + w @ s
        m = self.fit_mask
        return np.polynomial.polynomial.polyfit(z[m], self.y[m], self.order)


def _as_records(u, y, name_u="u", name_y="y") -> list[tuple[np.ndarray, np.ndarray]]:
    if isinstance(u, np.ndarray) and u.ndim == 1 or (not isinstance(u, (list, tuple))):
        us, ys = [u], [y]
    else:
        us, ys = list(u), list(y)
        if not isinstance(y, (list, tuple)) or len(ys) != len(us):
            raise DataError(f"{name_u} and {name_y} must both be signals or lists of as many records")
    out = []
    for i, (a, b) in enumerate(zip(us, ys)):
        a, b = np.asarray(a, float), np.asarray(b, float)
        if a.ndim != 1 or b.ndim != 1:
            raise DataError(f"{name_u}/{name_y} record {i}: 1-D signals expected, got shapes "
                            f"{a.shape} and {b.shape}")
        if a.size != b.size:
            raise DataError(f"{name_u}/{name_y} record {i}: lengths differ ({a.size} vs {b.size})")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise DataError(f"{name_u}/{name_y} record {i} contains NaN or infinite samples")
        out.append((a, b))
    return out


def _concat(records):
    u = np.concatenate([r[0] for r in records])
    y = np.concatenate([r[1] for r in records])
    starts = np.zeros(u.size, bool)
    starts[np.cumsum([0] + [r[0].size for r in records[:-1]])] = True
    return u, y, starts


def fit(u, y, dt: float, *, cells: int | None = None, max_cells: int = 3, order: int = 5,
        update: str = "exact", u_val=None, y_val=None, holdout: float = 0.2,
        n_starts: int = 3, n_screen: int = 48, max_nfev: int = 60,
        jacobian: str = "batched", seed: int = 0) -> tuple[MPLParams, MPLFitReport]:
    """Fit an mPL model y ~ mPL(u) by least squares; returns the model and a report.

    ``u``, ``y``: signals (T,) or lists of records (each simulated from rest); ``dt`` in s.
    ``cells=None`` adds cells (up to ``max_cells``) while the validation RMSE improves by more
    than 1 %: on ``u_val``/``y_val`` when given, else on the last ``holdout`` of the training data
    (the final model is then refitted on all of it). Recipe of ../shared/notes/mpl_model.md:
    u and y normalised to [0, 1], each cell parameterised by (log tau, log P_T, w) with tau
    bounded to [2 dt, half the record], w0 = 1, g (order ``order``) solved by linear least squares
    inside the residual (variable projection), scipy ``least_squares(method="trf")`` with a
    finite-difference Jacobian from one batched simulation of all perturbed parameter sets, started
    from the best ``n_starts`` of ``n_screen`` Latin-hypercube candidates (the Table II values
    among them), all screened in one batched simulation. ``jacobian="2-point"`` lets scipy
    difference one parameter at a time instead (slower; kept as a benchmark peer).
    To fit a compensator, pass the sensor signal as ``u`` and the reference force as ``y``.
    """
    t0 = time.perf_counter()
    _check_fit_options(dt, cells, max_cells, order, update, holdout, jacobian)
    records = _as_records(u, y)
    u_all, y_all, starts = _concat(records)
    if u_all.size < 4 * (order + 4):
        raise DataError(f"mPL fit needs at least {4 * (order + 4)} samples, got {u_all.size}")
    lo_u, hi_u = u_all.min(), u_all.max()
    lo_y, hi_y = y_all.min(), y_all.max()
    if hi_u <= lo_u or hi_y <= lo_y:
        raise DataError("mPL fit needs a varying input and output (constant signal given)")
    su, sy = hi_u - lo_u, hi_y - lo_y
    un, yn = (u_all - lo_u) / su, (y_all - lo_y) / sy

    val_records = None
    if u_val is not None or y_val is not None:
        if u_val is None or y_val is None:
            raise DataError("give both u_val and y_val for validation")
        val_records = _as_records(u_val, y_val, "u_val", "y_val")
    fit_mask = np.ones(un.size, bool)
    if cells is None and val_records is None:
        n_hold = int(round(holdout * un.size))
        fit_mask[-n_hold:] = False
    prob = _Problem(un, yn, dt, starts, fit_mask, order, update)
    if val_records is not None:
        uv, yv, sv = _concat(val_records)
        vprob = _Problem((uv - lo_u) / su, (yv - lo_y) / sy, dt, sv,
                         np.ones(uv.size, bool), order, update)
    else:
        vprob = dataclasses.replace(prob, fit_mask=~fit_mask)
    fitter = _Fitter(prob, vprob, max(r[0].size for r in records) * dt,
                     np.random.default_rng(seed), n_starts, n_screen, max_nfev, jacobian)
    best_theta, best_val, history, message = fitter.cells(cells, max_cells, sy,
                                                          val_records is not None)
    if cells is None and val_records is None:
        # refit the chosen model on all training data (warm start)
        prob.fit_mask = np.ones(un.size, bool)
        best_theta = fitter.local_fit(best_theta, *fitter.bounds(best_theta.size // 3)).x
    params = _to_physical(best_theta, prob.coefficients(best_theta), lo_u, su, lo_y, sy, update)
    yhat = np.concatenate([params.simulate(a, dt) for a, _ in records])
    train_rmse = float(np.sqrt(np.mean((yhat - y_all) ** 2)))
    report = MPLFitReport(n_cells=params.n_cells, order=order, update=update,
                          iterations=fitter.counters["nfev"], jacobians=fitter.counters["njev"],
                          starts=fitter.counters["starts"], rmse=train_rmse,
                          val_rmse=None if best_val is None or not np.isfinite(best_val)
                          else float(best_val),
                          history=tuple(history), time_s=time.perf_counter() - t0,
                          message=str(message))
    return params, report


def _check_fit_options(dt, cells, max_cells, order, update, holdout, jacobian) -> None:
    """The options of :func:`fit`: a one-line ParameterError for the first bad one."""
    if update not in UPDATES:
        raise ParameterError("update", update, "one of " + ", ".join(UPDATES))
    if jacobian not in ("batched", "2-point"):
        raise ParameterError("jacobian", jacobian, "batched or 2-point")
    if not (isinstance(order, (int, np.integer)) and 0 <= order <= 9):
        raise ParameterError("order", order, "an integer 0..9")
    if cells is not None and not (isinstance(cells, (int, np.integer)) and 1 <= cells <= 8):
        raise ParameterError("cells", cells, "an integer 1..8 or None (choose by validation)")
    if not (isinstance(max_cells, (int, np.integer)) and 1 <= max_cells <= 8):
        raise ParameterError("max_cells", max_cells, "an integer 1..8")
    if not (0.05 <= holdout <= 0.5):
        raise ParameterError("holdout", holdout, "0.05 <= value <= 0.5")
    if not (np.isfinite(dt) and dt > 0):
        raise ParameterError("dt", dt, "a time step > 0 s")


class _Fitter:
    """The nonlinear search of :func:`fit` on a normalised problem: Latin-hypercube screening,
    local trust-region fits, cells added while the validation error falls. ``vprob`` holds the
    validation rows (its ``fit_mask``): given records, or the held-out tail of ``prob``."""

    def __init__(self, prob: _Problem, vprob: _Problem, rec_len: float,
                 rng_: np.random.Generator, n_starts: int, n_screen: int, max_nfev: int,
                 jacobian: str):
        self.prob, self.vprob, self.rec_len, self.rng = prob, vprob, rec_len, rng_
        self.n_starts, self.n_screen, self.max_nfev = n_starts, n_screen, max_nfev
        self.jacobian = jacobian
        dt = prob.dt
        lb_tau, ub_tau = np.log(2 * dt), np.log(max(rec_len / 2, 4 * dt))
        self.bounds_cell = (np.array([lb_tau, np.log(1e-3), -10.0]),
                            np.array([ub_tau, np.log(10.0), 10.0]))
        self.counters = {"nfev": 0, "njev": 0, "starts": 0}

    def bounds(self, N: int) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the parameters of N cells."""
        lb = np.concatenate([np.repeat(self.bounds_cell[0][i], N) for i in range(3)])
        ub = np.concatenate([np.repeat(self.bounds_cell[1][i], N) for i in range(3)])
        return lb, ub

    def cells(self, cells: int | None, max_cells: int, sy: float, given_val: bool
              ) -> tuple[np.ndarray, float | None, list, str]:
        """The fitted parameters, their validation RMSE (output unit), the history of
        (cells, train RMSE, validation RMSE) and the last local fit's message: ``cells`` cells,
        or cells added up to ``max_cells`` while the validation RMSE falls by more than 1 %."""
        history = []
        best_theta, best_val = None, np.inf
        n_range = [cells] if cells is not None else range(1, max_cells + 1)
        theta = None
        message = ""
        for N in n_range:
            res = self.screen_and_fit(N, theta if (theta is not None and cells is None)
                                      else None)
            theta = res.x
            train = float(np.sqrt(2 * res.cost / max(1, self.prob.fit_mask.sum()))) * sy
            val = self.val_rmse(theta) * sy if (cells is None or given_val) else None
            history.append((int(N), float(train),
                            float(val) if val is not None else float("nan")))
            message = res.message
            if cells is not None:
                best_theta, best_val = theta, val
                break
            if val < best_val * 0.99:
                best_theta, best_val = theta, val
                if val <= 1e-9 * sy:        # exact already: more cells cannot help
                    break
            else:
                break
        return best_theta, best_val, history, message

    def val_rmse(self, theta: np.ndarray) -> float:
        """Validation RMSE (normalised) of theta, with g fitted on the training rows."""
        g = self.prob.coefficients(theta)
        pr, mask = self.vprob, self.vprob.fit_mask
        N = theta.size // 3
        tau, pt, w = np.exp(theta[:N]), np.exp(theta[N:2 * N]), theta[2 * N:]
        s = cell_states(pr.u, pt, pt / (2 * tau), pr.dt, pr.update, starts=pr.starts)
        yhat = np.polynomial.polynomial.polyval(pr.u + w @ s, g)
        err = yhat[mask] - pr.y[mask]
        v = float(np.sqrt(np.mean(err * err)))
        return v if np.isfinite(v) else float("inf")

    def local_fit(self, theta0: np.ndarray, lb: np.ndarray, ub: np.ndarray):
        """scipy's trust-region least squares from ``theta0`` within the bounds."""
        from scipy import optimize

        prob = self.prob
        cache = {}

        def fun(th):
            key = th.tobytes()
            if key not in cache:
                cache.clear()
                cache[key] = prob.residuals(th)[0]
            return cache[key]

        def jac(th):
            f0 = fun(th)
            h = 1e-7 * (1.0 + np.abs(th))
            step = np.where(th + h <= ub, h, -h)
            pert = th[None, :] + np.diag(step)
            fp = prob.residuals(pert)
            return ((fp - f0[None, :]) / step[:, None]).T

        res = optimize.least_squares(fun, np.clip(theta0, lb, ub),
                                     jac=jac if self.jacobian == "batched" else "2-point",
                                     bounds=(lb, ub),
                                     method="trf", x_scale="jac", max_nfev=self.max_nfev,
                                     ftol=1e-10, xtol=1e-10, gtol=1e-10)
        self.counters["nfev"] += res.nfev
        self.counters["njev"] += int(res.njev or 0)
        self.counters["starts"] += 1
        return res

    def candidates(self, N: int, fixed: np.ndarray | None) -> np.ndarray:
        """``n_screen`` starting points for N cells (the first N-1 cells from ``fixed``), each
        candidate's cells sorted by tau."""
        from scipy.stats import qmc

        dt, rec_len, n_screen = self.prob.dt, self.rec_len, self.n_screen
        n_new = N if fixed is None else 1
        lhs = qmc.LatinHypercube(d=3 * n_new, seed=self.rng).random(n_screen)
        lo_s = np.array([np.log(max(0.1, 2 * dt)), np.log(0.01), -1.0])
        hi_s = np.array([np.log(max(min(300.0, rec_len / 2), 4 * dt)), np.log(1.0), 1.0])
        new = lo_s.repeat(n_new) + lhs * (hi_s - lo_s).repeat(n_new)   # (n_screen, 3 n_new)
        if fixed is None:
            table2 = np.array([np.log(0.5), np.log(0.2), -0.1])  # Table II: tau = 0.5 s
            new[0] = table2.repeat(n_new)
            if n_new > 1:   # log-spread taus for the Table II start
                new[0, :n_new] = np.linspace(np.log(0.5), hi_s[0], n_new)
            cand = new
        else:
            Nf = N - 1
            cand = np.concatenate([np.repeat(fixed[None, :Nf], n_screen, 0), new[:, :1],
                                   np.repeat(fixed[None, Nf:2 * Nf], n_screen, 0), new[:, 1:2],
                                   np.repeat(fixed[None, 2 * Nf:], n_screen, 0),
                                   0.1 * new[:, 2:3]], axis=1)
        # sort each candidate's cells by tau (removes the permutation symmetry)
        order_ = np.argsort(cand[:, :N], axis=1)
        return np.concatenate([np.take_along_axis(cand[:, i * N:(i + 1) * N], order_, 1)
                               for i in range(3)], axis=1)

    def screen_and_fit(self, N: int, fixed: np.ndarray | None):
        """Candidates for N cells (the first N-1 cells from ``fixed``), best local fit."""
        lb, ub = self.bounds(N)
        cand = np.clip(self.candidates(N, fixed), lb, ub)
        costs = np.concatenate([np.sum(self.prob.residuals(c) ** 2, axis=1)
                                for c in np.array_split(cand, max(1, len(cand) // 16))])
        best = None
        for i in np.argsort(costs)[:self.n_starts]:
            res = self.local_fit(cand[i], lb, ub)
            if best is None or res.cost < best.cost:
                best = res
        return best


def _to_physical(theta, g_n, lo_u, su, lo_y, sy, update) -> MPLParams:
    """Map a normalised solution back to input/output units (w0 = 1, V_b absorbs the offsets)."""
    N = theta.size // 3
    tau, pt_n, w = np.exp(theta[:N]), np.exp(theta[N:2 * N]), theta[2 * N:]
    pt = pt_n * su
    ps = pt / (2 * tau)
    v_b = -lo_u * (1.0 + w.sum())
    g = sy * np.asarray(g_n) / su ** np.arange(len(g_n))
    g[0] += lo_y
    return MPLParams(w0=1.0, w=tuple(w), V_b=float(v_b), P_T=tuple(pt), P_S=tuple(ps),
                     g=tuple(g), update=update)


def with_update(params: MPLParams, update: str) -> MPLParams:
    """The same parameters with the other time update (``"exact"`` or ``"euler"``)."""
    return dataclasses.replace(params, update=update)
