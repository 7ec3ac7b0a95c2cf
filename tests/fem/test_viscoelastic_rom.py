"""Reduced-order march of ``solve_history`` (``method="reduced"|"auto"``) against the full march:
closed-form creep and relaxation, models with several stiffness groups, rigid couplings,
springs, two step sizes and batch mode; its certification (a too-small basis is enriched or the
full march runs); determinism; and the strap's default protocol (slow)."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.prony import Prony
from designlab.fem.history import History
from designlab.fem.reduced_march import ROM_MIN_STEPS, ROM_TOL, ReducedHistoryResult
from designlab.fem.viscoelastic import solve_history
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh

L, W, E0 = 10.0, 2.0, 12.0
PR1 = Prony(g=(0.4,), tau=(2.0,), k=(0.4,), k_tau=(2.0,))
SOFT = Prony(g=(0.3, 0.2), tau=(0.5, 5.0), k=(0.1,), k_tau=(2.0,))
HARD = Prony(g=(0.25,), tau=(0.5,))


def bar(prony: Prony) -> Model:
    """Bar along x, free to contract laterally (uniaxial stress), minimal supports."""
    mesh = box_tet_mesh(L, W, W, 4, 1, 1).quadratic()
    model = Model(mesh, materials={"block": Material("tpu", E=E0, nu=0.45, prony=prony)})
    p = mesh.points
    at = lambda x: np.nonzero(np.all(np.abs(p - x) < 1e-9, axis=1))[0]  # noqa: E731
    model.fix("xmin", "x")
    model.fix(at([0, 0, 0]), "yz")
    model.fix(at([0, W, 0]), "z")
    model.fix(at([0, 0, W]), "y")
    return model


def two_material_bar(rigid: bool = False) -> Model:
    """Two materials with different series and bulk terms (three stiffness groups), a spring,
    loads on two cases (through a rigid coupling when ``rigid``)."""
    mesh = box_tet_mesh(8.0, 2.0, 2.0, 4, 1, 1).quadratic()
    c = mesh.points[mesh.cells[:, :4]].mean(axis=1)
    region = (c[:, 0] > 4.0).astype(np.int64)
    mesh = TetMesh(mesh.points, mesh.cells, region, {0: "soft", 1: "hard"},
                   {"soft": "m", "hard": "m"}, dict(mesh.facet_sets))
    model = Model(mesh, materials={"soft": Material("soft", E=12.0, nu=0.45, prony=SOFT),
                                   "hard": Material("hard", E=40.0, nu=0.35, prony=HARD)})
    model.fix("xmin")
    model.traction("xmax", (0.2, 0.0, 0.05), case="pull")
    if rigid:
        end = model.rigid("end", "xmax")
        model.force(end, force=(0.0, 0.1, 0.0), moment=(0.05, 0.0, 0.0), case="twist")
    else:
        model.traction("xmax", (0.0, 0.1, 0.0), case="twist")
    p = model.mesh.points
    mid = int(np.argmin(np.linalg.norm(p - [4.0, 2.0, 2.0], axis=1)))
    model.spring("support", a=mid, k=3.0, axis=(0.0, 0.0, 1.0))
    return model


def long_history(n: int = 200) -> History:
    """Ramps, holds, a jump (a second step size) and a sine over ``n`` steps of 0.05 s."""
    t = np.r_[np.linspace(0.0, 2.0, 41), 2.0, np.linspace(2.0, 0.05 * n, n - 40)[1:]]
    pull = np.minimum(t, 1.0) * (t < 6.0)
    twist = np.where(t >= 2.0, 1.0, 0.0) * np.cos(t)
    twist[41] = 0.0          # the jump at t = 2 s: 0 then 1 (a repeated time, dt = 0)
    return History(t, {"pull": pull, "twist": twist})


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_reduced_creep_matches_closed_form_and_full_march():
    model = bar(PR1)
    s0 = 0.5
    model.traction("xmax", (s0, 0.0, 0.0), case="hang")
    tau = PR1.tau[0]
    hist = History.step_hold(6 * tau / PR1.g_inf, 120, {"hang": 1.0})
    full = solve_history(model, hist)
    red = solve_history(model, hist, method="reduced")
    assert isinstance(red, ReducedHistoryResult) and red.march == "reduced"
    assert red.rom_residual <= ROM_TOL and 1 <= red.basis_size <= 10
    ux = red.U[: 3 * model.n_points].reshape(-1, 3, len(hist.t))[:, 0]
    u_end = ux[model.mesh.points[:, 0] > L - 1e-9].mean(0)
    Einf = E0 * PR1.g_inf
    J = 1 / Einf - (1 / Einf - 1 / E0) * np.exp(-hist.t * PR1.g_inf / tau)
    np.testing.assert_allclose(u_end, s0 * J * L, rtol=0.01)       # the time discretisation
    assert rel(red.U, full.U) < 1e-9
    assert rel(red.F_int, full.F_int) < 1e-9


def test_reduced_relaxation_after_a_step_is_exact():
    """Prescribed motions are not reduced: the full march runs and says why."""
    model = bar(PR1)
    model.prescribe("xmax", displacement=(0.01 * L, None, None), case="pull")
    hist = History.step_hold(20.0, 100, {"pull": 1.0})
    res = solve_history(model, hist, method="reduced")
    assert res.march == "full (prescribed motions)" and res.rom_residual is None
    force = -res.wrench("xmin")[:, 3]
    np.testing.assert_allclose(force, W * W * 0.01 * E0 * PR1.relaxation(hist.t), rtol=1e-9)


@pytest.mark.parametrize("rigid,batch,forces", [(False, False, True), (True, False, False),
                                                (False, True, True), (True, True, False)])
def test_reduced_equals_full_march(rigid, batch, forces):
    model = two_material_bar(rigid)
    hist = long_history()
    full = solve_history(model, hist, solver="direct", batch=batch, forces=forces)
    red = solve_history(model, hist, solver="direct", batch=batch, forces=forces,
                        method="reduced")
    assert full.march == "full" and red.march == "reduced"
    assert red.rom_residual <= ROM_TOL
    assert red.U.shape == full.U.shape
    assert rel(red.U, full.U) < 1e-8
    for step in (0, 41, 42, 120, -1):
        np.testing.assert_allclose(red.displacement(step), full.displacement(step), rtol=0,
                                   atol=1e-8 * np.abs(full.U).max())
    dofs = [3, 10, 50]
    np.testing.assert_allclose(red.dofs(dofs), full.dofs(dofs), rtol=0,
                               atol=1e-8 * np.abs(full.U).max())
    np.testing.assert_allclose(red.spring_force("support"), full.spring_force("support"),
                               rtol=0, atol=1e-8 * np.abs(full.spring_force("support")).max())
    if rigid:
        np.testing.assert_allclose(red.twist("end"), full.twist("end"), rtol=0,
                                   atol=1e-8 * np.abs(full.twist("end")).max())
    f = lambda U: np.asarray(U)[:7].sum(axis=0)     # noqa: E731  (a linear map of columns)
    np.testing.assert_allclose(red.linear(f), f(full.U), rtol=0,
                               atol=1e-8 * np.abs(f(full.U)).max())
    np.testing.assert_array_equal(full.linear(f), f(full.U))
    if forces:
        assert rel(red.F_int, full.F_int) < 1e-8
        np.testing.assert_allclose(red.wrench("xmin"), full.wrench("xmin"), rtol=0,
                                   atol=1e-8 * np.abs(full.wrench("xmin")).max())
    else:
        assert red.F_int is None


def test_certification_catches_a_too_small_basis():
    model = two_material_bar()
    hist = long_history()
    full = solve_history(model, hist, solver="direct", forces=False)
    # one vector and no room to grow: the residual check fails, the full march runs
    one = solve_history(model, hist, solver="direct", forces=False, method="reduced",
                        rom_basis=1, rom_max=1)
    assert one.march.startswith("full (reduced basis of 1 left residual")
    np.testing.assert_array_equal(one.U, full.U)
    # one vector with room: enriched with the worst step's residual until it certifies
    grown = solve_history(model, hist, solver="direct", forces=False, method="reduced",
                          rom_basis=1)
    assert grown.march == "reduced" and grown.basis_size > 1
    assert grown.rom_residual <= ROM_TOL
    assert rel(grown.U, full.U) < 1e-8
    # a looser basis reports a residual above the tolerance when asked to accept it
    loose = solve_history(model, hist, solver="direct", forces=False, method="reduced",
                          rom_basis=2, rom_max=2, rom_tol=1.0)
    assert loose.march == "reduced" and loose.rom_residual > ROM_TOL
    assert rel(loose.U, full.U) > 1e-8


def test_auto_method_and_default():
    model = two_material_bar()
    short = History(np.linspace(0.0, 2.0, ROM_MIN_STEPS), {"pull": np.ones(ROM_MIN_STEPS)})
    a = solve_history(model, short, forces=False, method="auto")
    b = solve_history(model, short, forces=False)
    assert a.march == f"full ({ROM_MIN_STEPS} steps <= {ROM_MIN_STEPS})" and b.march == "full"
    np.testing.assert_array_equal(a.U, b.U)
    hist = long_history()
    assert solve_history(model, hist, forces=False, method="auto").march == "reduced"
    assert solve_history(model, hist, forces=False).march == "full"     # the default
    with pytest.raises(ParameterError, match="method"):
        solve_history(model, hist, method="fast")
    with pytest.raises(ParameterError, match="rom_tol"):
        solve_history(model, hist, method="reduced", rom_tol=0.0)
    with pytest.raises(ParameterError, match="rom_max"):
        solve_history(model, hist, method="reduced", rom_max=0)
    with pytest.raises(ParameterError, match="rom_basis"):
        solve_history(model, hist, method="reduced", rom_basis=2.5)


def test_reduced_is_the_same_bit_for_bit_run_to_run():
    model = two_material_bar(rigid=True)
    hist = long_history()
    a = solve_history(model, hist, forces=False, method="reduced")
    b = solve_history(model, hist, forces=False, method="reduced")
    assert a.march == b.march == "reduced"
    np.testing.assert_array_equal(a.basis, b.basis)
    np.testing.assert_array_equal(a.U, b.U)
    assert a.rom_residual == b.rom_residual


@pytest.mark.slow
def test_strap_default_protocol_reduced_equals_full():
    """The strap's default model and protocol (41.8k DOF, 511 steps): gauge strain histories
    and the peak displacement of the two marches (measured: ~5e-12 of the largest strain)."""
    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap import virtual as S
    from designlab.sensors.strap import model as strap_model
    from designlab.sensors.protocols import StrapLoadTest

    part, protocol, settings = ArchStrap(), StrapLoadTest(), S.StrapModelSettings()
    model, gauges, _ = strap_model.build_model(part, strap_model.mesh_strap(part, settings), settings)
    t, fn, fx = protocol.time_history()
    hist = History(t, {"F_n": fn, "F_x": fx})
    out = {}
    for method in ("full", "auto"):
        res = solve_history(model, hist, solver=settings.solver, forces=False, method=method)
        out[method] = (res, np.column_stack([res.linear(gauges[c].strain)
                                             for c in S.CHANNELS]))
    (full, sf), (red, sr) = out["full"], out["auto"]
    assert red.march == "reduced" and red.rom_residual <= ROM_TOL and red.basis_size <= 40
    assert np.all(np.abs(sr - sf).max(axis=0) <= 1e-9 * np.abs(sf).max(axis=0))
    peak = int(np.argmax(fn))
    assert rel(red.displacement(peak), full.displacement(peak)) < 1e-9
    from designlab.fem.viscoelastic import long_time_displacements

    got, res = red.long_time()              # measured: residual 2.3e-10, 5e-12 of max |u|
    want = long_time_displacements(model, solver=settings.solver)
    assert res <= ROM_TOL and rel(got, want) < 1e-9


def test_long_time_displacements_from_the_basis():
    """The relaxed response of every load case from the reduced basis equals the factorised
    one when certified (the creep bar: its basis holds it); a basis that does not hold it to
    the tolerance (two materials, three stiffness groups, a 10 s history) gives None, as does
    a full march."""
    from designlab.fem.viscoelastic import long_time_displacements

    model = bar(PR1)
    model.traction("xmax", (0.5, 0.0, 0.0), case="hang")
    model.traction("xmax", (0.0, 0.02, 0.0), case="side")
    hist = History.step_hold(20.0, 100, {"hang": 1.0, "side": -1.0})
    red = solve_history(model, hist, method="reduced")
    got, res = red.long_time()
    assert res <= ROM_TOL
    want = long_time_displacements(model)
    assert got.shape == want.shape and rel(got, want) < 1e-9
    assert solve_history(model, hist).long_time() is None
    model = two_material_bar(rigid=True)
    red = solve_history(model, long_history(), solver="direct", forces=False,
                        method="reduced")
    assert red.march == "reduced" and red.long_time() is None
    assert red._long_residual > 1e-6          # measured 2.5e-4: not the relaxed response
