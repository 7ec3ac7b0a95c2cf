"""Stress and safety factor: von Mises of a known field, relaxed moduli, the safety factor
against each material's documented strength, the warning below 2, and the fields of the VTU."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.fem.materials import MATERIALS, get_material
from designlab.fem.stress import case_stresses, relaxed, stress_report, stress_warnings
from designlab.mesh.tetmesh import box_tet_mesh


def _bar(material: str):
    return box_tet_mesh(10.0, 2.0, 2.0, 5, 2, 2, body="bar", material=material)


def _uniaxial(mesh, eps: float, nu: float) -> np.ndarray:
    x = mesh.points
    return np.c_[eps * x[:, 0], -nu * eps * x[:, 1], -nu * eps * x[:, 2]]


def test_every_material_has_a_strength_with_its_source_or_says_none():
    for m in MATERIALS.values():
        assert m.strength_source, m.name
        if m.strength is not None:
            assert m.strength > 0 and m.strength_basis
    assert get_material("ABS").strength == 26.0


@pytest.mark.parametrize("name", ["steel", "ABS"])
def test_uniaxial_von_mises_and_safety_factor(name):
    """Uniaxial stress sigma = E_inf eps everywhere; safety factor strength / sigma."""
    mat = get_material(name)
    rel = relaxed(mat)
    eps = 1e-3
    mesh = _bar(name)
    cs, = case_stresses(mesh, {"pull": ("pull along x", _uniaxial(mesh, eps, rel.nu))})
    sigma = rel.E * eps
    assert np.allclose(cs.cell, sigma, rtol=1e-9) and np.allclose(cs.node, sigma, rtol=1e-9)
    rep = stress_report(mesh, [cs])
    e = rep["load_cases"]["pull"]["bodies"]["bar"]
    assert e["max_von_mises_MPa"] == pytest.approx(sigma)
    assert e["safety_factor"] == pytest.approx(mat.strength / sigma)
    assert rep["min_safety_factor"] == pytest.approx(mat.strength / sigma)
    if name == "ABS":      # relaxation lowers the modulus by the Prony terms
        assert rel.E < mat.E and rel.E == pytest.approx(mat.E * mat.prony.g_inf, rel=0.05)


def test_warning_below_two_and_none_above():
    mesh = _bar("ABS")
    nu = relaxed(get_material("ABS")).nu
    E = relaxed(get_material("ABS")).E
    low = 26.0 / 1.5 / E           # safety factor 1.5
    high = 26.0 / 3.0 / E          # 3
    for eps, n_warn in ((low, 1), (high, 0)):
        cs = case_stresses(mesh, {"c": ("case", _uniaxial(mesh, eps, nu))})
        w = stress_warnings(stress_report(mesh, cs))
        assert len(w) == n_warn
    assert "safety factor 1.5 < 2" in stress_warnings(stress_report(
        mesh, case_stresses(mesh, {"c": ("case", _uniaxial(mesh, low, nu))})))[0]


def test_material_without_strength_is_said():
    mesh = _bar("PI-ETPU")
    cs = case_stresses(mesh, {"c": ("case", _uniaxial(mesh, 1e-3, 0.45))})
    rep = stress_report(mesh, cs)
    assert rep["load_cases"]["c"]["bodies"]["bar"]["safety_factor"] is None
    assert any("no documented strength" in w for w in stress_warnings(rep))


@pytest.mark.slow
def test_prediction_json_and_vtu_carry_the_stress(tmp_path):
    import json

    import pyvista as pv

    from designlab.predict.record import write_prediction
    from designlab.predict.run import predict

    pred = predict("fingertip", {}, settings={"edge_length": 4.0, "mesh_convergence": False})
    write_prediction(pred, tmp_path / "p")
    doc = json.loads((tmp_path / "p" / "prediction.json").read_text())
    st = doc["stress"]
    # every load point of the protocol at every rotation, both printed bodies
    n = len(pred.protocol.g1_locations + pred.protocol.g2_locations)
    assert len(st["load_cases"]) == n * len(pred.settings.rotations_deg)
    for case in st["load_cases"].values():
        assert set(case["bodies"]) == {"base", "cap"}
    assert st["critical"]["safety_factor"] == st["min_safety_factor"] > 0
    grid = pv.read(tmp_path / "p" / "deformed.vtu")
    vm = [k for k in grid.point_data if k.startswith("von Mises")]
    assert len(vm) == n                                # rotation 0 in the VTU
    assert list(grid.field_data["region_names"]) == ["base", "cap"]
