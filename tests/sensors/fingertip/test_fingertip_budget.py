"""The fingertip's calibration error budget in ``predict fingertip`` (``force_error_test``): the
FSS015/DAQ readout noise through seed 001's calibration on the FEM the prediction solved (no
second FEM), force error per axis on held-out points beside Fig. 9, deterministic per seed."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow     # one coarse fingertip prediction (~15 s CPU) for the module


@pytest.fixture(scope="module")
def predicted(tmp_path_factory):
    """A coarse fingertip prediction (contact model), written with its report."""
    from designlab.predict.record import write_prediction
    from designlab.predict.run import predict

    pred = predict("fingertip", {}, settings={"edge_length": 4.0})
    out = tmp_path_factory.mktemp("budget") / "fingertip"
    write_prediction(pred, out)
    return pred, out


def test_prediction_json_has_the_budget(predicted):
    pred, out = predicted
    doc = json.loads((out / "prediction.json").read_text())
    fe = doc["force_error_test"]
    for a in "xyz":
        e = fe["per_axis"][a]
        assert set(e) >= {"mean", "std", "max_abs", "rms"}
        assert 0 < e["std"] <= e["max_abs"] < 5.0          # N, on loads up to 2.1 N
    # seed 001 Fig. 9: P_x, P_y estimated well, P_z poorly
    std = {a: fe["per_axis"][a]["std"] for a in "xyz"}
    assert std["z"] > std["x"] and std["z"] > std["y"]
    assert fe["worst_axis"] == "z" and fe["matches_paper_worst_axis"] is True
    assert fe["Pz_error_over_xy"] == pytest.approx(std["z"] / max(std["x"], std["y"]))
    assert "Pz poorly" in fe["paper"]["finding"] and fe["paper"]["condition_number"] == 34.92
    assert fe["paper"]["force_error_per_axis_N"] is None       # Fig. 9 prints no numbers
    b = fe["budget"]
    assert b["repeatability_percent_fs"] == 0.2 and b["daq"].startswith("16 bit")
    assert b["sensitivity_mV_per_V_per_N"] == [2.4, 2.4, 2.4] and b["seed"] == 0
    assert "reused" in b["structure"]
    assert fe["load_sets"] == {"calibration": 72, "held_out_points": 1224}
    # the split: the axial error is the readout noise, the radial one the 3-sensor model's
    assert fe["split_std"]["z"]["readout_noise"] > fe["split_std"]["z"]["model_error"]


def test_budget_is_cheap_and_reuses_the_fem(predicted, monkeypatch):
    """Under 2 s added (measured in the prediction's timings) and no FEM: the condensation and
    the mesher are not called again."""
    import designlab.sensors.fingertip.calibration as fc
    import designlab.sensors.fingertip.contact as fcon

    pred, _ = predicted
    assert pred.timings_s["force_error_test"] < 2.0

    def boom(*a, **k):
        raise AssertionError("a second FEM")

    monkeypatch.setattr(fcon, "condense_fingertip", boom)
    monkeypatch.setattr(fc, "condense_structure", boom)
    for where in ("model", "contact"):   # defined in model, imported by name in contact
        monkeypatch.setattr(f"designlab.sensors.fingertip.{where}.mesh_fingertip", boom)
    from designlab.geometry.parts import make_part

    r = fc.prediction_force_error(make_part("fingertip", pred.params), pred.protocol, pred.result)
    assert r["per_axis"] == pred.metrics["force_error_test"]["per_axis"]


def test_same_seed_same_numbers_other_seed_other_noise(predicted):
    from designlab.geometry.parts import make_part
    from designlab.sensors.fingertip.calibration import prediction_force_error

    pred, _ = predicted
    part = make_part("fingertip", pred.params)
    again = prediction_force_error(part, pred.protocol, pred.result)
    assert json.dumps(again, sort_keys=True) == json.dumps(pred.metrics["force_error_test"],
                                                           sort_keys=True)
    other = dataclasses.replace(pred.result, settings=dataclasses.replace(
        pred.result.settings, seed=7))
    r7 = prediction_force_error(part, pred.protocol, other)
    assert r7["budget"]["seed"] == 7
    assert r7["per_axis"]["z"]["std"] != again["per_axis"]["z"]["std"]
    assert r7["worst_axis"] == "z"                 # the ordering is not one lucky draw


def test_no_readout_noise_leaves_the_model_error(predicted):
    """With the repeatability off and a 32-bit DAQ the readout part of the error vanishes."""
    from designlab.geometry.parts import make_part
    from designlab.sensors.fingertip.calibration import prediction_force_error

    pred, _ = predicted
    clean = dataclasses.replace(pred.result, settings=dataclasses.replace(
        pred.result.settings, repeatability_percent_fs=0.0, daq_bits=32))
    r = prediction_force_error(make_part("fingertip", pred.params), pred.protocol, clean)
    for a in "xyz":
        assert r["split_std"][a]["readout_noise"] < 1e-4
        assert r["per_axis"][a]["std"] == pytest.approx(r["split_std"][a]["model_error"],
                                                         rel=1e-3)
    # noise-free, the radial error (the moments three sensors cannot tell from forces) stays
    # and the axial one nearly vanishes: P_z is worst through the readout noise
    noisy = pred.metrics["force_error_test"]["per_axis"]
    assert r["per_axis"]["x"]["std"] == pytest.approx(noisy["x"]["std"], rel=0.1)
    assert r["per_axis"]["z"]["std"] < 0.1 * noisy["z"]["std"]


def test_condensed_structure_gives_the_monte_carlo_structure_numbers(predicted):
    """The prediction's condensation (ball, wells, bolt inside) and the Monte Carlo's (wells,
    bolt head; bolt added analytically) are the same structure: same contact forces."""
    from designlab.geometry.parts import make_part
    from designlab.sensors.fingertip.calibration import (build_of, condensed_unit_responses,
                                                         structure, unit_responses)

    pred, _ = predicted
    part = make_part("fingertip", pred.params)
    sett = pred.result.settings
    b = build_of(sett)
    fem = structure(part, sett, pred.protocol)
    for build in (b, dataclasses.replace(b, contact=False)):
        a = unit_responses(part, fem, sett, build)["normal"]
        c = condensed_unit_responses(part, pred.result.condensed, build)["normal"]
        assert np.abs(a - c).max() < 1e-9 * np.abs(a).max()
    from designlab.errors import ParameterError

    with pytest.raises(ParameterError, match="printed_modulus_scale"):
        condensed_unit_responses(part, pred.result.condensed,
                                 dataclasses.replace(b, printed_modulus_scale=0.9))


def test_report_and_summary_show_the_budget(predicted):
    from html.parser import HTMLParser

    pred, out = predicted
    html = (out / "report.html").read_text()
    assert 'id="force-error"' in html

    class Cells(HTMLParser):
        def __init__(self):
            super().__init__()
            self.on, self.depth, self.text = False, 0, []

        def handle_starttag(self, tag, attrs):
            if tag == "section" and ("id", "force-error") in attrs:
                self.on = True
            elif tag == "section" and self.on:
                self.depth += 1

        def handle_endtag(self, tag):
            if tag == "section" and self.on:
                if self.depth:
                    self.depth -= 1
                else:
                    self.on = False

        def handle_data(self, data):
            if self.on and data.strip():
                self.text.append(data.strip())

    p = Cells()
    p.feed(html)
    fe = pred.metrics["force_error_test"]
    for a in "xyz":
        assert f"{fe['per_axis'][a]['std']:.4g}" in p.text
    assert any("Fig. 9" in t for t in p.text)
    rows = {r[0]: r[1] for r in pred.summary_rows()}
    assert rows["force error std, z"] == f"{fe['per_axis']['z']['std']:.4g}"
    # the terminal summary of designlab predict (cli): per axis, then the line, then the paper
    from designlab.predict.report import force_error_lines

    lines = dict(force_error_lines(pred.metrics))
    z = fe["per_axis"]["z"]
    assert lines["force error z (N, held-out)"] == (
        f"{z['mean']:.4g} ± {z['std']:.4g} (max |e| {z['max_abs']:.4g})")
    assert "P_z worst, as Fig. 9" in lines["force error"]
    assert "Pz poorly sensed" in lines["paper"]


def test_linear_model_budget_runs_on_the_linear_fem_gains(predicted):
    """``contact=false``: the budget's readings are the linear FEM's sensor forces per unit
    wrench; they equal the condensed structure with the bilateral springs put back."""
    from designlab.geometry.parts import make_part
    from designlab.sensors.fingertip.calibration import (build_of, calibration_test,
                                                         prediction_force_error)

    pred, _ = predicted
    part = make_part("fingertip", pred.params)
    lin = dataclasses.replace(pred.result.settings, contact=False)
    r = prediction_force_error(part, pred.protocol, dataclasses.replace(
        pred.result, condensed=None, settings=lin))
    assert r["stick_margin"] is None and "linear FEM" in r["budget"]["structure"]
    ref = calibration_test(part, pred.result.condensed, lin, pred.protocol, build_of(lin))
    for a in "xyz":
        for k in ("mean", "std", "max_abs"):
            assert r["per_axis"][a][k] == pytest.approx(ref["per_axis"][a][k], rel=1e-6)
