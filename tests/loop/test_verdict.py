"""The verdict against a noise floor estimated from the data: synthetic logs with a known
truth (a ripple outside the library, strain-history softening in the damage and the recovery
form, a pure delay, a plain drift, noise alone), each with white noise of 0.01 N."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.loop import effects as fx
from designlab.loop.loop import run_loop
from designlab.loop.noise_floor import noise_floor
from designlab.loop.report import FLOOR_FACTOR, verdict_kind
from designlab.measured.dataset import from_arrays

DT = 0.1
NOISE = 0.01


def drive(rng: np.random.Generator, T: float) -> np.ndarray:
    """Holds at random levels (0-10 mm) joined by ramps, plus a small multisine."""
    t = np.arange(0, T, DT)
    kt, kx = [0.0, 3.0], [0.0, 0.0]
    while kt[-1] < T:
        kt.append(kt[-1] + rng.uniform(1.0, 6.0))
        kx.append(rng.uniform(0.0, 10.0))
        kt.append(kt[-1] + rng.uniform(2.0, 15.0))
        kx.append(kx[-1])
    x = np.interp(t, kt, kx)
    ms = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
             for f in rng.uniform(0.05, 0.4, 4))
    return np.clip(x + 0.375 * ms * (t > 3.0), 0.0, 10.0)


def log(kind: str, seed: int = 0, T: float = 600.0):
    """One run: the first 60 % trains, the rest validates; truth = 0.2 + 0.3 x + ``kind``."""
    rng = np.random.default_rng(seed)
    x = drive(rng, T)
    t = np.arange(x.size) * DT
    seg = np.zeros(x.size, int)
    y = 0.2 + 0.3 * x
    if kind in ("softening", "mullins"):   # triangle cycles of growing amplitude
        x = (2.0 + 8.0 * t / T) * (1 - np.abs(2 * ((t / 20.0) % 1.0) - 1))
        x_max = np.maximum.accumulate(x)
        if kind == "softening":      # damage: the gain falls as the running maximum grows
            y = 0.2 + 0.3 * x * (1 - 0.04 * x_max)
        else:                        # recovery: softer below the running maximum
            y = 0.2 + 0.3 * x - 0.15 * x * (1 - np.exp(-(x_max - x) / 1.0))
    elif kind == "ripple":           # a static law no effect of the library describes
        y = y + 0.08 * np.sin(2 * np.pi * x / 2.0)
    elif kind == "delay":
        y = 0.2 + 0.3 * fx.shift(x, 0.4, t, seg)
    elif kind == "long delay":       # the base fitted on it has its gain biased low
        y = 0.2 + 0.3 * fx.shift(x, 1.7, t, seg)
    elif kind == "drift":
        y = y + 0.4 * t / T
    elif kind == "settling":         # a drift that settles with a time constant of T / 4
        y = y + 0.4 * (1 - np.exp(-t / (0.25 * T)))
    elif kind != "noise":
        raise ValueError(kind)
    y = y + rng.normal(0, NOISE, x.size)
    return from_arrays(t, {"displacement": x}, {"force": y}, segment=seg,
                       role=np.where(t <= 0.6 * T, "train", "validate"))


@pytest.mark.parametrize("sigma", [0.01, 0.5])
def test_noise_floor_of_white_noise_within_20_percent(sigma):
    rng = np.random.default_rng(4)
    n = 6000
    t = np.arange(n) * DT
    seg = (t > 300).astype(int)
    signal = 3.0 * np.sin(2 * np.pi * t / 40.0)       # smooth: the difference leaves it out
    load = rng.uniform(-5, 5, n)                       # a white input: its map comes out
    y = signal + 0.4 * load + rng.normal(0, sigma, n)
    f = noise_floor(y, load[:, None], seg)
    assert f["sigma"] == pytest.approx(sigma, rel=0.2)
    assert "difference" in f["method"] and f["samples"] == n


def test_verdict_rule_against_the_floor():
    assert verdict_kind(0.0101, 0.0101, 0.012, floor=0.01) == "noise"
    assert verdict_kind(0.2, 0.0105, 0.15, floor=0.01) == "explained"
    # a failing peer does not make an error 3x the floor explained
    assert verdict_kind(0.19, 0.03, 0.04, floor=0.01) == "missing mechanism"
    # within the factor, but the residual still correlates with an input
    assert verdict_kind(0.2, 0.012, None, floor=0.01, structure_r=0.5) == "missing mechanism"
    # within the factor, and a peer much better still
    assert verdict_kind(0.2, 0.014, 0.01, floor=0.01) == "missing mechanism"


def test_noise_only_is_noise_without_effects():
    out = run_loop(log("noise", T=300.0), "linear", peer=False).report["outputs"]["force"]
    assert out["effects"] == []
    assert out["noise_floor"]["sigma"] == pytest.approx(NOISE, rel=0.2)
    assert out["verdict_kind"] == "noise" and out["verdict"].startswith("noise: ")


@pytest.mark.slow
def test_out_of_library_structure_is_not_explained():
    rep = run_loop(log("ripple"), "linear").report
    out = rep["outputs"]["force"]
    assert out["verdict_kind"] == "missing mechanism", out["verdict"]
    assert out["error_after"] > FLOOR_FACTOR * out["noise_floor"]["sigma"]
    assert out["noise_floor"]["sigma"] == pytest.approx(NOISE, rel=0.2)
    # the verdict's numbers are loop.json's
    assert f"{out['error_after']:.4g}" in out["verdict"]
    assert f"{out['noise_floor']['sigma']:.4g}" in out["verdict"]
    assert {p["kind"] for p in out["peers"]} == {"narx", "gbt"}
    assert all(p["converged"] and p["error"] > 0 for p in out["peers"])
    assert rep["best_peer"] in ("narx", "gbt") and out["peer"]["kind"] == "narx"
    best = min(out["peers"], key=lambda p: p["inner_error"])
    assert best["kind"] == out["best_peer"] and f"{best['error']:.4g}" in out["verdict"]


@pytest.mark.slow
def test_damage_softening_is_the_damage_effect():
    """The gain falls with the running maximum under growing amplitudes: the damage form is
    found first, at most one effect follows, the error falls to at most half the base's and the
    verdict agrees with the floor and the peers."""
    out = run_loop(log("softening"), "linear").report["outputs"]["force"]
    names = [e["name"] for e in out["effects"]]
    assert names[0] == "damage" and len(names) <= 2, out["verdict"]
    assert out["error_after"] <= 0.5 * out["error_before"]
    floor = out["noise_floor"]["sigma"]
    best = next(p for p in out["peers"] if p["kind"] == out["best_peer"])
    kind = ("explained" if out["error_after"] <= FLOOR_FACTOR * floor
            and best["error"] * 1.3 >= out["error_after"] else "missing mechanism")
    assert out["verdict_kind"] == kind == "explained", out["verdict"]
    assert f"{out['error_after']:.4g}" in out["verdict"] and f"{floor:.4g}" in out["verdict"]


@pytest.mark.slow
def test_mullins_softening_is_one_effect():
    """Recovery-form softening under growing amplitudes: ``mullins`` first and at most one more
    effect (its width refined between the grid's values leaves the noise)."""
    out = run_loop(log("mullins"), "linear", peer=False).report["outputs"]["force"]
    names = [e["name"] for e in out["effects"]]
    assert names[0] == "mullins" and len(names) <= 2, out["verdict"]
    assert out["error_after"] <= 0.5 * out["error_before"]
    assert out["error_after"] <= FLOOR_FACTOR * out["noise_floor"]["sigma"]


@pytest.mark.slow
def test_the_backward_pass_removes_an_effect_at_the_noise_level(monkeypatch):
    """Mullins softening with its width held to the coarse grid and no damage effect offered:
    the forward pass follows ``mullins`` with effects that fit its mismatch (and extrapolate
    badly to the larger validation amplitudes); the backward pass refits them together and
    removes each that accounts for no more held-out error than the noise floor, with its
    numbers in ``dropped``."""
    from designlab.loop.effects.mullins import Mullins

    monkeypatch.setattr(Mullins, "refine", "", raising=False)
    monkeypatch.delitem(fx.EFFECTS, "damage", raising=False)
    out = run_loop(log("mullins"), "linear", peer=False).report["outputs"]["force"]
    forward = [r["accepted"] for r in out["rounds"] if r["accepted"]]
    names = [e["name"] for e in out["effects"]]
    assert len(forward) > len(names) and out["dropped"], forward
    assert names[0] == "mullins" and len(names) <= 2, out["verdict"]
    assert out["error_after"] <= 0.5 * out["error_before"]
    for d in out["dropped"]:
        cv = d["cv"]
        assert cv["removed"] and d["why"] == cv["why"]
        assert cv["accounts_for"] == pytest.approx(
            np.sqrt(max(cv["error_without"] ** 2 - cv["error_with"] ** 2, 0.0)))
        assert cv["accounts_for"] <= cv["noise_floor"] or "forward rule" in d["why"] \
            or "within" in d["why"]
        assert d["key"] in out["verdict"]


@pytest.mark.slow
@pytest.mark.parametrize("kind, seed, delay", [("delay", 0, 0.4), ("long delay", 6, 1.7)])
def test_a_pure_delay_is_one_effect(kind, seed, delay):
    out = run_loop(log(kind, seed), "linear").report["outputs"]["force"]
    assert [e["name"] for e in out["effects"]] == ["lag"], out["verdict"]
    assert out["effects"][0]["parameters"]["delay_s"] == pytest.approx(delay, abs=0.05)
    assert out["verdict_kind"] == "explained"


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["drift", "settling"])
def test_a_plain_drift_is_explained_to_the_noise(kind):
    out = run_loop(log(kind), "linear").report["outputs"]["force"]
    assert out["effects"][0]["name"] == "drift"
    assert out["error_after"] <= 1.2 * NOISE
    assert out["verdict_kind"] == "explained", out["verdict"]


