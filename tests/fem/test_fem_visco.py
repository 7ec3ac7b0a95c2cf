"""Viscoelastic solver against 1-D analytic relaxation/creep and homogeneous shear/bulk fields."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.prony import Prony
from designlab.fem.history import History
from designlab.fem.viscoelastic import solve_history
from designlab.mesh.tetmesh import box_tet_mesh

L, W = 10.0, 2.0
E0 = 12.0


def bar(prony: Prony, order: int = 2) -> Model:
    """Bar along x, free to contract laterally (uniaxial stress), minimal supports."""
    mesh = box_tet_mesh(L, W, W, 4, 1, 1)
    mesh = mesh.quadratic() if order == 2 else mesh
    model = Model(mesh, materials={"block": Material("tpu", E=E0, nu=0.45, prony=prony)})
    p = mesh.points
    at = lambda x: np.nonzero(np.all(np.abs(p - x) < 1e-9, axis=1))[0]  # noqa: E731
    model.fix("xmin", "x")
    model.fix(at([0, 0, 0]), "yz")
    model.fix(at([0, W, 0]), "z")
    model.fix(at([0, 0, W]), "y")
    return model


# same terms on shear and bulk moduli: nu is constant, E(t) = E0 (g_inf + sum g exp(-t/tau))
PR2 = Prony(g=(0.3, 0.2), tau=(0.5, 5.0), k=(0.3, 0.2), k_tau=(0.5, 5.0))
PR1 = Prony(g=(0.4,), tau=(2.0,), k=(0.4,), k_tau=(2.0,))


def test_relaxation_after_a_step_is_exact():
    model = bar(PR2)
    eps0 = 0.01
    model.prescribe("xmax", displacement=(eps0 * L, None, None), case="pull")
    hist = History.step_hold(20.0, 100, {"pull": 1.0})
    res = solve_history(model, hist)
    force = -res.wrench("xmin")[:, 3]
    analytic = W * W * eps0 * E0 * PR2.relaxation(hist.t)
    np.testing.assert_allclose(force, analytic, rtol=1e-9)
    assert res.factorizations == 1            # constant dt; the glassy jump by PCG on it
    pcg = [s for s in res.solvers if s.kind == "pcg"]
    assert len(pcg) == 1 and max(pcg[0].iterations) <= 10


def test_relaxation_after_a_ramp_matches_convolution():
    model = bar(PR1, order=1)
    eps0, tr = 0.01, 1.0
    model.prescribe("xmax", displacement=(eps0 * L, None, None), case="pull")
    hist = History.piecewise([0.0, tr, 10.0], [0.0, 1.0, 1.0], case="pull", dt=0.05)
    res = solve_history(model, hist)
    force = -res.wrench("xmin")[:, 3]
    t = hist.t
    g, tau = PR1.g[0], PR1.tau[0]
    rate = eps0 / tr
    # sigma(t) = rate int_0^min(t,tr) E(t - s) ds for a linear ramp then hold
    a = np.minimum(t, tr)
    sig = rate * E0 * (PR1.g_inf * a + g * tau * (np.exp(-(t - a) / tau) - np.exp(-t / tau)))
    np.testing.assert_allclose(force, W * W * sig, rtol=1e-9, atol=1e-12)


def test_creep_under_constant_load_within_one_percent():
    model = bar(PR1)
    s0 = 0.5
    model.traction("xmax", (s0, 0.0, 0.0), case="hang")
    tau, g = PR1.tau[0], PR1.g[0]
    hist = History.step_hold(6 * tau / PR1.g_inf, 120, {"hang": 1.0})
    res = solve_history(model, hist)
    ux = res.U[: 3 * model.n_points].reshape(-1, 3, len(hist.t))[:, 0]
    u_end = ux[model.mesh.points[:, 0] > L - 1e-9].mean(0)
    # standard linear solid: J(t) = 1/E_inf - (1/E_inf - 1/E0) exp(-t g_inf / tau)
    Einf = E0 * PR1.g_inf
    J = 1 / Einf - (1 / Einf - 1 / E0) * np.exp(-hist.t * PR1.g_inf / tau)
    np.testing.assert_allclose(u_end, s0 * J * L, rtol=0.01)
    assert abs(u_end[0] / (s0 / E0 * L) - 1) < 1e-9          # instantaneous response
    assert res.factorizations == 1


def test_deviatoric_and_volumetric_split():
    """Homogeneous simple shear relaxes with G(t); pure dilatation with K(t) (here: no bulk
    terms, so the pressure stays constant)."""
    pr = Prony(g=(0.5,), tau=(1.0,))
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1).quadratic()
    mat = Material("m", E=E0, nu=0.3, prony=pr)
    model = Model(mesh, materials={"block": mat})
    gam, th = 0.01, 0.003
    for s in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        model.prescribe(s, displacement=lambda x: np.c_[gam * x[:, 1], 0 * x[:, 0],
                                                        0 * x[:, 0]], case="shear")
        model.prescribe(s, displacement=lambda x: th / 3 * x, case="dil")
    hist_s = History.step_hold(3.0, 30, {"shear": 1.0})
    hist_d = History.step_hold(3.0, 30, {"dil": 1.0})
    fs = solve_history(model, hist_s).wrench("xmax")[:, 4]       # f_y = sigma_xy on x-face
    np.testing.assert_allclose(fs, mat.G * gam * pr.relaxation(hist_s.t), rtol=1e-9)
    fd = solve_history(model, hist_d).wrench("xmax")[:, 3]       # normal force on x-face
    np.testing.assert_allclose(fd, np.full(len(fd), mat.K * th), rtol=1e-9)


@pytest.mark.parametrize("order,solver", [(1, "direct"), (1, "amg"), (2, "amg")])
def test_elastic_material_history_equals_static(order, solver):
    mesh = box_tet_mesh(4.0, 1.0, 1.0, 4, 1, 1)
    mesh = mesh.quadratic() if order == 2 else mesh
    model = Model(mesh, materials={"block": Material("e", E=100.0, nu=0.3)})
    model.fix("xmin")
    model.traction("xmax", (0.0, 0.0, -0.1), case="tip")
    from designlab.fem.static import solve_static

    u = solve_static(model).displacement("tip")
    hist = History(np.linspace(0, 1, 5), {"tip": np.linspace(0, 1, 5)})
    res = solve_history(model, hist, solver=solver)
    tol = 1e-10 if solver == "direct" else 1e-7
    np.testing.assert_allclose(res.displacement(-1), u, rtol=tol, atol=tol * abs(u).max())
    np.testing.assert_allclose(res.displacement(2), 0.5 * u, rtol=tol, atol=tol * abs(u).max())


def test_history_bad_input():
    with pytest.raises(ParameterError, match="non-decreasing"):
        History(np.array([0.0, 2.0, 1.0]))
    model = bar(PR1)
    model.traction("xmax", (0.1, 0, 0), case="hang")
    with pytest.raises(ParameterError, match="history case"):
        solve_history(model, History(np.array([0.0, 1.0]), {"oops": np.ones(2)}))


def test_batch_history_equals_separate_histories():
    model = bar(PR1)
    model.traction("xmax", (0.2, 0.0, 0.0), case="pull")
    model.traction("xmax", (0.0, 0.0, 0.01), case="shear")
    t = np.linspace(0.0, 4.0, 21)
    amp = {"pull": np.minimum(t, 1.0), "shear": np.where(t > 2.0, 1.0, 0.0)}
    both = solve_history(model, History(t, amp), batch=True)
    assert both.U.shape == (model.n_dofs, 2, len(t))
    for i, c in enumerate(("pull", "shear")):
        one = solve_history(model, History(t, {c: amp[c]}))
        # the same march; the multi-column solves round differently: 1e-12 of the largest
        # displacement (round-off carried by the history forces: ~1e-13 measured)
        tol = 1e-12 * np.abs(one.U).max()
        np.testing.assert_allclose(both.U[:, i], one.U, rtol=1e-10, atol=tol)
        np.testing.assert_allclose(both.wrench("xmin")[i], one.wrench("xmin"), atol=1e-12)
        np.testing.assert_allclose(both.displacement(5)[i], one.displacement(5), atol=tol)


def test_history_without_forces_same_displacements():
    model = bar(PR2)
    model.traction("xmax", (0.2, 0.0, 0.0), case="pull")
    t = np.linspace(0.0, 4.0, 21)
    hist = History(t, {"pull": np.minimum(t, 1.0)})
    full = solve_history(model, hist)
    lean = solve_history(model, hist, forces=False)
    np.testing.assert_array_equal(lean.U, full.U)
    assert lean.F_int is None
    with pytest.raises(ModelError, match="forces=False"):
        lean.wrench("xmin")
