"""predict -> model.json -> loop: the virtual test's prediction is the base the measured-data
loop starts from; an effect the FEM lacks is found in the residual on held-out data."""

import numpy as np

from designlab.calibration.dataset import from_arrays
from designlab.calibration.loop import load_model, run_loop
from designlab.calibration.predict import sensor_model

GAINS = {"Ch1": {"F_n": 0.030, "F_x": 0.020}, "Ch2": {"F_n": 0.029, "F_x": -0.013}}


def _strap_prediction():
    return {"design": {"part": "strap", "params": {}}, "sensitivity": {"V_per_N": GAINS}}


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
