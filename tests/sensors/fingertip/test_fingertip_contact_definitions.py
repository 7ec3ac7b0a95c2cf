"""The candidate explanations of the unmet seed 001 goals: the readings of the paper's
compressed-sensor change, the Table II dome and height datum, the bolt head's seat (closed-form
and lumped checks, fast)."""

import math
import warnings

import numpy as np
import pytest

from designlab.geometry.fingertip import TABLE_II_HEIGHTS, CantileverFingertip
from designlab.sensors.fingertip.model import FSS015_V_PER_N, wrench_at_ball
from designlab.sensors.fingertip.contact import lumped_condensed, run_contact_test
from designlab.sensors.fingertip.joint import bolt_head_joint, moment_sensitivity
from designlab.sensors.fingertip.paper_readings import (CHANGE_DEFINITIONS, PAPER,
                                                       compressed_changes)
from designlab.sensors.fingertip.paper import (GOAL_CHANGE_POINTS, paper_comparison, table_ii_dome)
from designlab.sensors.fingertip.model import ContactSettings
from designlab.sensors.protocols import HangingWeightTest


def _runs(spans_first, spans_last, rots=(0.0, 60.0)):
    """Synthetic runs: sensor force spans (N) at the heaviest weight (step 1) over a zero start."""
    runs, S = [], []
    for rot in rots:
        for name, sp in (("h9", spans_first), ("h1", spans_last)):
            runs.append(("G1", name, rot, None, None))
            S.append(np.array([[0.0, 0.0, 0.0], sp]) * FSS015_V_PER_N)
    return runs, np.array(S)


def test_compressed_change_definitions_closed_form():
    runs, S = _runs([0.8, -0.2, 0.1], [2.0, -0.5, 0.3])
    d = compressed_changes(runs, S, 1, "h9", "h1", applied_N=2.0)
    assert set(d) == set(CHANGE_DEFINITIONS)
    assert d["relative_to_first_span"] == pytest.approx(150.0, rel=1e-12)     # 1.2 / 0.8
    assert d["relative_to_last_span"] == pytest.approx(60.0, rel=1e-12)       # 1.2 / 2.0
    assert d["percent_of_applied_force"] == pytest.approx(60.0, rel=1e-12)    # 1.2 N / 2 N
    # the sensor is the one most compressed at the last location, not at the first
    runs, S = _runs([0.9, 0.5, 0.0], [0.4, 1.0, 0.0])
    d = compressed_changes(runs, S, 1, "h9", "h1", applied_N=1.0)
    assert d["relative_to_first_span"] == pytest.approx(100.0, rel=1e-12)     # sensor 2
    assert d["percent_of_applied_force"] == pytest.approx(50.0, rel=1e-12)


def test_frictionless_linear_changes_follow_the_linear_readings():
    """Zero friction, no Hertz: the contact model is the linear one, so each definition follows
    from the linear sensor forces per unit wrench at h9 and h1 (independent arithmetic)."""
    part = CantileverFingertip.tested()
    cf = lumped_condensed(part, bolt_axial=2.0e4, bolt_lateral=2.0e3, bolt_rotational=3.0e4)
    s = ContactSettings(friction_coefficient=0.0, hertz=False, repeatability_percent_fs=0.0)
    proto = HangingWeightTest()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = run_contact_test(part, proto, s, cf, rotations_deg=(0.0,))
    d = rep["paper_comparison"]["compressed_change_G1_definitions"]
    applied = proto.loads_N.max() - proto.loads_N[0]
    pts = part.load_points(0.0)
    f9, f1 = (wrench_at_ball(*pts[n]) @ cf.linear_unit for n in ("h9", "h1"))
    k = int(np.argmax(f1))
    assert d["relative_to_first_span"] == pytest.approx(100 * (f1[k] - f9[k]) / f9[k], rel=1e-6)
    assert d["relative_to_last_span"] == pytest.approx(100 * (f1[k] - f9[k]) / f1[k], rel=1e-6)
    # spans are load x unit reading: the change per N of applied force is f1 - f9
    assert d["percent_of_applied_force"] == pytest.approx(100 * (f1[k] - f9[k]), rel=1e-6)
    assert applied == pytest.approx(2.2759, rel=1e-4)
    assert rep["paper_comparison"]["compressed_change_G1_pct"] == d["relative_to_first_span"]


