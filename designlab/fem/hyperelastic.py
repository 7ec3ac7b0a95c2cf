"""Geometrically nonlinear static analysis: compressible neo-Hookean solids, total Lagrangian.

:func:`solve_hyperelastic` finds the large-deformation equilibrium of a
:class:`~designlab.fem.model.Model` (its TET4/TET10 mesh, supports, dead loads, springs and
couplings), neo-Hookean where given, St-Venant-Kirchhoff elsewhere, by Newton's method over
load increments; :func:`solve_calculix_neo_hooke` is the CalculiX reference it is checked
against. The energy, stresses and solution method: docs/hyperelastic.md.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from designlab.errors import ModelError, ParameterError
from designlab.fem.assembly import _bsr_to_csr, block_pattern
from designlab.fem.model import Model, System
from designlab.fem.solvers import MANY_RHS, factorize

_CHUNK = 2048          # cells per batch of the tangent's element matrices
_I3 = np.eye(3)


@dataclass(frozen=True)
class NeoHooke:
    """Compressible neo-Hookean parameters: ``mu`` (shear, MPa) and ``kappa`` (bulk, MPa),
    W = mu/2 (I1bar - 3) + kappa/2 (J - 1)^2 (CalculiX: C10 = mu/2, D1 = 2/kappa)."""

    mu: float
    kappa: float

    def __post_init__(self):
        if not (self.mu > 0):
            raise ParameterError("mu", self.mu, "> 0 MPa (neo-Hookean shear modulus)")
        if not (self.kappa > 0):
            raise ParameterError("kappa", self.kappa, "> 0 MPa (neo-Hookean bulk modulus)")

    @classmethod
    def from_linear(cls, E: float, nu: float) -> "NeoHooke":
        """The neo-Hookean solid whose small-strain limit is (E, nu): mu = E / (2 (1 + nu)),
        kappa = E / (3 (1 - 2 nu))."""
        if not (E > 0):
            raise ParameterError("E", E, "> 0 MPa")
        if not (-1.0 < nu < 0.5):
            raise ParameterError("nu", nu, "in (-1, 0.5)")
        return cls(E / (2.0 * (1.0 + nu)), E / (3.0 * (1.0 - 2.0 * nu)))

    @property
    def C10(self) -> float:
        return 0.5 * self.mu

    @property
    def D1(self) -> float:
        return 2.0 / self.kappa


# ---------------------------------------------------------------- constitutive laws (vectorised)

def _cof(F: np.ndarray) -> np.ndarray:
    """Cofactor matrices of (..., 3, 3) arrays: cof(F) = det(F) F^-T."""
    a, b, c = F[..., 0, 0], F[..., 0, 1], F[..., 0, 2]
    d, e, f = F[..., 1, 0], F[..., 1, 1], F[..., 1, 2]
    g, h, i = F[..., 2, 0], F[..., 2, 1], F[..., 2, 2]
    cof = np.empty_like(F)
    cof[..., 0, 0] = e * i - f * h
    cof[..., 0, 1] = f * g - d * i
    cof[..., 0, 2] = d * h - e * g
    cof[..., 1, 0] = c * h - b * i
    cof[..., 1, 1] = a * i - c * g
    cof[..., 1, 2] = b * g - a * h
    cof[..., 2, 0] = b * f - c * e
    cof[..., 2, 1] = c * d - a * f
    cof[..., 2, 2] = a * e - b * d
    return cof


def _invariants(H: np.ndarray):
    """For F = I + H: j = J - 1, i1 = I1 - 3, c1 + c2 = cof F - I (c1 = tr H I - H^T,
    c2 = cof H), all without cancellation."""
    trH = np.einsum("...ii->...", H)
    c2 = _cof(H)
    detH = np.einsum("...j,...j->...", H[..., 0, :], c2[..., 0, :])
    HH = np.einsum("...ij,...ji->...", H, H)                  # tr(H^2)
    j = trH + 0.5 * (trH * trH - HH) + detH
    i1 = 2.0 * trH + np.einsum("...ij,...ij->...", H, H)
    c = trH[..., None, None] * _I3 - np.swapaxes(H, -1, -2) + c2
    return j, i1, c


def neo_hooke_energy(H: np.ndarray, mu, kappa) -> np.ndarray:
    """W (MPa) at displacement gradients H = F - I (..., 3, 3)."""
    j, i1, _ = _invariants(H)
    J = 1.0 + j
    return 0.5 * mu * (J ** (-2.0 / 3.0) * (3.0 + i1) - 3.0) + 0.5 * kappa * j ** 2


def uniaxial_closed_form(nh: "NeoHooke", stretch: float) -> tuple[float, float]:
    """(P11 [MPa], lateral stretch t) of :class:`NeoHooke` in uniaxial stress at ``stretch``:
    F = diag(stretch, t, t), P22 = 0 solved for t by Brent's method to 1e-15 (the reference
    of the homogeneous-block checks)."""
    from scipy.optimize import brentq

    lam = float(stretch)

    def P(t):
        J = lam * t * t
        I1 = lam * lam + 2 * t * t
        a = nh.mu * J ** (-2 / 3)
        p22 = a * (t - I1 / (3 * t)) + nh.kappa * J * (J - 1) / t
        p11 = a * (lam - I1 / (3 * lam)) + nh.kappa * J * (J - 1) / lam
        return p11, p22
    t = brentq(lambda t: P(t)[1], 0.2, 3.0, xtol=1e-15, rtol=1e-15)
    return P(t)[0], t


def neo_hooke_stress(H: np.ndarray, mu, kappa, tangent: bool = True):
    """First Piola-Kirchhoff stress P (..., 3, 3) and, with ``tangent``, A = dP/dF
    (..., 3, 3, 3, 3) indexed [i, J, k, L], at displacement gradients H = F - I. ``mu``,
    ``kappa``: scalars or arrays broadcasting against H[..., 0, 0].

    P = mu J^-2/3 (F - I1/3 F^-T) + kappa (J - 1) cof F, the bracket formed as
    (J F - I1/3 cof F) / J = (H + j F - c - i1/3 (I + c)) / J (the identities cancel
    exactly)."""
    j, i1, c = _invariants(H)
    J = 1.0 + j
    if np.any(~(J > 0)):
        raise ModelError("an element turned inside out (det F <= 0)")
    F = _I3 + H
    mu = np.asarray(mu, float)
    kappa = np.asarray(kappa, float)
    a = mu * J ** (-2.0 / 3.0)                             # mu J^-2/3
    dev = (H + j[..., None, None] * F - c - (i1 / 3.0)[..., None, None] * (_I3 + c)) \
        / J[..., None, None]
    cofF = _I3 + c
    P = a[..., None, None] * dev + (kappa * j)[..., None, None] * cofF
    if not tangent:
        return P, None
    Hi = cofF / J[..., None, None]                         # F^-T
    I1 = 3.0 + i1
    HH = np.einsum("...iJ,...kL->...iJkL", Hi, Hi)
    HHt = np.einsum("...iL,...kJ->...iJkL", Hi, Hi)
    FH = np.einsum("...iJ,...kL->...iJkL", F, Hi)
    FH = FH + np.einsum("...iJkL->...kLiJ", FH)
    delta = np.einsum("ik,JL->iJkL", _I3, _I3)
    ax = (..., None, None, None, None)
    A = a[ax] * (delta - (2.0 / 3.0) * FH + (2.0 / 9.0) * I1[ax] * HH
                 + (I1 / 3.0)[ax] * HHt) \
        + (kappa * (2.0 * J - 1.0) * J)[ax] * HH - (kappa * J * j)[ax] * HHt
    return P, A


def svk_stress(H: np.ndarray, lam, mu, tangent: bool = True):
    """St-Venant-Kirchhoff at H = F - I: P = F S, S = lam tr(E) I + 2 mu E,
    E = (H + H^T + H^T H) / 2; A = dP/dF [i, J, k, L]."""
    lam = np.asarray(lam, float)
    mu = np.asarray(mu, float)
    F = _I3 + H
    E = 0.5 * (H + np.swapaxes(H, -1, -2) + np.einsum("...kI,...kJ->...IJ", H, H))
    trE = np.einsum("...ii->...", E)
    S = (lam * trE)[..., None, None] * _I3 + 2.0 * mu[..., None, None] * E
    P = S + H @ S
    if not tangent:
        return P, None
    b = F @ np.swapaxes(F, -1, -2)
    ax = (..., None, None, None, None)
    A = (np.einsum("ik,...JL->...iJkL", _I3, S)
         + lam[ax] * np.einsum("...iJ,...kL->...iJkL", F, F)
         + mu[ax] * (np.einsum("...ik,JL->...iJkL", b, _I3)
                     + np.einsum("...iL,...kJ->...iJkL", F, F)))
    return P, A


# ---------------------------------------------------------------- the discrete problem

@dataclass(frozen=True, eq=False)
class Continuum:
    """The hyperelastic mesh part of a Model: per cell either neo-Hookean (mu, kappa) or
    St-Venant-Kirchhoff (lam, mu) parameters."""

    model: Model
    neo: np.ndarray              # (m,) bool
    p1: np.ndarray               # (m,) mu (neo) or lam (SVK)
    p2: np.ndarray               # (m,) kappa (neo) or mu (SVK)
    #: (m, nq, 3, 3) inverse of a stress-free reference stretch G per quadrature point, or
    #: None (the mesh is stress-free): the elastic part of F is F G^-1 (a prestrain, e.g. a
    #: band printed shorter than the path it is worn on; :meth:`with_pre`)
    pre: np.ndarray | None = None

    @classmethod
    def of(cls, model: Model, hyper: dict | None) -> "Continuum":
        hyper = dict(hyper or {})
        mesh = model.mesh
        names = {mesh.region_names.get(int(r), str(r)): int(r) for r in np.unique(mesh.region)}
        unknown = sorted(set(hyper) - set(names))
        if unknown:
            raise ParameterError("hyper", unknown[0], "a body of the mesh: "
                                 + ", ".join(sorted(names)))
        m = mesh.n_cells
        neo, p1, p2 = np.zeros(m, bool), np.zeros(m), np.zeros(m)
        for body, rid in names.items():
            sel = mesh.region == rid
            h = hyper.get(body)
            if h is not None:
                if not isinstance(h, NeoHooke):
                    raise ParameterError(f"hyper[{body!r}]", h, "a NeoHooke(mu, kappa)")
                neo[sel], p1[sel], p2[sel] = True, h.mu, h.kappa
            else:
                mat = model.region_materials[rid]
                p1[sel], p2[sel] = mat.lame
        return cls(model, neo, p1, p2)

    def with_pre(self, pre: np.ndarray | None) -> "Continuum":
        """The same continuum with the inverse reference stretch ``pre`` (m, nq, 3, 3) per
        quadrature point (None: none). The energy per mesh volume is det(G) W(F G^-1), so
        P = det(G) P_e(F G^-1) G^-T and A = det(G) A_e G^-1 G^-1 (G^-1 contracted with A_e's
        second and fourth index)."""
        if pre is not None:
            pre = np.asarray(pre, float)
            want = self.model.basis.dx.shape + (3, 3)
            if pre.shape != want:
                raise ParameterError("pre", pre.shape, f"an array of shape {want}")
            if np.any(~(np.linalg.det(pre) > 0)):
                raise ParameterError("pre", "det <= 0", "inverse stretches with det > 0")
        return dataclasses.replace(self, pre=pre)

    def elastic_gradient(self, H: np.ndarray) -> np.ndarray:
        """H_e = F G^-1 - I of displacement gradients H (m, nq, 3, 3); H without ``pre``."""
        if self.pre is None:
            return H
        return H @ self.pre + (self.pre - _I3)

    def displacement_gradient(self, u: np.ndarray) -> np.ndarray:
        """(m, nq, 3, 3) H = du/dX = F - I at the quadrature points; ``u`` (3 n_points,)."""
        b = self.model.basis
        ue = u.reshape(-1, 3)[self.model.mesh.cells]                 # (m, nn, 3)
        return np.einsum("eai,eqaJ->eqiJ", ue, b.dNdx, optimize=True)

    def stress(self, H: np.ndarray, tangent: bool):
        """P (m, nq, 3, 3) and A (m, nq, 3, 3, 3, 3) or None at displacement gradients H."""
        nq = H.shape[1]
        He = self.elastic_gradient(H)
        P = np.empty_like(H)
        A = np.empty(H.shape + (3, 3)) if tangent else None
        for neo, law in ((True, neo_hooke_stress), (False, svk_stress)):
            sel = np.nonzero(self.neo == neo)[0]
            if not len(sel):
                continue
            p1 = np.repeat(self.p1[sel, None], nq, 1)
            p2 = np.repeat(self.p2[sel, None], nq, 1)
            Ps, As = law(He[sel], p1, p2, tangent)
            P[sel] = Ps
            if tangent:
                A[sel] = As
        if self.pre is None:
            return P, A
        g = self.pre
        jg = 1.0 / np.linalg.det(g)                                   # det G
        P = jg[..., None, None] * (P @ np.swapaxes(g, -1, -2))
        if tangent:
            A = jg[..., None, None, None, None] * np.einsum("...iMkN,...JM,...LN->...iJkL",
                                                            A, g, g, optimize=True)
        return P, A

    def internal_force(self, P: np.ndarray) -> np.ndarray:
        """(3 n_points,) f_a,i = sum_q dx G_aJ P_iJ."""
        b = self.model.basis
        fe = np.einsum("eqaJ,eqiJ,eq->eai", b.dNdx, P, b.dx, optimize=True)
        dofs = 3 * self.model.mesh.cells[:, :, None] + np.arange(3)
        return np.bincount(dofs.ravel(), weights=fe.ravel(), minlength=b.n_dofs)

    def tangent(self, A: np.ndarray) -> sp.csr_matrix:
        """Consistent tangent (3 n_points square CSR), K_(a i)(b k) = sum_q dx G_aJ A_iJkL
        G_bL, scattered into the mesh's cached node-block pattern."""
        b = self.model.basis
        mesh = self.model.mesh
        pat = block_pattern(mesh)
        m, nq, nn, _ = b.dNdx.shape
        nnzb = len(pat.indices)
        data = np.zeros((9, nnzb))
        for s in range(0, m, _CHUNK):
            e = slice(s, min(s + _CHUNK, m))
            c = e.stop - e.start
            Gw = b.dNdx[e] * b.dx[e][:, :, None, None]                       # (c, nq, nn, 3)
            T = np.matmul(Gw, A[e].transpose(0, 1, 3, 2, 4, 5).reshape(c, nq, 3, 27))
            # T[c, q, a, (i k L)] = sum_J Gw_aJ A_iJkL
            T = T.reshape(c, nq, nn * 9, 3)
            K = np.matmul(T, b.dNdx[e].transpose(0, 1, 3, 2)).sum(axis=1)  # (c, nn*9, nn)
            K = K.reshape(c, nn, 3, 3, nn)                                  # [a, i, k, b]
            idx = pat.scatter[e].ravel()                                    # (a, b) order
            for i in range(3):
                for k in range(3):
                    w = K[:, :, i, k, :].ravel()
                    data[3 * i + k] += np.bincount(idx, weights=w, minlength=nnzb)
        return _bsr_to_csr(pat, np.ascontiguousarray(data.T))


