"""Virtual wrench test of the seed 002 flexure: pose through the true K, wrench back through the
designer's closed form; Table I statistics, K_f in SI, hysteresis only with Prony materials."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from designlab.sensors.flexure import model as flexure_model
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
    s = flexure_model.helical_spring(PART)
    assert to_si(stiffness_zero_pitch(s)) == pytest.approx(
        to_si(stiffness_zero_pitch(VISIFLEX_CATALOG)), rel=1e-12)
    assert s.active_length == pytest.approx(VISIFLEX_CATALOG.active_length)


@pytest.mark.slow
def test_default_truth_is_the_chain_of_the_spring_as_built():
    """`predict flexure` (SpringFlexure defaults) and `designlab flexure` (catalogue preset)
    use the same spring as built: the chain's 6x6 at the 10 N working load, at the spring
    centre; the chain's seat-to-seat length is the part's (an independent number: the CAD)."""
    import time

    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import ChainSettings

    assert ft.FlexureModelSettings().truth == "chain"
    s = flexure_model.spring_as_built(PART)
    assert (s.wire_radius, s.coils, s.inactive_coils) == (VISIFLEX_CATALOG.wire_radius,
                                                           VISIFLEX_CATALOG.coils,
                                                           VISIFLEX_CATALOG.inactive_coils)
    t0 = time.perf_counter()
    p = ft.run(PART)
    assert time.perf_counter() - t0 < 3.0              # ~0.5 s on an idle core; CI slack
    ref = chain_stiffness(VISIFLEX_CATALOG, ChainSettings(working_load_N=10.0))
    assert np.array(p.report["K_f"]) == pytest.approx(ref.K_loaded_centre_si, rel=1e-9)
    assert np.array(p.report["K_f_chain"]) == pytest.approx(ref.K_centre_si, rel=1e-9)
    assert p.report["chain"]["length_mm"] == pytest.approx(PART.length, abs=1e-3)
    assert p.report["K_f_source"] == "chain" and p.report["mesh"] is None
    # the chain is not the Timoshenko column: the ground ends and contact move the lateral term
    Kt = to_si(stiffness_timoshenko(flexure_model.helical_spring(PART)))
    assert abs(p.report["K_f"][3][3] / Kt[3, 3] - 1) > 0.2
    # unloaded: the chain's first state
    p0 = ft.run(PART, None, ft.FlexureModelSettings(working_load_N=0.0))
    assert np.array(p0.report["K_f"]) == pytest.approx(ref.K_centre_si, rel=1e-9)
    assert p0.report["K_f_chain_loaded"] is None
    # seated (not bonded) ground faces press on the discs at 10 N: ABS (2.2 GPa) seats are
    # softer than PLA (3.5 GPa) ones; bonded faces leave no seat contact to soften
    seated = ft.FlexureModelSettings(seat="contact")
    k_pla = ft.run(PART, None, seated).report["K_f"][5][5]
    k_abs = ft.run(dataclasses.replace(PART, disc_material="ABS"), None, seated).report["K_f"][5][5]
    assert k_abs < k_pla < p.report["K_f"][5][5]


def test_chain_truth_of_plain_ends_and_bad_designs():
    """Plain ends: no dead turn, no contact; a pitch whose coils touch at the working load is a
    one-line error naming pitch_angle."""
    from designlab.errors import ParameterError

    plain = SpringFlexure(ends="plain", active_coils=3.0)
    s = flexure_model.spring_as_built(plain)
    assert s.inactive_coils == 0 and s.coils == 3.0
    p = ft.run(plain)
    assert p.report["chain"]["contacts"] == 0 and p.report["K_f_chain_loaded"] is None
    tight = SpringFlexure(pitch_angle=0.035)    # pitch 3.05 mm: 1.02 mm gaps, 1.46 mm per turn at 10 N
    with pytest.raises(ParameterError, match="pitch_angle") as exc:
        ft.run(tight)
    assert "\n" not in str(exc.value)


def test_closed_form_truth_error_statistics():
    """Timoshenko truth, zero-pitch design: the force estimate along x is scaled by
    k_x(design) / k_x(Timoshenko), so the error on +-f levels has zero mean and a known std."""
    prot = FlexureWrenchTest()
    p = ft.run(PART, prot, TIM)
    r = p.report
    json.dumps(r)
    Kd = stiffness_zero_pitch(flexure_model.helical_spring(PART))
    Kt = stiffness_timoshenko(flexure_model.helical_spring(PART), frame="centre")
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
        0.02 * stiffness_zero_pitch(flexure_model.helical_spring(PART))[5, 5], rel=0.3)


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
    assert set(p.report["timings_s"]) == {"mesh", "assemble", "solve", "metrics", "wire_stress"}


def test_prony_material_gives_hysteresis():
    abs_v = dataclasses.replace(get_material("ABS"), prony=Prony(g=(0.3,), tau=(2.0,)))
    prot = FlexureWrenchTest(steps=2)
    p = ft.run(PART, prot, dataclasses.replace(BOX, hold_s=2.0, dt_s=0.5),
               materials={"block": abs_v}, mesh=_prism())
    h = p.report["hysteresis_percent"]
    assert h["overall"] > 1.0
    assert all(v > 0.5 for v in h["by_location"].values())
    json.dumps(p.report)


def test_a_face_set_the_part_does_not_have_is_refused():
    """base_set/tip_set are read by the FEM truth only: set with another truth they ran
    silently unused."""
    from designlab.errors import ParameterError
    from designlab.sensors.flexure.model import FlexureModelSettings

    for name in ("base_set", "tip_set"):
        with pytest.raises(ParameterError, match=f"{name}='nonexistent' is not allowed: "
                                                 "'flexure_"):
            FlexureModelSettings(**{name: "nonexistent"})
    assert FlexureModelSettings(truth="fem", base_set="zmin").base_set == "zmin"
