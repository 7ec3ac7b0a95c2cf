"""FEM core: elements, assembly, loads, couplings, springs, solvers and bad input."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.assembly import cell_basis, stiffness
from designlab.fem.facets import area_weights, facet_basis
from designlab.fem.solvers import factorize
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh

NU0 = Material("nu0", E=1000.0, nu=0.0)
SOFT = Material("soft", E=10.0, nu=0.3)


def distorted(order: int, seed: int = 0) -> TetMesh:
    """2x2x2 box with the interior corner node moved (and curved mid-edges for TET10)."""
    m = box_tet_mesh(2.0, 2.0, 2.0, 2, 2, 2)
    pts = m.points.copy()
    inner = np.all((pts > 1e-9) & (pts < 2 - 1e-9), axis=1)
    pts[inner] += [0.21, -0.13, 0.17]
    m = TetMesh(pts, m.cells, m.region, m.region_names, m.materials, m.facet_sets)
    if order == 2:
        m = m.quadratic()
        rng = np.random.default_rng(seed)
        pts = m.points.copy()
        interior = np.ones(len(pts), bool)
        for tri in m.facet_sets.values():
            interior[np.unique(tri)] = False
        pts[interior & (np.arange(len(pts)) >= 27)] += rng.uniform(-0.08, 0.08,
                                                                   (1, 3))
        m = TetMesh(pts, m.cells, m.region, m.region_names, m.materials, m.facet_sets)
    return m


@pytest.mark.parametrize("order", [1, 2])
def test_patch_test_linear_field_is_exact(order):
    mesh = distorted(order)
    A = np.array([[1e-3, 2e-3, -1e-3], [0.5e-3, -2e-3, 1e-3], [3e-3, 0.0, 1e-3]])
    c = np.array([0.01, -0.02, 0.03])
    field = lambda x: x @ A.T + c  # noqa: E731
    model = Model(mesh, materials={"block": SOFT})
    for s in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        model.prescribe(s, displacement=field)
    res = solve_static(model)
    np.testing.assert_allclose(res.displacement(), field(mesh.points), atol=1e-12)
    eps = res.strain()
    exact = np.r_[A[0, 0], A[1, 1], A[2, 2], A[0, 1] + A[1, 0], A[0, 2] + A[2, 0],
                  A[1, 2] + A[2, 1]]
    np.testing.assert_allclose(eps, np.broadcast_to(exact, eps.shape), atol=1e-12)
    # interior nodes are in equilibrium: zero residual force
    boundary = np.unique(np.concatenate([np.ravel(t) for t in mesh.facet_sets.values()]))
    free = np.setdiff1d(np.arange(mesh.n_points), boundary)
    assert np.abs(res.reactions()[free]).max() < 1e-12


@pytest.mark.parametrize("order", [1, 2])
def test_stiffness_symmetric_with_six_rigid_modes(order):
    mesh = distorted(order)
    K = stiffness(cell_basis(mesh), 5.0, 3.0)
    assert abs(K - K.T).max() < 1e-12 * abs(K).max()
    vals = spla.eigsh(K, k=8, sigma=-1e-3, which="LM", return_eigenvectors=False)
    vals = np.sort(vals)
    assert np.all(np.abs(vals[:6]) < 1e-9 * vals[-1])
    assert vals[6] > 1e-3 * vals[-1]


def test_cantilever_tet10_converges_to_timoshenko():
    L, b, h, P, E = 100.0, 10.0, 10.0, 1.0, 1000.0
    I = b * h**3 / 12
    ref = P * L**3 / (3 * E * I) + P * L / (5 / 6 * E / 2 * b * h)
    errs = []
    for n in (1, 2):
        mesh = box_tet_mesh(L, b, h, 10 * n, n, n).quadratic()
        model = Model(mesh, materials={"block": NU0})
        model.fix("xmin")
        model.traction("xmax", (0.0, 0.0, -P / (b * h)))
        u = solve_static(model).displacement()
        tip = -u[mesh.points[:, 0] > L - 1e-9, 2].mean()
        errs.append(abs(tip / ref - 1))
    assert errs[1] < errs[0] and errs[1] < 0.01


@pytest.mark.parametrize("order", [1, 2])
def test_traction_and_pressure_integrate_to_totals(order):
    mesh = box_tet_mesh(3.0, 2.0, 1.0, 3, 2, 1)
    mesh = mesh.quadratic() if order == 2 else mesh
    model = Model(mesh, materials={"block": SOFT})
    model.traction("zmax", (0.1, -0.2, 0.3), case="t")
    model.pressure("xmax", 0.5, case="p")
    model.body_force((0.0, 0.0, -2.0), case="b")
    model.fix("zmin")
    sysm = model.build()
    f = lambda c: sysm.F[:, sysm.case_index(c)].reshape(-1, 3).sum(0)  # noqa: E731
    np.testing.assert_allclose(f("t"), np.array([0.1, -0.2, 0.3]) * 6.0, rtol=1e-12)
    np.testing.assert_allclose(f("p"), [-0.5 * 2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(f("b"), [0.0, 0.0, -12.0], rtol=1e-12)
    if order == 2:   # TRI6 consistent loads: flat-face corners carry nothing under uniform load
        fb = facet_basis(mesh, mesh.facet_sets["zmax"])
        w = area_weights(mesh, fb)
        assert np.allclose(w[np.unique(fb.nodes[:, :3])], 0.0, atol=1e-14)
        assert w.sum() == pytest.approx(6.0)


def test_distributing_coupling_reproduces_force_and_moment():
    mesh = box_tet_mesh(4.0, 2.0, 2.0, 4, 2, 2).quadratic()
    model = Model(mesh, materials={"block": SOFT})
    ref_pt = np.array([6.0, 1.0, 3.0])
    hook = model.distributing_coupling("hook", "xmax", ref_point=ref_pt)
    F, M = np.array([0.3, -1.0, 2.0]), np.array([0.5, 0.7, -0.2])
    model.force(hook, F, M, case="w")
    model.fix("xmin")
    res = solve_static(model)
    f = res.system.F[: 3 * mesh.n_points, 0].reshape(-1, 3)
    assert np.all(f[np.setdiff1d(np.arange(mesh.n_points), hook.nodes)] == 0)
    np.testing.assert_allclose(f.sum(0), F, atol=1e-12)
    moment = np.cross(mesh.points - ref_pt, f).sum(0)
    np.testing.assert_allclose(moment, M, atol=1e-12)
    # reactions balance the applied wrench
    np.testing.assert_allclose(res.wrench("xmin", "w", about=ref_pt), -np.r_[M, F], atol=1e-9)


def test_rigid_coupling_moves_set_rigidly_and_springs_read_equilibrium():
    # seed-001-like: a block whose base is rigid, on three buttons at 45 deg elevation
    mesh = box_tet_mesh(2.0, 2.0, 2.0, 2, 2, 2).quadratic()
    model = Model(mesh, materials={"block": SOFT})
    base = model.rigid("base", "zmin", ref_point=(1.0, 1.0, 0.0))
    el = np.deg2rad(45)
    axes = []
    for i, az in enumerate(np.deg2rad([270, 30, 150])):
        ax = -np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        axes.append(ax)
        model.spring(f"s{i}", a=(base, (1.0, 1.0, 0.0) - 0.5 * ax), k=1e3, axis=ax)
    model.fix(base, "rxryrz")
    F = np.array([0.2, -0.1, -1.0])
    model.traction("zmax", F / 4.0, case="push")
    res = solve_static(model)
    u = res.displacement("push")
    tw = res.twist(base, "push")
    ids = base.nodes
    rigid = tw[3:] + np.cross(tw[:3], mesh.points[ids] - base.x)
    np.testing.assert_allclose(u[ids], rigid, atol=1e-14)
    readings = np.array([res.spring_force(f"s{i}", "push") for i in range(3)])
    np.testing.assert_allclose(np.array(axes).T @ readings, F, atol=1e-10)
    # the readings are the geometry-matrix solve (compression positive for a push)
    np.testing.assert_allclose(readings, np.linalg.solve(np.array(axes).T, F), atol=1e-10)


def test_spring_preload_and_prescribed_rigid_twist():
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1).quadratic()
    model = Model(mesh, materials={"block": Material("st", E=1e5, nu=0.3)})
    top = model.rigid("top", "zmax")
    model.fix("zmin")
    model.spring("bolt", a=top, k=50.0, axis=(0, 0, 1), preload=3.0, case="pre")
    model.prescribe(top, displacement=(0.0, 0.0, None), rotation=(0.0, 0.0, 0.01), case="rot")
    res = solve_static(model)
    assert res.twist(top, "rot")[2] == pytest.approx(0.01)
    s_pre = res.spring_force("bolt", "pre")
    uz = res.twist(top, "pre")[5]
    assert s_pre == pytest.approx(3.0 + 50.0 * uz)
    # the block carries the bolt force: reaction at zmin balances it
    assert res.wrench("zmin", "pre")[5] == pytest.approx(s_pre, rel=1e-9)


def test_amg_matches_direct():
    mesh = box_tet_mesh(10.0, 2.0, 2.0, 10, 2, 2).quadratic()
    model = Model(mesh, materials={"block": SOFT})
    model.fix("xmin")
    model.traction("xmax", (0.0, 0.01, -0.02))
    u1 = solve_static(model, solver="direct").displacement()
    res = solve_static(model, solver="amg")
    np.testing.assert_allclose(res.displacement(), u1, rtol=1e-6, atol=1e-9 * abs(u1).max())
    assert res.solver.kind == "amg"


def test_factorized_solves_many_rhs():
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    K = stiffness(cell_basis(mesh), 1.0, 1.0)[3:, 3:] + 0.0
    K = K + 1e-3 * np.eye(K.shape[0])
    lin = factorize(K, "direct")
    F = np.random.default_rng(1).normal(size=(K.shape[0], 3))
    X = lin.solve(F)
    np.testing.assert_allclose(K @ X, F, atol=1e-9)
    assert lin.solve(F[:, 0]).shape == (K.shape[0],)


# ---- bad input: one line each ----

def test_under_constrained_model():
    mesh = box_tet_mesh(2.0, 1.0, 1.0, 2, 1, 1)
    model = Model(mesh, materials={"block": SOFT})
    model.fix("xmin", "x")
    model.traction("xmax", (1.0, 0.0, 0.0))
    with pytest.raises(ModelError, match=r"under-constrained: 3 rigid-body modes free"):
        solve_static(model)


def test_inverted_element():
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 2, 1, 1)
    cells = mesh.cells.copy()
    cells[3] = cells[3][[0, 2, 1, 3]]
    bad = TetMesh(mesh.points, cells, mesh.region, mesh.region_names, mesh.materials)
    with pytest.raises(ModelError, match=r"1 inverted or degenerate elements .* element id 3"):
        Model(bad).basis


def test_region_without_material():
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    bare = TetMesh(mesh.points, mesh.cells, mesh.region, {0: "part"}, {})
    with pytest.raises(ModelError, match=r"region 0 \(part\) has no material"):
        Model(bare)


@pytest.mark.parametrize("kw,name", [({"E": 0.0}, r"m\.E"), ({"E": -5.0}, r"m\.E"),
                                     ({"nu": 0.5}, r"m\.nu"), ({"nu": -1.0}, r"m\.nu")])
def test_bad_material_constants(kw, name):
    args = {"E": 10.0, "nu": 0.3} | kw
    with pytest.raises(ParameterError, match=name):
        Material("m", **args)


def test_unknown_sets_and_names():
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    model = Model(mesh)
    with pytest.raises(ModelError, match=r"facet set 'top' does not exist; available: xmax"):
        model.traction("top", (0, 0, 1))
    with pytest.raises(ModelError, match=r"set 'nope' does not exist"):
        model.fix("nope")
    with pytest.raises(ParameterError, match="solver"):
        model.fix("xmin")
        solve_static(model, solver="magic")
    with pytest.raises(ParameterError, match="material"):
        Model(mesh, materials={"block": "unobtainium"})
    with pytest.raises(ParameterError, match="components"):
        model.fix("xmin", "w")


def test_beam_between_rigid_master_and_ground():
    from designlab.fem.beam import beam_stiffness, circular_section

    mesh = box_tet_mesh(2.0, 2.0, 2.0, 1, 1, 1).quadratic()
    model = Model(mesh, materials={"block": Material("jelly", E=1e-7, nu=0.3)})
    model.fix("zmin")
    top = model.rigid("top", "zmax", ref_point=(1.0, 1.0, 2.0))
    steel = Material("st", E=210000.0, nu=0.3)
    sec = circular_section(2.0)
    Lb = 20.0
    K = beam_stiffness(top.x + [Lb, 0, 0], top.x, steel.E, steel.G, **sec)
    # beam from the clamp (end a in beam_stiffness) to the top master: our end a is the master
    model.beam("bolt", (top, top.x), None, _swap_ends(K))
    model.force(top, force=(0.0, 0.0, -1.0), case="F")
    res = solve_static(model)
    uz = res.twist(top, "F")[5]
    ref = -(Lb**3 / (3 * steel.E * sec["Iy"]) + Lb / (steel.G * sec["As"]))
    assert uz == pytest.approx(ref, rel=1e-4)
    # the clamped end of the beam carries the load: beam end force balances it
    fb = res.beam_force("bolt", "F")
    assert fb[2] == pytest.approx(-1.0, rel=1e-4)


def _swap_ends(K):
    """12x12 stiffness with end a and end b exchanged."""
    p = np.r_[np.arange(6, 12), np.arange(6)]
    return K[np.ix_(p, p)]


@pytest.mark.parametrize("order,degree", [(1, 2), (2, 4)])
def test_mass_and_gravity_totals(order, degree):
    from designlab.fem.assembly import mass

    mesh = box_tet_mesh(3.0, 2.0, 1.0, 3, 2, 1, material="steel")
    mesh = mesh.quadratic() if order == 2 else mesh
    rho = 7.85e-9
    M = mass(cell_basis(mesh, degree=degree), rho)
    assert M[0::3, 0::3].sum() == pytest.approx(rho * 6.0, rel=1e-12)
    assert abs(M - M.T).max() < 1e-12 * abs(M).max()
    model = Model(mesh)
    model.gravity()
    model.fix("zmin")
    res = solve_static(model)
    np.testing.assert_allclose(res.applied_wrench("gravity")[3:], [0, 0, -rho * 6.0 * 9810.0],
                               rtol=1e-12)
    np.testing.assert_allclose(res.wrench("zmin", "gravity")[3:], [0, 0, rho * 6.0 * 9810.0],
                               rtol=1e-9, atol=1e-12 * rho * 6.0 * 9810.0)


def test_floating_second_body_is_reported():
    a = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    b = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1, origin=(3.0, 0.0, 0.0))
    n = a.n_points
    fs = dict(a.facet_sets) | {"b_" + k: v + n for k, v in b.facet_sets.items()}
    two = TetMesh(np.vstack([a.points, b.points]), np.vstack([a.cells, b.cells + n]),
                  np.zeros(2 * a.n_cells, np.int64), {0: "block"}, {"block": "ABS"}, fs)
    model = Model(two)
    model.fix("xmin")
    with pytest.raises(ModelError, match=r"6 rigid-body modes free \(2 connected parts\)"):
        solve_static(model)
    # a spring from the second body to ground along x leaves 5
    model.spring("s", a=int(n), k=1.0, axis=(1, 0, 0))
    with pytest.raises(ModelError, match=r"5 rigid-body modes free"):
        solve_static(model)
    model.fix("b_xmin")
    assert solve_static(model).displacement().shape == (2 * n, 3)