@dataclass(frozen=True)
class Increment:
    """One converged load increment: load factor, Newton iterations, residual history
    (|r| / reference per iteration, the first before any correction), line-search halvings."""

    lam: float
    iterations: int
    residuals: tuple[float, ...]
    halvings: int


@dataclass(frozen=True, eq=False)
class HyperelasticResult:
    """Displacement ``u`` (n_dofs,) of the equilibrium at load factor 1 and how it was found.

    ``increments``: the converged increments; ``cuts``: increments cut in half; ``rtol``: the
    convergence tolerance; ``seconds``: wall time; ``assemblies``: tangent assemblies."""

    system: System
    continuum: Continuum
    u: np.ndarray
    f_ext: np.ndarray
    increments: tuple[Increment, ...]
    cuts: int
    rtol: float
    seconds: float
    assemblies: int
    solver: str = field(default="")

    @property
    def model(self) -> Model:
        return self.system.model

    @property
    def iterations(self) -> int:
        return sum(i.iterations for i in self.increments)

    def displacement(self) -> np.ndarray:
        """(n_points, 3) nodal displacements, mm."""
        return self.u[: 3 * self.model.n_points].reshape(-1, 3)

    def displacement_gradient(self) -> np.ndarray:
        """(m, nq, 3, 3) H = F - I at the quadrature points."""
        return self.continuum.displacement_gradient(self.u[: 3 * self.model.n_points])

    def deformation_gradient(self) -> np.ndarray:
        """(m, nq, 3, 3) F at the quadrature points."""
        return _I3 + self.displacement_gradient()

    def first_piola(self) -> np.ndarray:
        """(m, nq, 3, 3) first Piola-Kirchhoff stress, MPa (force per reference area)."""
        return self.continuum.stress(self.displacement_gradient(), False)[0]

    def cauchy(self) -> np.ndarray:
        """(m, nq, 3, 3) Cauchy stress sigma = P F^T / J, MPa."""
        F = self.deformation_gradient()
        P = self.first_piola()
        return P @ np.swapaxes(F, -1, -2) / np.linalg.det(F)[..., None, None]

    def reactions(self) -> np.ndarray:
        """(n_points, 3) f_int - f_ext on the mesh nodes: the support reactions (N)."""
        n3 = 3 * self.model.n_points
        fi = self.continuum.internal_force(self.first_piola())
        return (fi - self.f_ext[:n3]).reshape(-1, 3)

    def green_strain(self) -> np.ndarray:
        """(m, nq, 6) Green-Lagrange strain, engineering shears (xx, yy, zz, xy, xz, yz)."""
        H = self.displacement_gradient()
        E = 0.5 * (H + np.swapaxes(H, -1, -2) + np.einsum("...kI,...kJ->...IJ", H, H))
        return np.stack([E[..., 0, 0], E[..., 1, 1], E[..., 2, 2], 2 * E[..., 0, 1],
                         2 * E[..., 0, 2], 2 * E[..., 1, 2]], -1)

    def principal_stretches(self) -> np.ndarray:
        """(m, nq, 3) principal stretches (ascending), sqrt of the eigenvalues of C."""
        F = self.deformation_gradient()
        C = np.einsum("...kI,...kJ->...IJ", F, F)
        return np.sqrt(np.linalg.eigvalsh(C))

    def summary(self) -> dict:
        """Plain numbers: increments, iterations, cuts, final residuals, time."""
        return {"increments": len(self.increments), "iterations": self.iterations,
                "iterations_per_increment": [i.iterations for i in self.increments],
                "cuts": self.cuts, "rtol": self.rtol,
                "final_residual": self.increments[-1].residuals[-1] if self.increments else 0.0,
                "tangent_assemblies": self.assemblies, "seconds": round(self.seconds, 3),
                "solver": self.solver}


