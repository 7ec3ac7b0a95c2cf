"""Prony series from measured relaxation or creep data, and the exact uniaxial responses of a
generalized Maxwell material (the analytic references the FEM viscoelastic solver is checked against).

Units: time s, modulus/stress MPa, compliance 1/MPa, strain dimensionless.

Two material views share one set of functions:

* ``nu=None``: a 1-D rod whose Young's modulus relaxes as ``E(t) = E0 (g_inf + sum g_i exp(-t/tau_i))``
  (equivalently a 3-D isotropic solid whose shear and bulk moduli relax alike, constant Poisson ratio);
* ``nu`` given: a 3-D isotropic bar in uniaxial stress (lateral faces free) whose shear modulus
  relaxes with ``prony.g/tau`` and bulk modulus with ``prony.k/k_tau`` (elastic bulk if none), with
  instantaneous moduli from ``E0`` and ``nu``.

Either model is a linear state-space system ``x' = A x + B u``, ``y = C x + D u`` in the internal
(viscous) strains; responses to piecewise-linear inputs use its exact first-order-hold
discretisation (``scipy.linalg.expm``), step responses its eigen-decomposition.

Fits (``-> (E0, Prony, report)``, positive terms, sum < 1): :func:`fit_prony_relaxation`
(step-strain test), :func:`fit_prony_creep` (step-stress test), :func:`fit_prony_history` (any
strain history with its stress: finite-rate ramps, holds, cycles).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eig, expm
from scipy.optimize import least_squares, nnls
from scipy.signal import lfilter, lfiltic

from designlab.errors import DataError, ParameterError
from designlab.fem.prony import Prony


# --------------------------------------------------------------------------- state-space models


@dataclass(frozen=True)
class _LinearModel:
    A: np.ndarray
    B: np.ndarray  # (n,)
    C: np.ndarray  # (n,)
    D: float

    def step(self, t: np.ndarray, u0: float = 1.0) -> np.ndarray:
        """Output at times ``t`` >= 0 after a step of the input to ``u0`` at t = 0 (state 0 before)."""
        t = np.asarray(t, float)
        if len(self.B) == 0:
            return np.full(t.shape, self.D * u0)
        x_ss = -np.linalg.solve(self.A, self.B) * u0
        lam, V = eig(self.A)
        if np.linalg.cond(V) < 1e8 and np.all(np.abs(lam.imag) <= 1e-9 * np.abs(lam.real)):
            # x(t) = x_ss - expm(A t) x_ss, diagonalised
            w = (self.C @ V).real * np.linalg.solve(V, x_ss).real
            return self.C @ x_ss + self.D * u0 - np.exp(np.multiply.outer(t, lam.real)) @ w
        y = [self.C @ (x_ss - expm(self.A * s) @ x_ss) for s in t.ravel()]
        return self.D * u0 + np.reshape(y, t.shape)

    def spectrum(self) -> tuple[float, np.ndarray, np.ndarray]:
        """Step response to a unit input as ``y_inf + sum_k a_k exp(-t/theta_k)``:
        returns ``(y_inf, a, theta)`` (theta ascending)."""
        if len(self.B) == 0:
            return self.D, np.zeros(0), np.zeros(0)
        lam, V = eig(self.A)
        lam = lam.real
        x_ss = -np.linalg.solve(self.A, self.B)
        a = -(self.C @ V).real * np.linalg.solve(V, x_ss).real
        theta = -1.0 / lam
        o = np.argsort(theta)
        return float(self.C @ x_ss + self.D), a[o], theta[o]

    def response(self, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Output at the knots of a piecewise-linear input history ``u(t)`` starting from rest;
        ``u[0]`` is applied as a jump at ``t[0]``; repeated times are jumps (exact between knots)."""
        t, u = np.asarray(t, float), np.asarray(u, float)
        n = len(self.B)
        x = np.zeros(n)
        y = np.empty(len(t))
        y[0] = self.D * u[0]
        cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for k in range(1, len(t)):
            dt = t[k] - t[k - 1]
            if n and dt > 0:
                key = round(dt, 15)
                if key not in cache:
                    # first-order hold: d/ds [x, u, udot] = [[A, B, 0], [0, 0, 1], [0, 0, 0]]
                    M = np.zeros((n + 2, n + 2))
                    M[:n, :n] = self.A
                    M[:n, n] = self.B
                    M[n, n + 1] = 1.0
                    E = expm(M * dt)
                    cache[key] = (E[:n, :n], E[:n, n], E[:n, n + 1])
                Phi, G0, G1 = cache[key]
                x = Phi @ x + G0 * u[k - 1] + G1 * (u[k] - u[k - 1]) / dt
            y[k] = self.C @ x + self.D * u[k]
        return y


