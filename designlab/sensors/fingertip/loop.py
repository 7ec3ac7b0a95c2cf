"""The loop, both ways, for seed 001's fingertip (hanging weights at load points on the tip).

measured -> loop: a dataset card of a hanging-weight test has the inputs

* the hanging mass (``weight``, g, tray included; a drive input),
* where it hangs: the moment arm of the load about the ball centre (``location``, mm, kind
  ``location``: the height of a lateral G1 load, the radius of an axial G2 load),
* the fingertip's rotation (``rotation``, deg, quantity angle),

and the outputs ``sensor_1..3`` (V, change from the unloaded reading). ``designlab loop --base
load-arm`` fits the wrench such a load makes (:mod:`designlab.loop.base_models`) and searches the
residual: seed 001's friction proportional to the moment arm is ``friction_arm``.

loop -> predict (:func:`apply_model`): the learned mechanisms are added to a new design's
virtual-test channels (its linear FEM readings, the base ``gains`` of the loop: wrench at the
ball -> sensor V) along the protocol's staircase at every load point and rotation, and the
metrics (hysteresis eq. 1, calibration matrix, condition number...) are evaluated again.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from designlab.calibration.calibration_matrix import (condition_number, cross_talk_percent,
                                                      fit_calibration_matrix, linearity_percent)
from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps
from designlab.errors import ParameterError
from designlab.sensors.protocols import G_ACC, HangingWeightTest

OUTPUTS = ("sensor_1", "sensor_2", "sensor_3")
#: what a measured fingertip card gives, by role: (name used here, quantity, kind, unit)
ROLES = {"load": ("weight", "mass", "drive", "g"),
         "arm": ("location", "length", "location", "mm"),
         "rotation": ("rotation", "angle", "drive", "deg")}


def moment_arm(point: np.ndarray, direction: np.ndarray) -> float:
    """Moment arm (mm) of a force along ``direction`` through ``point`` about the ball centre
    (the origin): ``|p x d| / |d|``; the height of a lateral load, the radius of an axial one."""
    d = np.asarray(direction, float)
    return float(np.linalg.norm(np.cross(np.asarray(point, float), d)) / np.linalg.norm(d))


@dataclass(frozen=True)
class LoadRun:
    """One loading/unloading staircase: a load point at one rotation of the fingertip."""

    group: str
    name: str
    rotation_deg: float
    arm_mm: float
    wrench: np.ndarray           # (6,) f_x, f_y, f_z (N), m_x, m_y, m_z (N mm) per N of load


def load_runs(part, protocol: HangingWeightTest, rotations_deg) -> list[LoadRun]:
    """Every (load point, rotation) of the protocol on ``part``, G1 then G2."""
    from designlab.sensors.fingertip.model import wrench_at_ball
    from designlab.sensors.fingertip.runs import location_rotations

    return [LoadRun(group, name, float(rot), moment_arm(p, d), wrench_at_ball(p, d))
            for group, name, rot, p, d in location_rotations(part, protocol, rotations_deg)]


def linear_readings(unit: np.ndarray, run: LoadRun, load: np.ndarray) -> np.ndarray:
    """(n_t, 3) sensor readings (V) of the linear virtual test: ``unit`` (n_t, 6, 3) sensor force
    per unit wrench (N), the run's wrench per N, the load history (N)."""
    from designlab.sensors.fingertip.model import FSS015_V_PER_N

    return FSS015_V_PER_N * np.einsum("tcs,c->ts", unit, run.wrench) * load[:, None]


def staircase_inputs(run: LoadRun, load: np.ndarray) -> dict[str, np.ndarray]:
    """The card's inputs of one run by role: hanging mass (g), moment arm (mm), rotation (deg)."""
    n = load.size
    return {"load": load / G_ACC * 1e3, "arm": np.full(n, run.arm_mm),
            "rotation": np.full(n, run.rotation_deg)}


def _roles(inputs: dict[str, dict]) -> dict[str, str]:
    """The learned model's input names by role, from their quantity and kind."""
    out = {}
    for name, meta in inputs.items():
        q, k = meta.get("quantity"), meta.get("kind", "drive")
        if k == "location":
            out.setdefault("arm", name)
        elif q == "angle":
            out.setdefault("rotation", name)
        elif q in ("mass", "force") and k == "drive":
            out.setdefault("load", name)
    return out


def _needed_inputs(model) -> set[str]:
    """Inputs the model's effects read (their channel and input names among their settings)."""
    names = set(model.inputs)
    need = set()
    for effs in model.effects.values():
        for f in effs:
            if f.effect.channel:
                need.add(f.effect.channel)
            need |= {v for v in f.theta.values() if isinstance(v, str) and v in names}
    return need


