"""The loop's report: loop.json's records per output, the verdicts, and the files written.

Each output's entry is assembled once from what the selection left (:class:`Selected`); the
verdict is a list of clauses joined in one place, the peer's sentence one template per kind.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import atomic_write_json
from designlab.calibration.metrics import ncc, rmse
from designlab.loop import effects as fx
from designlab.loop.model import SensorModel
from designlab.loop.plots import plot_output
from designlab.measured.dataset import Dataset

#: the acceptance rule as loop.json states it
RULE = ("mean relative held-out RMSE improvement over the held-out units (runs or blocks) "
        "> min_relative, and > n_se standard errors or > 0 on every unit")

#: the peer verdict's sentence per kind (values in the output's unit)
PEER_VERDICTS = {
    "explained": "explained: physics {after:.4g} {unit} vs NARX peer {peer:.4g} {unit} "
                 "(base {base:.4g} {unit})",
    "noise": "noise: neither the physics ({after:.4g} {unit}) nor the NARX peer "
             "({peer:.4g} {unit}) lowers the base's {base:.4g} {unit} by 5 %",
    "missing mechanism": "missing mechanism: the NARX peer reaches {peer:.4g} {unit}, the "
                         "physics {after:.4g} {unit} (base {base:.4g} {unit}); the residual "
                         "correlates most with {top}",
}

#: the loop.json keys of the first output repeated at the top
FIRST_OUTPUT_KEYS = ("effects", "error_before", "error_after", "validation",
                     "unexplained_fraction", "peer", "explained_of_learnable", "verdict_kind")


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
        "stopped": stop, "verdict": verdict(s.accepted, stop, unexplained, corrs),
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


def verdict(accepted: list[dict], stop: str, unexplained: float, corrs: list[dict]) -> str:
    """The selection's verdict: what was accepted, why it stopped, what the validation data
    did not confirm, and what the remaining residual is and correlates with."""
    clauses = [f"{len(accepted)} effect(s) accepted", stop]
    unconfirmed = [a["key"] for a in accepted if not a["validation_improved"]]
    if unconfirmed:
        clauses.append("not confirmed by the validation data (its error rose with them): "
                       + ", ".join(unconfirmed))
    clauses.append(f"the remaining residual is {100 * unexplained:.1f} % of the validation "
                   f"variance and correlates most with {_strongest(corrs)}")
    return "; ".join(clauses)


def verdict_kind(base: float, after: float, peer: float | None) -> str:
    """noise: neither the physics model nor the peer lowers the base's validation error by
    5 %; explained: the physics model does (by 5 %) and is within 1.3x of the peer; missing
    mechanism: otherwise (the peer does much better than the physics model)."""
    phys = after < 0.95 * base
    if peer is None or not np.isfinite(peer):
        return "explained" if phys else "noise"
    if not phys and peer >= 0.95 * base:
        return "noise"
    if phys and after <= 1.3 * peer:
        return "explained"
    return "missing mechanism"


def add_peer(rep: dict, ser: dict, data: Dataset, o: str, pred: np.ndarray, info: dict) -> None:
    """The NARX peer's prediction ``pred`` of every sample and what it was (``info``) into an
    output's entry: its validation error, the explained fraction of the learnable error, the
    verdict kind and its sentence before the selection's verdict."""
    vmask = data.role == "validate"
    yv = data.outputs[o][vmask]
    err = rmse(yv, pred[vmask])
    info["error"] = err
    base, after = rep["error_before"], rep["error_after"]
    rep["peer"] = info
    rep["explained_of_learnable"] = ((base - after) / (base - err) if base - err > 0
                                     else None)
    kind = verdict_kind(base, after, err)
    rep["verdict_kind"] = kind
    unit = rep["unit"]
    clauses = [PEER_VERDICTS[kind].format(after=after, peer=err, base=base, unit=unit,
                                          top=_strongest(ser.get("corrs") or []))]
    if rep["explained_of_learnable"] is None:
        clauses.append(f"the peer is no better than the base ({err:.4g} vs {base:.4g} {unit}): "
                       "explained_of_learnable is null")
    rep["verdict"] = "; ".join([*clauses, rep["verdict"]])
    ser["peer_val"] = pred[vmask]


def no_peer(rep: dict) -> None:
    """An output's entry without the peer."""
    rep["peer"] = None
    rep["explained_of_learnable"] = None
    rep["verdict_kind"] = None


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
    """loop.json, model.json and PNG plots into ``out`` (each written atomically).

    Returns:
        The files written, plots first.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Any] = []
    for o, ser in result.series.items():
        written += plot_output(o, ser, result.report["outputs"][o], out)
    p = out / "model.json"
    result.model.save(p)
    written.append(p)
    p = out / "loop.json"
    atomic_write_json(p, result.report)
    written.append(p)
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
