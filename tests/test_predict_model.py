"""predict -> model.json -> loop: the virtual test's prediction is the base the measured-data
loop starts from; an effect the FEM lacks is found in the residual on held-out data."""

import numpy as np

from designlab.measured.dataset import from_arrays
from designlab.loop.loop import load_model, run_loop
from designlab.sensors.predict import sensor_model as _sensor_model

GAINS = {"Ch1": {"F_n": 0.030, "F_x": 0.020}, "Ch2": {"F_n": 0.029, "F_x": -0.013}}


def _strap_prediction():
    return {"design": {"part": "strap", "params": {}}, "sensitivity": {"V_per_N": GAINS}}


def sensor_model(pred, result):
    return _sensor_model(pred["design"]["part"], pred["design"], pred, result)


def test_strap_prediction_becomes_a_loop_base(tmp_path):
    sensor_model(_strap_prediction(), None).save(tmp_path / "model.json")
    model = load_model(tmp_path / "model.json")
    assert set(model.outputs) == {"Ch1", "Ch2"}
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) * 0.1
    fn = 2.5 * (1 - np.cos(2 * np.pi * t / 7.0)) + rng.uniform(0, 1, n)
    fx = 0.5 * np.sin(2 * np.pi * t / 11.0)
    clean = {ch: g["F_n"] * fn + g["F_x"] * fx for ch, g in GAINS.items()}
    # the printed sensor drifts (e.g. warming up): the FEM prediction has no drift
    measured = {ch: v + 2e-4 * t + rng.normal(0, 2e-3, n) for ch, v in clean.items()}
    role = np.where(t < 0.6 * t[-1], "train", "validate")
    data = from_arrays(t, {"F_n": fn, "F_x": fx}, measured, role=role,
                       units={"F_n": "N", "F_x": "N", "Ch1": "V", "Ch2": "V"})
    base_pred = model.predict(data, "Ch1")
    np.testing.assert_allclose(base_pred, clean["Ch1"], atol=1e-12)
    rep = run_loop(data, model, outputs=["Ch1"]).report
    names = [e["name"] for e in rep["effects"]]
    assert names and names[0] == "drift"
    assert rep["error_after"] < 0.5 * rep["error_before"]


def test_loop_model_corrects_a_new_design_prediction(tmp_path):
    """loop -> predict: effects learned on a measured strap are added to another design's
    virtual-test channels and the metrics are evaluated again."""
    from types import SimpleNamespace

    from designlab.sensors import strap as strap_test
    from designlab.loop.loop import run_loop
    from designlab.sensors.protocols import StrapLoadTest

    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) * 0.1
    fn = 2.5 * (1 - np.cos(2 * np.pi * t / 7.0)) + rng.uniform(0, 1, n)
    fx = 0.5 * np.sin(2 * np.pi * t / 11.0)
    measured = {ch: g["F_n"] * fn + g["F_x"] * fx + 2e-4 * t + rng.normal(0, 2e-3, n)
                for ch, g in GAINS.items()}
    data = from_arrays(t, {"F_n": fn, "F_x": fx}, measured,
                       role=np.where(t < 0.6 * t[-1], "train", "validate"),
                       units={"F_n": "N", "F_x": "N", "Ch1": "V", "Ch2": "V"})
    sensor_model(_strap_prediction(), None).save(tmp_path / "base.json")
    learned = run_loop(data, load_model(tmp_path / "base.json")).model
    learned.save(tmp_path / "learned.json")

    # a "new design": other gains, the strap protocol, an elastic virtual test
    prot, settings = StrapLoadTest(), strap_test.StrapModelSettings()
    tt, Fn, Fx = prot.time_history()
    new = {"Ch1": {"F_n": 0.02, "F_x": 0.015}, "Ch2": {"F_n": 0.02, "F_x": -0.015}}
    dV = np.column_stack([new[c]["F_n"] * Fn + new[c]["F_x"] * Fx for c in ("Ch1", "Ch2")])
    result = SimpleNamespace(t=tt, F_n=Fn, F_x=Fx, dV=dV, strain=dV)
    before = strap_test.evaluate(prot, settings, tt, Fn, Fx, dV, dV)
    pred = {"design": {"part": "strap"}, "sensitivity": {"V_per_N": new}}
    after = strap_test.apply_model(pred, result, tmp_path / "learned.json", prot, settings)
    assert after["learned_effects"]["Ch1"][0] == "drift"
    assert before["hysteresis_percent"]["overall"] < 1e-9
    assert after["hysteresis_percent"]["overall"] > 0.1     # the drift opens the loop
