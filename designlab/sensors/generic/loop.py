"""loop -> predict for a sensor definition: the effects a loop learned on a measured sensor
(outputs named as the definition's channels, inputs as its loads, e.g. ``tip_Fz``) are added to
this design's readings over its protocol, and the calibration, force error and hysteresis are
evaluated again."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.sensors.generic import metrics

#: the loop's quantity of each reading unit a definition's transducers use
_QUANTITY = {"V": "voltage", "mV/V": "voltage", "mm": "length", "rad": "angle", "pF": "voltage",
             "uT": "voltage"}
#: samples per hold of the protocol's time series the learned effects see
SAMPLES_PER_HOLD = 20


def _learned(model_path: str | Path, channels: list[str], loads: list[str]):
    from designlab.loop.model import load_model

    learned = load_model(model_path, "--model")
    missing = [c for c in learned.effects if c not in channels]
    if missing:
        raise ParameterError("--model", str(model_path), "a model whose outputs are this "
                             f"sensor's channels ({', '.join(channels)}; it has "
                             f"{', '.join(missing)})")
    for effs in learned.effects.values():
        for f in effs:
            if f.effect.channel and f.effect.channel not in loads:
                raise ParameterError("--model", str(model_path), "effects on this sensor's "
                                     f"loads ({', '.join(loads)}; an effect uses input "
                                     f"{f.effect.channel!r})")
    return learned


def corrected_readings(learned, t: np.ndarray, loads: dict[str, np.ndarray],
                       readings: np.ndarray, channels: list[str],
                       units: dict[str, str]) -> np.ndarray:
    """(n, n_channels) readings of the time series plus the learned effects (the mechanisms
    only: the measured sensor's refit of its own base is not carried over)."""
    from designlab.loop import effects as fx
    from designlab.measured.dataset import from_arrays

    quantity = {k: "torque" if k.rsplit("_", 1)[-1].startswith("M") else "force" for k in loads}
    unit = {k: "Nmm" if quantity[k] == "torque" else "N" for k in loads}
    data = from_arrays(t, loads, {c: readings[:, i] for i, c in enumerate(channels)},
                       units={**unit, **units}, quantities={**quantity, **{
                           c: _QUANTITY.get(units.get(c, ""), "voltage") for c in channels}})
    out = readings.copy()
    for i, c in enumerate(channels):
        y = readings[:, i].copy()
        for f in learned.effects.get(c, []):
            f = dataclasses.replace(f, nuisance=(), alpha=(0.0,) * int(bool(f.effect.intercept)))
            y = y + fx.contribution(f, fx.Context(data, c, y, (), None))
        out[:, i] = y
    return out


def apply_model(report: dict[str, Any], result, model_path: str | Path, protocol, settings,
                part=None) -> dict[str, Any]:
    """The corrected metrics with ``learned_effects`` and ``learned_from``."""
    channels = [c["name"] for c in report["channels"]]
    units = {c["name"]: c["unit"] for c in report["channels"]}
    P, active = metrics.active_loads(result.loads, result.load_names)
    learned = _learned(model_path, channels, active)
    hold = float(report["hold_s"])
    n = len(P)
    t = (np.arange(n * SAMPLES_PER_HOLD) + 1) * hold / SAMPLES_PER_HOLD
    idx = np.repeat(np.arange(n), SAMPLES_PER_HOLD)
    ends = np.arange(n) * SAMPLES_PER_HOLD + SAMPLES_PER_HOLD - 1
    S = corrected_readings(learned, t, {a: P[idx, j] for j, a in enumerate(active)},
                           result.readings[idx], channels, units)[ends]
    noise = np.array([c["noise"] for c in report["channels"]], float)
    moment_cols = [i for i, a in enumerate(active) if a.rsplit("_", 1)[-1].startswith("M")]
    cal = metrics.calibration(S, P, moment_cols, report.get("moment_scale_mm"), noise)
    fe = metrics.force_error(S, P, noise, protocol.noise_repeats, protocol.seed)
    proto = part.protocol() if part is not None else None
    loops = proto.loops() if proto is not None and hasattr(proto, "loops") else []
    hyst = metrics.hysteresis(loops, S)
    out = {"calibration_matrix": cal["matrix"], "condition_number": cal["condition_number"],
           "cross_talk_percent": dict(zip(active, cal["cross_talk_percent"])),
           "force_error": {**report["force_error"], "rms": dict(zip(active, fe["rms"])),
                           "rms_std": dict(zip(active, fe["rms_std"]))},
           "learned_effects": {c: [f.effect.name for f in learned.effects.get(c, [])]
                               for c in channels},
           "learned_from": str(model_path),
           "loop_protocol": (f"the protocol's loads in order, each held {hold:g} s "
                             f"({SAMPLES_PER_HOLD} samples), read at the end of the hold")}
    if hyst is not None:
        out["hysteresis_percent"] = hyst
    return out
