"""The fingertip's readout: the FSS015 repeatability, zero drift and DAQ quantisation of the
sensor readings, and the hysteresis of eq. (1) over readout draws. Units N; readings V.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps

# the settings and their sourced defaults live with the fingertip's model settings (which derive
# from ContactSettings, so that ``--setting friction_coefficient=...`` reaches this model)
from designlab.sensors.fingertip.model import FSS015_V_PER_N, ContactSettings
from designlab.sensors.protocols import FSS015_RANGE_N


def repeatability_sigma_V(percent_fs: float) -> float:
    """Standard deviation (V) of one reading's repeatability error. Honeywell defines the FSS
    repeatability as "the maximum difference between output readings when the same force is
    applied consecutively ... approaching from the same direction" (FSS datasheet, Table 2 note
    9): the +-band bounds the difference of two readings, whose sigma is sqrt(2) x a reading's.
    Read as a 2-sigma band on that difference: sigma = band / (2 sqrt 2), 0.0707 % FS for the
    FSS015's 0.2 % (seed 001 Table I). Taking the band on one reading (sigma = band / 2) would be
    sqrt 2 too wide."""
    return percent_fs / 100.0 * FSS015_RANGE_N * FSS015_V_PER_N / (2.0 * np.sqrt(2.0))


def readings_noise(S_true: np.ndarray, settings: ContactSettings, rng_: np.random.Generator):
    """Readings (V) with the FSS015 repeatability (normal, :func:`repeatability_sigma_V`), a
    linear zero drift over each loop (random sign), and the DAQ quantisation. ``S_true`` (B,
    steps, 3)."""
    fs_V = FSS015_RANGE_N * FSS015_V_PER_N
    sig = repeatability_sigma_V(settings.repeatability_percent_fs)
    S = S_true + sig * rng_.standard_normal(S_true.shape)
    if settings.zero_drift_percent_fs > 0:
        n = S_true.shape[1]
        drift = settings.zero_drift_percent_fs / 100.0 * fs_V * rng_.choice(
            [-1.0, 1.0], size=(S_true.shape[0], 1, 3))
        S = S + drift * np.linspace(0.0, 1.0, n)[None, :, None]
    lsb = settings.daq_lsb_V
    return np.round(S / lsb) * lsb


def run_rng(seed: int, location: str, rotation_deg: float) -> np.random.Generator:
    """The readout noise generator of one (location, rotation) run: seeded by ``seed``, the
    location's name (CRC-32) and the rotation in millidegrees, so the same input gives the same
    numbers in any process and whatever else the protocol contains."""
    import zlib

    return np.random.default_rng([int(seed), zlib.crc32(location.encode()),
                                  int(round(rotation_deg * 1000)) % 2 ** 32])


def readout_draws(S_true, runs, seq, settings: ContactSettings, protocol) -> dict[str, Any]:
    """The robust eq. 1 with readout over ``settings.readout_draws`` noise draws (each run's
    generator :func:`run_rng` continued; without zero drift draw 0 is the reported reading):
    by location the mean and standard deviation over draws, by group the lowest location's
    value per draw (mean, sd, min, max), and the share of draws in which G1 falls monotonically
    from its first to its last location with first >= 2 x last. The readout is random, so a
    single draw's order of close locations is not a prediction; this is its spread. Noise only:
    no contact solve is repeated."""
    n = settings.readout_draws
    names = [r[1] for r in runs]
    order = list(dict.fromkeys(names))
    H = np.empty((n, len(order)))
    idx = {nm: [b for b, x in enumerate(names) if x == nm] for nm in order}
    S = np.stack([readings_noise(np.repeat(S_true[b:b + 1], n, axis=0), settings,
                                 run_rng(settings.seed, r[1], r[2]))
                  for b, r in enumerate(runs)], axis=1)           # (draws, B, steps, 3)
    h = _eq1(seq, S.reshape((-1,) + S.shape[2:]))[1].reshape(n, len(runs))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for j, nm in enumerate(order):
            H[:, j] = np.nanmean(h[:, idx[nm]], axis=1)
    out: dict[str, Any] = {
        "draws": n, "seed": settings.seed,
        "definition": "robust_eq1_span10 with the FSS015/DAQ readout errors",
        "by_location": {nm: {"mean": float(H[:, j].mean()), "sd": float(H[:, j].std(ddof=1))
                             if n > 1 else 0.0} for j, nm in enumerate(order)}}
    for group, locs in (("G1", protocol.g1_locations), ("G2", protocol.g2_locations)):
        cols = [order.index(x) for x in locs if x in order]
        if not cols:
            continue
        low = H[:, cols].min(axis=1)
        sd = float(low.std(ddof=1)) if n > 1 else 0.0
        out[f"{group}_lowest"] = {"mean": float(low.mean()), "sd": sd,
                                  "standard_error": sd / math.sqrt(n),
                                  "min": float(low.min()), "max": float(low.max())}
        if group == "G1" and len(cols) > 1:
            v = H[:, cols]
            ok = np.all(np.diff(v, axis=1) < 0, axis=1) & (v[:, 0] >= 2.0 * v[:, -1])
            out["G1_monotonic_share"] = float(ok.mean())
            m = v.mean(axis=0)
            # the mean profile's steps against their standard errors (paired over the draws)
            d = np.diff(v, axis=1)
            se = d.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(d.shape[1])
            out["G1_mean_profile"] = {
                "locations": [order[c] for c in cols], "mean": m.tolist(),
                "monotonic": bool(np.all(np.diff(m) < 0) and m[0] >= 2.0 * m[-1]),
                "smallest_fall_over_its_standard_error": float(np.min(-d.mean(0) / np.where(
                    se > 0, se, np.inf))) if n > 1 else None}
    return out


def _eq1(seq, S):
    """(paper, robust, zero_span) eq. 1 of every loop at once, ``S`` (B, steps, 3) -> three (B,)
    arrays: mean over all three sensors / over the sensors whose span is >= 10 % of the
    largest; ``zero_span``: whether a sensor had no span but a loop (eq. 1 divides by zero:
    the paper's definition is then infinite)."""
    S = np.asarray(S, float)
    B = S.shape[0]
    lu, su, ld, sd = loop_from_steps(seq, S.transpose(1, 0, 2).reshape(S.shape[1], -1))
    h = np.asarray(hysteresis_percent(lu, su, ld, sd), float).reshape(B, 3)
    span = np.abs(su[-1] - su[0]).reshape(B, 3)
    keep = span >= 0.1 * span.max(axis=1, keepdims=True)
    h = np.where((span == 0) & np.isnan(h), np.nan, h)   # no span, no loop: 0/0, left out
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return (np.nanmean(h, axis=1), np.nanmean(np.where(keep, h, np.nan), axis=1),
                np.any((span == 0) & np.isinf(h), axis=1))