class _Newton:
    """Newton's method on the equilibrium of one System: the internal forces and tangent,
    the reduced linear solves, and one load increment (predictor, corrections, line search);
    counts the tangent assemblies and keeps the last linear solver's kind."""

    def __init__(self, system: System, cont: Continuum, f_ext, g, solver: str, rtol: float,
                 max_iter: int, max_halvings: int):
        self.system, self.cont, self.f_ext, self.g = system, cont, f_ext, g
        self.solver, self.rtol = solver, rtol
        self.max_iter, self.max_halvings = max_iter, max_halvings
        self.n3 = 3 * system.model.n_points
        self.T = system.T
        self.Tt = system.T.T.tocsr()
        self.assemblies = 0
        self.kind = ""

    def forces(self, u, tangent: bool):
        """(f_int (n_dofs,), tangent or None) at displacement ``u``, springs included."""
        cont, system = self.cont, self.system
        P, A = cont.stress(cont.displacement_gradient(u[:self.n3]), tangent)
        fi = np.zeros(system.n_dofs)
        fi[:self.n3] = cont.internal_force(P)
        fi += system.K_spring @ u
        if tangent:
            self.assemblies += 1
        return fi, (system.K(cont.tangent(A)) if tangent else None)

    def solve(self, Kt, r):
        """The reduced system's solution; one factorisation per iteration: "auto" chooses as
        for many right-hand sides (PARDISO from 5k unknowns on instead of SuperLU up to 20k)."""
        lin = factorize(self.system.reduce(Kt), self.solver, n_rhs=MANY_RHS)
        self.kind = lin.kind
        return lin.solve(r)

    def line_search(self, q_try, dq, lam_new, rn, ref) -> tuple[float, int]:
        """(step, halvings): the step along ``dq`` halved while the residual grows or a cell
        inverts, at most ``max_halvings`` times; past that -> ModelError."""
        step, halv = 1.0, 0
        for _ in range(self.max_halvings + 1):
            try:
                u_t = self.T @ (q_try + step * dq) + lam_new * self.g
                fi_t, _ = self.forces(u_t, False)
                rn_t = np.linalg.norm(self.Tt @ (fi_t - lam_new * self.f_ext)) / ref
                if rn_t < rn or step < 1.0 / 2 ** self.max_halvings:
                    return step, halv
            except ModelError:
                pass
            step *= 0.5
            halv += 1
        raise ModelError("line search failed")

    def increment(self, q, lam: float, lam_new: float, fi_prev, Kt_prev):
        """One load increment lam -> lam_new from the equilibrium (q, f_int, tangent) at lam:
        (q, u, f_int, tangent, Increment) at lam_new, or None if ``max_iter`` corrections do
        not reach the tolerance (the residual after the last one is not evaluated); an
        inverted cell -> ModelError."""
        T, Tt, g, f_ext = self.T, self.Tt, self.g, self.f_ext
        # predictor: the tangent at the last equilibrium takes the increment of the
        # prescribed values and the loads
        r = Tt @ (fi_prev + Kt_prev @ ((lam_new - lam) * g) - lam_new * f_ext)
        q_try = q + self.solve(Kt_prev, -r)
        res_hist: list[float] = []
        halv = 0
        for it in range(self.max_iter):
            u = T @ q_try + lam_new * g
            fi, Kt = self.forces(u, True)
            r = Tt @ (fi - lam_new * f_ext)
            ref = max(np.linalg.norm(lam_new * f_ext), np.linalg.norm(fi), 1e-300)
            rn = np.linalg.norm(r) / ref
            res_hist.append(rn)
            if rn <= self.rtol:
                return q_try, u, fi, Kt, Increment(lam_new, it, tuple(res_hist), halv)
            dq = self.solve(Kt, -r)
            step, h = self.line_search(q_try, dq, lam_new, rn, ref)
            halv += h
            q_try = q_try + step * dq
        return None