def _chain(modulus: float, g: np.ndarray, tau: np.ndarray):
    """One Maxwell chain ``s = M (e - g . a)``, ``a_i' = (e - a_i)/tau_i``: the pieces
    (A_aa, e-coefficient per a, output coefficients) of its equations."""
    return (-np.diag(1.0 / tau), 1.0 / tau, modulus * g)


def _model(E0: float, prony: Prony, nu: float | None, controlled: str) -> _LinearModel:
    """State-space model of the uniaxial bar; ``controlled`` is 'strain' (output stress) or
    'stress' (output strain)."""
    g, tau = np.asarray(prony.g, float), np.asarray(prony.tau, float)
    if nu is None:
        Ad, bd, cd = _chain(E0, g, tau)
        if controlled == "strain":  # sigma = E0 (eps - g.a), a' = Ad a + bd eps
            return _LinearModel(Ad, bd, -cd, E0)
        # eps = sigma/E0 + g.a
        return _LinearModel(Ad + np.outer(bd, g), bd / E0, g.copy(), 1.0 / E0)
    G0, K0 = E0 / (2 * (1 + nu)), E0 / (3 * (1 - 2 * nu))
    k, kt = np.asarray(prony.k, float), np.asarray(prony.k_tau, float)
    ng, nk = len(g), len(k)
    n = ng + nk
    # state x = [alpha (shear, on gamma = eps_a - eps_l), beta (bulk, on e_v = eps_a + 2 eps_l)]
    # S = 2 G0 (gamma - g.alpha) = sigma; p = K0 (e_v - k.beta) = sigma / 3; eps_a = e_v/3 + 2 gamma/3
    rate = np.concatenate([1.0 / tau, 1.0 / kt])
    Gx = np.concatenate([g, np.zeros(nk)])  # gamma = Gx.x + ...
    Kx = np.concatenate([np.zeros(ng), k])  # e_v = Kx.x + ...
    sel_g = np.concatenate([np.ones(ng), np.zeros(nk)])
    if controlled == "stress":
        # gamma = sigma/(2 G0) + g.alpha; e_v = sigma/K0/3 + k.beta
        cg, ck = 1 / (2 * G0), 1 / (3 * K0)
    else:
        # 2 G0 gamma - 3 K0 e_v = 2 G0 g.alpha - 3 K0 k.beta ; 2/3 gamma + 1/3 e_v = eps
        Mx = np.array([[2 * G0, -3 * K0], [2 / 3, 1 / 3]])
        Minv = np.linalg.inv(Mx)
        rhs_x = np.vstack([2 * G0 * Gx - 3 * K0 * Kx, np.zeros(n)])
        gam_x, ev_x = Minv @ rhs_x
        cg, ck = Minv @ np.array([0.0, 1.0])
        Gx, Kx = gam_x, ev_x
    # a' = rate * (driver - a), driver = gamma for shear states, e_v for bulk states
    drive_x = np.where(sel_g[:, None] > 0, Gx[None, :], Kx[None, :])
    drive_u = np.where(sel_g > 0, cg, ck)
    A = rate[:, None] * (drive_x - np.eye(n))
    B = rate * drive_u
    if controlled == "stress":  # output eps_a = e_v/3 + 2 gamma/3
        return _LinearModel(A, B, Kx / 3 + 2 * Gx / 3, ck / 3 + 2 * cg / 3)
    # output sigma = 2 G0 (gamma - g.alpha)
    return _LinearModel(A, B, 2 * G0 * (Gx - np.concatenate([g, np.zeros(nk)])), 2 * G0 * cg)


def _check_material(E0: float, nu: float | None) -> None:
    if not (np.isfinite(E0) and E0 > 0):
        raise ParameterError("E0", E0, "a finite instantaneous modulus > 0 MPa")
    if nu is not None and not (-1 < nu < 0.5):
        raise ParameterError("nu", nu, "-1 < nu < 0.5")


def relaxation_modulus(E0: float, prony: Prony, t, nu: float | None = None) -> np.ndarray:
    """Uniaxial relaxation modulus E(t) (MPa): stress after a unit step strain at t = 0."""
    _check_material(E0, nu)
    if nu is None:
        return E0 * prony.relaxation(t)
    return _model(E0, prony, nu, "strain").step(t)


