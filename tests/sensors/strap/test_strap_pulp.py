"""The solid finger pulp under the strap (``finger_model = "solid"``, sensors/strap/pulp.py)."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh
from designlab.sensors.strap import pulp as sp
from designlab.sensors.strap import pulp_layer as strap_pulp_layer
E, NU, DEPTH, P = 0.06, 0.49, 3.0, 0.01          # MPa, -, mm, MPa


def _layer(order: int, n: int = 4, layers: int = 3) -> TetMesh:
    """A 6 x 6 mm surface (z = 0, structured n x n squares of two triangles) extruded 3 mm
    down as the pulp."""
    xs = np.linspace(0, 6, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    nid = np.arange(len(pts)).reshape(n + 1, n + 1)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    tri = np.vstack([np.column_stack([nid[i, j], nid[i + 1, j], nid[i + 1, j + 1]]),
                     np.column_stack([nid[i, j], nid[i + 1, j + 1], nid[i, j + 1]])])
    new, cells, far = strap_pulp_layer.extrude(pts, tri, DEPTH, layers)
    mesh = TetMesh(np.vstack([pts, new]), cells, np.zeros(len(cells), np.int64), {0: "pulp"},
                   {"pulp": "pulp"}, {"top": tri, "bone": far})
    return mesh.quadratic() if order == 2 else mesh


def _compress(mesh: TetMesh, confined: bool) -> float:
    m = Model(mesh, {"pulp": strap_pulp_layer.pulp_material(E, NU)})
    x = mesh.points
    m.fix("bone", "z")
    if confined:                   # no lateral strain anywhere
        m.fix(np.arange(mesh.n_points), "xy")
    else:                          # frictionless faces: symmetry planes only
        m.fix(np.nonzero(np.isclose(x[:, 0], 0))[0], "x")
        m.fix(np.nonzero(np.isclose(x[:, 1], 0))[0], "y")
    m.traction("top", (0.0, 0.0, -P))
    u = solve_static(m).displacement()
    top = np.unique(mesh.facet_sets["top"])
    return float(-u[top, 2].mean())


@pytest.mark.parametrize("order", [1, 2])
def test_layer_compression_matches_closed_form(order):
    """Uniform pressure on the extruded layer: confined p d / M (M = 17.1 E at nu 0.49) and
    frictionless unconfined p d / E, to 1e-6 (uniform states are in every element's space:
    this checks the extrusion, the orientation and the material, not locking)."""
    ref = strap_pulp_layer.layer_closed_form(E, NU, DEPTH, P)
    mesh = _layer(order)
    assert np.all(mesh.corner_volumes > 0)
    assert _compress(mesh, True) == pytest.approx(ref["confined_mm"], rel=1e-6)
    assert _compress(mesh, False) == pytest.approx(ref["unconfined_mm"], rel=1e-6)
    assert ref["unconfined_mm"] / ref["confined_mm"] == pytest.approx(
        (1 - NU) / ((1 + NU) * (1 - 2 * NU)), rel=1e-12)


@pytest.mark.slow
def test_tet10_does_not_lock_at_nu_049_on_a_bonded_layer():
    """Uniform states cannot show locking (every element holds them): a layer bonded to the
    bone (far face fixed) under a uniform top traction has free edges and a non-uniform
    field. At nu 0.49 the pulp's TET10 on 4 x 4 squares, 2 layers, is within 1 % of 16 x 16,
    8 layers (measured 0.6 %), while TET4 on the coarse mesh is > 20 % too stiff (measured
    35 %): the check sees locking, and TET10 has none to speak of."""
    def bonded(mesh):
        m = Model(mesh, {"pulp": strap_pulp_layer.pulp_material(E, NU)})
        m.fix("bone")
        m.traction("top", (0.0, 0.0, -P))
        u = solve_static(m).displacement()
        return float(-u[np.unique(mesh.facet_sets["top"]), 2].mean())

    fine = bonded(_layer(2, 16, 8))
    assert bonded(_layer(2, 4, 2)) == pytest.approx(fine, rel=0.01)
    assert bonded(_layer(1, 4, 2)) < 0.8 * fine


def test_add_pulp_is_conforming_on_a_tet10_body():
    """A TET10 block with the pulp extruded from its bottom face: the shared face keeps the
    block's mid-edge nodes (no duplicate nodes) and, both bodies of the pulp's material (the
    same lateral strain: a bonded stiff block would restrain the pulp), the 5 mm column
    compresses as one, p (h + d) / E (frictionless, uniaxial stress), to 1e-6."""
    block = box_tet_mesh(4.0, 4.0, 2.0, 3, 3, 2, body="block", material="ABS").quadratic()
    mesh = strap_pulp_layer.add_pulp(block, block.facet_sets["zmin"][:, :3], DEPTH, 2)
    assert mesh.order == 2 and np.all(mesh.corner_volumes > 0)
    key = np.round(mesh.points, 9)
    assert len(np.unique(key, axis=0)) == mesh.n_points
    assert len(np.unique(mesh.cells)) == mesh.n_points          # every node used
    m = Model(mesh, {"pulp": strap_pulp_layer.pulp_material(E, NU), "block": strap_pulp_layer.pulp_material(E, NU)})
    x = mesh.points
    m.fix(sp.BONE, "z")
    m.fix(np.nonzero(np.isclose(x[:, 0], 0))[0], "x")
    m.fix(np.nonzero(np.isclose(x[:, 1], 0))[0], "y")
    m.traction("zmax", (0.0, 0.0, -P))
    u = solve_static(m).displacement()
    want = P * (2.0 + DEPTH) / E
    assert float(-u[np.unique(mesh.facet_sets["zmax"]), 2].mean()) == pytest.approx(want,
                                                                                    rel=1e-6)


def test_bad_settings_are_one_line_errors():
    from designlab.sensors.strap.model import StrapModelSettings

    with pytest.raises(ParameterError, match="finger_model"):
        StrapModelSettings(finger_model="gel")
    with pytest.raises(ParameterError, match="pulp_poisson"):
        StrapModelSettings(pulp_poisson=0.5)
    with pytest.raises(ParameterError, match="pulp_layers"):
        StrapModelSettings(pulp_layers=1.5)


@pytest.mark.slow
def test_solid_pulp_changes_the_strap_prediction():
    """Coarse strap (2 mm TET4, elastic materials): the solid pulp replaces the springs (the
    prediction moves, the report says which finger and the pulp's strain), and a very soft
    pulp (0.001 MPa) reads like the unsupported strap (tissue_stiffness 0) within 5 %."""
    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap import virtual as st
    from designlab.sensors.strap import model as strap_model
    from designlab.sensors.strap.model import elastic_materials
    from designlab.sensors.protocols import StrapLoadTest

    part, proto = ArchStrap(), StrapLoadTest(n_steps=2, step_hold_s=1.0, dt_s=0.25, cycles=1,
                                             cycle_period_s=1.0)
    mats = elastic_materials(part)

    def sum_sens(**kw):
        s = st.StrapModelSettings(edge_length=2.0, order=1, mesh_convergence=False, **kw)
        r = st.run(part, proto, s, materials=mats).report
        return r["sensitivity"]["V_per_N"]["sum"]["F_n"], r["finger"]

    w, fw = sum_sens()
    s1, f1 = sum_sens(finger_model="solid")
    soft, _ = sum_sens(finger_model="solid", pulp_modulus=0.001)
    free, _ = sum_sens(tissue_stiffness=0.0)
    assert fw == {"finger_model": "winkler", "tissue_stiffness_N_per_mm3": 0.02}
    assert f1["finger_model"] == "solid" and f1["pulp_max_principal_strain_per_N"] > 0
    assert abs(s1 / w - 1) > 0.01
    assert soft == pytest.approx(free, rel=0.05)
    assert abs(w / free - 1) > 0.05                  # the default support is not negligible


def test_fem_key_holds_the_finger_model_it_uses():
    """Winkler: the pulp's settings leave the key (the key it had before the option); solid:
    the springs' stiffness leaves it and every pulp setting enters it."""
    import dataclasses

    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap import virtual as st
    from designlab.sensors.strap import model as strap_model
    from designlab.sensors.protocols import StrapLoadTest

    part, proto = ArchStrap(), StrapLoadTest()
    w = st.StrapModelSettings()
    key = strap_model.fem_key(part, proto, w)
    assert strap_model.fem_key(part, proto, dataclasses.replace(w, pulp_modulus=0.3)) == key
    s = dataclasses.replace(w, finger_model="solid")
    ks = strap_model.fem_key(part, proto, s)
    assert ks != key
    assert strap_model.fem_key(part, proto, dataclasses.replace(s, tissue_stiffness=0.05)) == ks
    other = {strap_model.fem_key(part, proto, dataclasses.replace(s, **kw)) for kw in (
        {"pulp_depth": 4.0}, {"pulp_modulus": 0.1}, {"pulp_poisson": 0.45}, {"pulp_layers": 3})}
    assert len(other) == 4 and ks not in other


def test_stretch_strain_and_principal_biot_of_known_deformations():
    """The nonlinear comparison's strain measures: |F d| - 1 along the gauge direction and
    the largest |principal stretch - 1| equal their closed forms for a uniaxial stretch with
    a rigid rotation (a rotation adds no strain, unlike the small strain B u)."""
    th = 0.4
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    F = R @ np.diag([1.3, 0.9, 1.0])
    H = (F - np.eye(3))[None, None]
    assert sp._principal_biot(H.reshape(-1, 3, 3))[0] == pytest.approx(0.3, rel=1e-12)

    class _G:                       # a gauge on one cell along x
        class model:
            class basis:
                x = np.zeros((1, 1, 3))
                dx = np.ones((1, 1))
        cells = np.array([0])
        direction = (1.0, 0.0, 0.0)
    assert sp._gauge_stretch_strain(_G, H) == pytest.approx(0.3, rel=1e-12)
    _G.direction = (0.0, 1.0, 0.0)
    assert sp._gauge_stretch_strain(_G, H) == pytest.approx(-0.1, rel=1e-12)


@pytest.mark.slow
def test_nonlinear_strap_tends_to_the_linear_one_at_small_load_and_departs_at_5_N():
    """Coarse strap (edge 3 mm) with the solid neo-Hookean pulp: at F_n = 0.01 N (one
    increment) the nonlinear gauge sum equals the linear one to 0.1 % (measured 0.9993), at
    the protocol's 5 N it is > 10 % lower (measured 0.843 secant, 0.768 over the last 1 N:
    geometric stiffening of the band). ~35 s."""
    from designlab.sensors.protocols import StrapLoadTest

    small = sp.nonlinear_comparison(steps=1, protocol=StrapLoadTest(normal_N=0.01),
                                    edge_length=3.0)
    assert small["neo-Hooke"]["secant_sum_over_linear"] == pytest.approx(1.0, abs=1e-3)
    assert small["neo-Hooke"]["solver"]["cuts"] == 0
    big = sp.nonlinear_comparison(steps=5, edge_length=3.0)
    row = big["neo-Hooke"]
    assert row["secant_sum_over_linear"] < 0.9
    assert row["local_sum_over_linear"] < row["secant_sum_over_linear"]
    assert row["pulp_p95_strain"] > 0.1 and big["linear"]["pulp_p95_strain"] > 0.1


def test_wrap_kinematics_strain_is_bending_and_needs_large_rotations():
    """The wrap map's exact strain (edge 3 mm): at most ~thickness / finger radius (0.6 / 9 =
    0.067; measured max 0.076, p95 0.062), the gauges' centreline stretch between 0 and that
    (measured 0.032), rotations up to ~pi, while the small strain of the same displacement
    reads nonsense (measured max 2.05, gauges -0.33): a linear analysis cannot carry the
    wrap."""
    w = sp.wrap_kinematics(edge_length=3.0)
    tr = w["thickness_mm"] / w["finger_radius_mm"]
    assert 0.5 * tr < w["strap_p95_strain"] < w["strap_max_strain"] < 1.3 * tr
    for ch in ("Ch1", "Ch2"):
        assert 0.0 < w[f"{ch}_stretch_strain"] < tr
        assert abs(w[f"{ch}_small_strain_reading"] - w[f"{ch}_stretch_strain"]) > 0.1
    assert w["max_rotation_rad"] > 2.0
    assert w["small_strain_reading_max"] > 5 * w["strap_max_strain"]


@pytest.mark.slow
def test_wrap_equilibrium_relaxes_the_map_and_responds_like_the_worn_model_at_small_load():
    """Edge 3 mm, F_n 0.05 N in one increment: the wrap's equilibrium (Newton from the map,
    quadratic at the end: last residual < 1e-9) relaxes the gauges' stretch from the map's
    0.032 (bending about the inner face) to 0.0016 (measured: about the mid-plane), and the
    signal per newton on the wrapped, prestressed strap is within 10 % of the linear worn
    model's (measured 3.1 % above)."""
    from designlab.sensors.strap import virtual as st
    from designlab.sensors.strap import model as strap_model
    from designlab.sensors.protocols import StrapLoadTest

    w = sp.wrap_equilibrium(steps=1, protocol=StrapLoadTest(normal_N=0.05), edge_length=3.0)
    assert w["wrap_residuals"][-1] <= 1e-9
    for m, e in zip(w["gauge_stretch_map"], w["gauge_stretch_wrapped"]):
        assert 0.02 < m < 0.05 and abs(e) < 0.2 * m
    s = st.StrapModelSettings(finger_model="solid", edge_length=3.0, mesh_convergence=False)
    from designlab.geometry.strap import ArchStrap
    from designlab.fem.static import solve_static
    from designlab.sensors.strap.model import elastic_materials

    part = ArchStrap()
    model, gauges, _ = strap_model.build_model(part, strap_model.mesh_strap(part, s), s, elastic_materials(part))
    res = solve_static(model)
    u = res.U[:, res.system.case_index("F_n")]
    lin = sum(float(gauges[c].strain(u)) for c in st.CHANNELS)
    assert w["signal_at_peak"][2] / 0.05 == pytest.approx(lin, rel=0.1)