def _load_factors(system: System, cases) -> np.ndarray:
    """The factor of each of the system's load cases; ``cases``: {case: factor}, a case name,
    or None for a model with one case."""
    if cases is None:
        if len(system.cases) != 1:
            raise ParameterError("cases", None, "{case: factor} for a model with cases "
                                 + ", ".join(system.cases))
        cases = {system.cases[0]: 1.0}
    elif isinstance(cases, str):
        cases = {cases: 1.0}
    w = np.zeros(len(system.cases))
    for c, f in cases.items():
        w[system.case_index(c)] += float(f)
    return w


def solve_hyperelastic(model: Model, hyper: dict | None = None, cases=None, steps: int = 5,
                       rtol: float = 1e-9, max_iter: int = 25, max_cuts: int = 8,
                       max_halvings: int = 6, solver: str = "auto",
                       on_increment=None, pre: np.ndarray | None = None,
                       ramp_pre: bool = False, u0: np.ndarray | None = None
                       ) -> HyperelasticResult:
    """Large-deformation static equilibrium of ``model`` (the method: docs/hyperelastic.md).

    hyper: {body: NeoHooke}; other bodies are St-Venant-Kirchhoff with their Material.
    cases: {case: factor} (default: the model's only case, factor 1; a str: that case).
    steps: equal load increments; rtol: residual tolerance (relative); solver: as
    :func:`~designlab.fem.solvers.factorize`. The solve starts from the reference
    configuration (u = 0). ``on_increment(lam, u)``: called after every converged increment
    with the load factor and the displacement (n_dofs,) (e.g. to record a load-response
    curve). An increment that does not converge (or inverts a cell) is cut in half, at most
    ``max_cuts`` times in a row.

    ``pre``: a prestrain, the inverse stress-free reference stretch per quadrature point
    (:meth:`Continuum.with_pre`); with ``ramp_pre`` it is applied along with the load factor
    (G^-1 = I + lam (pre - I): a prestress step), else in full from the start. ``u0``: the
    displacement (n_dofs,) to start from instead of u = 0 (e.g. a prestressed equilibrium;
    its prescribed values must be the model's at load factor 0, and the model may have no
    rigid coupling)."""
    t0 = time.perf_counter()
    if not (isinstance(steps, (int, np.integer)) and steps >= 1):
        raise ParameterError("steps", steps, "an integer >= 1")
    if not (0 < rtol < 1):
        raise ParameterError("rtol", rtol, "in (0, 1)")
    system = model.build()
    w = _load_factors(system, cases)
    f_ext = (system.F + system.F_preload) @ w
    cont = Continuum.of(model, hyper)
    cont = cont.with_pre(pre)
    newton = _Newton(system, cont.with_pre(_I3 + 0.0 * pre) if ramp_pre and pre is not None
                     else cont, f_ext, system.G @ w, solver, rtol, max_iter, max_halvings)
    q, u_prev = _start(system, u0)
    lam, dlam = 0.0, 1.0 / steps
    incs: list[Increment] = []
    cuts = cuts_in_row = 0
    fi_prev, Kt_prev = newton.forces(u_prev, True)
    while lam < 1.0:
        lam_new = lam + dlam
        if lam_new > 1.0 - 1e-9:         # the last increment ends exactly at 1
            lam_new = 1.0
        if ramp_pre and pre is not None:
            newton.cont = cont.with_pre(_I3 + lam_new * (pre - _I3))
        try:
            done = newton.increment(q, lam, lam_new, fi_prev, Kt_prev)
        except ModelError:
            done = None
        if done is None:
            cuts += 1
            cuts_in_row += 1
            if cuts_in_row > max_cuts:
                raise ModelError(f"hyperelastic solve did not converge: load factor {lam:.4g} "
                                 f"reached, increment cut {max_cuts} times in a row")
            dlam *= 0.5
            continue
        cuts_in_row = 0
        q, u_prev, fi_prev, Kt_prev, inc = done
        lam = lam_new
        incs.append(inc)
        if on_increment is not None:
            on_increment(lam, u_prev)
    return HyperelasticResult(system, newton.cont, u_prev, f_ext, tuple(incs), cuts, rtol,
                              time.perf_counter() - t0, newton.assemblies, newton.kind)