def creep_compliance(E0: float, prony: Prony, t, nu: float | None = None) -> np.ndarray:
    """Uniaxial creep compliance J(t) (1/MPa): strain after a unit step stress at t = 0.
    J(0) = 1/E0, J(inf) = 1/E(inf); exact (eigen-decomposition of the internal-variable ODEs)."""
    _check_material(E0, nu)
    return _model(E0, prony, nu, "stress").step(t)


def retardation_spectrum(E0: float, prony: Prony, nu: float | None = None):
    """Creep compliance as ``J(t) = J_inf - sum_k j_k exp(-t/lambda_k)``: ``(J_inf, j, lambda)``."""
    _check_material(E0, nu)
    J_inf, a, theta = _model(E0, prony, nu, "stress").spectrum()
    return J_inf, -a, theta


def stress_response(E0: float, prony: Prony, t, strain, nu: float | None = None) -> np.ndarray:
    """Uniaxial stress (MPa) at the knots ``t`` (s, non-decreasing; repeats are jumps) of a
    piecewise-linear strain history, starting from rest (exact)."""
    _check_material(E0, nu)
    t, strain = _history(t, strain, "strain")
    return _model(E0, prony, nu, "strain").response(t, strain)


def strain_response(E0: float, prony: Prony, t, stress, nu: float | None = None) -> np.ndarray:
    """Uniaxial strain at the knots of a piecewise-linear stress history (MPa), from rest (exact)."""
    _check_material(E0, nu)
    t, stress = _history(t, stress, "stress")
    return _model(E0, prony, nu, "stress").response(t, stress)