def _learned(model_path: str | Path):
    """The loop's model with outputs sensor_1..3."""
    from designlab.loop.model import load_model

    learned = load_model(model_path, "--model")
    missing = [o for o in OUTPUTS if o not in learned.outputs]
    if missing:
        raise ParameterError("--model", str(model_path),
                             f"a fingertip model with outputs {', '.join(OUTPUTS)} (it has "
                             f"{', '.join(learned.outputs) or 'none'})")
    return learned


def _input_roles(learned, model_path: str | Path) -> dict[str, str]:
    """The model's input names by role; an error when an effect reads an input the virtual test
    does not have (other than the hanging weight, moment arm and rotation)."""
    roles = _roles(learned.inputs)
    by_name = {v: k for k, v in roles.items()}
    unknown = sorted(n for n in _needed_inputs(learned) if n not in by_name)
    if unknown:
        raise ParameterError("--model", str(model_path),
                             f"effects on the hanging weight, moment arm and rotation (it uses "
                             f"input {unknown[0]!r}, which the virtual test does not have)")
    return roles


def _mechanism(f):
    """The learned effect without the measured sensor's refit of its own base: the mechanism
    transfers, not the nuisance terms and intercept."""
    return dataclasses.replace(f, nuisance=(), alpha=(0.0,) * int(bool(f.effect.intercept)))


def _card_inputs(learned, roles: dict[str, str], runs: list[LoadRun],
                 load: np.ndarray) -> dict[str, np.ndarray]:
    """The runs' inputs under the model's names, in the card's canonical units (mass g, force
    N)."""
    by_role = {k: np.concatenate([staircase_inputs(r, load)[k] for r in runs])
               for k in ROLES}
    ins = {}
    for role, name in roles.items():
        v = by_role[role]
        if role == "load" and learned.inputs[name].get("quantity") == "force":
            v = v * 1e-3 * G_ACC
        ins[name] = v
    return ins


def _staircases(learned, roles, runs: list[LoadRun], unit: np.ndarray, t: np.ndarray,
                load: np.ndarray, dt_s: float):
    """The runs one after the other, as a test rig logs them (friction carries its state over):
    the dataset of the linear readings with the card's inputs, and those readings (n, 3)."""
    from designlab.measured.dataset import from_arrays

    seg = np.zeros(t.size * len(runs), int)
    tt = np.concatenate([t + b * (t[-1] + dt_s) for b in range(len(runs))])
    lin = np.concatenate([linear_readings(unit, r, load) for r in runs]) if runs else \
        np.zeros((0, 3))
    ins = _card_inputs(learned, roles, runs, load)
    data = from_arrays(tt, ins, {o: lin[:, k] for k, o in enumerate(OUTPUTS)}, segment=seg,
                       units={**{n_: learned.inputs[n_].get("unit") or None for n_ in ins},
                              **{o: "V" for o in OUTPUTS}},
                       quantities={n_: learned.inputs[n_].get("quantity") for n_ in ins},
                       kinds={n_: learned.inputs[n_].get("kind", "drive") for n_ in ins})
    return data, lin


def _with_effects(effects: dict[str, list], data, lin: np.ndarray) -> dict[str, np.ndarray]:
    """Each output's linear readings plus its effects' contributions (the base reads the wrench;
    here the readings are the linear test's: the effects only are added)."""
    from designlab.loop import effects as fx

    full = {}
    for k, o in enumerate(OUTPUTS):
        y = lin[:, k].copy()
        for f in effects[o]:
            y = y + fx.contribution(f, fx.Context(data, o, y, f.nuisance, None))
        full[o] = y
    return full


def _per_run(Y: np.ndarray, n_runs: int, n: int) -> list[np.ndarray]:
    """(n_runs * n, 3) readings split into one (n, 3) array per run."""
    return [Y[b * n:(b + 1) * n] for b in range(n_runs)]