def _start(system: System, u0):
    """(q, u) of the starting displacement: zero, or ``u0`` on a system whose free dofs are a
    selection (no rigid coupling)."""
    if u0 is None:
        return np.zeros(system.T.shape[1]), np.zeros(system.n_dofs)
    u0 = np.asarray(u0, float)
    if u0.shape != (system.n_dofs,):
        raise ParameterError("u0", u0.shape, f"a displacement of shape ({system.n_dofs},)")
    T = system.T
    if T.nnz != T.shape[1]:
        raise ModelError("u0: a start displacement needs a model without rigid couplings")
    q = np.asarray(T.T @ u0).ravel()
    return q, T @ q + (u0 - T @ (T.T @ u0))


# ---------------------------------------------------------------- CalculiX reference

def solve_calculix_neo_hooke(mesh, hyper: dict, prescribed, forces: np.ndarray,
                             increment: float = 0.1, rtol: float = 1e-8,
                             workdir=None, timeout_s: float = 3600.0) -> np.ndarray:
    """The same problem in CalculiX (``ccx``): ``*HYPERELASTIC, NEO HOOKE`` (C10 = mu/2,
    D1 = 2/kappa) per region, ``*STEP, NLGEOM`` with a fixed ``increment`` of the step
    (``*STATIC, DIRECT``), the residual tolerance of ``*CONTROLS, PARAMETERS=FIELD`` set to
    ``rtol`` (ccx's default 0.005 is loose for a comparison). ``hyper``: {region id:
    NeoHooke} for every region; ``prescribed``, ``forces`` as
    :func:`designlab.fem.calculix.write_inp` (the deck is written by it and edited). Returns
    the (n_points, 3) displacements (mm) at the end of the step (7 significant digits)."""
    import re

    from designlab.fem.calculix import (ccx_path, ccx_workdir, read_dat_displacements, run_ccx,
                                        write_inp)

    if not (0 < increment <= 1):
        raise ParameterError("increment", increment, "in (0, 1]")
    ccx_path()                      # one line when ccx is not installed, before any writing
    lin = {}
    for rid, h in hyper.items():
        if not isinstance(h, NeoHooke):
            raise ParameterError(f"hyper[{rid}]", h, "a NeoHooke(mu, kappa)")
        k, g = h.kappa, h.mu
        lin[int(rid)] = (9 * k * g / (3 * k + g), (3 * k - 2 * g) / (2 * (3 * k + g)))
    with ccx_workdir(workdir, prefix="designlab-ccx-nl-") as wd:
        write_inp(wd / "job.inp", mesh, lin, prescribed, forces)
        text = (wd / "job.inp").read_text()
        for rid, h in hyper.items():
            old = re.compile(rf"\*MATERIAL, NAME=M{int(rid)}\n\*ELASTIC\n[^\n]*\n")
            text, n = old.subn(f"*MATERIAL, NAME=M{int(rid)}\n*HYPERELASTIC, NEO HOOKE\n"
                               f"{h.C10:.13g}, {h.D1:.13g}\n", text)
            if n != 1:
                raise ModelError(f"region {rid}: material block not found in the deck")
        text = text.replace("*STEP\n*STATIC\n",
                            f"*STEP, NLGEOM, INC=10000\n*STATIC, DIRECT\n{increment:.13g}, 1.0\n"
                            f"*CONTROLS, PARAMETERS=FIELD\n{rtol:.3g}, {rtol:.3g}\n"
                            "*CONTROLS, PARAMETERS=TIME INCREMENTATION\n"
                            "50, 60, 9, 200, 10, 4, 12, 5, 6\n")
        (wd / "job.inp").write_text(text)
        run_ccx(wd, 1, timeout_s)
        text = (wd / "job.dat").read_text()
        # the .dat holds one displacement block per increment: keep the last
        last = text.rfind(" displacements (vx,vy,vz)")
        (wd / "last.dat").write_text(text[last:])
        return read_dat_displacements(wd / "last.dat", mesh.n_points)
