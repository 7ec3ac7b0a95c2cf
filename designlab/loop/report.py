"""The loop's report: loop.json's records per output, the verdicts, and the files written.

Each output's entry is assembled once from what the selection left (:class:`Selected`); the
verdict is a list of clauses joined in one place, the peer's sentence one template per kind.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import FileSet
from designlab.calibration.metrics import ncc, rmse
from designlab.loop import effects as fx
from designlab.loop.model import SensorModel
from designlab.loop.noise_floor import lag1_autocorrelation as lag1
from designlab.loop.plots import plot_output
from designlab.measured.dataset import Dataset

#: the acceptance rule as loop.json states it
RULE = ("mean relative held-out RMSE improvement over the held-out units (runs or blocks) "
        "> min_relative, and > n_se standard errors or > 0 on every unit")

#: the verdict's sentence per kind, against the noise floor (values in the output's unit)
PEER_VERDICTS = {
    "explained": "explained: the validation error {after:.4g} {unit} is {ratio:.2f}x the noise "
                 "floor {floor:.4g} {unit} (at most {factor:g}x), from the base's {base:.4g} "
                 "{unit}; the best peer ({peer_kind}) reaches {peer:.4g} {unit}; the residual "
                 "correlates at most with {top}",
    "noise": "noise: the base's validation error {base:.4g} {unit} is already {ratio_base:.2f}x "
             "the noise floor {floor:.4g} {unit} (at most {factor:g}x); the physics reaches "
             "{after:.4g} {unit}, the best peer ({peer_kind}) {peer:.4g} {unit}",
    "missing mechanism": "missing mechanism: the validation error {after:.4g} {unit} is "
                         "{ratio:.2f}x the noise floor {floor:.4g} {unit} (explained needs at "
                         "most {factor:g}x), from the base's {base:.4g} {unit}; the best peer "
                         "({peer_kind}) reaches {peer:.4g} {unit}; {why}",
}
#: why structure remains, per reason of :func:`verdict_kind` (a "missing mechanism")
MISSING_WHY = {
    "floor": "the residual correlates most with {top}",
    "correlated": "the residual still correlates with {top} (|r| >= {r_min:g})",
    "peer": "the peer does better by more than {margin:g}x; the residual correlates most with "
            "{top}",
}
#: "explained" needs the validation error within this factor of the noise floor
FLOOR_FACTOR = 1.5
#: "explained" needs no peer better than the physics by this factor
PEER_MARGIN = 1.3
#: a residual correlating this much with an input, its history or time has structure left
STRUCTURE_R = 0.3
#: loop.json's statement of the verdict's rule
VERDICT_RULE = (f"noise: the base's validation error is within {FLOOR_FACTOR:g}x the noise "
                f"floor; missing mechanism: the error after the selection is above "
                f"{FLOOR_FACTOR:g}x the floor, or the residual correlates with an input, its "
                f"history or time by |r| >= {STRUCTURE_R:g}, or the best peer is better by "
                f"more than {PEER_MARGIN:g}x; explained: otherwise")

#: the loop.json keys of the first output repeated at the top
FIRST_OUTPUT_KEYS = ("effects", "error_before", "error_after", "validation",
                     "unexplained_fraction", "peer", "explained_of_learnable", "verdict_kind",
                     "noise_floor", "best_peer")


@dataclass
class LoopResult:
    """The improved model, the loop.json report and the series behind the plots."""

    model: SensorModel
    report: dict
    series: dict = field(default_factory=dict)


@dataclass
class Selected:
    """What the selection of one output leaves for its report.

    Series on the training data (``y_train``, ``start_train``: the model as loaded or fitted,
    before any effect, ``final_train``) and on the validation data (``y_val``, ``base_val``:
    the model before the selection, ``final_val``), in the output's unit."""

    unit: str
    accepted: list[dict]
    rounds: list[dict]
    stages: list[dict]
    not_applicable: dict
    candidates_left: int
    max_effects: int
    run_offsets: dict | None
    base_parameters: dict
    y_train: np.ndarray
    start_train: np.ndarray
    final_train: np.ndarray
    y_val: np.ndarray
    base_val: np.ndarray
    final_val: np.ndarray
    dropped: list[dict] = field(default_factory=list)