@pytest.mark.slow
def test_noise_only_with_peers_is_noise():
    out = run_loop(log("noise"), "linear").report["outputs"]["force"]
    assert out["effects"] == [] and out["verdict_kind"] == "noise"
    assert len(out["peers"]) == 2


@pytest.mark.slow
def test_the_backward_pass_drops_effects_that_fit_noise(monkeypatch):
    """With the forward stop at the floor switched off and a rule that takes any gain, the
    forward pass adds effects to noise alone; the backward pass removes every one again."""
    from designlab.loop import loop as loop_mod

    monkeypatch.setattr(loop_mod, "AT_FLOOR", 0.0)
    backward = loop_mod._Selection._backward

    def at_the_floor(self, *args):
        monkeypatch.setattr(loop_mod, "AT_FLOOR", 1.1)
        return backward(self, *args)

    monkeypatch.setattr(loop_mod._Selection, "_backward", at_the_floor)
    out = run_loop(log("noise", seed=2), "linear", n_se=0.0, min_relative=0.0,
                   peer=False).report["outputs"]["force"]
    forward = [r["accepted"] for r in out["rounds"] if r["accepted"]]
    assert len(forward) > 1, forward
    assert out["effects"] == [] and {d["key"] for d in out["dropped"]} == set(forward)
    assert "dropped by the backward pass" in out["verdict"]
    assert out["verdict_kind"] == "noise"


def test_a_noiseless_log_has_a_floor_at_the_resolution_and_is_noise():
    ds = log("noise", T=300.0)
    x = ds.inputs["displacement"]
    clean = from_arrays(ds.t, ds.inputs, {"force": 0.2 + 0.3 * x}, segment=ds.segment,
                        role=ds.role)
    out = run_loop(clean, "linear", peer=False).report["outputs"]["force"]
    assert 0 < out["noise_floor"]["sigma"] < 1e-8          # the numbers' own resolution
    assert out["verdict_kind"] == "noise" and out["verdict"]
