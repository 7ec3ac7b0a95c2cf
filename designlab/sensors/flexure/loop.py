"""The loop, both ways, for seed 002's spring flexure (wrench at the fingertip -> pose). Details:
docs/models/flexure_modules.md.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.sensors.flexure.spring import TWIST, WRENCH
from designlab.sensors.flexure.model import evaluate, staircase_hysteresis

INPUT_UNITS = {**{w: "Nmm" for w in WRENCH[:3]}, **{w: "N" for w in WRENCH[3:]}}
OUTPUT_UNITS = {**{t: "rad" for t in TWIST[:3]}, **{t: "mm" for t in TWIST[3:]}}


def _unit_factor(learned_unit: str, ours: str) -> float:
    """Factor from our unit (rad or mm) to the model's output unit."""
    if not learned_unit or learned_unit == ours:
        return 1.0
    if ours == "rad" and learned_unit == "deg":
        return 180.0 / np.pi
    raise ParameterError("--model", learned_unit, f"a flexure model with outputs in {ours}"
                         + (" or deg" if ours == "rad" else ""))


def _learned(model_path: str | Path):
    from designlab.loop.model import load_model

    learned = load_model(model_path, "--model")
    missing = [o for o in TWIST if o not in learned.outputs]
    if missing:
        raise ParameterError("--model", str(model_path),
                             f"a flexure model with outputs {', '.join(TWIST)} (it has "
                             f"{', '.join(learned.outputs) or 'none'})")
    for effs in learned.effects.values():
        for f in effs:
            if f.effect.channel and f.effect.channel not in WRENCH:
                raise ParameterError("--model", str(model_path),
                                     f"effects on the wrench {', '.join(WRENCH)} (an effect "
                                     f"uses input {f.effect.channel!r})")
    return learned


def corrected_poses(learned, C: np.ndarray, t: np.ndarray, W: np.ndarray,
                    segment: np.ndarray | None = None) -> np.ndarray:
    """(n, 6) twists (rad, mm) of the wrench history ``W`` (n, 6) through the compliance ``C``
    (6x6, designlab units) plus the learned effects (the mechanisms only: the measured
    flexure's refit of its own base is not carried over)."""
    from designlab.loop import effects as fx
    from designlab.measured.dataset import from_arrays

    X = W @ C.T
    # the outputs in the units the model learned them in (an effect reading a pose output,
    # pose_reference, sees what it saw in the loop: deg when the card read deg)
    data = from_arrays(t, {w: W[:, i] for i, w in enumerate(WRENCH)},
                       {o: X[:, i] * _unit_factor(learned.units.get(o, ""), OUTPUT_UNITS[o])
                        for i, o in enumerate(TWIST)}, segment=segment,
                       units={**INPUT_UNITS, **{o: learned.units.get(o) or OUTPUT_UNITS[o]
                                                for o in TWIST}})
    out = X.copy()
    for i, o in enumerate(TWIST):
        k = _unit_factor(learned.units.get(o, ""), OUTPUT_UNITS[o])
        y = X[:, i] * k
        for f in learned.effects.get(o, []):
            f = dataclasses.replace(f, nuisance=(),
                                    alpha=(0.0,) * int(bool(f.effect.intercept)))
            y = y + fx.contribution(f, fx.Context(data, o, y, (), None))
        out[:, i] = y / k
    return out


def apply_model(report: dict[str, Any], prediction, model_path: str | Path, protocol,
                settings, part=None) -> dict[str, Any]:
    """loop -> predict: the effects a loop learned on a measured flexure are added to this
    design's poses and the wrench error, calibration and hysteresis are evaluated again.
    Returns the corrected metrics with ``learned_effects`` and ``learned_from``."""
    learned = _learned(model_path)
    C = np.linalg.inv(prediction.K_true)
    W = prediction.wrenches
    n_per = max(1, int(round(settings.hold_s / settings.dt_s)))
    Wt = np.repeat(W, n_per, axis=0)
    t = np.arange(len(Wt)) * settings.dt_s
    ends = np.arange(len(W)) * n_per + n_per - 1
    X_eff = corrected_poses(learned, C, t, Wt)[ends]
    noise = prediction.poses - W @ C.T                   # the run's pose noise, kept
    X = X_eff + noise
    W_est = X @ prediction.K_design.T
    out = evaluate(W, X, W_est, prediction.K_true, prediction.K_design)
    out["hysteresis_percent"] = _hysteresis(learned, C, prediction.K_design, protocol, settings)
    out["learned_effects"] = {o: [f.effect.name for f in learned.effects.get(o, [])]
                              for o in TWIST}
    out["learned_from"] = str(model_path)
    out["loop_protocol"] = (f"the protocol's wrenches in order, each held {settings.hold_s:g} s "
                            f"(dt {settings.dt_s:g} s), read at the end of the hold")
    return out


def _hysteresis(learned, C, K_design, protocol, settings) -> dict[str, Any]:
    """Eq. (1) per axis on the estimated wrench over a 0 -> max -> 0 staircase of each axis,
    through the compliance and the learned effects."""
    def twist_of(name, t, load):
        Wt = np.zeros((t.size, 6))
        Wt[:, WRENCH.index(name)] = load
        return corrected_poses(learned, C, t, Wt)

    return staircase_hysteresis(protocol, settings, K_design, twist_of,
                                f"elastic flexure + learned effects: staircase of "
                                f"{protocol.steps} levels, {settings.hold_s:g} s holds, "
                                "reading at the end of each hold")
