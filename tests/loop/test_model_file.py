"""A model.json with text, booleans or wrong-shaped values: one line naming the key (ModelError),
never an internal error while predicting."""

from __future__ import annotations

import json

import numpy as np
import pytest

from designlab.errors import ModelError
from designlab.loop.model import load_model
from designlab.measured.dataset import from_arrays
from designlab.sensors.sensor import linear_sensor_model

T = np.arange(50) * 0.1
DATA = from_arrays(T, {"displacement": np.sin(T)}, {"force": np.cos(T)})
EFFECT = {"name": "relaxation", "channel": "displacement", "theta": {"tau": [8.1]},
          "beta": [0.1], "alpha": [0.0, 0.0], "nuisance": ["displacement"]}


def _doc(tmp_path):
    path = tmp_path / "m.json"
    linear_sensor_model({"force": {"displacement": 0.3}}, {"force": "N"}, {}).save(path)
    return path, json.loads(path.read_text())


def _force(d):
    return d["model"]["base"]["parameters"]["force"]


@pytest.mark.parametrize("change, match", [
    (lambda d: _force(d)["gains"].update(displacement="abc"), r"gains\.displacement=abc"),
    (lambda d: _force(d)["gains"].update(displacement=True), r"gains\.displacement=True"),
    (lambda d: _force(d)["gains"].update(displacement=[1, 2]), r"gains\.displacement=\[1, 2\]"),
    (lambda d: _force(d).update(intercept="x"), r"intercept=x is not allowed: a number"),
    (lambda d: _force(d).update(gains=[1]), r"gains is not allowed"),
    (lambda d: d["model"]["base"]["inputs"].update(force="displacement"), r"inputs\.force="),
    (lambda d: d["model"]["base"]["parameters"].update(force=[1]), r"parameters\.force is not"),
    (lambda d: d["model"]["base"]["inputs"].pop("force"), r"parameters\.force is not"),
    (lambda d: d["model"]["outputs"]["force"]["effects"].append(dict(EFFECT, beta=["a"])),
     r"effects\[0\]\.beta=\['a'\]"),
    (lambda d: d["model"]["outputs"]["force"]["effects"].append(dict(EFFECT, beta=[1., 2., 3.])),
     r"effect relaxation on 'force' does not fit"),
    (lambda d: d["model"]["outputs"]["force"]["effects"].append(dict(EFFECT, theta={"tau": "x"})),
     r"effect relaxation on 'force' does not fit"),
])
def test_bad_values_are_one_line_model_errors(tmp_path, change, match):
    path, doc = _doc(tmp_path)
    change(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match=match):
        load_model(path).predict(DATA, "force")


def test_a_well_formed_model_with_an_effect_predicts(tmp_path):
    path, doc = _doc(tmp_path)
    doc["model"]["outputs"]["force"]["effects"].append(EFFECT)
    path.write_text(json.dumps(doc))
    assert np.isfinite(load_model(path).predict(DATA, "force")).all()
