"""Point contacts between a linear structure's master points: Hertz, Mindlin, Coulomb (mm N MPa).

Sensor-free building blocks of a small nonlinear contact problem on a linear structure
condensed to a few master points (:func:`condense`): the law of one contact
(:class:`HertzContact`, :class:`ContactLaw`: Hertz normal force, Mindlin stiffness, Coulomb or
partial slip) and :class:`ContactProblem`, which follows load paths with hysteresis. The
formulas and their sources: docs/reference/fem.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from designlab.errors import ModelError, ParameterError
from designlab.fem.model import Model, RefPoint, skew

#: Upper bound of a friction coefficient accepted as an input (dry clean metals reach ~1.2,
#: e.g. aluminium on aluminium 1.05-1.35; above 2 is not a Coulomb coefficient any more).
MU_MAX = 2.0


@dataclass(frozen=True)
class HertzContact:
    """Two elastic spheres of radii ``R1``, ``R2`` (mm; ``inf`` = a plane) and moduli E (MPa),
    Poisson ratios nu."""

    R1: float
    R2: float
    E1: float
    nu1: float
    E2: float
    nu2: float

    def __post_init__(self):
        for n in ("R1", "R2", "E1", "E2"):
            if not getattr(self, n) > 0:
                raise ParameterError(n, getattr(self, n), "> 0")
        for n in ("nu1", "nu2"):
            if not -1 < getattr(self, n) < 0.5:
                raise ParameterError(n, getattr(self, n), "-1 < value < 0.5")

    @property
    def R_star(self) -> float:
        """Effective radius 1/R* = 1/R1 + 1/R2, mm."""
        return 1.0 / (1.0 / self.R1 + 1.0 / self.R2)

    @property
    def E_star(self) -> float:
        """Contact modulus 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2, MPa."""
        return 1.0 / ((1 - self.nu1 ** 2) / self.E1 + (1 - self.nu2 ** 2) / self.E2)

    @property
    def G_star(self) -> float:
        """Tangential contact modulus 1/G* = (2-nu1)/G1 + (2-nu2)/G2, MPa (G = E/(2(1+nu)))."""
        G1, G2 = self.E1 / (2 * (1 + self.nu1)), self.E2 / (2 * (1 + self.nu2))
        return 1.0 / ((2 - self.nu1) / G1 + (2 - self.nu2) / G2)

    @property
    def c_approach(self) -> float:
        """delta = c N^(2/3): c = (9 / (16 R* E*^2))^(1/3), mm N^(-2/3)."""
        return (9.0 / (16.0 * self.R_star * self.E_star ** 2)) ** (1.0 / 3.0)

    def force(self, delta):
        """Normal force N = 4/3 E* sqrt(R*) delta^(3/2) (0 for delta <= 0), N."""
        d = np.maximum(np.asarray(delta, float), 0.0)
        return 4.0 / 3.0 * self.E_star * np.sqrt(self.R_star) * d ** 1.5

    def approach(self, N):
        """Approach of distant points delta(N) = (9 N^2 / (16 R* E*^2))^(1/3), mm."""
        return self.c_approach * np.maximum(np.asarray(N, float), 0.0) ** (2.0 / 3.0)

    def radius(self, N):
        """Contact radius a = (3 N R* / (4 E*))^(1/3), mm."""
        return (3.0 * np.maximum(np.asarray(N, float), 0.0) * self.R_star
                / (4.0 * self.E_star)) ** (1.0 / 3.0)

    def normal_stiffness(self, N):
        """dN/d(delta) = 2 E* a, N/mm."""
        return 2.0 * self.E_star * self.radius(N)

    def tangential_stiffness(self, N):
        """Mindlin's tangential stiffness of the stuck contact, k_t = 8 G* a, N/mm."""
        return 8.0 * self.G_star * self.radius(N)