def output_report(s: Selected, val: Dataset) -> tuple[dict, dict]:
    """loop.json's entry of one output and the series of its plots."""
    yv, yhat_v = s.y_val, s.final_val
    err_before = rmse(yv, s.base_val)
    r_v = yv - yhat_v
    var_y = float(np.var(yv))
    unexplained = float(np.var(r_v) / var_y) if var_y > 0 else float("nan")
    corrs = residual_correlations(val, r_v, yhat_v)
    stop = stop_reason(s.rounds, s.candidates_left, s.max_effects)
    rep = {
        "unit": s.unit, "effects": s.accepted,
        "error_before": err_before, "error_after": rmse(yv, yhat_v),
        "train_error_before": rmse(s.y_train, s.start_train),
        "train_error_after": rmse(s.y_train, s.final_train),
        "validation": _validation(val, yv, s.base_val, yhat_v),
        "unexplained_fraction": unexplained, "residual_correlations": corrs[:8],
        "stopped": stop, "verdict": verdict(s.accepted, stop, unexplained, corrs, s.dropped),
        "dropped": s.dropped,
        "rounds": s.rounds, "not_applicable": s.not_applicable,
        **({"run_offsets": s.run_offsets} if s.run_offsets is not None else {}),
        "base": s.base_parameters,
    }
    ser = {"t_val": val.t, "seg_val": val.segment, "y_val": yv, "base_val": s.base_val,
           "corrs": corrs,
           "final_val": yhat_v, "stages": s.stages, "residual_val": r_v,
           "top_var": corrs[0]["variable"] if corrs else None,
           "top_values": variable_values(val, corrs[0]["variable"], yhat_v) if corrs else None}
    return rep, ser


def _validation(val: Dataset, yv: np.ndarray, base_v: np.ndarray, yhat_v: np.ndarray) -> dict:
    return {"samples": len(val), "runs": sorted({val.segments[s]["path"]
                                                 for s in np.unique(val.segment)}),
            "rmse_before": rmse(yv, base_v), "rmse_after": rmse(yv, yhat_v),
            "ncc_after": ncc(yv, yhat_v),
            "range": float(np.ptp(yv)),
            "nrmse_after_percent": 100 * rmse(yv, yhat_v) / max(np.ptp(yv), 1e-300)}


def stop_reason(rounds: list[dict], candidates_left: int, max_effects: int) -> str:
    """Why the selection stopped, from its last round."""
    last = rounds[-1] if rounds else None
    if last is not None and last.get("at_floor"):
        f = last["at_floor"]
        return (f"what the model leaves in cross-validation ({f['held_out_error']:.4g}) is "
                f"within {f['factor']:g}x the noise floor of the training data "
                f"({f['noise_floor']:.4g}): a further effect could only fit noise")
    if last is not None and last.get("failed") and not candidates_left:
        return last["failed"]
    if last is not None and last["accepted"] is None and last["best"] is None:
        return "every candidate's fit failed (see rounds)"
    if last is not None and last["accepted"] is None:
        b = last["candidates"][last["best"]]
        return (f"no candidate lowers the held-out error by more than noise (best: "
                f"{last['best']}, {100 * b['relative']:+.2f} %, {b['z']:.1f} standard errors)")
    if not candidates_left:
        return "every applicable effect of the library is in the model"
    return f"max_effects = {max_effects} reached"


def _strongest(corrs: list[dict]) -> str:
    return (f"{corrs[0]['variable']} (r = {corrs[0]['correlation']:+.2f})" if corrs
            else "nothing")


def verdict(accepted: list[dict], stop: str, unexplained: float, corrs: list[dict],
            dropped: list[dict] = ()) -> str:
    """The selection's verdict: what was accepted, why it stopped, what the backward pass
    dropped, what the validation data did not confirm, and what the remaining residual is and
    correlates with."""
    clauses = [f"{len(accepted)} effect(s) accepted", stop]
    if dropped:
        clauses.append("dropped by the backward pass: " + ", ".join(
            f"{d['key']} ({d['why']})" for d in dropped))
    unconfirmed = [a["key"] for a in accepted if not a["validation_improved"]]
    if unconfirmed:
        clauses.append("not confirmed by the validation data (its error rose with them): "
                       + ", ".join(unconfirmed))
    clauses.append(f"the remaining residual is {100 * unexplained:.1f} % of the validation "
                   f"variance and correlates most with {_strongest(corrs)}")
    return "; ".join(clauses)


def verdict_kind(base: float, after: float, peer: float | None,
                 floor: float | None = None, structure_r: float = 0.0) -> str:
    """The verdict against the noise floor ``floor`` (see :data:`VERDICT_RULE`;
    ``structure_r``: the residual's largest |correlation| with an input, its history or time).
    Without a floor: noise when neither the physics nor the peer lowers the base's error by
    5 %, explained when the physics does and is within 1.3x of the peer."""
    return _verdict(base, after, peer, floor, structure_r)[0]


