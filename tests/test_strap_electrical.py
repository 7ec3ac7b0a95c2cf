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
from designlab.sensors import strap_electrical as el
from designlab.sensors import strap_fit as sf

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
                      sf.default_target())
    assert t["slots_strain_spread_percent_of_mean"] > 30
    assert t["personalised_sum_sensitivity_spread_percent"] < 1e-6
    # the personalised spread is the measurement's: 4x smaller sd, 4x smaller spread
    t2 = sf.size_table(np.arange(40.0, 75.0, 5.0), ETPU, 1800.0, 2200.0, 0.06,
                       sf.default_target(), measurement_sd_mm=0.125)
    assert t2["personalised_strain_spread_percent_of_mean"] == pytest.approx(
        t["personalised_strain_spread_percent_of_mean"] / 4)


def test_scan_gives_width_depth_and_rejects_open_surfaces(tmp_path):
    import trimesh

    cap = trimesh.creation.capsule(height=20.0, radius=8.0, count=[48, 48])
    cap.apply_scale([1.0, 14.0 / 16.0, 1.0])         # elliptic section 16 x 14 mm
    p = tmp_path / "finger.stl"
    cap.export(p)
    f = sf.finger_from_scan(p)
    assert f.width == pytest.approx(16.0, abs=0.3) and f.depth == pytest.approx(14.0, abs=0.3)
    open_ = cap.copy()
    open_.update_faces(np.arange(len(open_.faces)) > 10)
    q = tmp_path / "open.stl"
    open_.export(q)
    with pytest.raises(ParameterError, match="closed"):
        sf.finger_from_scan(q)


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


@pytest.mark.slow
def test_fit_strap_writes_3mf_and_fit_json_under_60_s(tmp_path):
    import json
    import time

    t0 = time.perf_counter()
    res = sf.fit_strap(sf.Finger(16.0, 14.0, 25.0), tmp_path)
    assert time.perf_counter() - t0 < 60
    assert res["prestrain"]["initial_strain"] == pytest.approx(sf.default_target(), abs=2e-4)
    assert (tmp_path / "strap" / "strap.3mf").stat().st_size > 1000
    data = json.loads((tmp_path / "fit.json").read_text())
    assert data["resolution_mN"]["F_n"] > 0 and data["material_stand_ins"]
