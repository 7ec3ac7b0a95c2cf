"""Static linear solve of a :class:`~designlab.fem.model.Model` for all its load cases at once.

``solve_static(model)`` -> :class:`StaticResult` with displacements, reactions, wrench
resultants on sets, spring forces and reference-point twists per load case.
Wrench order (m_x, m_y, m_z, f_x, f_y, f_z), twist order (w_x, w_y, w_z, v_x, v_y, v_z), as in
seed 002; N, N mm, mm, rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from designlab.errors import ModelError
from designlab.fem.assembly import block_pattern
from designlab.fem.model import Model, RefPoint, Spring, System
from designlab.fem.solvers import LinearSolver, factorize


def rigid_modes(model: Model, dofs_of: np.ndarray, x0: np.ndarray, L: float) -> np.ndarray:
    """(n_dofs, 6) rigid-body modes (translations, rotations scaled by 1/L about x0) restricted
    to the mesh nodes and rigid masters flagged in ``dofs_of`` (bool over graph nodes)."""
    npts = model.n_points
    R = np.zeros((model.n_dofs, 6))
    ids = np.nonzero(dofs_of[:npts])[0]
    r = (model.mesh.points[ids] - x0) / L
    for k in range(3):
        R[3 * ids + k, k] = 1.0
        e = np.zeros(3)
        e[k] = 1.0
        rot = np.cross(e, r)
        R[3 * ids[:, None] + np.arange(3), 3 + k] = rot
    for ref in model.refs.values():
        if ref.kind == "rigid" and dofs_of[npts + ref.index]:
            d = ref.dofs(npts)
            rr = (ref.x - x0) / L
            for k in range(3):
                e = np.zeros(3)
                e[k] = 1.0
                R[d[k], k] = 1.0
                R[d[:3], 3 + k] = np.cross(e, rr)
                R[d[3 + k], 3 + k] = 1.0 / L
    return R


def check_constrained(system: System) -> None:
    """ModelError if any connected part keeps rigid-body modes free (no constraints or springs
    removing all 6)."""
    model = system.model
    npts = model.n_points
    nref = sum(r.kind == "rigid" for r in model.refs.values())
    pat = block_pattern(model.mesh)
    rows = [np.repeat(np.arange(npts), np.diff(pat.indptr))]
    cols = [pat.indices]
    links = []
    for r in model.refs.values():
        if r.kind == "rigid":
            links.append(np.column_stack([r.nodes, np.full(len(r.nodes), npts + r.index)]))
    spring_rows = []
    Kd = system.K_el.diagonal()
    Rs = system.R_spring
    if Rs is not None and Rs.shape[0]:
        # one stacked map for all springs: link the graph nodes each spring touches (chain)
        Rc = Rs.tocoo()
        key = np.unique(np.column_stack([system.spring_of_row[Rc.row],
                                         _graph_nodes(model, Rc.col)]), axis=0)
        same = key[1:, 0] == key[:-1, 0]
        if same.any():
            links.append(np.column_stack([key[:-1, 1][same], key[1:, 1][same]]))
        spring_rows.append((np.sqrt(system.k_rows / kref_of(Kd))[:, None], Rs))
    for bm in model.beams.values():
        Lb = model.beam_map(bm)
        lam, vec = np.linalg.eigh(bm.K)
        keep = lam > 1e-12 * max(lam.max(), 0)
        spring_rows.append((1.0, sp.csr_matrix((np.sqrt(lam[keep] / kref_of(Kd))[:, None]
                                                 * vec[:, keep].T) @ Lb)))
        nodes = np.unique(_graph_nodes(model, Lb.indices))
        if len(nodes) > 1:
            links.append(np.column_stack([nodes[:-1], nodes[1:]]))
    if links:
        lk = np.vstack(links)
        rows.append(lk[:, 0])
        cols.append(lk[:, 1])
    ng = npts + nref
    A = sp.csr_matrix((np.ones(sum(len(r) for r in rows)), (np.concatenate(rows),
                       np.concatenate(cols))), shape=(ng, ng))
    ncomp, label = connected_components(A, directed=False)
    used = np.zeros(ng, bool)
    used[np.unique(model.mesh.cells)] = True
    used[npts:] = True
    cons = np.nonzero(system.constrained)[0]
    total_free = 0
    for c in np.unique(label[used]):
        members = label == c
        pts = model.mesh.points[np.nonzero(members[:npts])[0]]
        refs = [r.x for r in model.refs.values() if r.kind == "rigid" and members[npts + r.index]]
        allx = np.vstack([pts] + ([np.array(refs)] if refs else []))
        x0 = allx.mean(0)
        L = max(float(np.ptp(allx, axis=0).max()), 1e-9)
        R = rigid_modes(model, members, x0, L)
        M = [R[cons]]
        for scale, Rm in spring_rows:
            M.append(scale * (Rm @ R))
        sv = np.linalg.svd(np.vstack(M), compute_uv=False) if sum(len(m) for m in M) else []
        rank = int(np.sum(np.asarray(sv) > 1e-8))
        total_free += 6 - rank
    if total_free:
        raise ModelError(f"model is under-constrained: {total_free} rigid-body modes free "
                         f"({ncomp} connected parts); add fixed/prescribed displacements or "
                         "springs")


def kref_of(Kd: np.ndarray) -> float:
    """Typical stiffness (median positive diagonal) for scaling springs in the rank test."""
    return float(np.median(Kd[Kd > 0])) if np.any(Kd > 0) else 1.0


def _graph_nodes(model: Model, dofs: np.ndarray) -> np.ndarray:
    npts = model.n_points
    d = np.asarray(dofs)
    return np.where(d < 3 * npts, d // 3, npts + (d - 3 * npts) // 6)


def near_null_space(system: System) -> np.ndarray:
    """Rigid-body modes of the whole model in the reduced (free) coordinates, for AMG."""
    model = system.model
    used = np.ones(model.n_points + sum(r.kind == "rigid" for r in model.refs.values()), bool)
    x = model.mesh.points
    L = max(float(np.ptp(x, axis=0).max()), 1e-9)
    return rigid_modes(model, used, x.mean(0), L)[system.free_dofs]


def p1_prolongation(system: System):
    """For TET10 models: (P, B_c), the linear interpolation from the corner-node (TET4)
    reduced dofs to the reduced TET10 dofs and the coarse rigid-body modes; None for TET4.
    Used by the AMG solver as a p-multigrid level (SA-AMG works well on the P1 level)."""
    model = system.model
    mesh = model.mesh
    if mesh.order != 2:
        return None
    from designlab.mesh.tetmesh import TET10_EDGES

    npts, n = model.n_points, system.n_dofs
    corners = np.unique(mesh.cells[:, :4])
    mids, first = np.unique(mesh.cells[:, 4:].ravel(), return_index=True)
    cell, k = np.divmod(first, 6)
    a = mesh.cells[cell, TET10_EDGES[k, 0]]
    b = mesh.cells[cell, TET10_EDGES[k, 1]]
    rows = np.r_[corners, mids, mids]
    cols = np.r_[corners, a, b]
    vals = np.r_[np.ones(len(corners)), np.full(2 * len(mids), 0.5)]
    Pn = sp.csr_matrix((vals, (rows, cols)), shape=(npts, npts))
    nm = n - 3 * npts
    P_full = sp.block_diag([sp.kron(Pn, sp.identity(3)), sp.identity(nm)], format="csr") \
        if nm else sp.kron(Pn, sp.identity(3), format="csr")
    is_coarse = np.zeros(n, bool)
    is_coarse[(3 * corners[:, None] + np.arange(3)).ravel()] = True
    is_coarse[3 * npts:] = True
    ccols = np.nonzero(is_coarse[system.free_dofs])[0]
    nf = len(system.free_dofs)
    Sel = sp.csr_matrix((np.ones(nf), (np.arange(nf), system.free_dofs)), shape=(nf, n))
    P = (Sel @ P_full @ system.T.tocsc()[:, ccols]).tocsr()
    return P, near_null_space(system)[ccols]


@dataclass(frozen=True, eq=False)
class StaticResult:
    """Displacements ``U`` (n_dofs, n_cases) of a :class:`System` and derived quantities."""

    system: System
    U: np.ndarray
    solver: LinearSolver

    @property
    def model(self) -> Model:
        return self.system.model

    @property
    def cases(self) -> tuple[str, ...]:
        return self.system.cases

    def _u(self, case):
        return self.U[:, self.system.case_index(case)]

    def displacement(self, case: str = "default") -> np.ndarray:
        """(n_points, 3) nodal displacements, mm."""
        return self._u(case)[: 3 * self.model.n_points].reshape(-1, 3)

    def reactions(self, case: str = "default") -> np.ndarray:
        """(n_points, 3) forces that supports, couplings and springs exert on the body
        (K_el u - applied loads), N; zero at free nodes up to round-off."""
        n3 = 3 * self.model.n_points
        u = self._u(case)
        r = self.system.K_el @ u[:n3] - self.system.F[:n3, self.system.case_index(case)]
        return r.reshape(-1, 3)

    def wrench(self, where, case: str = "default", about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Resultant (m_x, m_y, m_z, f_x, f_y, f_z) of the reactions on the nodes of a set,
        moment about ``about``; N mm, N."""
        ids = self.model.nodes(where)
        r = self.reactions(case)[ids]
        arm = self.model.mesh.points[ids] - np.asarray(about, float)
        return np.r_[np.cross(arm, r).sum(0), r.sum(0)]

    def applied_wrench(self, case: str = "default", about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Resultant (m, f) of every applied load of ``case`` (mesh and reference points)."""
        m = self.model
        F = self.system.F[:, self.system.case_index(case)]
        f = F[: 3 * m.n_points].reshape(-1, 3)
        arm = m.mesh.points - np.asarray(about, float)
        out = np.r_[np.cross(arm, f).sum(0), f.sum(0)]
        for ref in m.refs.values():
            if ref.kind == "rigid":
                fv = F[ref.dofs(m.n_points)]
                out += np.r_[fv[3:] + np.cross(ref.x - np.asarray(about, float), fv[:3]), fv[:3]]
        return out

    def twist(self, ref: RefPoint | str, case: str = "default") -> np.ndarray:
        """(w_x, w_y, w_z, v_x, v_y, v_z) of a reference point; rad, mm."""
        ref = self.model.refs[ref] if isinstance(ref, str) else ref
        vw = self.model.twist_map(ref) @ self._u(case)
        return np.r_[vw[3:], vw[:3]]

    def spring_force(self, spring: Spring | str, case: str = "default") -> float | np.ndarray:
        """Spring reading (N): k * elongation + preload (3-vector for isotropic springs)."""
        s = self.model.springs[spring] if isinstance(spring, str) else spring
        e = self.model.spring_map(s) @ self._u(case)
        f = s.k * e + (s.preload if case == s.case else 0.0)
        return float(f[0]) if s.axis is not None else f

    def beam_force(self, beam, case: str = "default") -> np.ndarray:
        """(12,) forces and moments the beam exerts on its ends' dofs, negated: K (L u), i.e.
        (f_a, m_a, f_b, m_b) acting *on the beam* at its ends (N, N mm)."""
        b = self.model.beams[beam] if isinstance(beam, str) else beam
        return b.K @ (self.model.beam_map(b) @ self._u(case))

    def strain(self, case: str = "default") -> np.ndarray:
        """(m, nq, 6) engineering strains (xx, yy, zz, xy, xz, yz) at quadrature points."""
        m = self.model
        e = m.B @ self._u(case)[: 3 * m.n_points]
        return e.reshape(m.mesh.n_cells, -1, 6)

    def stress(self, case: str = "default") -> np.ndarray:
        """(m, nq, 6) Cauchy stress (MPa), same order, instantaneous moduli."""
        m = self.model
        return elastic_stress(self.strain(case), m.cell_values("K"), m.cell_values("G"))

    def von_mises(self, case: str = "default") -> np.ndarray:
        """(m,) cell-mean von Mises stress, MPa."""
        return von_mises(self.stress(case)).mean(axis=1)


def elastic_stress(eps: np.ndarray, K: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Isotropic stress from engineering strains (m, nq, 6); K, G per cell (MPa)."""
    tr = eps[..., :3].sum(-1)
    s = np.empty_like(eps)
    s[..., :3] = (2.0 * G[:, None, None]) * (eps[..., :3] - tr[..., None] / 3.0) \
        + (K[:, None] * tr)[..., None]
    s[..., 3:] = G[:, None, None] * eps[..., 3:]
    return s


def von_mises(s: np.ndarray) -> np.ndarray:
    """Von Mises equivalent of Voigt stresses (..., 6), same units."""
    a, b, c = s[..., 0], s[..., 1], s[..., 2]
    return np.sqrt(0.5 * ((a - b) ** 2 + (b - c) ** 2 + (c - a) ** 2)
                   + 3.0 * (s[..., 3] ** 2 + s[..., 4] ** 2 + s[..., 5] ** 2))


def solve_static(model: Model, solver: str = "auto", check: bool = True) -> StaticResult:
    """Solve every load case of ``model`` with one factorisation."""
    system = model.build()
    if check:
        check_constrained(system)
    K = system.K()
    Kr = system.reduce(K)
    Fr = system.T.T @ (system.F + system.F_preload - K @ system.G)
    lin = factorize(Kr, solver, near_null=lambda: near_null_space(system),
                    coarse=lambda: p1_prolongation(system), n_rhs=Fr.shape[1])
    q = lin.solve(Fr)
    U = system.T @ q + system.G
    return StaticResult(system, U, lin)