def _verdict(base: float, after: float, peer: float | None, floor: float | None,
             structure_r: float) -> tuple[str, str | None]:
    """(kind, why) of :func:`verdict_kind`; ``why`` a key of :data:`MISSING_WHY`."""
    has_peer = peer is not None and bool(np.isfinite(peer))
    if floor is None or not np.isfinite(floor) or floor <= 0:
        phys = after < 0.95 * base
        if not has_peer:
            return ("explained" if phys else "noise"), None
        if not phys and peer >= 0.95 * base:
            return "noise", None
        return ("explained", None) if phys and after <= 1.3 * peer else (
            "missing mechanism", "peer")
    if base <= FLOOR_FACTOR * floor:
        return "noise", None
    if after > FLOOR_FACTOR * floor:
        return "missing mechanism", "floor"
    if abs(structure_r) >= STRUCTURE_R:
        return "missing mechanism", "correlated"
    if has_peer and peer * PEER_MARGIN < after:
        return "missing mechanism", "peer"
    return "explained", None


def structure(corrs: list[dict]) -> dict | None:
    """The residual's strongest correlation with an input, its history or time (the
    prediction left out)."""
    return next((c for c in corrs if c["variable"] != "prediction"), None)


def _over(a: float, b: float, default: float | None = float("inf")) -> float | None:
    """a / b, ``default`` when b is not a positive number."""
    return a / b if np.isfinite(b) and b > 0 else default


def add_verdict(rep: dict, ser: dict, data: Dataset, o: str, floor: dict,
                peers: list[tuple[np.ndarray, dict]]) -> None:
    """The noise floor, the peers (each one's record in ``peers``, the best on the inner split
    named in ``best_peer``, the NARX network's record as ``peer``), the explained fraction of the learnable error, the verdict kind and its
    sentence before the selection's verdict, into an output's entry."""
    vmask = data.role == "validate"
    base, after, unit = rep["error_before"], rep["error_after"], rep["unit"]
    sigma = floor["sigma"]
    top = structure(ser.get("corrs") or [])
    r_top = top["correlation"] if top else 0.0
    rep["noise_floor"] = {**floor, "ratio_before": _over(base, sigma, None),
                          "ratio_after": _over(after, sigma, None),
                          "factor": FLOOR_FACTOR,
                          "residual_lag1_autocorrelation": lag1(ser["residual_val"],
                                                                data.segment[vmask])}
    rep["verdict_rule"] = VERDICT_RULE
    best = min(peers, key=lambda p: p[1].get("inner_error", p[1]["error"])) if peers else None
    err = best[1]["error"] if best else None
    rep["peers"] = [p[1] for p in peers]
    rep["best_peer"] = best[1]["kind"] if best else None
    # ``peer`` keeps the NARX network's record (its keys as ever); the verdict uses the best
    rep["peer"] = next((p[1] for p in peers if p[1]["kind"] == "narx"),
                       best[1] if best else None)
    rep["explained_of_learnable"] = ((base - after) / (base - err)
                                     if err is not None and base - err > 0 else None)
    kind, why = _verdict(base, after, err, sigma, r_top)
    rep["verdict_kind"] = kind
    values = {"after": after, "base": base, "unit": unit, "floor": sigma,
              "ratio": _over(after, sigma), "ratio_base": _over(base, sigma),
              "factor": FLOOR_FACTOR,
              "peer": err if err is not None else float("nan"),
              "peer_kind": rep["best_peer"] or "none fitted", "margin": PEER_MARGIN,
              "r_min": STRUCTURE_R,
              "top": _strongest([top] if top else [])}
    clauses = [PEER_VERDICTS[kind].format(**values, why=MISSING_WHY.get(why, "").format(
        **values))]
    if best and rep["explained_of_learnable"] is None:
        clauses.append(f"the peer is no better than the base ({err:.4g} vs {base:.4g} {unit}): "
                       "explained_of_learnable is null")
    rep["verdict"] = "; ".join([*clauses, rep["verdict"]])
    if best:
        ser["peer_val"] = best[0][vmask]
        ser["peer_kind"], ser["peer_error"] = best[1]["kind"], best[1]["error"]


