"""The loop's memory budget: the fits work on at most ``max_fit_samples``
training samples (longer training data is low-passed and decimated, loop.json's ``budget``
says by how much), the NARX peer trains on at most ``PEER_ROWS`` rows and is applied to a long
record in chunks; validation always uses every held-out sample. Data under the budget goes
through unchanged."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from designlab.errors import DataError
from designlab.loop import effects as fx
from designlab.loop import loop as L
from designlab.measured import narx
from designlab.measured.dataset import from_arrays

DT = 0.05


def _drive(rng: np.random.Generator, T: float) -> np.ndarray:
    """Ramps between random levels and holds (relaxation shows in the holds)."""
    t = np.arange(0, T, DT)
    kt, kx = [0.0, 3.0], [0.0, 0.0]
    while kt[-1] < T:
        kt += [kt[-1] + rng.uniform(1.0, 6.0), 0.0]
        kx += [rng.uniform(0.0, 10.0), 0.0]
        kt[-1] = kt[-2] + rng.uniform(2.0, 15.0)
        kx[-1] = kx[-2]
    return np.interp(t, kt, kx)


def _relaxing(T: float = 600.0, runs: int = 1, seed: int = 0):
    """y = 0.3 x + 0.2 highpass(x, 5 s) + noise 0.01 at 20 Hz; one run split 60/40 in time,
    or ``runs`` runs of which the last validates."""
    rng = np.random.default_rng(seed)
    xs = [_drive(rng, T) for _ in range(runs)]
    x = np.concatenate(xs)
    n1 = xs[0].size
    seg = np.repeat(np.arange(runs), n1)
    t = np.tile(np.arange(n1) * DT, runs)
    y = 0.3 * x + 0.2 * fx.highpass(x, 5.0, DT, seg) + rng.normal(0, 0.01, x.size)
    role = (np.where(t <= 0.6 * T, "train", "validate") if runs == 1
            else np.where(seg < runs - 1, "train", "validate"))
    return from_arrays(t, {"displacement": x}, {"force": y}, segment=seg, role=role)


def test_training_data_under_the_budget_is_used_as_it_is():
    ds = _relaxing(60.0)
    train = ds.train()
    out, info = L.fit_samples(train, len(train))
    assert out is train
    assert info == {"max_fit_samples": len(train), "train_samples": len(train),
                    "fit_samples": len(train), "decimation": 1, "decimated": False}


def test_decimation_per_run_within_the_budget_and_deterministic():
    ds = _relaxing(100.0, runs=3)
    train = ds.train()                                   # 2 runs of 2000 samples
    out, info = L.fit_samples(train, 1000)
    again, _ = L.fit_samples(train, 1000)
    assert info["decimated"] and info["decimation"] == 5 and len(out) <= 1000
    assert info["fit_samples"] == len(out) == 800
    assert out.dt == pytest.approx(5 * DT) and info["fit_rate_hz"] == pytest.approx(4.0)
    assert np.array_equal(out.outputs["force"], again.outputs["force"])
    for s in (0, 1):                                     # each run keeps its first sample
        assert out.t[out.segment == s][0] == train.t[train.segment == s][0]
        assert np.sum(out.segment == s) == 400
    # the anti-alias filter keeps the slow signal (ramps and holds): the decimated samples
    # are close to the original ones at the same times
    x0 = train.inputs["displacement"][train.segment == 0][::5]
    assert np.max(np.abs(out.inputs["displacement"][out.segment == 0] - x0)) < 0.3
    with pytest.raises(DataError, match="max_fit_samples=10 is not allowed: an integer >= 100"):
        L.run_loop(ds, "linear", max_fit_samples=10, peer=False)


@pytest.mark.slow
def test_a_decimated_loop_finds_the_same_effect_and_validates_on_every_sample(monkeypatch):
    """12 000 samples (7201 training): fitted at full rate and within a budget of 2500
    (decimated by 3 to 2401): relaxation is accepted first both times, with time constants and
    validation errors close; no fit sees more than the budget; the validation error is over
    all 4800 held-out samples."""
    ds = _relaxing()
    full = L.run_loop(ds, "linear", max_effects=1, peer=False)
    seen = []
    orig = fx.fit_group

    def spy(members, ctx, *a, **k):
        seen.append(len(ctx.data))
        return orig(members, ctx, *a, **k)

    monkeypatch.setattr(fx, "fit_group", spy)
    monkeypatch.setattr(fx.base, "fit_group", spy)
    dec = L.run_loop(ds, "linear", max_effects=1, peer=False, max_fit_samples=2500)
    assert seen and max(seen) <= 2500
    b0, b1 = full.report["budget"], dec.report["budget"]
    assert not b0["decimated"] and b0["fit_samples"] == 7201 and b0["decimation"] == 1
    assert b1["decimated"] and b1["decimation"] == 3 and b1["fit_samples"] == 2401
    assert b0["validation_samples"] == b1["validation_samples"] == 4799
    assert dec.report["validation"]["samples"] == 4799
    k0 = [e["key"] for e in full.report["effects"]]
    k1 = [e["key"] for e in dec.report["effects"]]
    assert k0 == k1 == ["relaxation[displacement]"]
    e0, e1 = full.report["error_after"], dec.report["error_after"]
    assert e0 < 0.5 * full.report["error_before"] and abs(e1 - e0) < 0.1 * e0
    # the decimated model's prediction on the full-rate data, as the report says
    y = dec.model.predict(ds, "force", ds.outputs["force"])
    v = ds.role == "validate"
    assert np.sqrt(np.mean((y[v] - ds.outputs["force"][v]) ** 2)) == pytest.approx(e1)


def test_narx_trains_on_a_row_subset_and_predicts_in_chunks(monkeypatch):
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(0, 0.05, (6000, 1)), 0)
    y = np.tanh(u) + 0.01 * rng.normal(size=u.shape)
    p = narx.NARXParams(input_delays=10, max_iter=30)
    net, rep = narx.fit(u, y, p)
    same, rep2 = narx.fit(u, y, p, max_rows=6000)          # under the budget: the same fit
    assert rep.stride == rep2.stride == 1 and np.array_equal(net.W1, same.W1)
    sub, rep3 = narx.fit([u[:3000], u[3000:]], [y[:3000], y[3000:]], p, max_rows=1000)
    assert rep3.stride == 6 and rep3.rows == 2 * len(range(0, 3000 - 10, 6)) <= 1000
    # chunked application equals the whole lagged matrix at once (chunk edges included)
    us = (u - net.u_mean) / net.u_std
    us = np.concatenate([np.repeat(us[:1], 10, 0), us])
    whole = (np.tanh(narx.lagged(us, 0, 10, 10) @ net.W1 + net.b1) @ net.W2 + net.b2) \
        * net.y_std + net.y_mean
    monkeypatch.setattr(narx, "CHUNK", 777)
    assert np.allclose(net.predict(u), whole, rtol=1e-12, atol=1e-12)


@pytest.mark.slow
def test_peak_memory_of_the_loop_command_on_300k_samples():
    """``designlab loop`` on 300 000 samples (179 999 training, decimated by 4): peak RSS under
    700 MB (measured 473 MB; before the budget 100 000 samples took 473 MB and the loop grew
    by ~2.5 KB per sample: about 1 GB here)."""
    bench = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_loop_memory.py"
    out = subprocess.run([sys.executable, str(bench), "300000"], capture_output=True,
                         text=True, timeout=900)
    assert "exit 0" in out.stdout, out.stdout + out.stderr
    rss = float(out.stdout.split("peak RSS ")[1].split(" MB")[0])
    assert rss < 700, out.stdout
