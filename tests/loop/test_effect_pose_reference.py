"""``pose_reference``: a pose reported about a point offset from the wrench's frame is found by
the loop on a loaded base, with its offset; nothing is found without one; and seed 002's
measured K_c (examples/flexure_kc_loop.py) gives the offsets measured there."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from designlab.frames import transform, transform_twist
from designlab.loop import effects as fx
from designlab.loop.base_models import Base
from designlab.loop.effects.pose_reference import PoseReference, moved_twist
from designlab.loop.loop import run_loop
from designlab.loop.model import SensorModel
from designlab.measured.dataset import from_arrays

ROOT = Path(__file__).resolve().parents[2]
TWIST = ("w_x", "w_y", "w_z", "v_x", "v_y", "v_z")
WRENCH = ("m_x", "m_y", "m_z", "f_x", "f_y", "f_z")
#: a spring-like compliance at its elastic centre: rocking, torsion (rad per N mm), lateral,
#: axial (mm per N)
C0 = np.diag([1 / 1000, 1 / 1000, 1 / 700, 1 / 5, 1 / 5, 1 / 4])


def base_model(C: np.ndarray) -> SensorModel:
    """A loaded linear base (as ``designlab predict`` writes): wrench -> twist through C."""
    gains = {o: {w: float(C[i, j]) for j, w in enumerate(WRENCH)} for i, o in enumerate(TWIST)}
    base = Base("linear", {o: WRENCH for o in TWIST},
                {o: {"intercept": 0.0, "gains": g} for o, g in gains.items()})
    return SensorModel(base, {}, {o: "rad" if o[0] == "w" else "mm" for o in TWIST})


def twist_data(offset: float, seed: int = 0, n: int = 200, outputs=TWIST):
    """Random wrenches (+-60 N mm, +-5 N), one a second, n training + n validation; the pose
    ``C0 W`` reported about ``offset`` mm along z, rotations logged in deg (the card's
    canonical unit), noise 1e-5 rad and 1 um."""
    rng = np.random.default_rng(seed)
    W = rng.uniform(-1, 1, (2 * n, 6)) * np.r_[[60.0] * 3, [5.0] * 3]
    X = W @ C0.T
    X = np.array([transform_twist(x, transform(translation=(0.0, 0.0, -offset))) for x in X])
    X = X + rng.normal(size=X.shape) * np.r_[[1e-5] * 3, [1e-3] * 3]
    X[:, :3] = np.degrees(X[:, :3])
    role = np.r_[["train"] * n, ["validate"] * n]
    return from_arrays(np.r_[np.arange(n), np.arange(n)].astype(float),
                       {w: W[:, j] for j, w in enumerate(WRENCH)},
                       {o: X[:, i] for i, o in enumerate(TWIST) if o in outputs},
                       segment=np.r_[np.zeros(n, int), np.ones(n, int)], role=role,
                       units={**{o: "deg" for o in TWIST[:3]}, **{o: "mm" for o in TWIST[3:]},
                              **{w: "Nmm" if w[0] == "m" else "N" for w in WRENCH}})


def test_the_rule_is_the_adjoint_of_designlab_frames():
    rng = np.random.default_rng(3)
    w, v = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    for i, axis in enumerate("xyz"):
        a = np.zeros(3)
        a[i] = 1.0
        ref = [transform_twist(np.r_[wk, vk], transform(translation=-2.5 * a))[3:]
               for wk, vk in zip(w, v)]
        assert np.allclose(moved_twist(w, v, 2.5, axis), ref)
    # along z: v_x += e w_y, v_y -= e w_x (the brief of docs/loop.md)
    assert np.allclose(moved_twist(w, v, 2.0, "z")[:, :2] - v[:, :2],
                       np.c_[2.0 * w[:, 1], -2.0 * w[:, 0]])


@pytest.mark.parametrize("e", [-11.09, 4.0])
@pytest.mark.slow
def test_a_planted_offset_is_found_first_with_its_size(e):
    res = run_loop(twist_data(e), base_model(C0), outputs=["v_x", "v_y"], folds=5,
                   max_effects=2, peer=False)
    for o, partner in (("v_x", "w_y"), ("v_y", "w_x")):
        rep = res.report["outputs"][o]
        first = rep["effects"][0]
        assert first["key"] == "pose_reference", (o, [x["key"] for x in rep["effects"]])
        p = first["parameters"]
        assert (p["axis"], p["partner"]) == ("z", partner)
        assert p["offset"] == pytest.approx(e, rel=0.01)
        # other candidates also pass in that round (input_gains, and the per-input effects
        # with a linear term, take part of the offset): pose_reference is taken first, as the
        # model's own error
        assert rep["rounds"][0]["candidates"]["pose_reference"]["accepted_rule"]
        assert rep["error_after"] < 0.1 * rep["error_before"]
        assert rep["error_after"] < 2e-3                       # the 1 um noise, and no more


def test_no_offset_nothing_found():
    d = twist_data(0.0, seed=1)
    model = base_model(C0)
    res = run_loop(d, model, outputs=["v_x", "v_y"], folds=5, max_effects=2, peer=False)
    train = d.train()
    for o in ("v_x", "v_y"):
        rep = res.report["outputs"][o]
        assert rep["effects"] == []
        cv = rep["rounds"][0]["candidates"]["pose_reference"]
        assert not cv["accepted_rule"] and cv["relative"] < 0.01
        # fitted anyway, on all training data: e is zero within the noise (1 um / ~35 mrad
        # rotations / sqrt(200) poses ~ 2 um)
        yhat = model.predict(train, o)
        f = fx.fit(PoseReference(), fx.Context(train, o, yhat, WRENCH),
                   train.outputs[o] - yhat, np.ones(len(train), bool))
        assert abs(f.beta[0]) < 0.01


def test_not_applicable_without_the_partner_rotation_or_on_a_fitted_base():
    d = twist_data(3.0, n=60)
    why = PoseReference.applies(d, "w_x", WRENCH)
    assert isinstance(why, str) and "rotation is the same about every point" in why
    no_rot = twist_data(3.0, n=60, outputs=("v_x", "v_y", "v_z"))
    why = PoseReference.applies(no_rot, "v_x", WRENCH)
    assert isinstance(why, str) and "no partner rotation of v_x" in why
    only_wz = twist_data(3.0, n=60, outputs=("w_z", "v_z"))
    assert isinstance(PoseReference.applies(only_wz, "v_z", WRENCH), str)   # w_z: no partner
    # v_x's partners: w_y (offset along z) and w_z (along y); the grid has both
    ctx = fx.Context(d, "v_x", d.outputs["v_x"], ())
    assert [(g["axis"], g["partner"], g["sign"]) for g in PoseReference().grid(ctx)] == [
        ("y", "w_z", -1.0), ("z", "w_y", 1.0)]
    res = run_loop(twist_data(3.0, n=60), "linear", outputs=["v_x"], folds=5, max_effects=0,
                   peer=False)
    assert res.report["outputs"]["v_x"]["not_applicable"]["pose_reference"].startswith(
        "the base is fitted on this data")


@pytest.mark.parametrize("angle_unit", ["rad", "deg"])
def test_loop_to_predict_adds_e_times_the_partner_rotation(angle_unit):
    """``corrected_poses`` (loop -> predict of the flexure) gives the pose reported about the
    fitted point: v_x + e w_y, v_y - e w_x, with the model's rotations in rad, whichever unit
    the model learned its rotations in (a card reading deg)."""
    from designlab.loop.effects.base import Fitted
    from designlab.sensors.flexure.loop import corrected_poses

    model = base_model(C0)
    model.units.update({o: angle_unit for o in TWIST[:3]})
    e = -6.5
    eff = PoseReference()
    model.effects = {"v_x": [Fitted(eff, {"axis": "z", "partner": "w_y", "sign": 1.0},
                                    (e,), (), ())],
                     "v_y": [Fitted(eff, {"axis": "z", "partner": "w_x", "sign": -1.0},
                                    (e,), (), ())]}
    rng = np.random.default_rng(2)
    W = rng.uniform(-1, 1, (50, 6)) * np.r_[[60.0] * 3, [5.0] * 3]
    X = W @ C0.T
    out = corrected_poses(model, C0, np.arange(50.0), W)
    assert np.allclose(out[:, 3:5], moved_twist(X[:, :3], X[:, 3:], e, "z")[:, :2])
    assert np.allclose(out[:, [0, 1, 2, 5]], X[:, [0, 1, 2, 5]])


def _example():
    spec = importlib.util.spec_from_file_location("flexure_kc_loop",
                                                  ROOT / "examples" / "flexure_kc_loop.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.slow
def test_measured_kc_offsets(tmp_path):
    """Seed 002's measured K_c, 92 training poses (seed 0), the default flexure's compliance
    with the wrench in the camera frame: the numbers of docs/loop.md."""
    r = _example().run(tmp_path, seed=0, folds=5, peer=False, outputs=["v_x", "v_y"])
    assert r["offsets"]["v_x"]["axis"] == "z"
    assert r["offsets"]["v_x"]["offset"] == pytest.approx(-6.58, abs=0.05)
    assert r["other_order"]["v_x"]["e_after_gain"] == pytest.approx(-2.95, abs=0.05)
    assert r["population"]["v_x"] == pytest.approx(-6.76, abs=0.01)
    assert r["population"]["v_y"] == pytest.approx(-5.65, abs=0.01)
    assert r["measured"]["zero_coupling_mm"] == pytest.approx(5.45, abs=0.005)
    assert "v_y" not in r["offsets"]                                 # 1.98 standard errors
    assert r["first_cv"]["v_y"]["z"] == pytest.approx(1.98, abs=0.01)