def tare_rule(tare: bool) -> str:
    """How a run not seen in training gets its offset, as loop.json states it."""
    new_run = (f"training is tared on its first {fx.TARE_S:g} s" if tare else
               "training gets the mean of the runs' offsets")
    return ("one intercept per training run in every fit; a run not seen in " + new_run
            + " (chosen by leave-one-run-out on the selected model: tare or mean, the lower "
              "error; the selection tares every held-out run)")


def selection_record(cv_kind: str, units: int, folds: int, gap_s: float, n_se: float,
                     min_relative: float) -> dict:
    """loop.json's ``selection``: the cross-validation and the acceptance rule."""
    return {"cv": cv_kind, "units": units, "folds": folds, "gap_s": gap_s, "n_se": n_se,
            "min_relative": min_relative, "rule": RULE}


def data_summary(data: Dataset) -> dict:
    """loop.json's ``data``: samples, rate, runs and repairs."""
    return {"samples": len(data), "rate_hz": 1.0 / data.dt,
            "runs": [dict(s) for s in data.segments],
            "train_samples": int(np.sum(data.role == "train")),
            "validate_samples": int(np.sum(data.role == "validate")),
            "repaired": data.report.get("repaired_total", {})}


def loop_report(base_name: str, outputs: dict[str, dict], selection: dict, data: dict,
                budget: dict) -> dict:
    """loop.json: the first output's results at the top, then every output's entry."""
    first = outputs[next(iter(outputs))]
    return {"output": next(iter(outputs)), **{k: first[k] for k in FIRST_OUTPUT_KEYS},
            "metric": "rmse", "base": base_name, "outputs": outputs, "selection": selection,
            "data": data, "budget": budget}


def residual_correlations(data: Dataset, residual: np.ndarray, yhat: np.ndarray,
                          lags_s: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0, 10.0)) -> list[dict]:
    """Pearson correlation of a residual with the inputs, their rates, lagged inputs, time in
    the run and the prediction, strongest first."""
    def cands():   # one variable at a time: a long record holds no table of them
        for n, x in data.inputs.items():
            yield n, x
            yield f"d{n}/dt", fx.rate(x, data.dt, data.segment)
            for L in lags_s:
                yield f"{n}(t-{L:g}s)", fx.shift(x, L, data.t, data.segment)
        yield "time in run", data.time_in_run()
        yield "prediction", yhat

    out = []
    for name, v in cands():
        if np.std(v) > 0 and np.std(residual) > 0:
            out.append({"variable": name, "correlation": float(np.corrcoef(residual, v)[0, 1])})
    return sorted(out, key=lambda r: -abs(r["correlation"]))


def variable_values(data: Dataset, name: str, yhat: np.ndarray) -> np.ndarray:
    """The values of a variable named by :func:`residual_correlations`."""
    if name == "time in run":
        return data.time_in_run()
    if name == "prediction":
        return yhat
    if name.startswith("d") and name.endswith("/dt"):
        n = name[1:-3]
        return fx.rate(data.inputs[n], data.dt, data.segment)
    if "(t-" in name:
        n, lag = name.split("(t-")
        return fx.shift(data.inputs[n], float(lag.rstrip("s)")), data.t, data.segment)
    return data.inputs[name]


def write_outputs(result: LoopResult, out: str | Path) -> list[Path]:
    """loop.json, model.json and PNG plots into ``out``, written as a set
    (:class:`~designlab.atomic.FileSet`): a full disk leaves none of them half-written.

    Returns:
        The files written, plots first.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Any] = []
    with FileSet() as files:
        for o, ser in result.series.items():
            written += plot_output(o, ser, result.report["outputs"][o], out, files)
        written.append(files.write_json(out / "model.json", result.model.to_json()))
        written.append(files.write_json(out / "loop.json", result.report))
    return written


def effect_entry(effect: fx.Effect, f: fx.Fitted, cv: dict, correlation: float,
                 train_before: float, train_after: float, refitted: list[str],
                 error_before: float, error_after: float) -> dict:
    """loop.json's record of an accepted effect: its parameters, the evidence that admitted it
    (cross-validation, training errors) and whether the validation data agree."""
    return {
        "name": effect.name, "channel": effect.channel, "key": effect.key,
        "parameters": fx.describe(f), "doc": effect.summary,
        "evidence": {"cv": cv, "correlation_with_residual": correlation,
                     "train_error_before": train_before, "train_error_after": train_after},
        **({"refitted_with_it": refitted} if refitted else {}),
        "error_before": error_before, "error_after": error_after,
        # selection sees the training data only: whether the validation data agree
        "validation_improved": bool(error_after < error_before)}