@dataclass(frozen=True)
class ContactLaw:
    """One contact point. Normal: approach ``delta`` shared by the Hertz contact (``hertz``,
    None = rigid) and a linear spring in series (``k_series`` N/mm, None = rigid; at least one
    of the two). Tangential: ``k_t(N)`` = Mindlin's stiffness of ``hertz`` in series with
    ``kt_series`` (N/mm, None = rigid); with no Hertz contact, ``kt_series`` alone. Coulomb
    friction coefficient ``mu``. ``microslip``: 0 = the contact sticks whole until it slides
    (elastic-perfectly-plastic); n > 0 = Mindlin's partial slip as n Iwan elements
    (:func:`iwan_elements`; n = 1 is the elastic-perfectly-plastic law again)."""

    mu: float
    hertz: HertzContact | None = None
    k_series: float | None = None
    kt_series: float | None = None
    microslip: int = 0

    def __post_init__(self):
        if not (0.0 <= self.mu <= MU_MAX):
            raise ParameterError("friction_coefficient", self.mu, f"0 <= value <= {MU_MAX:g}")
        if not (isinstance(self.microslip, (int, np.integer)) and 0 <= self.microslip <= 1000):
            raise ParameterError("microslip_elements", self.microslip,
                                 "a whole number 0 <= n <= 1000 (0: no partial slip)")
        if self.hertz is None and self.k_series is None:
            raise ParameterError("contact law", None, "a Hertz contact, a series spring or both")
        if self.hertz is None and self.mu > 0 and self.kt_series is None:
            raise ParameterError("kt_series", None, "a tangential stiffness when mu > 0 and "
                                 "there is no Hertz contact")

    # ------------------------------------------------------------------ normal
    def normal(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, dN/d delta) for approaches ``delta`` (any shape): the series of a Hertz contact
        and a linear spring, solved for N (Newton on s = N^(1/3): delta = s^3/k + c s^2 is
        convex in s, so Newton from an upper bound converges monotonically)."""
        d = np.asarray(delta, float)
        pos = d > 0
        dp = np.where(pos, d, 0.0)
        if self.hertz is None:
            return self.k_series * dp, np.where(pos, self.k_series, 0.0)
        c = self.hertz.c_approach
        if self.k_series is None:
            N = (dp / c) ** 1.5
            return N, np.where(pos, 1.5 * np.sqrt(dp / c) / c, 0.0)
        k = self.k_series
        s = np.minimum(np.cbrt(k * dp), np.sqrt(dp / c))
        for _ in range(60):
            f = s ** 3 / k + c * s ** 2 - dp
            fp = 3 * s ** 2 / k + 2 * c * s
            step = np.where(fp > 0, f / np.where(fp > 0, fp, 1.0), 0.0)
            s = s - step
            if np.all(np.abs(step) <= 1e-15 * np.maximum(s, 1e-300)):
                break
        N = s ** 3
        # dN/d delta = 1 / (1/k + (2/3) c N^(-1/3))
        with np.errstate(divide="ignore"):
            dN = np.where(s > 0, 1.0 / (1.0 / k + (2.0 / 3.0) * c / np.where(s > 0, s, 1.0)),
                          0.0)
        return N, np.where(pos, dN, 0.0)

    def approach(self, N) -> np.ndarray:
        """Total approach at normal force N (inverse of :meth:`normal`), mm."""
        N = np.maximum(np.asarray(N, float), 0.0)
        out = np.zeros_like(N)
        if self.hertz is not None:
            out = out + self.hertz.approach(N)
        if self.k_series is not None:
            out = out + N / self.k_series
        return out

    # ------------------------------------------------------------------ tangential
    def kt(self, N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k_t, dk_t/dN): Mindlin 8 G* a(N) in series with ``kt_series``."""
        N = np.maximum(np.asarray(N, float), 0.0)
        if self.hertz is None:
            k = np.full_like(N, self.kt_series if self.kt_series is not None else 0.0)
            return k, np.zeros_like(N)
        km = self.hertz.tangential_stiffness(N)
        with np.errstate(divide="ignore", invalid="ignore"):
            dkm = np.where(N > 0, km / (3.0 * np.where(N > 0, N, 1.0)), 0.0)
        if self.kt_series is None:
            return km, dkm
        ks = self.kt_series
        k = km * ks / (km + ks)
        return k, dkm * (ks / (km + ks)) ** 2


