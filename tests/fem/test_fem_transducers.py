"""Virtual transducers and result output."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.materials import get_material
from designlab.fem.output import write_png, write_result_vtu
from designlab.fem.prony import Prony
from designlab.fem.transducers import (ForceButton, ReactionWrench, RigidPose, StrainGauge,
                                       divider_voltage)
from designlab.fem.history import History
from designlab.fem.viscoelastic import solve_history
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh


def two_region_block() -> TetMesh:
    """Box whose upper half (z > 1) is the conductive trace region."""
    m = box_tet_mesh(4.0, 2.0, 2.0, 4, 2, 2).quadratic()
    zc = m.points[m.cells[:, :4]].mean(1)[:, 2]
    region = (zc > 1.0).astype(np.int64)
    return TetMesh(m.points, m.cells, region, {0: "strap", 1: "trace"},
                   {"strap": "NinjaFlex", "trace": "PI-ETPU"}, m.facet_sets)


def uniform_strain_model(A: np.ndarray) -> Model:
    mesh = two_region_block()
    model = Model(mesh)
    for s in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        model.prescribe(s, displacement=lambda x: x @ A.T, case="field")
    return model


def test_strain_gauge_uniform_field_is_exact():
    A = np.array([[0.01, 0.002, 0.0], [0.002, -0.004, 0.001], [0.0, 0.001, -0.003]])
    model = uniform_strain_model(A)
    res = solve_static(model)
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    eps_d = d @ (0.5 * (A + A.T)) @ d
    g = StrainGauge(model, "trace", direction=d)
    r = g.read(res)
    GF = get_material("PI-ETPU").gauge_factor
    assert r["strain"][0] == pytest.approx(eps_d, rel=1e-12)
    assert r["dR_R"][0] == pytest.approx(GF * eps_d, rel=1e-12)
    assert r["resistance_ohm"][0] == pytest.approx(1800.0 * (1 + GF * eps_d), rel=1e-12)
    assert r["voltage_V"][0] == pytest.approx(5.0 * r["resistance_ohm"][0]
                                              / (r["resistance_ohm"][0] + 2200.0))
    # a direction field (normalised here) gives the same for a constant field
    g2 = StrainGauge(model, "trace", direction=lambda x: np.broadcast_to([2.0, 2.0, 0.0],
                                                                         x.shape))
    assert g2.strain(res.U)[0] == pytest.approx(eps_d, rel=1e-12)
    # quadratic term and temperature
    g3 = StrainGauge(model, "trace", direction=d, gauge_quadratic=10.0)
    assert g3.dR_R(eps_d, temperature=30.0) == pytest.approx(
        (1 + GF * eps_d + 10 * eps_d**2) * (1 + 0.002 * 10.0) - 1)


def test_divider_voltage_and_gauge_errors():
    assert divider_voltage(1800.0) == pytest.approx(5 * 1800 / 4000)
    assert divider_voltage(1800.0, across="resistor") == pytest.approx(5 * 2200 / 4000)
    with pytest.raises(ParameterError, match="across"):
        divider_voltage(1.0, across="both")
    model = Model(two_region_block())
    with pytest.raises(ParameterError, match="gauge_factor"):
        StrainGauge(model, "strap")            # NinjaFlex is not piezoresistive
    with pytest.raises(ModelError, match="region 'nail' does not exist"):
        StrainGauge(model, "nail")


def test_button_pose_wrench_readings_static_and_history():
    mesh = box_tet_mesh(2.0, 2.0, 4.0, 2, 2, 4).quadratic()
    pr = Prony(g=(0.3,), tau=(1.0,), k=(0.3,), k_tau=(1.0,))
    model = Model(mesh, materials={"block": Material("v", E=12.0, nu=0.4, prony=pr)})
    top = model.rigid("top", "zmax")
    model.fix("zmin")
    model.spring("button", a=top, k=5.0, axis=(0, 0, -1))
    model.force(top, force=(0.0, 0.0, -1.0), case="press")
    res = solve_static(model)
    f = ForceButton("button").read(res)
    pose = RigidPose("top").read(res)
    w = ReactionWrench("zmin").read(res)
    assert f.shape == (1,) and pose.shape == (1, 6) and w.shape == (1, 6)
    assert f[0] == pytest.approx(-5.0 * pose[0, 5])          # compression positive
    assert w[0, 5] + f[0] == pytest.approx(1.0, rel=1e-9)     # base + button carry the load
    hist = History.step_hold(5.0, 25, {"press": 1.0})
    hres = solve_history(model, hist)
    fh = ForceButton("button").read(hres)
    wh = ReactionWrench("zmin").read(hres)
    assert fh[0] == pytest.approx(f[0], rel=1e-9)            # glassy = instantaneous
    np.testing.assert_allclose(wh[:, 5] + fh, 1.0, rtol=1e-9)  # equilibrium at every step
    assert fh[-1] > fh[0]          # the block relaxes, the stiff-ish button takes more load


@pytest.mark.slow
def test_vtu_and_png_written_atomically(tmp_path):
    import meshio

    model = Model(two_region_block())
    model.fix("xmin")
    model.traction("xmax", (0.0, 0.0, -0.05))
    res = solve_static(model)
    p = write_result_vtu(tmp_path / "r.vtu", res)
    m = meshio.read(p)
    assert m.cells[0].type == "tetra10"
    np.testing.assert_allclose(m.point_data["displacement"], res.displacement())
    assert set(m.cell_data) >= {"region", "strain", "stress", "von_mises"}
    png = write_png(tmp_path / "r.png", model.mesh, res.displacement(), title="test")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["r.png", "r.vtu"]


def test_gauge_on_batch_history_and_history_vtu(tmp_path):
    import meshio

    mesh = two_region_block()
    pr = Prony(g=(0.3,), tau=(1.0,), k=(0.3,), k_tau=(1.0,))
    model = Model(mesh, materials={"strap": Material("tpu", E=12.0, nu=0.45, prony=pr),
                                   "trace": "PI-ETPU"})
    model.fix("xmin")
    model.traction("xmax", (0.1, 0.0, 0.0), case="pull")
    model.traction("xmax", (0.0, 0.0, 0.02), case="bend")
    t = np.linspace(0.0, 3.0, 7)
    res = solve_history(model, History(t, {"pull": np.ones(7), "bend": np.ones(7)}),
                        batch=True)
    g = StrainGauge(model, "trace", direction=(1.0, 0.0, 0.0))
    r = g.read(res)
    assert r["strain"].shape == (2, 7) and r["voltage_V"].shape == (2, 7)
    assert np.all(np.diff(r["strain"][0]) > 0)           # creep of the strap under tension
    p = write_result_vtu(tmp_path / "h.vtu", res, (0, -1))
    np.testing.assert_allclose(meshio.read(p).point_data["displacement"],
                               res.displacement(-1)[0])