def apply_model(report: dict[str, Any], prediction, model_path: str | Path,
                protocol: HangingWeightTest, settings, part=None) -> dict[str, Any]:
    """loop -> predict: the mechanisms a loop learned on a measured fingertip (``model.json`` of
    ``designlab loop``, outputs sensor_1..3) are added to this design's linear virtual-test
    readings at every load point and rotation of the protocol; returns the metrics evaluated
    again (hysteresis, calibration matrix, condition number, ...), ``learned_effects``,
    ``learned_from`` and ``loop_base`` (the same metrics of the linear readings alone).
    ``part``: the design (its load points); default: ``prediction.part``."""
    learned = _learned(model_path)
    part = part if part is not None else getattr(prediction, "part", None)
    if part is None:
        raise ParameterError("--model", str(model_path),
                             "the fingertip design whose load points the effects act at")
    roles = _input_roles(learned, model_path)
    t, load, step = protocol.time_history()
    unit = prediction.unit_readings
    if unit.shape[0] != t.size:
        unit = np.broadcast_to(unit[-1], (t.size, 6, 3))
    runs = load_runs(part, protocol, settings.rotations_deg)
    effects = {o: [_mechanism(f) for f in learned.effects.get(o, [])] for o in OUTPUTS}
    data, lin = _staircases(learned, roles, runs, unit, t, load, protocol.dt_s)
    full = _with_effects(effects, data, lin)
    corrected = _per_run(np.column_stack([full[o] for o in OUTPUTS]), len(runs), t.size)
    out = evaluate_readings(protocol, settings.rotations_deg, t, load, step, runs, corrected)
    plain = evaluate_readings(protocol, settings.rotations_deg, t, load, step, runs,
                              _per_run(lin, len(runs), t.size))
    out["loop_base"] = {k: plain[k] for k in ("hysteresis_percent", "condition_number",
                                               "linearity_percent_span")}
    out["loop_base"]["what"] = ("the design's linear virtual test (FEM gains: wrench at the "
                                "ball -> sensor V) without the learned effects")
    out["learned_effects"] = {o: [f.effect.name for f in effects[o]] for o in OUTPUTS}
    out["learned_from"] = str(model_path)
    return out


def evaluate_readings(protocol: HangingWeightTest, rotations_deg, t: np.ndarray,
                      load: np.ndarray, step: np.ndarray, runs: list[LoadRun],
                      readings: list[np.ndarray]) -> dict[str, Any]:
    """The metrics of :func:`designlab.sensors.fingertip.virtual.evaluate` from given readings (V,
    (n_t, 3) per run of :func:`load_runs`): eq. 1 per sensor over the sensors whose span is at
    least 10 % of the largest, mean over rotations, then locations; the calibration matrix from
    the reading changes at the largest weight; condition number, sensitivity, linearity."""
    from designlab.sensors.fingertip.model import FSS015_V_PER_N

    masks = protocol.read_masks(t, step)
    seq = protocol.sequence_g
    k = int(np.argmax(seq))
    per: dict[str, list[float]] = {}
    S_rows, P_rows, loops = [], [], {}
    lin = []
    for r, Y in zip(runs, readings):
        S = np.array([Y[m].mean(axis=0) for m in masks])
        lu, su, ld, sd = loop_from_steps(seq, S)
        span = np.abs(su[-1] - su[0])
        keep = span >= 0.1 * span.max()
        per.setdefault(r.name, []).append(float(np.mean(hysteresis_percent(lu, su, ld, sd)[keep])))
        f = r.wrench[:3]
        P_rows.append(f * (load[masks[k]].mean() - load[masks[0]].mean()))
        S_rows.append(S[k] - S[0])
        if r.rotation_deg == rotations_deg[0]:
            loops[r.name] = {"weights_g": seq.tolist(), "readings_V": S.tolist()}
            for ch in range(3):
                if np.ptp(S[: k + 1, ch]) > 0:
                    lin.append(linearity_percent(seq[: k + 1], S[: k + 1, ch]))
    by_location = {n: float(np.mean(v)) for n, v in per.items()}
    group = {}
    for g, names in (("G1", protocol.g1_locations), ("G2", protocol.g2_locations)):
        vals = [by_location[n] for n in names if n in by_location]
        if vals:
            group[g] = float(np.mean(vals))
    S_all, P_all = np.array(S_rows), np.array(P_rows)
    A, fit = fit_calibration_matrix(S_all, P_all)
    sens = np.linalg.pinv(A)
    return {
        "hysteresis_percent": {"overall": float(np.mean(list(by_location.values()))),
                               "by_group": group, "by_location": by_location},
        "calibration_matrix": A.tolist(),
        "calibration_units": "N per V (P = A S)",
        "condition_number": condition_number(A),
        "calibration_fit": fit,
        "sensitivity": {"V_per_N": {ax: float(np.linalg.norm(sens[:, i]))
                                    for i, ax in enumerate("xyz")},
                        "matrix_V_per_N": sens.tolist()},
        "linearity_percent_span": float(max(lin)) if lin else float("nan"),
        "cross_talk_percent": cross_talk_percent(P_all, S_all @ A.T).tolist(),
        "loops": loops,
        "peak_sensor_force_N": float(np.abs(S_all).max() / FSS015_V_PER_N),
        "applied_vs_estimated": {"applied_N": P_all.tolist(),
                                 "estimated_N": (S_all @ A.T).tolist()},
    }