def iwan_elements(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Mindlin's partial slip as ``n`` parallel Jenkins elements (Iwan 1966): (w, c), element
    e's stiffness ``w_e k_t`` and slip force ``c_e mu N`` (sum w = sum c = 1). Under a growing
    tangential displacement d, Cattaneo-Mindlin's stiffness falls as ``k_t sqrt(1 - d/d_s)``
    (d_s = 3 mu N / (2 k_t): the contact slides); element e, of equal stiffness 1/n, slips at
    ``x_e d_s`` where that remaining stiffness passes the middle of its share:
    ``x_e = 1 - (1 - (e - 1/2)/n)^2``; its slip force ``w_e k_t x_e d_s``, scaled so the whole
    contact slides at exactly mu N. n = 1 gives the elastic-perfectly-plastic law."""
    n = int(n)
    if n < 1:
        raise ParameterError("microslip_elements", n, ">= 1")
    w = np.full(n, 1.0 / n)
    x = 1.0 - (1.0 - (np.arange(1, n + 1) - 0.5) / n) ** 2
    c = w * x
    return w, c / c.sum()


def mindlin_tangential_force(d, mu_N: float, k_t: float):
    """Cattaneo-Mindlin's monotonic tangential force at displacement ``d`` (mm) under a
    constant normal force: ``T = mu N (1 - (1 - d/d_s)^(3/2))`` for d < d_s = 3 mu N / (2 k_t),
    mu N beyond (Johnson eq. 7.39 inverted), N."""
    d_s = 1.5 * mu_N / k_t
    u = np.clip(np.asarray(d, float) / d_s, 0.0, 1.0)
    return mu_N * (1.0 - (1.0 - u) ** 1.5)


def mindlin_loop_energy(T_amp: float, mu_N: float, k_t: float) -> float:
    """Energy dissipated per full cycle +-T_amp of Mindlin and Deresiewicz's loop at a constant
    normal force (Johnson eq. 7.53 with d_s = 3 mu N / (2 k_t)):
    ``4.8 mu N d_s [1 - (1-q)^(5/3) - (5q/6)(1 + (1-q)^(2/3))]``, q = T_amp / (mu N), N mm."""
    q = T_amp / mu_N
    if not 0.0 <= q <= 1.0:
        raise ParameterError("T_amp", T_amp, f"0 <= value <= mu N = {mu_N:g}")
    d_s = 1.5 * mu_N / k_t
    return 4.8 * mu_N * d_s * (1.0 - (1.0 - q) ** (5.0 / 3.0)
                               - (5.0 * q / 6.0) * (1.0 + (1.0 - q) ** (2.0 / 3.0)))


@dataclass
class ContactState:
    """History variables of ``(batch, m)`` contacts: tangential force ``T`` (.., 2) and the
    tangential relative displacement ``gt`` (.., 2) at the last converged increment; ``N``;
    with partial slip, the Iwan elements' forces ``Te`` (.., 2, n) (None: all unloaded); ``D``
    (.., 3, 3) the contact tangent at that increment's solution (None: not known), the first
    Newton step's tangent of the next increment."""

    T: np.ndarray
    gt: np.ndarray
    N: np.ndarray
    g: np.ndarray            # (.., 3) relative displacement (normal, t1, t2), mm
    Te: np.ndarray | None = None
    D: np.ndarray | None = None

    @classmethod
    def zero(cls, batch: int, m: int) -> "ContactState":
        z = np.zeros((batch, m))
        return cls(np.zeros((batch, m, 2)), np.zeros((batch, m, 2)), z.copy(),
                   np.zeros((batch, m, 3)))

    def copy(self) -> "ContactState":
        return ContactState(self.T.copy(), self.gt.copy(), self.N.copy(), self.g.copy(),
                            None if self.Te is None else self.Te.copy(),
                            None if self.D is None else self.D.copy())

    def take(self, idx) -> "ContactState":
        return ContactState(self.T[idx].copy(), self.gt[idx].copy(), self.N[idx].copy(),
                            self.g[idx].copy(), None if self.Te is None else self.Te[idx].copy(),
                            None if self.D is None else self.D[idx].copy())


class LawArrays:
    """The parameters of ``m`` contact laws as (m,) arrays, for evaluating all contacts of a
    batch at once (inverse stiffnesses 0 = rigid): what :func:`contact_forces` and
    :func:`partial_slip` take, and a :class:`ContactProblem` builds from its laws."""

    def __init__(self, laws: list[ContactLaw]):
        self.mu = np.array([lw.mu for lw in laws])
        self.ks_inv = np.array([0.0 if lw.k_series is None else 1.0 / lw.k_series
                                for lw in laws])
        self.c = np.array([0.0 if lw.hertz is None else lw.hertz.c_approach for lw in laws])
        # Mindlin k_m = 8 G* a = A N^(1/3), A = 8 G* (3 R* / (4 E*))^(1/3)
        self.A = np.array([0.0 if lw.hertz is None else 8.0 * lw.hertz.G_star * (
            3.0 * lw.hertz.R_star / (4.0 * lw.hertz.E_star)) ** (1.0 / 3.0) for lw in laws])
        self.kts = np.array([np.inf if lw.kt_series is None else lw.kt_series for lw in laws])
        self.hertz = self.c > 0
        n = {lw.microslip for lw in laws}
        if len(n) > 1:
            raise ModelError(f"contact laws with different microslip element counts {sorted(n)}")
        self.n_el = n.pop() if n else 0
        self.w_el, self.c_el = iwan_elements(self.n_el) if self.n_el else (None, None)

    def normal(self, delta: np.ndarray, N_guess: np.ndarray | None = None):
        """(N, dN/d delta) for approaches (B, m): delta = N/k + c N^(2/3), Newton on
        s = N^(1/3) (f(s) = s^3/k + c s^2 - delta is convex increasing for s > 0: from above it
        converges monotonically, from below the first step lands above)."""
        d = np.maximum(delta, 0.0)
        ki, c = self.ks_inv, self.c
        with np.errstate(divide="ignore", invalid="ignore"):
            up = np.minimum(np.where(ki > 0, np.cbrt(d / np.where(ki > 0, ki, 1.0)), np.inf),
                            np.where(c > 0, np.sqrt(d / np.where(c > 0, c, 1.0)), np.inf))
        s = up
        if N_guess is not None:
            sg = np.cbrt(np.maximum(N_guess, 0.0))
            s = np.where((sg > 0) & (sg < up), sg, up)
        for _ in range(80):
            f = s ** 3 * ki + c * s ** 2 - d
            fp = 3.0 * s ** 2 * ki + 2.0 * c * s
            step = np.divide(f, fp, out=np.zeros_like(f), where=fp > 0)
            s = np.maximum(s - step, 0.0)
            if not (np.abs(step) > 1e-14 * s).any():
                break
        N = s ** 3
        denom = ki + (2.0 / 3.0) * c * np.divide(1.0, s, out=np.zeros_like(s), where=s > 0)
        dN = np.divide(1.0, denom, out=np.zeros_like(s), where=(denom > 0) & (d > 0))
        # a rigid series and Hertz at s = 0: the stiffness is 0 there, the limit of 2 E* a
        return N, dN

    def kt(self, N: np.ndarray):
        """(k_t, dk_t/dN) (B, m): Mindlin A N^(1/3) in series with k_t,series."""
        N = np.maximum(N, 0.0)
        s = np.cbrt(N)
        km = self.A * s
        dkm = np.divide(km, 3.0 * N, out=np.zeros_like(N), where=N > 0)
        kts = self.kts
        fin = np.isfinite(kts)
        if not fin.any():
            return np.where(self.hertz, km, 0.0), dkm
        ks = np.where(fin, kts, 1.0)
        r = np.where(fin, ks / (km + ks), 1.0)
        k = np.where(self.hertz, km * r, np.where(fin, kts, 0.0))
        dk = np.where(self.hertz, dkm * r ** 2, 0.0)
        return k, dk


def contact_forces(laws, g: np.ndarray, state: ContactState, gap0: np.ndarray | None = None,
                   elements: bool = False):
    """Forces ``p`` (B, m, 3) = (N, T1, T2) that B exerts on A for relative displacements
    ``g`` (B, m, 3), starting the increment from ``state``, and their tangent dp/dg
    (B, m, 3, 3); ``elements``: also the Iwan elements' forces (B, m, 2, n) of a partial-slip
    law (None for the others), which the committed state keeps. ``laws``: the contact laws
    (list, or their :class:`LawArrays`). Approach ``delta = gap0 - g_n`` (``gap0``: initial
    interference, mm). Tangential: trial T = T_old - k_t(N) (g_t - g_t,old); slip when
    |T| > mu N (return to the cone). Open contacts (N = 0) carry nothing."""
    la = laws if isinstance(laws, LawArrays) else LawArrays(laws)
    p = np.zeros_like(g)
    D = np.zeros(g.shape + (3,))
    delta = (0.0 if gap0 is None else np.asarray(gap0, float)) - g[..., 0]
    N, dN = la.normal(delta, state.N)
    p[..., 0] = N
    D[..., 0, 0] = -dN
    if not (la.mu > 0).any():
        return (p, D, None) if elements else (p, D)
    kt, dkt = la.kt(N)
    dg = g[..., 1:] - state.gt
    if la.n_el:
        T, Dtt, DtN, Te = partial_slip(la, N, dN, kt, dkt, dg, state)
        p[..., 1:] = T
        D[..., 1:, 1:] = Dtt
        D[..., 1:, 0] = DtN
        return (p, D, Te) if elements else (p, D)
    Ttr = state.T - kt[..., None] * dg
    nT = np.linalg.norm(Ttr, axis=-1)
    lim = la.mu * N
    closed = N > 0
    slip = (nT > lim) & closed
    th = np.divide(Ttr, nT[..., None], out=np.zeros_like(Ttr), where=nT[..., None] > 0)
    r = np.where(slip, np.divide(lim, nT, out=np.zeros_like(nT), where=nT > 0), 1.0)
    T = np.where(closed[..., None], r[..., None] * Ttr, 0.0)
    P = np.eye(2) - np.where(slip[..., None, None], th[..., :, None] * th[..., None, :], 0.0)
    Dtt = (r * -kt)[..., None, None] * P
    dTtr_dgn = (-dkt)[..., None] * dg * (-dN)[..., None]          # through k_t(N(g_n))
    DtN = r[..., None] * (P @ dTtr_dgn[..., None])[..., 0] \
        + np.where(slip[..., None], la.mu[:, None] * th * (-dN)[..., None], 0.0)
    p[..., 1:] = T
    D[..., 1:, 1:] = np.where(closed[..., None, None], Dtt, 0.0)
    D[..., 1:, 0] = np.where(closed[..., None], DtN, 0.0)
    return (p, D, None) if elements else (p, D)


def partial_slip(la: LawArrays, N, dN, kt, dkt, dg, state: ContactState):
    """Tangential force, its tangent (d/dg_t, d/dg_n) and the elements' forces (B, m, 2, n) of
    the Iwan model of :func:`iwan_elements` (B, m contacts, n elements): element e's trial
    ``t_e = Te - w_e k_t(N) dg``, returned to its circle ``c_e mu N`` when outside (the Coulomb
    return map of :func:`contact_forces` per element); an open contact carries nothing.
    Written component by component (the tangent plane is 2-D): the projector form
    ``sum_e -w_e k_t r_e (I - s_e th_e th_e^T)``, with ``r_e th_e th_e^T = lim_e t_e t_e^T /
    |t_e|^3`` for a slipping element, without (.., n, 2, 2) arrays."""
    w, c = la.w_el, la.c_el                                   # (n,)
    Te_old = state.Te if state.Te is not None else np.zeros(N.shape + (2, la.n_el))
    kte = kt[..., None] * w                                   # (B, m, n)
    dgx, dgy = dg[..., 0, None], dg[..., 1, None]
    tx = Te_old[..., 0, :] - kte * dgx
    ty = Te_old[..., 1, :] - kte * dgy
    nT = np.sqrt(tx * tx + ty * ty)
    lim = (la.mu[:, None] * N[..., None]) * c                 # (B, m, n)
    cl = (N > 0)[..., None]
    slip = (nT > lim) & cl                                    # then nT > lim >= 0
    inv = 1.0 / np.where(slip, nT, 1.0)
    r = np.where(slip, lim * inv, cl.astype(float))           # 0 on an open contact
    rx, ry = r * tx, r * ty
    Te = np.stack([rx, ry], axis=-2)
    q = np.where(slip, lim * inv * inv * inv, 0.0)            # lim / |t|^3 where slipping
    qk = q * kte
    kr = (kte * r).sum(-1)
    Dtt = np.empty(N.shape + (2, 2))
    qx = qk * tx
    Dtt[..., 0, 0] = (qx * tx).sum(-1) - kr
    Dtt[..., 0, 1] = Dtt[..., 1, 0] = (qx * ty).sum(-1)
    Dtt[..., 1, 1] = (qk * ty * ty).sum(-1) - kr
    # d/dg_n through N(g_n) (dN/dg_n = -dN): every trial moves by (dk_t w_e dN) dg, then the
    # return (r_e, minus the th_e component when slipping); each slipping element's circle grows
    # by mu c_e (-dN) along th_e
    a = dkt * dN
    qw = q * w
    proj = tx * dgx + ty * dgy
    wr = (w * r).sum(-1)
    sc = np.where(slip, c * inv, 0.0)
    mu_dN = la.mu * dN
    DtN = np.empty(N.shape + (2,))
    DtN[..., 0] = a * (wr * dg[..., 0] - (qw * tx * proj).sum(-1)) - mu_dN * (sc * tx).sum(-1)
    DtN[..., 1] = a * (wr * dg[..., 1] - (qw * ty * proj).sum(-1)) - mu_dN * (sc * ty).sum(-1)
    T = np.stack([rx.sum(-1), ry.sum(-1)], axis=-1)
    return T, Dtt, DtN, Te


def commit(g: np.ndarray, p: np.ndarray, Te: np.ndarray | None = None,
           D: np.ndarray | None = None) -> ContactState:
    """State after a converged increment: an open contact forgets its tangential history (its
    reference moves with it, so it re-closes stuck). ``Te``: the Iwan elements' forces; ``D``:
    the contact tangent at the solution."""
    return ContactState(p[:, :, 1:].copy(), g[:, :, 1:].copy(), p[:, :, 0].copy(), g.copy(),
                        None if Te is None else Te.copy(), None if D is None else D.copy())


@dataclass
class PathResult:
    """Forces (B, n_points, m, 3) and relative displacements at every load point of a path,
    the final state, the number of Newton iterations, and lift-off events ``(batch, point,
    contact)`` where a contact that was closed opened."""

    p: np.ndarray
    g: np.ndarray
    state: ContactState
    iterations: int
    lift_off: list[tuple[int, int, int]] = field(default_factory=list)


@dataclass
class ContactProblem:
    """``m`` contacts with laws ``laws`` on a linear structure of flexibility ``C`` (n x n) at
    its master dofs, contact maps ``L`` (m, 3, n) (rows: normal, t1, t2 of A relative to B)
    and initial interferences ``gap0`` (m,) (0: touching without force)."""

    C: np.ndarray
    L: np.ndarray
    laws: list[ContactLaw]
    gap0: np.ndarray | None = None
    tol: float = 1e-12            # relative, on the relative displacements
    max_iter: int = 60

    def __post_init__(self):
        self.C = np.asarray(self.C, float)
        self.L = np.asarray(self.L, float)
        m, three, n = self.L.shape
        if three != 3 or self.C.shape != (n, n) or len(self.laws) != m:
            raise ModelError(f"contact problem: C {self.C.shape}, L {self.L.shape}, "
                             f"{len(self.laws)} laws do not match")
        self.Lf = self.L.reshape(3 * m, n)
        self.F = self.Lf @ self.C @ self.Lf.T          # contact flexibility (3m x 3m)
        self._gap_scale = 0.0 if self.gap0 is None else float(np.abs(self.gap0).max())
        self._la = LawArrays(self.laws)
        m = self.m
        self._eye = np.eye(3 * m)
        k, i, j = np.meshgrid(np.arange(m), np.arange(3), np.arange(3), indexing="ij")
        self._bd = ((3 * k + i).ravel(), (3 * k + j).ravel())     # D[:, k, i, j] -> Dbd

    @property
    def m(self) -> int:
        return self.L.shape[0]

    def free_motion(self, f: np.ndarray) -> np.ndarray:
        """(B, m, 3) relative displacements of the loads ``f`` (B, n) with no contact force."""
        return (np.atleast_2d(f) @ self.C.T @ self.Lf.T).reshape(-1, self.m, 3)

    def _forces(self, g: np.ndarray, state: ContactState):
        """Contact forces, their tangent and the Iwan elements' forces (None without partial
        slip) at the relative displacements ``g`` (the laws' :func:`contact_forces`; a subclass
        may evaluate its laws faster, with the same numbers)."""
        return contact_forces(self._la, g, state, self.gap0, elements=True)

    def solve_increment(self, g0: np.ndarray, state: ContactState, g_start: np.ndarray):
        """Equilibrium g = g0 + F p(g) for free motions ``g0`` (B, m, 3), from ``g_start``.
        Returns (g, p, iterations, the Iwan elements' forces or None, the tangent (B, m, 3,
        3)), all from the last residual evaluation at the converged g.

        Newton with backtracking, each load history (batch row) on its own: a row leaves once
        its residual is within the tolerance after at least one step (a converged row is not
        evaluated again while others converge); ``iterations`` is the most any row took. When
        the state carries the previous increment's tangent, a first step is tried with it and
        kept for the rows whose residual it reduces: as the motion goes on, elements slipping
        at their limit keep slipping, which the tangent at the start cannot tell from sticking
        (a hold on a creeping structure then takes 1-2 steps fewer); at a reversal it fails
        and the row starts from the tangent at g_start as without it."""
        Bn, m = g0.shape[:2]
        FT, Fb, eye = self.F.T, self.F[None], self._eye[None]
        rows, cols = self._bd
        forces = self._forces
        # the motions' scale: the free motion, the start, and an initial interference (a problem
        # loaded by its interference alone has zero free motion)
        scale = max(float(np.abs(g0).max()), float(np.abs(g_start).max()),
                    self._gap_scale, 1e-9)
        tol, floor = self.tol * scale, 1e-15 * scale
        out = {"g": g_start.copy(), "p": np.empty_like(g_start),
               "D": np.empty(g_start.shape + (3,)), "Te": None}

        def residual(g, g0a, st):
            p, D, Te = forces(g, st)
            n = len(g)
            return (g - g0a).reshape(n, -1) - p.reshape(n, -1) @ FT, D, p, Te

        def newton_step(D, R):
            n = len(R)
            Dbd = np.zeros((n, 3 * m, 3 * m))             # block-diagonal tangent
            Dbd[:, rows, cols] = D.reshape(n, -1)
            return np.linalg.solve(eye - Fb @ Dbd, -R[..., None])[..., 0].reshape(n, m, 3)

        act = np.arange(Bn)                                # rows still iterating
        g, g0a, st = out["g"].copy(), g0, state
        R, D, p, Te = residual(g, g0a, st)
        it0, conv = 0, np.zeros(Bn, bool)
        if state.D is not None and state.D.shape == D.shape:
            it0 = 1
            dx = newton_step(state.D, R)
            R1, D1, p1, Te1 = residual(g + dx, g0a, st)
            ok = np.linalg.norm(R1, axis=1) <= np.linalg.norm(R, axis=1) * (1 - 1e-4) + floor
            if ok.any():
                g, R, D, p = (np.where(ok[(...,) + (None,) * (a.ndim - 1)], a1, a)
                              for a, a1 in ((g, g + dx), (R, R1), (D, D1), (p, p1)))
                if Te is not None:
                    Te = np.where(ok[:, None, None, None], Te1, Te)
                conv = ok & (np.abs(R).max(axis=1) <= tol)
        it = it0
        while True:
            if conv.any():                                 # retire the converged rows
                done = act[conv]
                out["g"][done], out["p"][done], out["D"][done] = g[conv], p[conv], D[conv]
                if Te is not None:
                    if out["Te"] is None:
                        out["Te"] = np.empty((Bn,) + Te.shape[1:])
                    out["Te"][done] = Te[conv]
                if conv.all():
                    break
                keep = ~conv
                act = act[keep]
                g, R, D, p = g[keep], R[keep], D[keep], p[keep]
                Te = None if Te is None else Te[keep]
                g0a, st = g0[act], state.take(act)
            if it >= self.max_iter + it0:
                raise ModelError(f"contact increment did not converge in {self.max_iter} Newton "
                                 f"iterations (residual {np.abs(R).max():.3g} mm)")
            it += 1
            na = len(act)
            dx = newton_step(D, R)
            # backtracking on the residual norm, per load history (stick/slip and open/closed
            # switches make the residual only piecewise smooth); when no step length reduces
            # it, the full step is taken (the next tangent is the one of the new stick/slip set)
            r0 = np.linalg.norm(R, axis=1)
            lam = np.ones(na)
            for _ in range(8):
                g_try = g + lam[:, None, None] * dx
                R_try, D_try, p_try, Te_try = residual(g_try, g0a, st)
                worse = np.linalg.norm(R_try, axis=1) > r0 * (1 - 1e-4 * lam) + floor
                if not worse.any():
                    break
                lam = np.where(worse, 0.5 * lam, lam)
            else:
                lam = np.where(worse, 1.0, lam)
                g_try = g + lam[:, None, None] * dx
                R_try, D_try, p_try, Te_try = residual(g_try, g0a, st)
            g, R, D, p, Te = g_try, R_try, D_try, p_try, Te_try
            conv = np.abs(R).max(axis=1) <= tol
        return out["g"], out["p"], it, out["Te"], out["D"]

    def initial_state(self, state: ContactState) -> ContactState:
        """A copy of ``state`` to start a path from; a partial-slip problem refuses a state with
        tangential forces but no element forces (their split is not known)."""
        if self._la.n_el and state.Te is None and np.any(state.T != 0):
            raise ModelError("a partial-slip contact problem started from a state with "
                             "tangential forces but no Iwan element forces")
        return state.copy()

    def advance(self, g0: np.ndarray, state: ContactState, g_start: np.ndarray):
        """One increment to the free motions ``g0`` from ``state``: (g, p, new state, Newton
        iterations, the (batch, contact) pairs that opened)."""
        closed_before = state.N > 0
        g, p, it, Te, D = self.solve_increment(g0, state, g_start)
        st = commit(g, p, Te, D)
        opened = [(int(b), int(k)) for b, k in zip(*np.nonzero(closed_before & ~(st.N > 0)))]
        return g, p, st, it, opened

    def solve_path(self, f_points: np.ndarray, state: ContactState, n_sub: int = 1,
                   f_start: np.ndarray | None = None) -> PathResult:
        """Follow the master loads ``f_points`` (B, n_points, n) from ``f_start`` (B, n; default
        the loads of the state, zero for a fresh one) in straight segments of ``n_sub``
        increments each; the readings are the states at the points."""
        f_points = np.asarray(f_points, float)
        Bn, npt, n = f_points.shape
        f_prev = np.zeros((Bn, n)) if f_start is None else np.asarray(f_start, float)
        st = self.initial_state(state)
        g = st.g.copy()
        P = np.zeros((Bn, npt, self.m, 3))
        Gs = np.zeros_like(P)
        iters = 0
        lift = []
        for j in range(npt):
            for s in range(1, n_sub + 1):
                f = f_prev + (f_points[:, j] - f_prev) * (s / n_sub)
                g, _, st, it, opened = self.advance(self.free_motion(f), st, g)
                iters += it
                lift += [(b, j, k) for b, k in opened]
            f_prev = f_points[:, j]
            P[:, j] = np.concatenate([st.N[..., None], st.T], -1)
            Gs[:, j] = g
        return PathResult(P, Gs, st, iters, lift)


@dataclass
class RelaxingContactProblem:
    """``m`` contacts on a linear structure whose stiffness at its master dofs relaxes by one
    Prony term: ``K(t) = K_inf + dK exp(-t / tau)`` (a standard linear solid at the masters:
    ``K_inf`` long-time, ``K_inf + dK`` instantaneous). With ``h`` the relaxing branch's master
    forces, ``K_inf q + h = f + L^T p`` and ``dh/dt = -h / tau + dK dq/dt``; over a step of
    length dt with q linear in time the exponential rule gives ``h' = e h + gamma dK (q' - q)``,
    ``e = exp(-dt/tau)``, ``gamma = tau/dt (1 - e)`` (1 at dt = 0: the instantaneous stiffness).
    Each step is then one increment of a :class:`ContactProblem` of flexibility
    ``(K_inf + gamma dK)^-1`` under the load ``f - e h + gamma dK q``. Exact for a structure
    whose stiffness is ``K_inf + dK exp(-t/tau)`` at its masters; a static condensation of a
    body with one Prony term is that at t = 0 and t = inf and close between (the check against
    the full viscoelastic FEM is the caller's). ``problem_cls`` builds the per-step problems
    (a subclass with faster laws gives the same numbers)."""

    K_inf: np.ndarray
    dK: np.ndarray
    tau: float
    L: np.ndarray
    laws: list[ContactLaw]
    gap0: np.ndarray | None = None
    problem_cls: type = ContactProblem

    def __post_init__(self):
        self.K_inf = np.asarray(self.K_inf, float)
        self.dK = np.asarray(self.dK, float)
        if not self.tau > 0:
            raise ParameterError("tau", self.tau, "> 0 s")
        self._steps: dict[float, tuple] = {}
        self.Lf = np.asarray(self.L, float).reshape(-1, self.K_inf.shape[0])

    def step(self, dt: float):
        """(problem, gamma, e) of a step of length ``dt`` s (cached per dt)."""
        key = float(dt)
        if key not in self._steps:
            e = math.exp(-key / self.tau)
            gamma = 1.0 if key == 0 else self.tau / key * (1.0 - e)
            C = np.linalg.inv(self.K_inf + gamma * self.dK)
            C = 0.5 * (C + C.T)
            self._steps[key] = (self.problem_cls(C, self.L, self.laws, self.gap0), gamma, e)
        return self._steps[key]

    def master_motion(self, f: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Long-time master motions ``K_inf^-1 (f + L^T p)`` of loads f (B, n) and contact forces
        p (B, m, 3): the relaxed state (h = 0) an assembly step leaves."""
        return np.linalg.solve(self.K_inf, (f + p.reshape(len(f), -1) @ self.Lf).T).T

    def solve_history(self, f_points: np.ndarray, dt: np.ndarray, state: ContactState,
                      q: np.ndarray, h: np.ndarray, n_sub: int = 1,
                      f_start: np.ndarray | None = None):
        """Follow master loads ``f_points`` (B, npt, n) reached after ``dt`` (npt,) s each: a
        point with dt = 0 is a load change, ramped in ``n_sub`` instantaneous increments; a point
        with dt > 0 is one step of that length with the load applied over it (a hold when the
        load does not change). Starts from ``state`` and the master motions ``q``, relaxing
        forces ``h`` (B, n). Returns (PathResult, q, h)."""
        f_points = np.asarray(f_points, float)
        Bn, npt, n = f_points.shape
        f_prev = np.zeros((Bn, n)) if f_start is None else np.asarray(f_start, float)
        st = self.step(0.0)[0].initial_state(state)
        q, h = np.array(q, float), np.array(h, float)
        g = st.g.copy()
        m = self.L.shape[0]
        P = np.zeros((Bn, npt, m, 3))
        Gs = np.zeros_like(P)
        iters, lift = 0, []
        for j in range(npt):
            subs = [(s / n_sub, 0.0) for s in range(1, n_sub + 1)] if dt[j] == 0 else \
                [(1.0, float(dt[j]))]
            for frac, d in subs:
                f = f_prev + (f_points[:, j] - f_prev) * frac
                prob, gamma, e = self.step(d)
                f_eff = f - e * h + gamma * (q @ self.dK.T)
                g, p, st, it, opened = prob.advance(prob.free_motion(f_eff), st, g)
                iters += it
                lift += [(b, j, k) for b, k in opened]
                q_new = (f_eff + p.reshape(Bn, -1) @ self.Lf) @ prob.C.T
                h = e * h + gamma * ((q_new - q) @ self.dK.T)
                q = q_new
            f_prev = f_points[:, j]
            P[:, j] = np.concatenate([st.N[..., None], st.T], -1)
            Gs[:, j] = g
        return PathResult(P, Gs, st, iters, lift), q, h


# ---------------------------------------------------------------------- static condensation

def _master_map(model: Model, master) -> np.ndarray:
    """(k, n_dofs) dense map u -> master dofs: a RefPoint -> its 6 dofs (translation v, rotation
    w; distributing couplings: the weighted rigid fit), ``(RefPoint, xyz)`` -> the 3
    translations of a point moving with it."""
    if isinstance(master, tuple):
        ref, p = master
        M = np.hstack([np.eye(3), -skew(np.asarray(p, float) - ref.x)])
        return M @ model.twist_map(ref).toarray()
    if isinstance(master, RefPoint):
        return model.twist_map(master).toarray()
    raise ParameterError("master", master, "a RefPoint or (RefPoint, xyz)")


def condense(model: Model, masters: list, solver: str = "direct", check: bool = True,
             keep_cases: tuple[str, ...] = (), return_result: bool = False):
    """Flexibility of a linear FEM model at its master points by unit loads (exact static
    condensation; one factorisation, one back-substitution per master dof).

    ``masters``: RefPoints (6 dofs each: forces f_x, f_y, f_z then moments m_x, m_y, m_z, and
    the conjugate (v, w)) or ``(RefPoint, xyz)`` (3 dofs: a force at that point, carried by the
    reference point as force + moment, and its displacement). Returns ``(C, R)``: C (n, n)
    N -> mm flexibility (symmetric), R {case: (n,)} the master motions under the model's own
    load cases named in ``keep_cases`` (their equivalent master loads are ``inv(C) @ R``).
    The model gets the load cases ``_condense_i``; its other cases are solved alongside.
    ``return_result``: also return the static result (``(C, R, result)``), whose other cases
    (spring forces, displacement fields) then cost no second factorisation."""
    from designlab.fem.static import solve_static

    maps = [_master_map(model, m) for m in masters]
    Lm = np.vstack(maps)                                  # (n, n_dofs)
    names = []
    for mi, m in enumerate(masters):
        ref, p = (m if isinstance(m, tuple) else (m, None))
        for i in range(maps[mi].shape[0]):
            e = np.zeros(6)
            e[i] = 1.0
            force, moment = (e[:3], e[3:]) if p is None else (
                e[:3], np.cross(np.asarray(p, float) - ref.x, e[:3]))
            name = f"_condense_{len(names)}"
            model.force(ref, force=force, moment=moment, case=name)
            names.append(name)
    res = solve_static(model, solver=solver, check=check)
    idx = [res.system.case_index(c) for c in names]
    C = Lm @ res.U[:, idx]
    asym = np.abs(C - C.T).max() / np.abs(C).max()
    if asym > 1e-6:
        raise ModelError(f"condensed flexibility is not symmetric ({asym:.2g}): the masters' "
                         "loads and motions are not conjugate")
    C = 0.5 * (C + C.T)
    R = {c: Lm @ res.U[:, res.system.case_index(c)] for c in keep_cases}
    return (C, R, res) if return_result else (C, R)
