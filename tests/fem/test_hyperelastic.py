"""Geometrically nonlinear neo-Hookean / St-Venant-Kirchhoff solids (fem/hyperelastic.py)."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from designlab.errors import ModelError, ParameterError
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.hyperelastic import (Continuum, NeoHooke, neo_hooke_energy, neo_hooke_stress,
                                        solve_calculix_neo_hooke, solve_hyperelastic, svk_stress,
                                        uniaxial_closed_form)
from designlab.fem.materials import Material
from designlab.mesh.tetmesh import box_tet_mesh

MAT = Material("soft", E=1.0, nu=0.45)
STIFF = Material("stiff", E=20.0, nu=0.3)
NH = NeoHooke.from_linear(MAT.E, MAT.nu)


def _two_bodies(order: int, n=(4, 2, 2), size=(8.0, 2.0, 2.0)):
    """A box split at x = size/2: "soft" (x < half) and "stiff" (x > half)."""
    mesh = box_tet_mesh(*size, *n, material="ABS")
    x = mesh.points[mesh.cells[:, :4]].mean(1)[:, 0]
    region = (x > size[0] / 2).astype(np.int64)
    mesh = dataclasses.replace(mesh, region=region, region_names={0: "soft", 1: "stiff"},
                               materials={"soft": "soft", "stiff": "stiff"})
    return mesh.quadratic() if order == 2 else mesh


def _model(mesh):
    return Model(mesh, {"soft": MAT, "stiff": STIFF})


@pytest.mark.parametrize("law", ["neo", "svk"])
def test_pointwise_tangent_and_stress_are_derivatives(law):
    """A = dP/dF by central differences (h 1e-6) to 1e-8 relative, and P = dW/dF for the
    neo-Hookean energy, at a random F with det F > 0 (the laws take H = F - I); P at a
    small strain keeps its relative precision (no F = I + H cancellation)."""
    rng = np.random.default_rng(3)
    F = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    assert np.linalg.det(F) > 0
    fn = neo_hooke_stress if law == "neo" else svk_stress
    p = (np.array([0.7]), np.array([5.0]))
    H = F - np.eye(3)
    P, A = fn(H[None], *p)
    h = 1e-6
    Afd = np.zeros((3, 3, 3, 3))
    for k in range(3):
        for L in range(3):
            d = np.zeros((3, 3))
            d[k, L] = h
            Afd[:, :, k, L] = (fn((H + d)[None], *p, tangent=False)[0]
                               - fn((H - d)[None], *p, tangent=False)[0])[0] / (2 * h)
    assert np.abs(A[0] - Afd).max() < 1e-8 * np.abs(A).max()
    if law == "neo":
        Pfd = np.zeros((3, 3))
        for i in range(3):
            for J in range(3):
                d = np.zeros((3, 3))
                d[i, J] = h
                Pfd[i, J] = (neo_hooke_energy(H + d, 0.7, 5.0)
                             - neo_hooke_energy(H - d, 0.7, 5.0)) / (2 * h)
        assert np.abs(P[0] - Pfd).max() < 1e-8 * np.abs(P).max()
    # at H ~ 1e-9 the stress is linear in H to 1e-8 (cancellation would leave ~1e-7)
    Hs = 1e-9 * (H + H.T)
    lin = fn(Hs[None], *p, tangent=False)[0][0]
    lam, mu = (p[1][0] - 2 * p[0][0] / 3, p[0][0]) if law == "neo" else (p[0][0], p[1][0])
    ref = lam * np.trace(Hs) * np.eye(3) + 2 * mu * Hs
    assert np.abs(lin - ref).max() < 1e-8 * np.abs(ref).max()


@pytest.mark.parametrize("order", [1, 2])
def test_assembled_tangent_is_the_derivative_of_the_internal_force(order):
    """The global tangent (neo-Hookean and SVK cells, the scatter into the block pattern)
    against central differences of the internal force at a random displacement field
    (strains of a few %): max error / max entry < 1e-7, on every column."""
    mesh = _two_bodies(order)
    model = _model(mesh)
    cont = Continuum.of(model, {"soft": NeoHooke.from_linear(MAT.E, MAT.nu)})
    rng = np.random.default_rng(7)
    u = 0.03 * rng.standard_normal(3 * mesh.n_points)
    P, A = cont.stress(cont.displacement_gradient(u), True)
    K = cont.tangent(A).toarray()
    assert np.abs(K - K.T).max() < 1e-12 * np.abs(K).max()
    h = 1e-6
    Kfd = np.zeros_like(K)
    for j in range(len(u)):
        d = np.zeros_like(u)
        d[j] = h
        fp = cont.internal_force(cont.stress(cont.displacement_gradient(u + d), False)[0])
        fm = cont.internal_force(cont.stress(cont.displacement_gradient(u - d), False)[0])
        Kfd[:, j] = (fp - fm) / (2 * h)
    assert np.abs(K - Kfd).max() < 1e-7 * np.abs(K).max()


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("stretch", [1.5, 0.7])
def test_uniaxial_stretch_matches_the_closed_form(order, stretch):
    """A 2 x 3 x 4 mm block pulled (or pushed) to ``stretch`` along x on frictionless
    symmetry planes: nominal stress (reaction / reference area) and the lateral stretch
    equal the energy's closed form to 1e-8 (a homogeneous state: every element holds it)."""
    nh = NeoHooke.from_linear(1.0, 0.4)
    L = (2.0, 3.0, 4.0)
    mesh = box_tet_mesh(*L, 2, 2, 3, material="soft")
    mesh = mesh.quadratic() if order == 2 else mesh
    m = Model(mesh, {"block": MAT})
    m.fix("xmin", "x")
    m.fix("ymin", "y")
    m.fix("zmin", "z")
    m.prescribe("xmax", ((stretch - 1) * L[0], None, None))
    r = solve_hyperelastic(m, {"block": nh}, steps=4, rtol=1e-12)
    P11, t = uniaxial_closed_form(nh, stretch)
    f = r.reactions()[m.nodes("xmax"), 0].sum()
    assert f / (L[1] * L[2]) == pytest.approx(P11, rel=1e-8)
    u = r.displacement()
    ymax = m.nodes("ymax")
    assert u[ymax, 1] == pytest.approx((t - 1) * L[1], rel=1e-8)
    s = r.summary()
    assert s["increments"] == 4 and s["final_residual"] <= 1e-12 and s["cuts"] == 0