def _history(t, u, name):
    t, u = np.asarray(t, float).ravel(), np.asarray(u, float).ravel()
    if len(t) != len(u) or len(t) < 1:
        raise DataError(f"t and {name} must have the same length >= 1 (got {len(t)} and {len(u)})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
        raise DataError(f"t and {name} must be finite numbers")
    if np.any(np.diff(t) < 0):
        raise DataError("t must be non-decreasing (s)")
    return t, u


# --------------------------------------------------------------------------- fitting


def _check_data(t, y, name: str, n_terms: int):
    if isinstance(n_terms, bool) or not isinstance(n_terms, (int, np.integer)) or not 1 <= n_terms <= 12:
        raise ParameterError("n_terms", n_terms, "an integer 1..12")
    t, y = np.asarray(t, float).ravel(), np.asarray(y, float).ravel()
    if len(t) != len(y):
        raise DataError(f"t and {name} have different lengths ({len(t)} and {len(y)})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise DataError(f"t and {name} must be finite (NaN or inf found)")
    if np.any(t < 0):
        raise DataError(f"t has negative times (min {t.min():g} s); times since loading must be >= 0 s")
    if np.any(np.diff(t) <= 0):
        raise DataError("t must be strictly increasing (s)")
    if len(t) < 2 * n_terms + 2:
        raise DataError(f"{len(t)} points are too few for {n_terms} Prony terms "
                        f"(need >= {2 * n_terms + 2})")
    if np.any(y <= 0):
        raise DataError(f"{name} must be > 0 at every time")
    if t[-1] <= 0 or np.count_nonzero(t > 0) < 2:
        raise DataError("t must span a positive duration (s)")
    return t, y


def _tau_grid(t: np.ndarray, n: int) -> np.ndarray:
    tp = t[t > 0]
    lo, hi = np.log10(tp[0]), np.log10(t[-1])
    return 10 ** np.linspace(lo + 0.25 * (hi - lo) / n, hi - 0.25 * (hi - lo) / n, n)


def _finish(E_inf, E_i, tau, t, y, model_fn, res, n_terms, kind, nu, denom=None):
    keep = E_i > 1e-7 * (E_inf + E_i.sum())
    E0 = float(E_inf + E_i.sum())
    g, tau = E_i[keep] / E0, tau[keep]
    o = np.argsort(tau)
    g, tau = tuple(float(x) for x in g[o]), tuple(float(x) for x in tau[o])
    # without nu the data says nothing about the shear/bulk split: constant Poisson ratio, the
    # bulk modulus relaxes like the shear modulus, so a 3-D FEM bar reproduces E(t) exactly
    prony = Prony(g=g, tau=tau) if nu is not None else Prony(g=g, tau=tau, k=g, k_tau=tau)
    pred = model_fn(E0, prony)
    rel = (pred - y) / (y if denom is None else denom)
    report = {
        "kind": kind,
        "n_terms_requested": int(n_terms),
        "n_terms": len(prony.g),
        "dropped_terms": int(np.count_nonzero(~keep)),
        "E0": E0,
        "E_inf": float(E_inf),
        "g_inf": prony.g_inf,
        "nu": nu,
        "rms_rel_error": float(np.sqrt(np.mean(rel ** 2))),
        "max_rel_error": float(np.max(np.abs(rel))),
        "n_points": int(len(t)),
        "success": bool(res.success),
        "message": str(res.message),
    }
    return E0, prony, report


def _fit(n: int, resid, init_amp, tau0: np.ndarray, lt_bounds: tuple[float, float], scale: float):
    """Least squares over ``[E_inf, E_1..n, log tau_1..n]`` (E_inf > 0, E_i >= 0, log tau within
    ``lt_bounds``) from three spreads of the initial time constants ``tau0``; ``resid(E_inf,
    E_i, tau)`` gives the residual vector, ``init_amp(tau) -> (E_inf, E_i)`` the start."""
    lt_lo, lt_hi = lt_bounds

    def unpack(p):
        return p[0] * scale, p[1:n + 1] * scale, np.exp(p[n + 1:])

    lb = np.concatenate([[1e-9], np.zeros(n), np.full(n, lt_lo)])
    ub = np.concatenate([[np.inf], np.full(n, np.inf), np.full(n, lt_hi)])
    best = None
    mid = np.exp(np.mean(np.log(tau0)))
    for shrink in (1.0, 0.6, 1.6):
        tau = mid * (tau0 / mid) ** shrink
        E_inf0, E_i0 = init_amp(tau)
        p0 = np.concatenate([[max(E_inf0 / scale, 1e-6)], np.maximum(E_i0 / scale, 1e-6),
                             np.clip(np.log(tau), lt_lo + 1e-9, lt_hi - 1e-9)])
        res = least_squares(lambda p: resid(*unpack(p)), p0, bounds=(lb, ub), x_scale="jac",
                            method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12,
                            max_nfev=400 * (2 * n + 1))
        if best is None or res.cost < best.cost:
            best = res
    E_inf, E_i, tau = unpack(best.x)
    return E_inf, E_i, tau, best


def _log_tau_bounds(t: np.ndarray) -> tuple[float, float]:
    tp = t[t > 0]
    return np.log(tp[0]) - np.log(10.0), np.log(t[-1]) + np.log(10.0)


def fit_prony_relaxation(t, modulus_or_stress, n_terms: int = 3, *, strain0: float | None = None,
                         nu: float | None = None):
    """Fit a generalized Maxwell material to a uniaxial relaxation test.

    ``t`` (s, strictly increasing, >= 0); ``modulus_or_stress``: relaxation modulus E(t) (MPa),
    or stress (MPa) under the step strain ``strain0``. With ``nu`` the shear modulus relaxes and
    the bulk modulus stays elastic (3-D bar in uniaxial stress); without, E relaxes (1-D rod) and
    the returned Prony carries the same terms on the bulk modulus (``k = g``, constant nu).
    Returns ``(E0, Prony, report)``: instantaneous modulus E0 (MPa), positive relative terms
    (sum < 1), report with the relative residuals. Terms that fit to zero are dropped.
    FEM material: ``dataclasses.replace(material, E=E0, prony=prony)``.
    """
    name = "modulus" if strain0 is None else "stress"
    if strain0 is not None and not (np.isfinite(strain0) and strain0 != 0):
        raise ParameterError("strain0", strain0, "a finite, non-zero step strain")
    t, y = _check_data(t, modulus_or_stress, name, n_terms)
    if strain0 is not None:
        y = y / strain0
        if np.any(y <= 0):
            raise DataError("stress/strain0 must be > 0 at every time")
    if nu is not None:
        _check_material(1.0, nu)

    def forward(E_inf, E_i, tau):
        if nu is None:
            return E_inf + np.exp(-np.outer(t, 1.0 / tau)) @ E_i
        E0 = E_inf + E_i.sum()
        return _model(E0, _raw_prony(E_i / E0, tau), nu, "strain").step(t)

    def init_amp(tau0):
        Phi = np.column_stack([np.ones_like(t), np.exp(-np.outer(t, 1.0 / tau0))])
        a, _ = nnls(Phi / y[:, None], np.ones_like(y))
        return a[0], a[1:]

    E_inf, E_i, tau, res = _fit(n_terms, lambda *p: forward(*p) / y - 1.0, init_amp,
                                _tau_grid(t, n_terms), _log_tau_bounds(t), float(np.max(y)))
    return _finish(E_inf, E_i, tau, t, y, lambda E0, p: relaxation_modulus(E0, p, t, nu), res,
                   n_terms, "relaxation", nu)


def fit_prony_creep(t, compliance_or_strain, n_terms: int = 3, *, stress0: float | None = None,
                    nu: float | None = None):
    """Fit a generalized Maxwell material to a uniaxial creep test.

    ``compliance_or_strain``: creep compliance J(t) (1/MPa), or strain under the step stress
    ``stress0`` (MPa). The relaxation Prony terms are fitted directly through the exact creep
    compliance of the model, so the result plugs into the FEM material unchanged.
    Returns ``(E0, Prony, report)`` as :func:`fit_prony_relaxation`.
    """
    name = "compliance" if stress0 is None else "strain"
    if stress0 is not None and not (np.isfinite(stress0) and stress0 != 0):
        raise ParameterError("stress0", stress0, "a finite, non-zero step stress (MPa)")
    t, y = _check_data(t, compliance_or_strain, name, n_terms)
    if stress0 is not None:
        y = y / stress0
        if np.any(y <= 0):
            raise DataError("strain/stress0 must be > 0 at every time")
    if nu is not None:
        _check_material(1.0, nu)

    def forward(E_inf, E_i, tau):
        E0 = E_inf + E_i.sum()
        return _model(E0, _raw_prony(E_i / E0, tau), nu, "stress").step(t)

    def init_amp(tau0):
        # relaxation guess from the reciprocal compliance (exact at both ends of the test)
        Phi = np.column_stack([np.ones_like(t), np.exp(-np.outer(t, 0.5 / tau0))])
        a, _ = nnls(Phi * y[:, None], np.ones_like(y))
        E0 = 1.0 / y[0] if t[0] == 0 else a.sum()
        E_inf = min(a[0], 0.9 * E0)
        w = a[1:] if a[1:].sum() > 0 else np.ones(len(tau0))
        return E_inf, (E0 - E_inf) * w / w.sum()

    E_inf, E_i, tau, res = _fit(n_terms, lambda *p: forward(*p) / y - 1.0, init_amp,
                                _tau_grid(t, n_terms), _log_tau_bounds(t), float(1.0 / np.min(y)))
    return _finish(E_inf, E_i, tau, t, y, lambda E0, p: creep_compliance(E0, p, t, nu), res,
                   n_terms, "creep", nu)


def _uniform_response(model: _LinearModel, u: np.ndarray, dt: float, relaxed: bool) -> np.ndarray:
    """Output for input samples ``u`` on a uniform grid of step ``dt`` (input linear between
    samples: exact), starting from rest with a jump to ``u[0]`` or relaxed (equilibrium) at
    ``u[0]``. Modal decomposition, one IIR filter (scipy.signal.lfilter) per mode."""
    y = model.D * u
    if len(model.B) == 0:
        return y
    x0 = -np.linalg.solve(model.A, model.B) * u[0] if relaxed else np.zeros(len(model.B))
    lam, V = eig(model.A)
    if np.linalg.cond(V) > 1e8 or np.any(np.abs(lam.imag) > 1e-9 * np.abs(lam.real)):
        # (nearly) defective: exact first-order-hold recursion on the state; a relaxed start
        # is rest plus the equilibrium response to u[0] (linearity)
        t = dt * np.arange(len(u))
        if relaxed:
            y_inf = model.C @ (-np.linalg.solve(model.A, model.B)) + model.D
            return model.response(t, u - u[0]) + y_inf * u[0]
        return model.response(t, u)
    lam, V = lam.real, V.real
    b = np.linalg.solve(V, model.B)
    z0 = np.linalg.solve(V, x0)
    c = model.C @ V
    x = lam * dt
    a = np.exp(x)
    phi0 = np.expm1(x) / lam
    phi1 = (np.expm1(x) - x) / (lam * x)
    for k in range(len(lam)):
        bb = np.array([b[k] * phi1[k], b[k] * (phi0[k] - phi1[k])])
        aa = np.array([1.0, -a[k]])
        zi = lfiltic(bb, aa, y=[z0[k]], x=[u[0]])
        z = np.empty(len(u))
        z[0] = z0[k]
        z[1:] = lfilter(bb, aa, u[1:], zi=zi)[0]
        y = y + c[k] * z
    return y


def fit_prony_history(t, strain, stress, n_terms: int = 3, *, nu: float | None = None,
                      start: str = "rest", dt: float | None = None):
    """Fit a generalized Maxwell material to any uniaxial strain history and its stress
    (ramps, holds, cycles: e.g. a real relaxation test with a finite loading rate).

    ``t`` (s, strictly increasing), ``strain`` (-), ``stress`` (MPa), resampled linearly to a
    uniform step ``dt`` (default: the median step) when the samples are not uniform.
    ``start``: "rest" (undeformed before t[0]; strain[0] is applied as a jump) or "relaxed"
    (held at strain[0] long enough to be in equilibrium). ``nu`` as in
    :func:`fit_prony_relaxation`. Returns ``(E0, Prony, report)``; the report's errors are
    relative to max |stress|.
    """
    if start not in ("rest", "relaxed"):
        raise ParameterError("start", start, "rest or relaxed")
    if isinstance(n_terms, bool) or not isinstance(n_terms, (int, np.integer)) or not 1 <= n_terms <= 12:
        raise ParameterError("n_terms", n_terms, "an integer 1..12")
    t, eps, sig = (np.asarray(x, float).ravel() for x in (t, strain, stress))
    if not len(t) == len(eps) == len(sig):
        raise DataError(f"t, strain and stress have different lengths ({len(t)}, {len(eps)}, {len(sig)})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(eps)) and np.all(np.isfinite(sig))):
        raise DataError("t, strain and stress must be finite (NaN or inf found)")
    if len(t) < 4 * n_terms + 4:
        raise DataError(f"{len(t)} points are too few for {n_terms} Prony terms (need >= {4 * n_terms + 4})")
    if np.any(np.diff(t) <= 0):
        raise DataError("t must be strictly increasing (s)")
    if not np.any(sig != 0) or not np.any(eps != eps[0]):
        raise DataError("strain must vary and stress must not be all zero")
    if nu is not None:
        _check_material(1.0, nu)
    steps = np.diff(t)
    if dt is None:
        dt = float(np.median(steps))
    if not (np.isfinite(dt) and dt > 0):
        raise ParameterError("dt", dt, "a time step > 0 s")
    if not np.allclose(steps, dt, rtol=1e-6, atol=0):
        grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
        eps, sig = np.interp(grid, t, eps), np.interp(grid, t, sig)
        t = grid
    relaxed = start == "relaxed"
    span = t[-1] - t[0]
    denom = float(np.max(np.abs(sig)))

    def forward(E_inf, E_i, tau):
        E0 = E_inf + E_i.sum()
        return _uniform_response(_model(E0, _raw_prony(E_i / E0, tau), nu, "strain"), eps, dt, relaxed)

    def init_amp(tau0):
        cols = [eps]
        for tt in tau0:   # unit Maxwell branch: h = eps - a, a' = (eps - a) / tau
            unit = _LinearModel(np.array([[-1.0 / tt]]), np.array([1.0 / tt]), np.array([-1.0]), 1.0)
            cols.append(_uniform_response(unit, eps, dt, relaxed))
        a, _ = nnls(np.column_stack(cols), sig)
        return a[0], a[1:]

    tau0 = 10 ** np.linspace(np.log10(2 * dt), np.log10(span), n_terms + 2)[1:-1]
    bounds = (np.log(dt / 10.0), np.log(10.0 * span))
    E_inf, E_i, tau, res = _fit(n_terms, lambda *p: (forward(*p) - sig) / denom, init_amp, tau0,
                                bounds, denom / max(float(np.max(np.abs(eps))), 1e-300))
    out = _finish(E_inf, E_i, tau, t, sig,
                  lambda E0, p: _uniform_response(_model(E0, p, nu, "strain"), eps, dt, relaxed),
                  res, n_terms, "history", nu, denom=denom)
    out[2]["dt"] = dt
    return out


class _RawProny:
    """Prony-like terms without the strict positivity check (zero terms allowed while fitting)."""

    def __init__(self, g, tau):
        self.g, self.tau, self.k, self.k_tau = tuple(g), tuple(tau), (), ()


def _raw_prony(g, tau):
    return _RawProny(g, tau)
