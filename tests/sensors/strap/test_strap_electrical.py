"""Strap electrical design from geometry, prestrain from the slots, personalised strap (fast)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.materials import (MeasuredProperty, get_material, stand_in_note,
                                     with_measured)
from designlab.fem.transducers import (divider_slope, johnson_noise_vrms,
                                       optimal_divider_resistor, quantization_noise_vrms)
from designlab.geometry.strap import CORNER_SQUARES, ArchStrap
from designlab.sensors.strap import electrical as el
from designlab.sensors.strap import fit as sf
from designlab.sensors.strap import prestrain as strap_prestrain
PAPER = ArchStrap()
ETPU = get_material("PI-ETPU")


def test_paper_geometry_is_1k8_by_construction_and_datasheet_rho_is_megaohms():
    assert el.gauge_resistance(PAPER)["total"] == pytest.approx(1800.0, rel=1e-12)
    rho = el.effective_resistivity()
    assert rho == pytest.approx(1800 * 0.2 / PAPER.trace_squares()["total"])
    rep = el.electrical_report(PAPER, ETPU, 0.06, 0.03)
    assert "2.04 MOhm" in rep["effective_resistivity_note"]
    # with contacts the resistivity drops, the paper's strap still reads 1.8 kOhm
    assert el.gauge_resistance(PAPER, contact_ohm=100)["total"] == pytest.approx(1800.0)
    assert el.effective_resistivity(100) < rho


def test_resistance_follows_rho_L_over_A():
    wide = dataclasses.replace(PAPER, strap_width=20.0)
    double = dataclasses.replace(wide, legs=8)
    r4, r8 = el.gauge_resistance(wide), el.gauge_resistance(double)
    # legs: doubling the legs doubles their resistance exactly; the turns go from 3 to 7
    assert r8["legs"] == pytest.approx(2 * r4["legs"], rel=1e-12)
    turn = r4["turns"] / 3
    assert r8["turns"] == pytest.approx(7 * turn, rel=1e-12)
    assert r8["pads"] == pytest.approx(r4["pads"])
    # R minus pads (and leads) doubles up to the one extra turn block per added pair
    core4 = r4["total"] - r4["pads"] - r4["leads"]
    core8 = r8["total"] - r8["pads"] - r8["leads"]
    assert core8 == pytest.approx(2 * core4 + turn, rel=1e-12)
    # R = rho L / A for the legs: length n x gauge_length, area w t
    rs = el.effective_resistivity() / PAPER.trace_thickness
    assert r4["legs"] == pytest.approx(rs * 4 * PAPER.gauge_length / PAPER.trace_width)
    longer = el.gauge_resistance(dataclasses.replace(PAPER, gauge_length=12.0,
                                                     gauge_offset=9.0))
    assert longer["legs"] == pytest.approx(rs * 4 * 12.0 / 0.8, rel=1e-12)
    wide = el.gauge_resistance(dataclasses.replace(PAPER, trace_width=1.6, lead_length=2.4))
    assert wide["legs"] == pytest.approx(r4["legs"] / 2, rel=1e-12)
    assert PAPER.trace_squares()["turns"] == pytest.approx(
        3 * (2 * CORNER_SQUARES + PAPER.trace_gap / PAPER.trace_width))


def test_divider_optimum_noise_and_self_heating():
    R = 1800.0
    rf = np.linspace(200, 10000, 2000)
    gain = R * divider_slope(R, rf)
    assert rf[np.argmax(gain)] == pytest.approx(optimal_divider_resistor(R), rel=0.01)
    assert johnson_noise_vrms(1000.0, 1.0, 300.0) == pytest.approx(4.07e-9, rel=1e-3)
    assert quantization_noise_vrms(5.0, 16) == pytest.approx(5 / 65536 / math.sqrt(12))
    rep = el.electrical_report(PAPER, ETPU, 0.06, 0.03)
    h = rep["self_heating"]
    assert h["current_mA"] == pytest.approx(1.25)
    assert h["power_mW"] == pytest.approx(1.25e-3 ** 2 * 1800 * 1e3)
    assert 0 < h["temperature_rise_K"] < 5
    assert h["F_x_equivalent_mN"] == 0.0
    assert rep["divider"]["gain_vs_optimum"] == pytest.approx(
        (2200 / 4000 ** 2) / (1800 / 3600 ** 2), rel=1e-9)
    # resolution: noise / sensitivity; half the sensitivity, twice the resolution
    rep2 = el.electrical_report(PAPER, ETPU, 0.03, 0.015)
    assert rep2["resolution_mN"]["F_n"] == pytest.approx(2 * rep["resolution_mN"]["F_n"])
    with pytest.raises(ParameterError, match="contact_ohm"):
        el.effective_resistivity(1000)


def test_trade_off_more_legs_more_resistance_same_strain():
    e = {"Ch1": {"F_n": 0.005, "F_x": 0.003}, "Ch2": {"F_n": 0.005, "F_x": -0.003}}
    wide = dataclasses.replace(PAPER, strap_width=20.0)
    a = el.trade_off(wide, e, ETPU)
    b = el.trade_off(dataclasses.replace(wide, legs=8), e, ETPU)
    assert b["R_ohm"] > 1.9 * a["R_ohm"]
    assert b["power_mW"] < a["power_mW"]               # higher R, less current squared R
    # the divider gain R R_f / (R + R_f)^2 falls once R passes R_f = 2.2 kOhm
    assert b["sum_F_n_V_per_N"] < a["sum_F_n_V_per_N"]


def test_slot_strains_and_prestrain_factors():
    P = 2 * math.pi * 9.0
    eps = [sf.initial_strain(PAPER, P, slot=k) for k in (1, 2, 3)]
    assert eps[0] < eps[1] < eps[2]
    assert eps == pytest.approx([0.0495, 0.1729, 0.3292], abs=2e-4)
    L = sf.wrap_path(PAPER, P)
    assert sf.initial_strain(PAPER, P, length=L) == pytest.approx(0.0)
    s = sf.prestrain_state(PAPER, P, ETPU, 1800.0, 2200.0, slot=2)
    assert s["geometrically_nonlinear_needed"]
    assert not sf.prestrain_state(PAPER, P, ETPU, 1800.0, 2200.0, slot=1)[
        "geometrically_nonlinear_needed"]
    assert 0 < s["electrical_factor"] < 1 and s["mechanical_factor"] > 1
    assert s["R_rest_ohm"] == pytest.approx(1800 * (1 + 3.8 * eps[1]))
    with pytest.raises(ParameterError, match="slot"):
        PAPER.engaged_length(4)


def test_fit_part_hits_the_target_and_bad_input_is_one_line():
    f = sf.Finger(16.0, 14.0, 25.0)
    tgt = sf.default_target()
    part = sf.fit_part(f, tgt)
    assert part.slot_count == 1
    assert sf.initial_strain(part, f.perimeter, slot=1) == pytest.approx(tgt, abs=2e-4)
    three = sf.fit_part(f, tgt, slots=3)
    assert sf.initial_strain(three, f.perimeter, slot=2) == pytest.approx(tgt, abs=2e-4)
    for bad, name in ((lambda: sf.Finger(40.0, 14.0, 25.0), "width"),
                      (lambda: sf.Finger(16.0, 4.0, 25.0), "depth"),
                      (lambda: sf.parse_finger("16,14"), "--finger"),
                      (lambda: sf.check_target(2.5, ETPU), "--target-strain"),
                      (lambda: sf.check_target(0.9, ETPU), "--target-strain"),
                      (lambda: sf.fit_part(f, tgt, slots=2), "--slots")):
        with pytest.raises(ParameterError, match=name) as exc:
            bad()
        assert "\n" not in str(exc.value) and "allowed" in str(exc.value)


def test_size_table_slots_vs_personalised():
    t = sf.size_table(np.arange(40.0, 75.0, 5.0), ETPU, 1800.0, 2200.0, 0.06,
                      sf.default_target(), measurement_sd_mm=0.5)
    assert t["slots_strain_cv_percent"] > 30
    assert t["personalised_sum_sensitivity_cv_percent"] < 1e-6
    # one spread definition: cv = population std / mean
    eps = [r["best_slot_strain"] for r in t["rows"]]
    assert t["slots_strain_cv_percent"] == pytest.approx(100 * np.std(eps) / np.mean(eps))
    assert "standard deviation / mean" in t["spread_definition"]
    # the personalised spread is the measurement's: 4x smaller sd, 4x smaller spread
    t2 = sf.size_table(np.arange(40.0, 75.0, 5.0), ETPU, 1800.0, 2200.0, 0.06,
                       sf.default_target(), measurement_sd_mm=0.125)
    assert t2["personalised_strain_cv_percent"] == pytest.approx(
        t["personalised_strain_cv_percent"] / 4)
    # 0.5 mm caliper sd misses the 10 % goal; the required sd just meets it
    assert t["measurement_sd_mm"] == 0.5 and not t["goal_met"] and t2["goal_met"]
    need = t["required_measurement_sd_mm_for_goal"]
    t3 = sf.size_table(np.arange(40.0, 75.0, 5.0), ETPU, 1800.0, 2200.0, 0.06,
                       sf.default_target(), measurement_sd_mm=need)
    assert t3["personalised_strain_cv_percent"] == pytest.approx(sf.GOAL_CV_PERCENT)
    with pytest.raises(ParameterError, match="measurement_sd_mm"):
        sf.size_table([50.0], ETPU, 1800.0, 2200.0, 0.06, 0.17, measurement_sd_mm=0)


def test_slot_table_uses_the_same_cv():
    t = strap_prestrain.slot_table(PAPER, 2 * math.pi * 9.0, ETPU, 1800.0, 2200.0, 0.05, 0.03)
    S = [r["sum_F_n_V_per_N"] for r in t["slots"]]
    assert t["sum_sensitivity_cv_percent"] == pytest.approx(100 * np.std(S) / np.mean(S))
    assert t["spread_definition"].startswith(sf.SPREAD_DEFINITION)
    # the ring-stiffening estimate removes most of the softening that offsets the divider's
    # loss of gain: the slots' spread grows (14 % -> 25 % on the 9 mm finger)
    assert t["sum_sensitivity_cv_percent"] == pytest.approx(13.8, abs=0.1)
    assert t["sum_sensitivity_cv_percent_with_ring_stiffening_estimate"] == pytest.approx(
        25.3, abs=0.1)


def test_target_bounds_are_zero_and_the_slots_largest_strain():
    for bad in (0.0, -0.1):
        with pytest.raises(ParameterError, match="--target-strain") as exc:
            sf.check_target(bad, ETPU)
        assert "0 < value" in str(exc.value)
    sf.check_target(0.01, ETPU)                     # small but tight: allowed


def test_stress_stiffening_estimate_is_reported_not_applied():
    P = 2 * math.pi * 9.0
    rows = [sf.prestrain_state(PAPER, P, ETPU, 1800.0, 2200.0, slot=k)["stress_stiffening"]
            for k in (1, 2, 3)]
    r2 = rows[1]
    eps0 = sf.initial_strain(PAPER, P, slot=2)
    lam = 1 + eps0
    sigma0 = ETPU.E * (lam - lam ** -2) / 3
    Et = ETPU.E * sf.neo_hooke(eps0)["tangent_over_E"]
    assert r2["ring_geometric_over_material"] == pytest.approx(sigma0 / Et)
    assert r2["membrane_tension_N"] == pytest.approx(sigma0 * PAPER.strap_width
                                                     * PAPER.thickness)
    assert r2["factor_with_ring_stiffening_estimate"] == pytest.approx(
        r2["softening_factor_in_use"] / (1 + sigma0 / Et))
    assert not r2["applied"]
    ratios = [r["ring_geometric_over_material"] for r in rows]
    assert ratios == sorted(ratios) and ratios[0] > 0


def test_scan_gives_width_depth_and_rejects_open_surfaces(tmp_path):
    import trimesh

    cap = trimesh.creation.capsule(height=20.0, radius=8.0, count=[48, 48])
    cap.apply_scale([1.0, 14.0 / 16.0, 1.0])         # elliptic section 16 x 14 mm
    p = tmp_path / "finger.stl"
    cap.export(p)
    f = sf.finger_from_scan(p)
    assert f.width == pytest.approx(16.0, abs=0.3) and f.depth == pytest.approx(14.0, abs=0.3)
    # the cut's own perimeter is used (an elliptic section: the ellipse's, within 1 %)
    assert f.section_perimeter == pytest.approx(f.ellipse_perimeter, rel=0.01)
    assert f.perimeter == f.section_perimeter and "scan" in f.perimeter_source
    # a squarer section: same extents, a longer band than the ellipse
    box = trimesh.creation.box(extents=[16.0, 14.0, 40.0]).subdivide().subdivide()
    b = tmp_path / "box.stl"
    box.export(b)
    fb = sf.finger_from_scan(b)
    assert fb.section_perimeter == pytest.approx(2 * (16 + 14), rel=1e-6)
    assert fb.perimeter > 1.2 * fb.ellipse_perimeter
    with pytest.raises(ParameterError, match="section_perimeter"):
        sf.Finger(16.0, 14.0, 25.0, section_perimeter=80.0)
    open_ = cap.copy()
    open_.update_faces(np.arange(len(open_.faces)) > 10)
    q = tmp_path / "open.stl"
    open_.export(q)
    with pytest.raises(ParameterError, match="closed"):
        sf.finger_from_scan(q)


def test_printed_part_relaxation_is_a_labelled_stand_in():
    for name in ("ABS", "PLA"):
        assert get_material(name).stand_ins == ("prony",)
        assert "prony is a stand-in" in stand_in_note(get_material(name))


def test_resistance_relaxation_is_stored_only_and_the_example_file_loads():
    curve = {"t_s": [0.0, 1.0, 10.0], "R_over_R0": [1.0, 0.98, 0.95], "strain": 0.1}
    rec = MeasuredProperty("PI-ETPU", "resistance_relaxation", curve, "strip, step hold",
                           "2025-01-15")
    m = with_measured(ETPU, [rec])
    assert m == ETPU and m.stand_ins == ETPU.stand_ins          # no field changes
    assert "resistance_relaxation: strip, step hold" in m.source
    bad = MeasuredProperty("PI-ETPU", "resistance_relaxation", {"t_s": [1.0, 0.5],
                                                                "R_over_R0": [1.0, 0.9]},
                           "x", "2025-01-15")
    with pytest.raises(ParameterError, match="resistance_relaxation"):
        with_measured(ETPU, [bad])
    from pathlib import Path

    from designlab.fem.materials import load_measured

    recs = load_measured(Path(__file__).parents[3] / "examples"
                         / "measured_materials_silicone.json")
    sil = with_measured(get_material("silicone"), recs)
    assert {r.quantity for r in recs} == {"E", "prony", "gauge_factor"}
    assert sil.E == get_material("silicone").E and "measured:" in sil.source


def test_measured_printed_data_replaces_a_stand_in():
    assert "gauge_factor" in stand_in_note(ETPU)
    rec = MeasuredProperty("PI-ETPU", "gauge_factor", 5.0, "strip test, 3 specimens",
                           "2025-01-15")
    m = with_measured(ETPU, [rec])
    assert m.gauge_factor == 5.0 and m.stand_ins == ("prony",)
    assert "strip test" in m.source
    with pytest.raises(ParameterError, match="date"):
        MeasuredProperty("PI-ETPU", "gauge_factor", 5.0, "x", "yesterday")
    with pytest.raises(ParameterError, match="quantity"):
        MeasuredProperty("PI-ETPU", "colour", 5.0, "x", "2025-01-15")


def test_cli_bad_finger_exits_2_and_writes_nothing(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "designlab.cli", "fit-strap", "--finger",
                        "60,14,25", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "width=60.0 is not allowed" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_bad_measured_file_exits_2_and_writes_nothing(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "o"
    bad = tmp_path / "m.json"
    bad.write_text('{"measured": [{"material": "PI-ETPU", "quantity": "colour", "value": 1, '
                   '"source": "x", "date": "2025-01-15"}]}')
    for f in (bad, tmp_path / "missing.json"):
        r = subprocess.run([sys.executable, "-m", "designlab.cli", "fit-strap", "--finger",
                            "16,14,25", "--measured", str(f), "--out", str(out)],
                           capture_output=True, text=True)
        assert r.returncode == 2, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
        assert not out.exists()


@pytest.mark.slow
def test_fit_strap_from_a_scan_under_2_minutes_cpu(tmp_path):
    """Goal: fit-strap from a scan STL in under 2 minutes. CPU time of this process (all its
    threads), so a loaded machine does not fail it; the figure is in docs/strap.md."""
    import json
    import time

    import trimesh

    cap = trimesh.creation.capsule(height=20.0, radius=8.0, count=[48, 48])
    cap.apply_scale([1.0, 14.0 / 16.0, 1.0])
    scan = tmp_path / "finger.stl"
    cap.export(scan)
    c0, w0 = time.process_time(), time.perf_counter()
    res = sf.fit_strap(sf.finger_from_scan(scan), tmp_path / "o")
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    print(f"fit-strap from a scan: {cpu:.1f} s CPU, {wall:.1f} s wall")
    assert cpu < 120
    data = json.loads((tmp_path / "o" / "fit.json").read_text())
    assert "scan" in data["finger_mm"]["perimeter_source"]
    assert data["finger_mm"]["perimeter"] == pytest.approx(
        data["finger_mm"]["section_perimeter"])
    assert res["prestrain"]["initial_strain"] == pytest.approx(sf.default_target(), abs=2e-4)


@pytest.mark.slow
def test_fit_strap_writes_3mf_and_fit_json_under_60_s(tmp_path):
    """Goal: fit-strap from measurements in under 60 s (CPU time of this process, as the scan
    test). With a measured gauge factor (--measured): the stand-in label goes, the record is
    in fit.json."""
    import json
    import time

    rec = MeasuredProperty("PI-ETPU", "gauge_factor", 5.0, "test record: strip, 3 specimens",
                           "2025-01-15")
    c0 = time.process_time()
    res = sf.fit_strap(sf.Finger(16.0, 14.0, 25.0), tmp_path, measured=[rec])
    assert time.process_time() - c0 < 60
    assert res["prestrain"]["initial_strain"] == pytest.approx(sf.default_target(), abs=2e-4)
    assert (tmp_path / "strap" / "strap.3mf").stat().st_size > 1000
    data = json.loads((tmp_path / "fit.json").read_text())
    assert data["resolution_mN"]["F_n"] > 0
    assert not any("gauge_factor" in n for n in data["material_stand_ins"])
    assert data["measured_materials"][0]["value"] == 5.0
    assert "ellipse" in data["finger_mm"]["perimeter_source"]
    assert data["size_table"]["goal_met"] is False


def test_personalised_spread_from_the_cited_measurement_errors():
    """The personalised strap's strain cv from the cited caliper %TEM range and the cited
    scan error (designlab/data/finger_measurement_error.json), both reported; the headline
    is the caliper at the upper end of its range."""
    P = np.arange(40.0, 75.0, 5.0)
    target = sf.default_target()
    src = sf.measurement_errors()
    assert src["caliper"]["rel_tem_percent"] == [2.25, 4.90]
    assert "10.1038/s41598-020-68457-6" in src["scan"]["source"]
    sp = sf.personalised_spread(P, target)
    inp = sp["inputs"]
    lo, hi = inp["caliper_tem_2.25_percent"], inp["caliper_tem_4.9_percent"]
    # the strain sd is linear in the relative caliper error
    assert hi["strain_cv_percent"] == pytest.approx(lo["strain_cv_percent"] * 4.90 / 2.25)
    # by hand on the largest finger: sd_P = r P / sqrt(2), sd_eps = sd_P (1 + t) / path
    path = sf.wrap_path(PAPER, 70.0)
    assert hi["strain_cv_percent"] == pytest.approx(
        100 * 0.049 * 70 / math.sqrt(2) * (1 + target) / path / target)
    # the scan: sd = MAE sqrt(pi / 2) on the perimeter itself; the smallest finger is worst
    sc = inp["scan_circumference_abs_error_0.58_mm"]
    assert sc["strain_cv_percent"] == pytest.approx(
        100 * 0.58 * math.sqrt(math.pi / 2) * (1 + target) / sf.wrap_path(PAPER, 40.0) / target)
    assert sc["strain_cv_percent_per_perimeter"][0] == sc["strain_cv_percent"]
    # what the cited numbers give against the 10 % goal (not tuned)
    assert lo["goal_met"] and not hi["goal_met"] and sc["goal_met"]
    assert inp["scan_mean_abs_error_0.3_mm"]["strain_cv_percent"] < sc["strain_cv_percent"]
    r = sp["caliper_relative_sd_percent_for_goal"]
    assert 2.25 < r < 4.90
    assert hi["strain_cv_percent"] * r / 4.90 == pytest.approx(sf.GOAL_CV_PERCENT)
    t = sf.size_table(P, ETPU, 1800.0, 2200.0, 0.06, target)
    assert t["measurement_sd_cited"] and not t["goal_met"]
    assert t["personalised_strain_cv_percent"] == pytest.approx(hi["strain_cv_percent"])
    assert t["measurement_sd_mm"] == pytest.approx(0.049 * 70 / math.pi)
    assert t["measurement_spread"]["inputs"] == inp
    # the caliper sd that meets the goal, on the headline's (largest) finger: r_goal x breadth
    assert t["required_measurement_sd_mm_for_goal"] == pytest.approx(r / 100 * 70 / math.pi)


def test_this_fingers_spread_follows_how_it_was_measured():
    target = sf.default_target()
    cal = sf.finger_spread(sf.Finger(16.0, 16.0, 25.0), target)
    assert cal["input"] == "caliper"
    # a circle: the ellipse gradient gives the circle's r P / sqrt(2)
    P = cal["perimeter_mm"]
    assert P == pytest.approx(16 * math.pi)
    assert cal["strain_cv_percent"]["caliper_tem_4.9_percent"] == pytest.approx(
        100 * sf.strain_sd(P, target, 0.049 * P / math.sqrt(2)) / target, rel=1e-6)
    assert not cal["goal_met"]["caliper_tem_4.9_percent"]
    e = sf.Finger(16.0, 14.0, 25.0).ellipse_perimeter
    scan = sf.finger_spread(sf.Finger(16.0, 14.0, 25.0, section_perimeter=round(e, 3)),
                            target)
    assert scan["input"] == "scan" and all(scan["goal_met"].values())
    assert scan["strain_cv_percent"]["scan_circumference_abs_error_0.58_mm"] == pytest.approx(
        100 * sf.strain_sd(round(e, 3), target, 0.58 * math.sqrt(math.pi / 2)) / target)


def test_pulp_compliance_lowers_the_worn_strain_by_its_closed_form():
    """The band's tension compresses a confined pulp layer (M = E (1 - nu) / ((1 + nu)
    (1 - 2 nu))): the equilibrium strain satisfies the wrap equation with the shrunken skin
    perimeter; a stiff pulp gives the rigid finger's strain; the estimate is reported."""
    P = 2 * math.pi * 9.0
    assert sf.confined_modulus(1.0, 0.49) == pytest.approx(0.51 / (1.49 * 0.02))
    r = sf.compliant_initial_strain(PAPER, P, ETPU, slot=2, pulp_E=0.06)
    e = r["initial_strain"]
    lam = 1 + e
    sigma = ETPU.E * (lam - lam ** -2) / 3
    R = P / (2 * math.pi) + PAPER.thickness / 2
    dr = sigma * PAPER.thickness * 3.0 / (R * sf.confined_modulus(0.06, 0.49))
    assert r["pulp_compression_mm"] == pytest.approx(dr, rel=1e-9)
    assert sf.wrap_path(PAPER, P - 2 * math.pi * dr) / PAPER.engaged_length(2) - 1 == \
        pytest.approx(e, abs=1e-12)
    assert 0 < e < r["rigid_finger_strain"] == pytest.approx(sf.initial_strain(PAPER, P, 2))
    stiff = sf.compliant_initial_strain(PAPER, P, ETPU, slot=2, pulp_E=1e6)
    assert stiff["initial_strain"] == pytest.approx(stiff["rigid_finger_strain"], abs=1e-6)
    c = sf.pulp_compliance(np.arange(40.0, 75.0, 5.0), sf.default_target(), ETPU, 1800.0,
                           2200.0, moduli=(0.02, 0.06, 0.3, 1e6))
    cv = [b["personalised_strain_cv_percent"] for b in c["by_modulus"]]
    assert cv[0] > cv[1] > cv[2] > cv[3] and cv[3] < 1e-3
    # a stiff pulp gives back the rigid finger's slot spread (slot_table)
    rigid = strap_prestrain.slot_table(PAPER, P, ETPU, 1800.0, 2200.0, 0.05, 0.03)
    assert c["by_modulus"][3]["slots_sum_sensitivity_cv_percent"] == pytest.approx(
        rigid["sum_sensitivity_cv_percent"], rel=1e-4)
    assert "NOT a literature value" in c["pulp_modulus_note"]