@pytest.mark.parametrize("order", [1, 2])
def test_small_strain_limit_is_the_linear_solution(order):
    """A cantilever (soft neo-Hookean half, stiff SVK half) under a tip traction that bends
    it by ~1e-7 of its length: the nonlinear solution equals solve_static's to 1e-6 relative
    (measured 7e-8 TET4, 2.6e-7 TET10: the difference is ~half the tip rotation), and at a
    1000 x larger load it differs by > 1e-5 (7e-5, 2.6e-4: the check sees the
    nonlinearity)."""
    def run(scale):
        m = _model(_two_bodies(order))
        m.fix("xmin")
        m.traction("xmax", (0.0, 0.0, -scale))
        lin = solve_static(m).displacement()
        nl = solve_hyperelastic(m, {"soft": NeoHooke.from_linear(MAT.E, MAT.nu)}, steps=1,
                                rtol=1e-12).displacement()
        return lin, nl
    lin, nl = run(1e-8)
    tip = np.abs(lin).max()
    assert 1e-7 < tip / 8.0 < 1e-5
    assert np.abs(nl - lin).max() < 1e-6 * tip
    lin, nl = run(1e-5)
    assert np.abs(nl - lin).max() > 1e-5 * np.abs(lin).max()


def test_newton_converges_quadratically_and_reports_it():
    """A bonded block compressed 30 % (TET10): every increment converges in <= 5 iterations,
    the residual history falls faster than linearly (r_k+1 < 10 r_k^1.5 at the last step),
    bit-identical on a second run."""
    mesh = box_tet_mesh(10, 10, 10, 3, 3, 3, material="soft").quadratic()
    m = Model(mesh, {"block": MAT})
    m.fix("zmin")
    m.prescribe("zmax", (0.0, 0.0, -3.0))
    nh = NeoHooke.from_linear(MAT.E, MAT.nu)
    r = solve_hyperelastic(m, {"block": nh}, steps=4)
    for inc in r.increments:
        assert inc.iterations <= 5
        res = inc.residuals
        assert res[-1] <= 1e-9
        assert res[-2] < 10 * res[-3] ** 1.5
    assert r.summary()["iterations"] == sum(r.summary()["iterations_per_increment"])
    r2 = solve_hyperelastic(m, {"block": nh}, steps=4)
    assert np.array_equal(r.u, r2.u)


def test_bad_input_is_a_one_line_error():
    m = Model(box_tet_mesh(1, 1, 1, 1, 1, 1, material="soft"), {"block": MAT})
    m.fix("zmin")
    with pytest.raises(ParameterError, match="mu"):
        NeoHooke(0.0, 1.0)
    with pytest.raises(ParameterError, match="hyper"):
        solve_hyperelastic(m, {"nobody": NeoHooke(1.0, 1.0)})
    with pytest.raises(ParameterError, match="steps"):
        solve_hyperelastic(m, {}, steps=0)


def test_a_load_beyond_what_the_mesh_can_carry_is_a_model_error():
    """A prescribed displacement that inverts the block (compressed by 120 %) cannot
    converge: the step cuts run out and the error says so."""
    m = Model(box_tet_mesh(1, 1, 2, 1, 1, 2, material="soft"), {"block": MAT})
    m.fix("zmin")
    m.prescribe("zmax", (0.0, 0.0, -2.4))
    with pytest.raises(ModelError, match="did not converge"):
        solve_hyperelastic(m, {"block": NeoHooke(1.0, 10.0)}, steps=2, max_cuts=3)


needs_ccx = pytest.mark.skipif(shutil.which("ccx") is None, reason="ccx not installed")