def test_paper_comparison_reports_the_change_in_every_definition():
    part = CantileverFingertip.tested()
    cf = lumped_condensed(part)
    s = ContactSettings()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = run_contact_test(part, HangingWeightTest(), s, cf, rotations_deg=(0.0, 60.0))
        pc = paper_comparison(part, HangingWeightTest(), s, cf, rep, rotations_deg=(0.0, 60.0))
    g = pc["goals"]["compressed_change_h9_to_h1"]
    assert set(g["by_definition"]) == set(CHANGE_DEFINITIONS)
    assert g["by_definition"]["relative_to_first_span"]["value_pct"] == pytest.approx(
        g["value_pct"], rel=1e-3)
    for v in g["by_definition"].values():
        assert v["met"] == (abs(v["value_pct"] - PAPER["compressed_change_h9_to_h1_pct"])
                            <= GOAL_CHANGE_POINTS)
    r = pc["compressed_change_r1_to_r5"]
    assert set(r["by_definition"]) == set(CHANGE_DEFINITIONS)
    assert r["by_definition"]["relative_to_first_span"] == pytest.approx(r["value_pct"], rel=1e-3)
    assert any("percentage of the applied force" in t
               for t in pc["matches"] + pc["does_not_match"])
    # the diagnosis beside the goal: the moment sensitivity against the paper's implied one
    ms = moment_sensitivity(part, cf, s)
    m = g["moment_sensitivity"]
    assert m["rho_per_mm_fem"]["frictionless"] == ms["frictionless"]["fem"]["rho_per_mm"]
    assert m["rho_per_mm_paper"] == pytest.approx(0.0307, abs=1e-4)
    said = [t for t in pc["matches"] + pc["does_not_match"]
            if t.startswith("compressed-sensor change h9 -> h1")]
    assert len(said) == 1
    # the lumped stand-in sends no moment to frictionless sensors: no restraint needed, none said
    assert m["rho_per_mm_fem"]["frictionless"] < m["rho_per_mm_paper"]
    assert m["rotational_restraint_for_paper_N_mm_per_rad"] == 0.0
    assert "moment sensitivity" not in said[0]


def test_table_ii_points_lie_on_one_dome_centred_at_h5():
    d = table_ii_dome(CantileverFingertip.tested())
    assert d["radius_spread_mm"] < 0.1                 # four pairs on one sphere
    assert 6.2 < d["R_mm"] < 6.5
    assert abs(d["z0_mm"] - TABLE_II_HEIGHTS[4]) < 0.1  # its centre is h5: h5..h9 the straight part
    assert d["pole_mm"] == pytest.approx(d["z0_mm"] + d["R_mm"])
    # on the tested design's base (11 mm below the ball centre) the datum is ~14.4 mm up
    assert d["below_ball_centre_mm"] == pytest.approx(11.0)
    assert d["datum_above_ball_centre_mm"] == pytest.approx(48.5 - 11.0 - d["pole_mm"])
    assert 14.2 < d["datum_above_ball_centre_mm"] < 14.6
    # the other pairing (h_i with r_(6-i)) is no sphere
    from designlab.geometry.fingertip import TABLE_II_RADII
    h, r = np.array(TABLE_II_HEIGHTS[:4]), np.array(TABLE_II_RADII[1:][::-1])
    A = np.c_[2 * h, np.ones(4)]
    z0, c = np.linalg.lstsq(A, r ** 2 + h ** 2, rcond=None)[0]
    assert np.ptp(np.sqrt(r ** 2 + (h - z0) ** 2)) > 10 * d["radius_spread_mm"]


def test_bolt_head_joint_limits():
    part = CantileverFingertip.tested()
    bj = bolt_head_joint(part)
    hand = moment_sensitivity(part, lumped_condensed(part))["frictionless"]["hand"]
    # bonded head = moment_sensitivity's hand estimate (bolt clamped under its head)
    assert bj["bonded"]["per_N"] == pytest.approx(hand["per_N"], rel=1e-3)
    assert bj["bonded"]["per_Nmm"] == pytest.approx(hand["per_Nmm"], rel=1e-3)
    # pinned head carries no moment: the load's moment is a couple between the sensors at the
    # ball centre and the head, d = |cap bottom| below it: rho = 1 / d; all lateral force goes
    # to the sensors (the compressed one, 30 deg off the load line: cos30 / (1.5 cos45))
    d = -part.cap_z[0]
    assert bj["pinned"]["rho_per_mm"] == pytest.approx(1.0 / d, rel=1e-6)
    assert bj["pinned"]["per_N"] == pytest.approx(math.cos(math.radians(30))
                                                  / (1.5 * math.cos(math.radians(45))), rel=1e-6)
    # sliding head: the moment goes down the bolt, none reaches the sensors
    assert abs(bj["sliding"]["per_Nmm"]) < 1e-9
    assert abs(bj["sliding"]["relative_to_first_span_pct"]) < 1e-6
    # demand: friction needed = shear / preload; lift-off moment of the annulus T (a^2+b^2)/(4a)
    a, b = part.head_diameter / 2, part.bolt_diameter / 2
    assert bj["head_lift_moment_N_mm"] == pytest.approx(20.0 * (a * a + b * b) / (4 * a))
    for dm in bj["demand"].values():
        assert dm["friction_needed_to_stay"] == pytest.approx(dm["head_shear_N"] / 20.0)
        assert dm["lifts_on_one_side"] == (dm["head_moment_N_mm"] > bj["head_lift_moment_N_mm"])
    assert bj["demand"]["h1"]["head_shear_N"] > bj["demand"]["h9"]["head_shear_N"]
