"""A model.json with text, booleans or wrong-shaped values: one line naming the key (ModelError),
never an internal error while predicting."""

from __future__ import annotations

import json

import numpy as np
import pytest

from designlab.atomic import jsonable
from designlab.cli import main
from designlab.errors import ModelError
from designlab.loop import effects as fx
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
     r"effects\[0\]\.beta=\[1\.0, 2\.0, 3\.0\] \(3 numbers\) is not allowed: 1 number"),
    (lambda d: d["model"]["outputs"]["force"]["effects"].append(dict(EFFECT, theta={"tau": "x"})),
     r"effects\[0\]\.theta=\{'tau': 'x'\} is not allowed: the settings effect relaxation"),
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


#: effects whose parameters have the wrong shape: (effect, the key and value named, allowed)
GAIN_OFFSET = {"name": "gain_offset", "channel": None, "theta": {}, "beta": [0.1, 0.02],
               "alpha": [0.0], "nuisance": ["displacement"]}
BAD_SHAPES = [
    (dict(GAIN_OFFSET, beta=[1.0]),
     r"effects\[0\]\.beta=\[1\.0\] \(1 number\) is not allowed: 2 numbers, one per regressor "
     r"of effect gain_offset"),
    (dict(EFFECT, beta=[]), r"beta=\[\] \(0 numbers\) is not allowed: 1 number"),
    (dict(EFFECT, theta={"tau": [8.1, 30.0]}), r"beta=\[0\.1\] \(1 number\) is not allowed: 2"),
    (dict(EFFECT, alpha=[0.0]),
     r"alpha=\[0\.0\] \(1 number\) is not allowed: 2 numbers \(an intercept and one gain per "
     r"nuisance input \(1\)\)"),
    (dict(GAIN_OFFSET, alpha=[0.0, 0.0]), r"alpha=\[0\.0, 0\.0\] \(2 numbers\) is not allowed: "
     r"1 number \(one gain per nuisance input \(1\)\)"),
    (dict(EFFECT, runs=["a", "b"], alpha=[0.0, 0.0, 0.0, 0.0]),
     r"is not allowed: 2 numbers or 3 numbers"),
    (dict(EFFECT, theta={}), r"theta=\{\} is not allowed: the settings effect relaxation reads "
     r"\(it has no 'tau'\)"),
    ({**EFFECT, "name": "drift", "channel": None, "theta": {"variant": "polynomial",
                                                          "order": 2.5, "duration_s": 1.0}},
     r"theta=.*order.* is not allowed: the settings effect drift reads \(order is not a whole "
     r"number >= 1\)"),
]


@pytest.mark.parametrize("effect, match", BAD_SHAPES)
def test_wrong_shaped_effect_parameters_are_refused_when_the_model_is_loaded(tmp_path, effect,
                                                                            match):
    """The lengths of every effect's beta, alpha and settings are checked by load_model, one
    line naming the file, the key, the value with its length and the length allowed (a short
    beta would otherwise fail inside the prediction, after the data are read)."""
    path, doc = _doc(tmp_path)
    doc["model"]["outputs"]["force"]["effects"].append(effect)
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match=match) as exc:
        load_model(path)
    assert str(exc.value).startswith(f"{path}: model.outputs.force.effects[0].")
    assert "\n" not in str(exc.value)


def test_predict_with_a_short_beta_in_the_model_is_exit_2_before_any_work(tmp_path, capsys,
                                                                          monkeypatch):
    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    path, doc = _doc(tmp_path)
    doc["model"]["outputs"]["force"]["effects"].append(dict(GAIN_OFFSET, beta=[1.0]))
    path.write_text(json.dumps(doc))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        main(["predict", "flexure", "--model", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert [line for line in err.splitlines() if line.startswith("error")] == [
        f"error: {path}: model.outputs.force.effects[0].beta=[1.0] (1 number) is not allowed: "
        "2 numbers, one per regressor of effect gain_offset at its theta"]
    assert not out.exists() and not (tmp_path / "logs").exists()


def _every_effect_data():
    """Data on which every effect of the library applies to one of its outputs: two runs, two
    drives, a location, a temperature; a mechanical translation with its partner rotation and
    an electrical output."""
    rng = np.random.default_rng(0)
    t = np.arange(400) * 0.1
    x, x2 = np.sin(t) + 0.1 * rng.normal(size=t.size), rng.normal(size=t.size)
    return from_arrays(t, {"displacement": x, "displacement_y": x2, "location": 2 + x2,
                           "temperature": 20 + x},
                       {"v_x": x + x2, "w_y": x2, "resistance": 100 + x},
                       segment=(t > 20).astype(int),
                       units={"v_x": "mm", "w_y": "rad", "resistance": "ohm"},
                       quantities={"v_x": "length", "w_y": "angle", "resistance": "resistance",
                                   "location": "length", "temperature": "temperature"},
                       kinds={"displacement": "drive", "displacement_y": "drive",
                              "location": "location", "temperature": "temperature"})


def test_every_effect_declares_the_width_its_features_have():
    """``Effect.width`` (what load_model checks a beta against) is the number of regressors
    ``features`` gives, for every setting of every effect's grid, and after a JSON round trip
    of the settings."""
    data = _every_effect_data()
    seen = set()
    for cls in fx.ordered():
        for out in ("v_x", "resistance"):
            got = cls.applies(data, out, ("displacement",))
            for e in (got if isinstance(got, list) else [cls()] if cls.name == "run_offset" else []):
                y = data.outputs[out]
                ctx = fx.Context(data, out, 0.9 * y, ("displacement",), y)
                for theta in e.grid(ctx):
                    back = fx.Fitted.from_json(json.loads(json.dumps(
                        {"name": e.name, "channel": e.channel, "theta": jsonable(theta),
                         "beta": [], "alpha": [], "nuisance": []})))
                    assert e.width(theta) == e.columns(ctx, theta).shape[1], (e.key, theta)
                    assert e.width(back.theta) == e.width(theta), (e.key, theta)
                    seen.add(e.name)
    assert seen == set(fx.EFFECTS)