@pytest.mark.slow
@needs_ccx
@pytest.mark.parametrize("order", [1, 2])
def test_bonded_block_at_30_percent_compression_matches_calculix(order):
    """A 10 mm cube bonded to rigid plates, the top pushed down 3 mm (30 %; principal
    stretches 0.52..1.43 on TET10): the nodal displacements equal CalculiX's (*HYPERELASTIC,
    NEO HOOKE, NLGEOM, the same mesh and elements) to 1e-6 of the largest displacement
    (measured 2.3e-7 on TET10: ccx prints 7 digits); the linear solution's bulge is 19 %
    (TET4) and 25 % (TET10) smaller (the check sees the nonlinearity)."""
    nh = NeoHooke.from_linear(1.0, 0.45)
    mesh = box_tet_mesh(10, 10, 10, 4, 4, 4, material="soft")
    mesh = mesh.quadratic() if order == 2 else mesh
    m = Model(mesh, {"block": MAT})
    m.fix("zmin")
    m.prescribe("zmax", (0.0, 0.0, -3.0))
    u = solve_hyperelastic(m, {"block": nh}, steps=5).displacement()
    bot, top = m.nodes("zmin"), m.nodes("zmax")
    pres = np.array([(n, d, 0.0) for n in bot for d in range(3)]
                    + [(n, d, -3.0 if d == 2 else 0.0) for n in top for d in range(3)])
    uc = solve_calculix_neo_hooke(mesh, {0: nh}, pres, np.zeros((mesh.n_points, 3)),
                                  increment=0.2)
    scale = np.abs(u).max()
    assert np.abs(u - uc).max() < 1e-6 * scale
    bulge = np.abs(u[:, :2]).max()
    assert np.abs(solve_static(m).displacement()[:, :2]).max() < 0.85 * bulge


@needs_ccx
@pytest.mark.slow
def test_cantilever_under_a_large_tip_force_matches_calculix():
    """A 20 x 2 x 2 mm TET10 cantilever (neo-Hookean, E 1 MPa, nu 0.45) under 0.01 N at its
    tip nodes (dead load, downwards): tip deflection 59 % of the length, axial Green strain
    up to 11 %; every displacement equals CalculiX's to 1e-6 of the largest (measured
    4.0e-7 with ccx increments of 0.05; with 0.1 ccx cuts back and ends 1e-5 off)."""
    nh = NeoHooke.from_linear(1.0, 0.45)
    mesh = box_tet_mesh(20, 2, 2, 10, 2, 2, material="soft").quadratic()
    m = Model(mesh, {"block": MAT})
    m.fix("xmin")
    tip = m.nodes("xmax")
    f = np.zeros((mesh.n_points, 3))
    f[tip, 2] = -0.01 / len(tip)
    m.nodal_force(tip, (0.0, 0.0, -0.01 / len(tip)))
    r = solve_hyperelastic(m, {"block": nh}, steps=10)
    u = r.displacement()
    assert 0.5 < -u[tip, 2].mean() / 20 < 0.7
    assert np.abs(r.green_strain()[..., 0]).max() > 0.08
    pres = np.array([(n, d, 0.0) for n in m.nodes("xmin") for d in range(3)])
    uc = solve_calculix_neo_hooke(mesh, {0: nh}, pres, f, increment=0.05)
    assert np.abs(u - uc).max() < 1e-6 * np.abs(u).max()


def test_springs_couplings_and_cases_come_from_the_model():
    """A cantilever block with a grounded spring, a rigid coupling on its free end loaded
    through its master (force and moment), a distributing coupling on a side, two load
    cases combined with factors: at a small load the nonlinear solution equals
    solve_static's combination of the cases to 1e-6 (measured 6.3e-8; at 100 x the load
    6.3e-6: the check sees the nonlinearity): the System's T (rigid masters), springs and
    loads are used as the linear solver uses them; on_increment is called at every
    converged increment."""
    mesh = box_tet_mesh(4, 2, 2, 4, 2, 2, material="soft").quadratic()
    m = Model(mesh, {"block": MAT})
    m.fix("xmin")
    top = m.rigid("top", "xmax")
    side = m.distributing_coupling("side", "ymax")
    m.force(top, force=(0.0, 0.0, -1e-8), moment=(1e-8, 0.0, 0.0), case="a")
    m.force(side, force=(0.0, 1e-8, 0.0), case="b")
    mid = int(np.argmin(np.linalg.norm(mesh.points - [2.0, 0.0, 2.0], axis=1)))
    m.spring("s", a=mid, k=0.5, axis=(0.0, 0.0, 1.0))
    lin = solve_static(m)
    u_lin = 2.0 * lin.U[:, lin.system.case_index("a")] - lin.U[:, lin.system.case_index("b")]
    seen = []
    r = solve_hyperelastic(m, {"block": NH}, cases={"a": 2.0, "b": -1.0}, steps=2,
                           rtol=1e-12, on_increment=lambda lam, u: seen.append(lam))
    assert seen == [0.5, 1.0]
    assert np.abs(r.u - u_lin).max() < 1e-6 * np.abs(u_lin).max()
    with pytest.raises(ParameterError, match="cases"):
        solve_hyperelastic(m, {"block": NH})
