"""Virtual wrench test of the seed 002 flexure: pose through the true K, wrench back through the
designer's closed form; Table I statistics, K_f in SI, hysteresis only with Prony materials."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from designlab.sensors.flexure import virtual as ft
from designlab.sensors.protocols import FlexureWrenchTest
from designlab.fem.materials import get_material
from designlab.fem.prony import Prony
from designlab.sensors.flexure.spring import (VISIFLEX_CATALOG, stiffness_timoshenko, stiffness_zero_pitch,
                                  to_si)
from designlab.geometry.flexure import SpringFlexure
from designlab.mesh.tetmesh import box_tet_mesh

PART = SpringFlexure()
TIM = ft.FlexureModelSettings(truth="timoshenko")


def test_part_gives_the_catalogue_spring():
    s = ft.helical_spring(PART)
    assert to_si(stiffness_zero_pitch(s)) == pytest.approx(
        to_si(stiffness_zero_pitch(VISIFLEX_CATALOG)), rel=1e-12)
    assert s.active_length == pytest.approx(VISIFLEX_CATALOG.active_length)


def test_closed_form_truth_error_statistics():
    """Timoshenko truth, zero-pitch design: the force estimate along x is scaled by
    k_x(design) / k_x(Timoshenko), so the error on +-f levels has zero mean and a known std."""
    prot = FlexureWrenchTest()
    p = ft.run(PART, prot, TIM)
    r = p.report
    json.dumps(r)
    Kd = stiffness_zero_pitch(ft.helical_spring(PART))
    Kt = stiffness_timoshenko(ft.helical_spring(PART), frame="centre")
    W = prot.wrenches()
    E = W - W @ np.linalg.inv(Kt).T @ Kd.T
    fx = r["wrench_error"]["stats"]["f_x"]
    assert fx["mean"] == pytest.approx(0, abs=1e-12)
    assert fx["std"] == pytest.approx(E[:, 3].std(ddof=1))
    assert r["wrench_error"]["table_I_forces_N"]["x"] == fx
    assert fx["std"] > 0.1                       # the column effect: ~20 % of k_x
    assert r["wrench_error"]["relative_percent_on_axis"]["f_z"] == pytest.approx(0, abs=1e-9)
    assert np.array(r["K_f"]) == pytest.approx(to_si(Kt))
    assert np.array(r["K_f_closed_form"]) == pytest.approx(to_si(Kd))
    assert r["K_f_fem"] is None and r["mesh"] is None and r["K_f_source"] == "timoshenko"
    assert "N*m/rad" in r["K_f_units"]
    assert r["condition_number"] == pytest.approx(np.linalg.cond(to_si(Kt)))
    # a calibration from the (pose, wrench) pairs recovers the true K
    assert np.array(r["calibration_matrix"]) == pytest.approx(to_si(Kt), rel=1e-6)
    sens = r["sensitivity"]["compliance_diagonal"]
    assert sens["v_z per f_z"] == pytest.approx(1 / Kt[5, 5])
    assert sens["w_x per m_x"] == pytest.approx(1 / Kt[0, 0])
    h = r["hysteresis_percent"]
    assert h["overall"] == 0.0 and set(h["by_location"]) == set(ft.WRENCH)
    assert "elastic" in h["note"]


def test_pose_noise_adds_scatter():
    base = ft.run(PART, None, TIM).report["wrench_error"]["stats"]["f_z"]["std"]
    noisy = ft.run(PART, None, dataclasses.replace(TIM, pose_noise_mm=0.02)).report
    assert base == pytest.approx(0, abs=1e-9)
    assert noisy["wrench_error"]["stats"]["f_z"]["std"] == pytest.approx(
        0.02 * stiffness_zero_pitch(ft.helical_spring(PART))[5, 5], rel=0.3)


def test_plots(tmp_path):
    p = ft.run(PART, None, TIM)
    paths = ft.plots(p, None, tmp_path)
    assert [q.name for q in paths] == ["flexure_wrench.png"]
    assert paths[0].stat().st_size > 1000 and len(list(tmp_path.iterdir())) == 1


def _prism():
    return box_tet_mesh(6, 6, 30, 2, 2, 6, origin=(-3, -3, 0), material="ABS").quadratic()


BOX = ft.FlexureModelSettings(truth="fem", base_set="zmin", tip_set="zmax")


def test_fem_truth_on_a_given_mesh_matches_the_6x6_routine():
    """The FEM path (any mesh with base/tip sets) agrees with designlab.sensors.flexure.helix_fem."""
    from designlab.sensors.flexure.helix_fem import stiffness_6x6

    mesh = _prism()
    p = ft.run(PART, FlexureWrenchTest(steps=1), BOX, mesh=mesh)
    ref = stiffness_6x6(mesh, "zmin", "zmax", centre=PART.spring_center)
    K = to_si(ref.K_centre)
    assert np.array(p.report["K_f"]) == pytest.approx(K, rel=1e-6, abs=1e-9 * np.abs(K).max())
    assert p.report["K_f_source"] == "fem" and p.report["mesh"]["cells"] == mesh.n_cells
    assert set(p.report["timings_s"]) == {"mesh", "assemble", "solve", "metrics"}


def test_prony_material_gives_hysteresis():
    abs_v = dataclasses.replace(get_material("ABS"), prony=Prony(g=(0.3,), tau=(2.0,)))
    prot = FlexureWrenchTest(steps=2)
    p = ft.run(PART, prot, dataclasses.replace(BOX, hold_s=2.0, dt_s=0.5),
               materials={"block": abs_v}, mesh=_prism())
    h = p.report["hysteresis_percent"]
    assert h["overall"] > 1.0
    assert all(v > 0.5 for v in h["by_location"].values())
    json.dumps(p.report)
