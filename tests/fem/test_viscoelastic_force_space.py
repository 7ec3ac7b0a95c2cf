"""solve_history carries the Prony history as nodal forces (one stiffness per group of
proportional time constants); here against the quadrature-point march it replaced (the
reference below: h_t at every quadrature point, strains through B, forces through B^T), on
models that exercise every branch: two materials with different series (no shared shape),
bulk terms, a prescribed motion, a rigid coupling, a spring, batch mode, forces on and off,
two step sizes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.assembly import stiffness
from designlab.fem.prony import Prony
from designlab.fem.static import check_constrained
from designlab.fem.history import History, PronyTables, step_gamma
from designlab.fem.viscoelastic import _by_tau, _shapes, solve_history
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh

_VOIGT_C = np.array([2.0, 2.0, 2.0, 1.0, 1.0, 1.0])

SOFT = Prony(g=(0.3, 0.2), tau=(0.5, 5.0), k=(0.1,), k_tau=(2.0,))
HARD = Prony(g=(0.25,), tau=(0.5,))


def reference_history(model: Model, history: History, batch: bool = False):
    """(U, F_int) of the quadrature-point march (the implementation before the nodal-force
    one; direct solves, one factorisation per step size)."""
    import scipy.sparse.linalg as spla

    system = model.build()
    check_constrained(system)
    t = history.t
    A = np.stack([history.amplitude(c) for c in system.cases], axis=1)
    Fc = system.F + system.F_preload
    if batch:
        F_all = Fc[:, :, None] * A.T[None]
        G_all = system.G[:, :, None] * A.T[None]
    else:
        F_all, G_all = (Fc @ A.T)[:, None], (system.G @ A.T)[:, None]
    nb = F_all.shape[1]
    n3 = 3 * model.n_points
    B, dx = model.B, model.basis.dx.ravel()
    pr = PronyTables(model)
    nqp, nq = len(dx), model.basis.dx.shape[1]
    dev, vol = _by_tau(pr.dev, pr.G0, nqp), _by_tau(pr.vol, pr.K0, nqp)
    H = np.zeros((len(dev[0]), nqp, 6, nb))
    M = np.zeros((len(vol[0]), nqp, nb))
    e_old, th_old = np.zeros((nqp, 6, nb)), np.zeros((nqp, nb))
    cvo = (dx[:, None] * _VOIGT_C)[:, :, None]
    Winf = (pr.G0 * pr.ginf)[:, None, None] * cvo
    Kinf = (dx * pr.K0 * pr.kinf)[:, None]
    Wdev = dev[1][:, :, None, None] * cvo[None]
    Wvol = (vol[1] * dx[None])[:, :, None]
    U = np.zeros((system.n_dofs, nb, len(t)))
    F_int = np.zeros((n3, nb, len(t)))
    T = system.T
    lus = {}
    for n in range(len(t)):
        dt = 0.0 if n == 0 else float(t[n] - t[n - 1])
        if n == 0 and not (np.any(F_all[..., 0]) or np.any(G_all[..., 0])):
            continue
        key = round(dt, 12)
        if key not in lus:
            Ge, Ke = pr.effective(dt)
            Gc, Kc = Ge.reshape(-1, nq)[:, 0], Ke.reshape(-1, nq)[:, 0]
            K = system.K(stiffness(model.basis, Kc - 2.0 * Gc / 3.0, Gc))
            lus[key] = (spla.splu(system.reduce(K).tocsc()), K)
        lu, K = lus[key]
        a_d = np.array([np.exp(-dt / tau) for tau in dev[0]])
        g_d = np.array([step_gamma(dt, tau) for tau in dev[0]])
        a_v = np.array([np.exp(-dt / tau) for tau in vol[0]])
        g_v = np.array([step_gamma(dt, tau) for tau in vol[0]])
        sig_h = -np.tensordot(g_d, Wdev, 1) * e_old
        for i in range(len(a_d)):
            sig_h += a_d[i] * Wdev[i] * H[i]
        if len(a_v):
            p_h = -np.tensordot(g_v, Wvol, 1) * th_old
            for i in range(len(a_v)):
                p_h += a_v[i] * Wvol[i] * M[i]
            sig_h[:, :3] += p_h[:, None]
        f_h = np.zeros((system.n_dofs, nb))
        f_h[:n3] = B.T @ sig_h.reshape(nqp * 6, nb)
        r = F_all[..., n] - f_h - K @ G_all[..., n]
        u = T @ lu.solve(T.T @ r) + G_all[..., n]
        U[..., n] = u
        e = (B @ u[:n3]).reshape(nqp, 6, nb)
        th = e[:, :3].sum(1)
        e[:, :3] -= (th / 3.0)[:, None]
        for i in range(len(a_d)):
            H[i] = a_d[i] * H[i] + g_d[i] * (e - e_old)
        for i in range(len(a_v)):
            M[i] = a_v[i] * M[i] + g_v[i] * (th - th_old)
        e_old, th_old = e, th
        sig = Winf * e
        for i in range(len(a_d)):
            sig += Wdev[i] * H[i]
        p = Kinf * th
        for i in range(len(a_v)):
            p += Wvol[i] * M[i]
        sig[:, :3] += p[:, None]
        F_int[..., n] = B.T @ sig.reshape(nqp * 6, nb)
    if not batch:
        U, F_int = U[:, 0], F_int[:, 0]
    return U, F_int


def two_material_bar(order: int = 2) -> Model:
    mesh = box_tet_mesh(8.0, 2.0, 2.0, 4, 1, 1)
    mesh = mesh.quadratic() if order == 2 else mesh
    c = mesh.points[mesh.cells[:, :4]].mean(axis=1)
    region = (c[:, 0] > 4.0).astype(np.int64)
    mesh = TetMesh(mesh.points, mesh.cells, region, {0: "soft", 1: "hard"},
                   {"soft": "m", "hard": "m"}, dict(mesh.facet_sets))
    return Model(mesh, materials={"soft": Material("soft", E=12.0, nu=0.45, prony=SOFT),
                                  "hard": Material("hard", E=40.0, nu=0.35, prony=HARD)})


def _loaded(model: Model, rigid: bool = False, prescribed: bool = False) -> Model:
    model.fix("xmin")
    model.traction("xmax", (0.2, 0.0, 0.05), case="pull")
    if rigid:
        end = model.rigid("end", "xmax")
        model.force(end, force=(0.0, 0.1, 0.0), moment=(0.05, 0.0, 0.0), case="twist")
    else:
        model.traction("xmax", (0.0, 0.1, 0.0), case="twist")
    p = model.mesh.points
    if prescribed:      # a moving support on part of the y = 0 face (away from the coupling)
        ids = np.nonzero((p[:, 1] < 1e-9) & (p[:, 0] > 1.0) & (p[:, 0] < 6.0))[0]
        model.prescribe(ids, displacement=(None, 0.01, None), case="pull")
    mid = int(np.argmin(np.linalg.norm(p - [4.0, 2.0, 2.0], axis=1)))
    model.spring("support", a=mid, k=3.0, axis=(0.0, 0.0, 1.0))
    return model


# two step sizes (0.2 s most often, 0.1 s after the jump at 1 s), ramps and a jump
T_GRID = np.r_[np.linspace(0.0, 1.0, 6), np.linspace(1.0, 1.5, 6)[1:],
               np.linspace(1.5, 4.0, 14)[1:]]
AMP = {"pull": np.minimum(T_GRID, 1.0), "twist": np.where(T_GRID >= 1.0, 1.0, 0.0) * np.cos(T_GRID)}


@pytest.mark.parametrize("rigid,prescribed,batch", [(False, False, False), (True, False, False),
                                                    (False, True, False), (False, False, True),
                                                    (True, True, True)])
def test_nodal_force_march_equals_quadrature_point_march(rigid, prescribed, batch):
    model = _loaded(two_material_bar(), rigid=rigid, prescribed=prescribed)
    hist = History(T_GRID, AMP)
    U_ref, F_ref = reference_history(model, hist, batch=batch)
    scale_u, scale_f = np.abs(U_ref).max(), np.abs(F_ref).max()
    assert scale_u > 0 and scale_f > 0
    full = solve_history(model, hist, solver="direct", batch=batch)
    lean = solve_history(model, hist, solver="direct", batch=batch, forces=False)
    np.testing.assert_allclose(full.U, U_ref, rtol=0, atol=1e-11 * scale_u)
    np.testing.assert_allclose(full.F_int, F_ref, rtol=0, atol=1e-11 * scale_f)
    np.testing.assert_allclose(lean.U, U_ref, rtol=0, atol=1e-11 * scale_u)
    assert lean.F_int is None
    # the applied forces come from the cases and amplitudes
    A = np.stack([hist.amplitude(c) for c in full.cases], axis=1)
    F = full.system.F[: 3 * model.n_points]
    np.testing.assert_array_equal(full.F_ext, F[:, :, None] * A.T[None] if batch else F @ A.T)


def test_history_is_the_same_bit_for_bit_run_to_run():
    model = _loaded(two_material_bar())
    hist = History(T_GRID, AMP)
    a = solve_history(model, hist, forces=False)
    b = solve_history(model, hist, forces=False)
    np.testing.assert_array_equal(a.U, b.U)


def test_proportional_time_constants_share_one_stiffness():
    """One Prony series on two materials (the strap's case): both taus are multiples of one
    moduli field; different relative terms per region are not."""
    same = np.array([[1.0, 2.0, 0.0], [0.3, 0.6, 0.0], [0.0, 1.0, 1.0]])
    groups = _shapes(same)
    assert [(ref, [m for m, _ in ms]) for ref, ms in groups] == [(0, [0, 1]), (2, [2])]
    assert groups[0][1][1][1] == pytest.approx(0.3, rel=1e-15)
    model = two_material_bar()
    one = dataclasses.replace(model.region_materials[1], prony=SOFT)
    m2 = Model(model.mesh, materials={"soft": model.region_materials[0], "hard": one})
    from designlab.fem.viscoelastic import _terms

    for m, n_groups in ((model, 3), (m2, 2)):
        taus, shear, bulk = _terms(PronyTables(m), m.basis.dx.shape[1])
        assert len(_shapes(np.concatenate([shear, bulk], axis=1))) == n_groups
    # and the march with shared stiffness still equals the reference
    _loaded(m2)
    hist = History(T_GRID, AMP)
    U_ref, _ = reference_history(m2, hist)
    U = solve_history(m2, hist, solver="direct", forces=False).U
    np.testing.assert_allclose(U, U_ref, rtol=0, atol=1e-11 * np.abs(U_ref).max())
