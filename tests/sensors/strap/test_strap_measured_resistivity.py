"""A measured resistivity of the printed trace replaces the back-calculated rho_eff in the
strap's electrical model (material data that is the printed TPU's)."""

from __future__ import annotations

import dataclasses
import json

import pytest

from designlab.errors import ParameterError
from designlab.fem.materials import MeasuredProperty, get_material, load_measured, with_measured
from designlab.geometry.strap import ArchStrap
from designlab.sensors.strap import electrical as el
PAPER = ArchStrap()
ETPU = get_material("PI-ETPU")
RHO = 14.08          # ohm*mm: twice the back-calculated 7.04, a number a 4-wire test could give


def _measured(rho=RHO, **kw):
    rec = MeasuredProperty("PI-ETPU", "resistivity", rho, "4-wire, 3 printed strips along the "
                           "raster, annealed", "2026-11-20", **kw)
    return with_measured(ETPU, [rec])


def test_library_resistivity_is_never_used_and_is_not_measured():
    assert ETPU.measured == ()
    assert el.measured_resistivity(ETPU) is None
    # the library's Table I value (8000 ohm*mm) does not reach the resistance
    assert el.gauge_resistance(PAPER, material=ETPU)["total"] == pytest.approx(1800.0,
                                                                               rel=1e-12)
    assert el.resistivity_in_use(0.0, ETPU) == (el.effective_resistivity(), "back-calculated")


def test_measured_resistivity_replaces_the_back_calculated_one():
    m = _measured()
    assert m.measured == ("resistivity",) and m.resistivity == RHO
    assert m == dataclasses.replace(ETPU, resistivity=RHO)        # only the value changed
    R_back = el.gauge_resistance(PAPER)
    R_meas = el.gauge_resistance(PAPER, material=m)
    # R = rho L / A with the measured rho: every part scales by rho_meas / rho_eff
    k = RHO / el.effective_resistivity()
    for part in ("legs", "turns", "leads", "pads", "total"):
        assert R_meas[part] == pytest.approx(k * R_back[part], rel=1e-12)
    assert R_meas["total"] == pytest.approx(RHO / PAPER.trace_thickness
                                            * PAPER.trace_squares()["total"], rel=1e-12)
    # contacts are added on top of the measured trace, not subtracted from it
    Rc = el.gauge_resistance(PAPER, contact_ohm=50.0, material=m)
    assert Rc["total"] == pytest.approx(R_meas["total"] + 100.0, rel=1e-12)
    # doubling the legs doubles the legs' resistance with the measured rho too
    wide = dataclasses.replace(PAPER, strap_width=20.0)
    r4 = el.gauge_resistance(wide, material=m)
    r8 = el.gauge_resistance(dataclasses.replace(wide, legs=8), material=m)
    assert r8["legs"] == pytest.approx(2 * r4["legs"], rel=1e-12)


def test_the_report_says_which_resistivity_is_in_use():
    rep = el.electrical_report(PAPER, _measured(), 0.06, 0.03)
    assert rep["resistivity_source"] == "measured"
    assert rep["effective_resistivity_ohm_mm"] == RHO
    assert rep["back_calculated_resistivity_ohm_mm"] == pytest.approx(
        el.effective_resistivity())
    assert rep["resistance_ohm"]["total"] == pytest.approx(3600.0, rel=1e-3)
    note = rep["effective_resistivity_note"]
    assert "MEASURED" in note and "4-wire, 3 printed strips" in note and "2026-11-20" in note
    assert "1800 ohm" in note                      # what the back-calculation would give
    # the divider works at the measured resistance (no R_rest given: unstrained)
    assert rep["resistance_at_rest_ohm"] == pytest.approx(rep["resistance_ohm"]["total"])
    back = el.electrical_report(PAPER, ETPU, 0.06, 0.03)
    assert back["resistivity_source"] == "back-calculated"
    assert back["resistance_ohm"]["total"] == pytest.approx(1800.0, rel=1e-12)
    # a higher resistance moves the divider off its optimum: the report follows it
    assert rep["divider"]["gain_vs_optimum"] < back["divider"]["gain_vs_optimum"]
    # the trade-off sweep uses it as well
    t = el.trade_off(PAPER, {"Ch1": {"F_n": 1e-3, "F_x": 1e-3},
                             "Ch2": {"F_n": 1e-3, "F_x": -1e-3}}, _measured())
    assert t["R_ohm"] == pytest.approx(rep["resistance_ohm"]["total"], rel=1e-12)


def test_bad_measured_resistivity_is_one_line(tmp_path):
    for bad in (0.0, -3.0, float("inf")):
        with pytest.raises(ParameterError, match="PI-ETPU.resistivity"):
            _measured(bad)
    with pytest.raises(ParameterError, match="a number"):
        _measured("high")
    # the file route: load_measured -> with_measured
    p = tmp_path / "m.json"
    p.write_text(json.dumps({"measured": [{"material": "PI-ETPU", "quantity": "resistivity",
                                           "value": RHO, "source": "4-wire strip",
                                           "date": "2026-11-20"}]}))
    m = with_measured(ETPU, load_measured(p))
    assert el.resistivity_in_use(0.0, m) == (RHO, "measured")


SHORT = {"n_steps": 2, "step_hold_s": 1.0, "dt_s": 0.25, "cycles": 1, "cycle_period_s": 1.0}
CHEAP = {"edge_length": 2.0, "order": 1, "mesh_convergence": False}


@pytest.mark.slow
def test_predict_strap_reads_the_gauges_at_the_measured_resistance(tmp_path):
    """End to end: predict strap --measured with a resistivity record twice the back-
    calculated one -> the electrical report, the gauges' operating point and the sensitivity
    all use the 3.6 kOhm it gives (a divider-gain change: R R_f / (R + R_f)^2)."""
    from designlab.predict.run import predict

    p = tmp_path / "m.json"
    p.write_text(json.dumps({"measured": [{"material": "PI-ETPU", "quantity": "resistivity",
                                           "value": RHO, "source": "4-wire strip (test)",
                                           "date": "2026-11-20"}]}))
    a = predict("strap", {}, protocol=SHORT, settings=CHEAP)
    b = predict("strap", {}, protocol=SHORT, settings=CHEAP, measured=p)
    ea, eb = a.metrics["electrical"], b.metrics["electrical"]
    assert ea["resistivity_source"] == "back-calculated"
    assert eb["resistivity_source"] == "measured"
    Ra, Rb = ea["resistance_ohm"]["total"], eb["resistance_ohm"]["total"]
    assert Rb == pytest.approx(RHO / el.effective_resistivity() * Ra, rel=1e-12)
    assert eb["resistance_at_rest_ohm"] == pytest.approx(eb["resistance_ohm"]["total"])
    sa = a.metrics["sensitivity"]["V_per_N"]["sum"]["F_n"]
    sb = b.metrics["sensitivity"]["V_per_N"]["sum"]["F_n"]
    assert sb == pytest.approx(el.scale_sensitivity(sa, Ra, Rb, 2200.0), rel=0.03)
    assert abs(sb / sa - 1) > 0.05                  # the change is larger than the tolerance
