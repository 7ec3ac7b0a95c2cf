"""Closing the loop: residual -> effect -> better model.

:func:`run_loop` starts from a BASE model (:mod:`designlab.loop.base_models`, or a saved
model), computes the residual ``measured - predicted`` on the training data and tries every
applicable mechanism of the effect library (:mod:`designlab.loop.effects`, one class per
mechanism). A candidate is accepted only when cross-validation on the training data shows that
it lowers the held-out RMSE by more than noise. With several training runs the held-out units
are the runs (leave-one-run-out: fitted on the other runs); with one run they are ``folds``
contiguous blocks of it (a guard gap around the held-out block). A candidate is acceptable when
the mean relative improvement of the held-out RMSE exceeds ``min_relative`` and either exceeds
``n_se`` standard errors of its unit-to-unit spread or is positive on every held-out unit. The
best such candidate is fitted on all the training data and added; repeat until nothing helps.
A candidate whose regressors depend on the data alone is fitted jointly with the accepted
effects of that kind (one least squares over the union of their regressors and the base's
affine part; after acceptance each member's settings are chosen again), and the model without
the candidate is refitted on the same rows for the comparison. With several training runs every
fit has one intercept per run; a held-out run is tared on its first seconds (the final model
tares a new run or gives it the runs' mean offset, whichever does better leave-one-run-out).
Errors are then reported on the validation data, beside a black-box peer (the NARX network of
:mod:`designlab.measured.narx`, same inputs and training data), with how much of the residual
remains unexplained, what it still correlates with, and a verdict (explained / missing
mechanism / noise).

Model file (JSON, written by :meth:`SensorModel.save`, read by :func:`load_model`)::

    {"format": "designlab-model", "version": 1,
     "model": {"base": {"kind": "stretch-fem", "inputs": {"force": ["displacement"]},
                        "parameters": {"force": {"E_MPa": 0.25, ...}}},
               "outputs": {"force": {"unit": "N", "effects": [
                   {"name": "relaxation", "channel": "displacement", "theta": {"tau": [8.1]},
                    "beta": [0.03], "alpha": [0.01, -0.002], "nuisance": ["displacement"],
                    "parameters": {...}}]}},
               "inputs": {"displacement": {"unit": "mm", "quantity": "length", "kind": "drive"}}},
     "provenance": {...}}

Effects are applied in order: each adds ``F(data, yhat) @ beta + [1, base inputs] @ alpha`` to
the prediction made before it.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from threadpoolctl import threadpool_limits

from designlab.atomic import atomic_write_bytes, atomic_write_json
from designlab.calibration.metrics import rmse
from designlab.errors import DataError, ModelError
from designlab.loop import effects as fx
from designlab.loop.base_models import Base, fit_base
from designlab.loop.base_models import predict as base_predict
from designlab.measured.dataset import Dataset

FORMAT = "designlab-model"

#: the memory and time budget of the fits: the selection, the effect fits and the base fit
#: work on at most this many training samples; longer training data is low-passed
#: (anti-alias) and decimated by a whole factor per run to fit (``budget`` in loop.json says
#: when and by how much). Errors on the validation data always use every held-out sample
#: (predictions of the whole record, the effects in their physical units: time constants in
#: s, widths in input units).
FIT_SAMPLES = 50_000
#: training rows of the NARX peer: beyond it the network trains on every stride-th row of the
#: training runs (each row with its full-rate history) and still predicts every sample
PEER_ROWS = 50_000


# --------------------------------------------------------------------------- the model


@dataclass
class SensorModel:
    """A base plus, per output, an ordered list of fitted effects."""

    base: Base
    effects: dict[str, list[fx.Fitted]] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    inputs: dict[str, dict] = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)

    @property
    def outputs(self) -> list[str]:
        return list(self.base.parameters)

    def predict(self, data: Dataset, output: str, measured: np.ndarray | None = None,
                upto: int | None = None) -> np.ndarray:
        """Prediction of ``output`` on ``data`` (output units) after the first ``upto``
        effects (all by default). ``measured`` lets run offsets tare runs never seen."""
        y = base_predict(self.base, data, output)
        for f in self.effects.get(output, [])[:upto]:
            ctx = fx.Context(data, output, y, f.nuisance, measured)
            y = y + fx.contribution(f, ctx)
        return y

    def to_json(self) -> dict:
        return {"format": FORMAT, "version": 1,
                "model": {"base": self.base.to_json(),
                          "outputs": {o: {"unit": self.units.get(o, ""),
                                          "effects": [f.to_json() for f in
                                                      self.effects.get(o, [])]}
                                      for o in self.outputs},
                          "inputs": self.inputs},
                "provenance": self.provenance}

    def save(self, path: str | Path) -> None:
        """Write the model as JSON, atomically (NaN/inf as null)."""
        atomic_write_json(Path(path), self.to_json())


def load_model(path: str | Path, what: str = "--base") -> SensorModel:
    """Read a model JSON written by :meth:`SensorModel.save` (``loop`` or ``predict``): size,
    encoding, nesting, finite numbers, ``format``/``version`` and the section types are checked;
    anything else is a one-line :class:`ModelError` (the file is data: nothing in it runs)."""
    from designlab.errors import DesignlabError, ParameterError
    from designlab.params import load_json

    p = Path(path)
    try:
        doc = load_json(p, what, max_bytes=64 * 1024 * 1024)
    except ParameterError as exc:
        raise ModelError(f"{p}: {what} needs {exc.allowed}") from None
    if not isinstance(doc, dict):
        raise ModelError(f"{p}: a JSON object is needed; expected a {FORMAT} file")
    if doc.get("format") != FORMAT:
        raise ModelError(f"{p}: format={str(doc.get('format'))[:60]!r} is not allowed: "
                         f"{FORMAT!r}")
    if doc.get("version") != 1 or isinstance(doc.get("version"), bool):
        raise ModelError(f"{p}: version={str(doc.get('version'))[:20]!r} is not allowed: 1 "
                         "(this designlab reads version 1)")
    m = doc.get("model")
    if not isinstance(m, dict) or not isinstance(m.get("base"), dict):
        raise ModelError(f"{p}: no 'model' section with a 'base' table; expected a {FORMAT} file")
    stack = [("model", m)]  # every parameter finite and sane: a 1e308 gain gives inf results
    while stack:
        where, v = stack.pop()
        if isinstance(v, dict):
            stack.extend((f"{where}.{k}", x) for k, x in v.items())
        elif isinstance(v, list):
            stack.extend((f"{where}[{i}]", x) for i, x in enumerate(v))
        elif isinstance(v, (int, float)) and not isinstance(v, bool) and not abs(v) <= 1e20:
            raise ModelError(f"{p}: {where[:120]}={str(v)[:30]} is not allowed: a finite "
                             "number with |value| <= 1e+20 (as data values)")
    outs, inputs, prov = m.get("outputs", {}), m.get("inputs", {}), doc.get("provenance", {})
    for name, v in (("model.outputs", outs), ("model.inputs", inputs), ("provenance", prov)):
        if not isinstance(v, dict):
            raise ModelError(f"{p}: {name} is not allowed: a JSON object")
    for o, v in outs.items():
        if not isinstance(v, dict) or not isinstance(v.get("effects", []), list):
            raise ModelError(f"{p}: model.outputs.{o} is not allowed: an object with an "
                             "'effects' list")
    try:
        base = Base.from_json(m["base"])
        eff = {o: [fx.Fitted.from_json(e) for e in v.get("effects", [])] for o, v in outs.items()}
    except DesignlabError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        raise ModelError(f"{p}: malformed model section ({type(exc).__name__}: "
                         f"{str(exc)[:80]})") from None
    return SensorModel(base, eff, {o: str(v.get("unit", "")) for o, v in outs.items()},
                       inputs, prov)


# --------------------------------------------------------------------------- helpers


def cv_blocks(n: int, folds: int, gap: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """(fit rows, held-out rows) masks of blocked time-series CV: ``folds`` contiguous blocks,
    ``gap`` samples on either side of the held-out block left out of the fit."""
    edges = np.linspace(0, n, folds + 1).astype(int)
    out = []
    for k in range(folds):
        held = np.zeros(n, bool)
        held[edges[k]:edges[k + 1]] = True
        rows = ~held
        rows[max(0, edges[k] - gap):min(n, edges[k + 1] + gap)] = False
        out.append((rows, held))
    return out


def fit_samples(train: Dataset, max_samples: int = FIT_SAMPLES) -> tuple[Dataset, dict]:
    """The training data the fits work on: ``train`` itself when it has at most
    ``max_samples`` samples, else each run's training part low-passed (zero-phase Butterworth
    at 0.4 x the new rate, as the card's ``rate`` does) and decimated by one whole factor
    ``q``, the smallest that leaves at most ``max_samples`` samples (every run keeps its first
    sample and at least 3). Deterministic. Returns the data and what was done (loop.json's
    ``budget``)."""
    from dataclasses import replace

    from designlab.loop.effects.base import _segments
    from designlab.measured.dataset import lowpass

    n = len(train)
    info: dict[str, Any] = {"max_fit_samples": int(max_samples), "train_samples": n}
    if n <= max_samples:
        return train, {**info, "fit_samples": n, "decimation": 1, "decimated": False}
    parts = _segments(train.segment)
    q = -(-n // max(max_samples - len(parts), 1))
    rate = 1.0 / train.dt
    idx, filt = [], {k: [] for k in (*train.inputs, *train.outputs)}
    for sl in parts:
        L = sl.stop - sl.start
        i = np.arange(0, L, q)
        if i.size < 3:
            i = np.unique(np.linspace(0, L - 1, min(L, 3)).astype(int))
        idx.append(sl.start + i)
        for k in filt:
            x = train.channel(k)[sl]
            filt[k].append((lowpass(x, rate, 0.4 * rate / q) if L > 3 * q else x)[i])
    rows = np.concatenate(idx)
    out = replace(train, t=train.t[rows], segment=train.segment[rows], role=train.role[rows],
                  inputs={k: np.concatenate(filt[k]) for k in train.inputs},
                  outputs={k: np.concatenate(filt[k]) for k in train.outputs})
    return out, {**info, "fit_samples": len(out), "decimation": int(q), "decimated": True,
                 "anti_alias_hz": 0.4 * rate / q, "rate_hz": rate, "fit_rate_hz": rate / q}


def cv_runs(data: Dataset) -> list[tuple[np.ndarray, np.ndarray]]:
    """(fit rows, held-out rows) masks of leave-one-run-out CV over the runs of ``data``."""
    out = []
    for s in np.unique(data.segment):
        held = data.segment == s
        out.append((~held, held))
    return out


def acceptable(cv: dict, n_se: float, min_relative: float) -> bool:
    """The acceptance rule: mean relative held-out improvement > ``min_relative`` and either
    > ``n_se`` standard errors or better on every held-out unit (run or block, at least 2)."""
    if cv.get("skipped"):
        return False
    every = cv["blocks_improved"] == cv["blocks"] >= 2
    return bool(cv["relative"] > min_relative
                and (cv["relative"] > n_se * cv["standard_error"] or every))


#: what a failing fit raises (a singular or non-finite system, NNLS out of iterations)
FIT_ERRORS = (ModelError, np.linalg.LinAlgError, FloatingPointError, ValueError, RuntimeError)


class _Affine(fx.Effect):
    """No regressors: the refit of the base's affine part alone (per-run intercepts with
    several training runs). The baseline of every cross-validated comparison."""

    def grid(self, ctx):
        return [{}]

    def features(self, ctx, theta):
        return np.zeros((len(ctx.data), 0))


def joint(effect: fx.Effect) -> bool:
    """Whether a candidate is fitted jointly with the refittable effects already accepted
    (regressors of the data alone, free or constrained coefficients, nothing beyond them)."""
    t = type(effect)
    return (not t.uses_prediction and not t.fixed_coefficients and t.intercept
            and t.extra is fx.Effect.extra)


def _members(effect: fx.Effect, tail: list[fx.Fitted]) -> tuple[list[fx.Effect], list]:
    """The members and settings of a joint fit of ``effect`` (its grid) with ``tail`` (their
    settings kept); an effect with its own solver (a constrained density) goes first."""
    return [f.effect for f in tail] + [effect], [[f.theta] for f in tail] + [None]


def _chain(fitted: list[fx.Fitted], ctx: fx.Context) -> np.ndarray:
    """Prediction of ``ctx.yhat`` plus ``fitted`` applied in order."""
    y = ctx.yhat
    for f in fitted:
        c = fx.Context(ctx.data, ctx.output, y, ctx.base_inputs, ctx.measured, ctx.cache,
                       per_run=ctx.per_run)
        y = y + fx.contribution(f, c)
    return y


def cross_validate(effect: fx.Effect, ctx: fx.Context, y: np.ndarray,
                   blocks: list[tuple[np.ndarray, np.ndarray]],
                   tail: list[fx.Fitted] | None = None,
                   baselines: list[np.ndarray] | None = None) -> dict:
    """Held-out RMSE of the current model without and with ``effect``, both fitted on the
    other blocks, per block. ``ctx.yhat`` is the prediction of the frozen part of the model;
    ``tail`` the accepted effects refitted jointly with a candidate (one least squares over the
    union of their regressors and the base's affine part); ``baselines[k]`` the model without
    the candidate fitted on block k's rows (default: ``ctx.yhat``). A candidate whose
    regressors depend on the prediction is fitted on top of the baseline. The improvement is
    taken relative to each block's error (blocks of a real record differ a lot in how hard they
    are): its mean, standard error (block-to-block spread / sqrt(blocks)) and the mean absolute
    improvement in output units."""
    tail = tail or []
    e0, e1 = [], []
    for k, (rows, held) in enumerate(blocks):
        base = baselines[k] if baselines is not None else ctx.yhat
        try:
            with np.errstate(all="raise"):
                if joint(effect):
                    members, thetas = _members(effect, tail)
                    fitted = fx.fit_group(members, ctx, y - ctx.yhat, rows, thetas)
                    pred = _chain(fitted, ctx)
                else:
                    c0 = fx.Context(ctx.data, ctx.output, base, ctx.base_inputs, ctx.measured,
                                    ctx.cache, per_run=ctx.per_run)
                    f = fx.fit(effect, c0, y - base, rows)
                    pred = base + fx.contribution(f, c0)
        except FIT_ERRORS as exc:
            return {"skipped": f"fit failed ({type(exc).__name__}: {exc})".splitlines()[0],
                    "relative": None, "accepted_rule": False}
        if not np.all(np.isfinite(pred)):
            return {"skipped": "non-finite contribution", "relative": None,
                    "accepted_rule": False}
        e0.append(rmse(y[held], base[held]))
        e1.append(rmse(y[held], pred[held]))
    e0, e1 = np.array(e0), np.array(e1)
    rel = (e0 - e1) / np.maximum(e0, 1e-300)
    se = float(np.std(rel, ddof=1) / math.sqrt(rel.size)) if rel.size > 1 else float("inf")
    return {"relative": float(rel.mean()), "standard_error": se,
            "z": float(rel.mean() / se) if se > 0 else float("inf"),
            "blocks_improved": int(np.sum(rel > 0)), "blocks": int(rel.size),
            "improvement": float((e0 - e1).mean()),
            "error_without": float(e0.mean()), "error_with": float(e1.mean()),
            "per_block_relative": rel.tolist(), "per_block_without": e0.tolist()}


def baselines(ctx: fx.Context, y: np.ndarray, blocks, tail: list[fx.Fitted]
              ) -> list[np.ndarray]:
    """Per CV block: the current model without a new candidate, its refittable ``tail`` and
    the base's affine part (per-run intercepts with several runs) fitted on the block's rows."""
    out = []
    for rows, _ in blocks:
        members = [f.effect for f in tail] + [_Affine()]
        fitted = fx.fit_group(members, ctx, y - ctx.yhat, rows,
                              [[f.theta] for f in tail] + [None])
        out.append(_chain(fitted, ctx))
    return out


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


# --------------------------------------------------------------------------- the loop


@dataclass
class LoopResult:
    """The improved model, the loop.json report and the series behind the plots."""

    model: SensorModel
    report: dict
    series: dict = field(default_factory=dict)


Progress = Callable[[str, int, int, str], None]   # (output, done, total, what)


def run_loop(data: Dataset, base: str | SensorModel = "linear", outputs: list[str] | None = None,
             folds: int = 10, max_effects: int = 8, n_se: float = 2.0,
             min_relative: float = 0.01, gap_s: float = 2.0,
             progress: Progress | None = None, peer: bool = True,
             max_fit_samples: int = FIT_SAMPLES) -> LoopResult:
    """Greedy forward selection of effects on top of ``base`` (see the module docstring).

    ``data`` must have training and validation samples (card roles or split). ``base`` is a
    base kind (``linear``, ``stretch-fem``, ...) fitted on the training data, or a loaded
    :class:`SensorModel` to continue from (its parameters are kept). ``peer``: also fit the
    NARX peer and give the verdict against it. ``max_fit_samples``: the fits' budget (see
    :data:`FIT_SAMPLES`; more training samples are decimated, loop.json's ``budget``)."""
    if isinstance(max_fit_samples, bool) or not isinstance(max_fit_samples, int) \
            or max_fit_samples < 10 * folds:
        raise DataError(f"max_fit_samples={max_fit_samples!r} is not allowed: an integer >= "
                        f"{10 * folds} (10 x folds)")
    val = data.validate()
    _check_runs(data, peer)
    train, budget = fit_samples(data.train(), max_fit_samples)
    if len(train) < 10 * folds:
        raise DataError(f"{len(train)} training samples are too few for {folds}-fold "
                        "cross-validation; give more data or a larger [split] train")
    if len(val) == 0:
        raise DataError("no validation samples: give a file role = \"validate\" or a "
                        "[split] train fraction")
    outs = list(outputs or data.outputs)
    for o in outs:
        if o not in data.outputs:
            raise DataError(f"output '{o}' is not in the data; it has {', '.join(data.outputs)}")
    if isinstance(base, SensorModel):
        model = base
        missing = [o for o in outs if o not in model.outputs]
        if missing:
            raise ModelError(f"the model has no output {missing[0]!r}; it has "
                             f"{', '.join(model.outputs)}")
        model.effects = {o: list(model.effects.get(o, [])) for o in model.outputs}
        base_name = f"model ({model.base.kind})"
        _convert_units(model, data, outs)
    else:
        model = SensorModel(fit_base(base, train, outs), {o: [] for o in outs})
        base_name = base
    model.units.update({o: data.units.get(o, "") for o in outs})
    model.inputs = {n: {"unit": data.units.get(n, ""), "quantity": data.quantities.get(n, ""),
                        "kind": data.kinds.get(n, "drive")} for n in data.inputs}
    gap = int(round(gap_s / train.dt))
    runs = np.unique(train.segment)
    if runs.size >= 2:
        blocks, cv_kind = cv_runs(train), "leave-one-run-out"
    else:
        blocks, cv_kind = cv_blocks(len(train), folds, gap), "blocked in time"
    report: dict[str, Any] = {"metric": "rmse", "base": base_name, "outputs": {},
                              "selection": {"cv": cv_kind, "units": len(blocks),
                                            "folds": folds, "gap_s": gap_s, "n_se": n_se,
                                            "min_relative": min_relative,
                                            "rule": "mean relative held-out RMSE improvement "
                                                    "over the held-out units (runs or blocks) "
                                                    "> min_relative, and > n_se standard "
                                                    "errors or > 0 on every unit"},
                              "data": _data_summary(data),
                              "budget": {**budget, "validation_samples": len(val),
                                         "peer_rows": PEER_ROWS if peer else None}}
    series: dict[str, Any] = {}
    cache_tr: dict = {}
    for o in outs:
        # thousands of small least squares: BLAS threads only cost time (and on a loaded
        # machine much more: 48 ms instead of 3 ms per fit measured on 2 shared cores)
        with threadpool_limits(1, user_api="blas"):
            rep, ser = _loop_output(model, o, data, train, val, blocks, max_effects, n_se,
                                    min_relative, cache_tr, progress,
                                    fitted_base=not isinstance(base, SensorModel))
        if peer:
            if progress:
                progress(o, 0, 1, "NARX peer")
            _add_peer(rep, ser, data, o)
        else:
            rep["peer"] = None
            rep["explained_of_learnable"] = None
            rep["verdict_kind"] = None
        report["outputs"][o] = rep
        series[o] = ser
    first = report["outputs"][outs[0]]
    report = {"output": outs[0], **{k: first[k] for k in (
        "effects", "error_before", "error_after", "validation", "unexplained_fraction", "peer",
        "explained_of_learnable", "verdict_kind")}, **report}
    conv = model.provenance.get("unit_conversions") if isinstance(base, SensorModel) else None
    errors = {o: {"before": r["error_before"], "after": r["error_after"]}
              for o, r in report["outputs"].items()}
    model.provenance = {**({"unit_conversions": conv} if conv else {}),
                        "loop": {"base": base_name, "card": data.report.get("card"),
                                 "errors": errors}}
    return LoopResult(model, report, series)


def _loop_output(model: SensorModel, o: str, data: Dataset, train: Dataset, val: Dataset,
                 blocks, max_effects, n_se, min_relative, cache_tr, progress,
                 fitted_base: bool = True) -> tuple[dict, dict]:
    """Greedy selection for one output. Validation predictions are made on the whole record
    (then masked), so filters and run offsets carry over from a run's training part."""
    y, yv, y_all = train.outputs[o], val.outputs[o], data.outputs[o]
    vmask = data.role == "validate"
    base_inputs = tuple(model.base.inputs[o])
    yhat = model.predict(train, o, y)
    yhat_all = model.predict(data, o, y_all)
    yhat_v = yhat_all[vmask]
    y0_val = yhat_v.copy()
    start_tr = model.predict(train, o, y, upto=0)
    cands, skipped = fx.library(train, o, base_inputs)
    # the base's input gains are refitted beside each effect only when the base was fitted on
    # this data (its least-squares gains took up part of what the effect explains); a loaded
    # model keeps its gains (their error is gain_offset's, one relative number): refitting
    # them would credit any effect with a new affine map of the inputs
    nuisance = base_inputs if fitted_base else ()
    if fitted_base:
        for c in [c for c in cands if type(c).first]:
            skipped[c.key] = "the base is fitted on this data (least-squares offset and gains)"
        cands = [c for c in cands if not type(c).first]
    have = {f.effect.key for f in model.effects[o]}
    cands = [c for c in cands if c.key not in have]
    per_run = np.unique(train.segment).size >= 2
    n_loaded = len(model.effects[o])
    tare, tare_cv = True, None   # selection: each held-out run is tared (re-zeroed) on its start
    err_before = rmse(yv, yhat_v)
    accepted, rounds, stages = [], [], []
    tail_start = len(model.effects[o])   # effects from here on are refitted with each candidate
    while len(accepted) < max_effects and cands:
        tail = model.effects[o][tail_start:]
        frozen = model.predict(train, o, y, upto=tail_start) if tail else yhat
        ctx = fx.Context(train, o, frozen, nuisance, y, cache_tr, per_run=per_run,
                         tare=tare)
        refit = fitted_base or bool(tail) or per_run
        try:
            base_k = baselines(ctx, y, blocks, tail) if refit else None
            # every candidate but a `first` one is fitted with an intercept (and a fitted
            # base's input gains) beside it: on a loaded base its baseline needs that refit
            # too, or it is credited with the base's own zero error (which the `first`
            # effects, gain_offset, measure against the base as loaded)
            base_affine = base_k if refit else baselines(ctx, y, blocks, [])
        except FIT_ERRORS as exc:
            rounds.append({"candidates": {}, "best": None, "accepted": None,
                           "failed": f"the current model cannot be refitted "
                                     f"({type(exc).__name__}: {exc})".splitlines()[0]})
            break
        results = {}
        for i, c in enumerate(cands):
            if progress:
                progress(o, i, len(cands), f"round {len(rounds) + 1}: {c.key}")
            cv = cross_validate(c, ctx, y, blocks, tail,
                                base_k if type(c).first else base_affine)
            cv["accepted_rule"] = acceptable(cv, n_se, min_relative)
            cv["fit"] = ("jointly with " + ", ".join(f.effect.key for f in tail)
                         if joint(c) and tail else "alone" if joint(c)
                         else "on top of the model")
            results[c.key] = cv
        if progress:
            progress(o, len(cands), len(cands), f"round {len(rounds) + 1} done")
        passing = [c for c in cands if results[c.key]["accepted_rule"]]
        scored = [c for c in cands if not results[c.key].get("skipped")]
        if not scored:
            rounds.append({"candidates": results, "best": None, "accepted": None})
            break
        best = max(scored, key=lambda c: results[c.key]["relative"])
        chosen = max(passing, key=lambda c: results[c.key]["relative"]) if passing else None
        # a loaded model's own zero and gain error go first: any other effect would absorb
        # them in its refit of the base's affine part and be credited with them
        chosen = next((c for c in passing if type(c).first), chosen)
        rounds.append({"candidates": results, "best": best.key,
                       "accepted": chosen.key if chosen else None})
        if chosen is None:
            break
        rows = np.ones(len(train), bool)
        try:
            with np.errstate(all="raise"):
                if joint(chosen):
                    members, thetas = _members(chosen, tail)
                    group = fx.fit_group(members, ctx, y - frozen, rows, thetas)
                    group = _retune(group, ctx, y - frozen, rows)
                    new_effects = model.effects[o][:tail_start] + group
                else:
                    c0 = fx.Context(train, o, yhat, nuisance, y, cache_tr, per_run=per_run,
                                    tare=tare)
                    new_effects = model.effects[o] + [fx.fit(chosen, c0, y - yhat, rows)]
                trial = SensorModel(model.base, {**model.effects, o: new_effects})
                yhat_new = trial.predict(train, o, y)
                yhat_all_new = trial.predict(data, o, y_all)
            if not (np.all(np.isfinite(yhat_new)) and np.all(np.isfinite(yhat_all_new))):
                raise ValueError("non-finite prediction")
        except FIT_ERRORS as exc:
            rounds[-1]["accepted"] = None
            rounds[-1]["failed"] = (f"{chosen.key}: the fit on all training data failed "
                                    f"({type(exc).__name__}: {exc})").splitlines()[0]
            cands = [c for c in cands if c.key != chosen.key]
            continue
        c_tr, c_all = yhat_new - yhat, yhat_all_new - yhat_all
        c_v = c_all[vmask]
        r_before = y - yhat
        corr = float(np.corrcoef(r_before, c_tr)[0, 1]) if np.std(c_tr) > 0 else 0.0
        e_b, e_a = rmse(yv, yhat_v), rmse(yv, yhat_v + c_v)
        f = new_effects[-1] if not joint(chosen) else next(
            g for g in new_effects[tail_start:] if g.effect.key == chosen.key)
        ctx_f = fx.Context(train, o, yhat, nuisance, y, cache_tr, per_run=per_run,
                           tare=tare)
        reg, reg_name = fx.regressor(f, ctx_f)
        stages.append({"key": chosen.key, "residual": r_before, "contribution": c_tr,
                       "regressor": reg, "regressor_name": reg_name})
        refitted = [g.effect.key for g in new_effects[tail_start:] if g.effect.key != chosen.key]
        accepted.append({
            "name": chosen.name, "channel": chosen.channel, "key": chosen.key,
            "parameters": fx.describe(f), "doc": chosen.summary,
            "evidence": {"cv": results[chosen.key], "correlation_with_residual": corr,
                         "train_error_before": rmse(y, yhat),
                         "train_error_after": rmse(y, yhat_new)},
            **({"refitted_with_it": refitted} if joint(chosen) and refitted else {}),
            "error_before": e_b, "error_after": e_a,
            # selection sees the training data only: whether the validation data agree
            "validation_improved": bool(e_a < e_b)})
        model.effects[o] = new_effects
        if joint(chosen) and fx.group_member(chosen):
            for g in accepted:   # the refitted effects' parameters as they are now
                h = next((e for e in new_effects[tail_start:] if e.effect.key == g["key"]),
                         None)
                if h is not None:
                    g["parameters"] = fx.describe(h)
        else:
            tail_start = len(new_effects)
        yhat, yhat_all = yhat_new, yhat_all_new
        yhat_v = yhat_all[vmask]
        cands = [c for c in cands if c.key != chosen.key]
    if per_run:
        tare, tare_cv = _choose_tare(model, train, o, y, nuisance, blocks, cache_tr,
                                     tail_start)
        if not tare:
            model.effects[o] = model.effects[o][:n_loaded] + [
                dataclasses.replace(f, tare=False) if f.runs else f
                for f in model.effects[o][n_loaded:]]
            yhat = model.predict(train, o, y)
            yhat_all = model.predict(data, o, y_all)
            yhat_v = yhat_all[vmask]
    tare_rep = None
    if per_run and not (model.effects[o] and model.effects[o][-1].runs):
        # the runs' own zeros: one offset per training run, a new run tared on its start
        c0 = fx.Context(train, o, yhat, nuisance, y, cache_tr)
        f = fx.fit(fx.EFFECTS["run_offset"](), c0, y - yhat, np.ones(len(train), bool),
                   [{"runs": fx.run_paths(train), "tare_s": fx.TARE_S if tare else 0.0}])
        model.effects[o].append(f)
        yhat = model.predict(train, o, y)
        yhat_all = model.predict(data, o, y_all)
        yhat_v = yhat_all[vmask]
        tare_rep = {"effect": "run_offset", "parameters": fx.describe(f)}
    if per_run:
        b0 = SensorModel(model.base, {o: []})
        c0 = fx.Context(train, o, b0.predict(train, o), nuisance, y, {})
        f0 = fx.fit(fx.EFFECTS["run_offset"](), c0, y - c0.yhat, np.ones(len(train), bool),
                    [{"runs": fx.run_paths(train), "tare_s": fx.TARE_S if tare else 0.0}])
        b0.effects[o] = [f0]
        tare_rep = {**(tare_rep or {}), "tare": tare, "choice_cv": tare_cv,
                    "error_base_with_offsets": rmse(yv, b0.predict(data, o, y_all)[vmask]),
                    "rule": "one intercept per training run in every fit; a run not seen in "
                            + (f"training is tared on its first {fx.TARE_S:g} s" if tare else
                               "training gets the mean of the runs' offsets") + " (chosen by "
                            "leave-one-run-out on the selected model: tare or mean, the lower "
                            "error; the selection tares every held-out run)"}
    r_v = yv - yhat_v
    var_y = float(np.var(yv))
    unexplained = float(np.var(r_v) / var_y) if var_y > 0 else float("nan")
    corrs = residual_correlations(val, r_v, yhat_v)
    last = rounds[-1] if rounds else None
    if last is not None and last.get("failed") and not cands:
        stop = last["failed"]
    elif last is not None and last["accepted"] is None and last["best"] is None:
        stop = "every candidate's fit failed (see rounds)"
    elif last is not None and last["accepted"] is None:
        b = last["candidates"][last["best"]]
        stop = (f"no candidate lowers the held-out error by more than noise (best: "
                f"{last['best']}, {100 * b['relative']:+.2f} %, {b['z']:.1f} standard errors)")
    elif not cands:
        stop = "every applicable effect of the library is in the model"
    else:
        stop = f"max_effects = {max_effects} reached"
    unconfirmed = [a["key"] for a in accepted if not a["validation_improved"]]
    verdict = (f"{len(accepted)} effect(s) accepted; " + stop
               + (f"; not confirmed by the validation data (its error rose with them): "
                  f"{', '.join(unconfirmed)}" if unconfirmed else "")
               + "; the remaining residual is "
               f"{100 * unexplained:.1f} % of the validation variance and correlates most with "
               + (f"{corrs[0]['variable']} (r = {corrs[0]['correlation']:+.2f})" if corrs
                  else "nothing"))
    rep = {
        "unit": val.units.get(o, ""), "effects": accepted,
        "error_before": err_before, "error_after": rmse(yv, yhat_v),
        "train_error_before": rmse(y, start_tr), "train_error_after": rmse(y, yhat),
        "validation": {"samples": len(val), "runs": sorted({val.segments[s]["path"]
                                                            for s in np.unique(val.segment)}),
                       "rmse_before": err_before, "rmse_after": rmse(yv, yhat_v),
                       "ncc_after": _ncc(yv, yhat_v),
                       "range": float(np.ptp(yv)),
                       "nrmse_after_percent": 100 * rmse(yv, yhat_v) / max(np.ptp(yv), 1e-300)},
        "unexplained_fraction": unexplained, "residual_correlations": corrs[:8],
        "stopped": stop, "verdict": verdict, "rounds": rounds, "not_applicable": skipped,
        **({"run_offsets": tare_rep} if tare_rep is not None else {}),
        "base": model.base.parameters.get(o, {}),
    }
    ser = {"t_val": val.t, "seg_val": val.segment, "y_val": yv, "base_val": y0_val,
           "corrs": corrs,
           "final_val": yhat_v, "stages": stages, "residual_val": r_v,
           "top_var": corrs[0]["variable"] if corrs else None,
           "top_values": _variable(val, corrs[0]["variable"], yhat_v) if corrs else None}
    return rep, ser


def _choose_tare(model: SensorModel, train: Dataset, o: str, y: np.ndarray,
                 base_inputs: tuple[str, ...], blocks, cache: dict, tail_start: int
                 ) -> tuple[bool, dict]:
    """How a run not seen in training gets its intercept in the final model: tared on its
    first seconds (as a rig re-zeros) or the mean of the training runs' offsets. Leave-one-run-
    out on the selected model (its refittable effects refitted per held-out run) decides: the
    lower mean held-out RMSE wins (ties: tare). The selection itself always tares the held-out
    run (on the base alone the tare can lose only because the base misses a mechanism)."""
    tail = model.effects[o][tail_start:]
    frozen = model.predict(train, o, y, upto=tail_start)
    errs = {}
    for tare in (True, False):
        ctx = fx.Context(train, o, frozen, base_inputs, y, cache, per_run=True, tare=tare)
        pred = baselines(ctx, y, blocks, tail)
        errs[tare] = float(np.mean([rmse(y[h], p[h]) for p, (_, h) in zip(pred, blocks)]))
    return errs[True] <= errs[False], {"tare": errs[True], "mean_offset": errs[False]}


def _retune(group: list[fx.Fitted], ctx: fx.Context, target: np.ndarray,
            rows: np.ndarray) -> list[fx.Fitted]:
    """One pass of coordinate descent over a jointly fitted group: each member's settings are
    chosen again from its grid (AIC) with the others' kept, so earlier effects' time constants
    and widths can follow the new one. Groups with a constrained member are kept as fitted."""
    if len(group) < 2 or not all(fx.group_member(f.effect) for f in group):
        return group
    for i in range(len(group)):
        thetas = [[f.theta] for f in group]
        thetas[i] = None
        group = fx.fit_group([f.effect for f in group], ctx, target, rows, thetas)
    return group


def _convert_units(model: SensorModel, data: Dataset, outs: list[str]) -> None:
    """A loaded model whose output unit differs from the data's (a ``predict`` model gives a
    flexure's rotations in rad, a card's angles are read in deg): a linear base without effects
    is rescaled to the data's unit (recorded in the provenance); anything else is a one-line
    ModelError naming the output and both units."""
    from designlab.measured.dataset import UNITS

    for o in outs:
        mu, du = model.units.get(o, ""), data.units.get(o, "")
        if not mu or not du or mu == du:
            continue
        table = next((t for t in UNITS.values() if mu in t and du in t), None)
        factor = (table[mu] / table[du] if table is not None
                  and not isinstance(table[mu], tuple) else None)
        if factor is None or model.base.kind != "linear" or model.effects.get(o):
            raise ModelError(f"the model predicts output '{o}' in {mu}, the data has it in {du}; "
                             "a model with effects or a nonlinear base cannot be rescaled")
        p = model.base.parameters[o]
        p["intercept"] = float(p["intercept"]) * factor
        p["gains"] = {k: float(v) * factor for k, v in p["gains"].items()}
        model.provenance.setdefault("unit_conversions", {})[o] = {
            "from": mu, "to": du, "factor": factor}
        model.units[o] = du


def _check_runs(data: Dataset, peer: bool) -> None:
    """Every run must be longer than the longest lag the loop uses (the NARX peer's input
    delays, the ``lag`` effect's 2 s): one-line DataError naming the run."""
    from designlab.measured.narx import NARXParams

    delays = NARXParams().input_delays
    need = delays + 2 if peer else 3
    why = (f"the NARX peer's {delays} input delays" if peer
           else "the rate and lag regressors need 3 samples")
    for s in np.unique(data.segment):
        n = int(np.sum(data.segment == s))
        if n < need:
            path = data.segments[s]["path"] if s < len(data.segments) else f"run {s}"
            raise DataError(f"run {path!r} has {n} samples; the loop needs at least {need} per "
                            f"run (the longest lag: {why})")


def fit_peer(data: Dataset, output: str, max_rows: int | None = PEER_ROWS
             ) -> tuple[np.ndarray, dict]:
    """The black-box peer: seed 000's NARX network (:mod:`designlab.measured.narx`, defaults:
    10 tanh neurons, 50 input delays, seed 0) from every varying input to ``output``, trained
    on the training runs (one record each; on every stride-th row beyond ``max_rows`` rows)
    and run over each whole run; returns its prediction of every sample of ``data`` and what
    it was."""
    import time

    from designlab.measured import narx

    t0 = time.perf_counter()
    tr = data.role == "train"
    names = [n for n in data.inputs if np.ptp(data.inputs[n][tr]) > 0]
    if not names:
        raise DataError("no input varies in the training data: the peer has nothing to learn")
    params = narx.NARXParams()
    recs_u, recs_y = [], []
    for s in np.unique(data.segment[tr]):
        m = tr & (data.segment == s)
        recs_u.append(np.column_stack([data.inputs[n][m] for n in names]))
        recs_y.append(data.outputs[output][m][:, None])
    model, fit_rep = narx.fit(recs_u, recs_y, params, max_rows=max_rows)
    del recs_u, recs_y
    pred = np.empty(len(data))
    for s in np.unique(data.segment):
        m = data.segment == s
        pred[m] = model.predict(np.column_stack([data.inputs[n][m] for n in names]))[:, 0]
    info = {"kind": "narx", "inputs": names, "hidden": params.hidden,
            "input_delays": params.input_delays, "delay_s": params.input_delays * data.dt,
            "seed": params.seed, "iterations": fit_rep.iterations,
            "converged": fit_rep.converged, "rows": fit_rep.rows, "stride": fit_rep.stride,
            "time_s": time.perf_counter() - t0}
    return pred, info


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


def _add_peer(rep: dict, ser: dict, data: Dataset, o: str) -> None:
    vmask = data.role == "validate"
    pred, info = fit_peer(data, o)
    yv = data.outputs[o][vmask]
    err = rmse(yv, pred[vmask])
    info["error"] = err
    base, after = rep["error_before"], rep["error_after"]
    rep["peer"] = info
    rep["explained_of_learnable"] = ((base - after) / (base - err) if base - err > 0
                                     else None)
    kind = verdict_kind(base, after, err)
    rep["verdict_kind"] = kind
    corrs = ser.get("corrs") or []
    top = (f"{corrs[0]['variable']} (r = {corrs[0]['correlation']:+.2f})" if corrs
           else "nothing")
    unit = rep["unit"]
    if kind == "explained":
        why = (f"explained: physics {after:.4g} {unit} vs NARX peer {err:.4g} {unit} "
               f"(base {base:.4g} {unit})")
    elif kind == "noise":
        why = (f"noise: neither the physics ({after:.4g} {unit}) nor the NARX peer "
               f"({err:.4g} {unit}) lowers the base's {base:.4g} {unit} by 5 %")
    else:
        why = (f"missing mechanism: the NARX peer reaches {err:.4g} {unit}, the physics "
               f"{after:.4g} {unit} (base {base:.4g} {unit}); the residual correlates most "
               f"with {top}")
    if rep["explained_of_learnable"] is None:
        why += (f"; the peer is no better than the base ({err:.4g} vs {base:.4g} {unit}): "
                "explained_of_learnable is null")
    rep["verdict"] = why + "; " + rep["verdict"]
    ser["peer_val"] = pred[vmask]


def _variable(data: Dataset, name: str, yhat: np.ndarray) -> np.ndarray:
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


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    from designlab.calibration.metrics import ncc
    return ncc(a, b)


def _data_summary(data: Dataset) -> dict:
    return {"samples": len(data), "rate_hz": 1.0 / data.dt,
            "runs": [dict(s) for s in data.segments],
            "train_samples": int(np.sum(data.role == "train")),
            "validate_samples": int(np.sum(data.role == "validate")),
            "repaired": data.report.get("repaired_total", {})}


# --------------------------------------------------------------------------- outputs


def write_outputs(result: LoopResult, out: str | Path) -> list[Path]:
    """loop.json, model.json and PNG plots into ``out`` (each written atomically)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for o, ser in result.series.items():
        written += _plots(o, ser, result.report["outputs"][o], out)
    p = out / "model.json"
    result.model.save(p)
    written.append(p)
    p = out / "loop.json"
    atomic_write_json(p, result.report)
    written.append(p)
    return written


def _file_safe(name: str) -> str:
    """A channel or effect name as a file-name part: anything but letters, digits, '.', '-'
    becomes '_' (a channel named 'a/b' or '[/bold]' never writes outside --out)."""
    import re

    return re.sub(r"[^\w.-]", "_", str(name))


def _savefig(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write_bytes(path, buf.getvalue())
    return path


def _plots(o: str, ser: dict, rep: dict, out: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    unit = rep["unit"]
    files = []
    fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    x = np.arange(ser["t_val"].size) * (np.median(np.diff(ser["t_val"])) if ser["t_val"].size
                                        > 1 else 1.0)
    ax[0].plot(x, ser["y_val"], "k", lw=0.8, label="measured")
    ax[0].plot(x, ser["base_val"], "C0", lw=0.8,
               label=f"base (RMSE {rep['error_before']:.4g} {unit})")
    ax[0].plot(x, ser["final_val"], "C3", lw=0.8,
               label=f"physics (RMSE {rep['error_after']:.4g} {unit})")
    if ser.get("peer_val") is not None:
        ax[0].plot(x, ser["peer_val"], "C2", lw=0.8, alpha=0.8,
                   label=f"NARX peer (RMSE {rep['peer']['error']:.4g} {unit})")
    ax[0].set_ylabel(f"{o} ({unit})")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].set_title(f"{o}: validation data")
    ax[1].plot(x, ser["y_val"] - ser["base_val"], "C0", lw=0.6, label="residual before")
    ax[1].plot(x, ser["residual_val"], "C3", lw=0.6, label="residual physics")
    if ser.get("peer_val") is not None:
        ax[1].plot(x, ser["y_val"] - ser["peer_val"], "C2", lw=0.6, alpha=0.8,
                   label="residual peer")
    ax[1].set_ylabel(f"residual ({unit})")
    ax[1].set_xlabel("validation time (s)")
    ax[1].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    files.append(_savefig(fig, out / f"timeseries_{_file_safe(o)}.png"))
    plt.close(fig)
    for k, st in enumerate(ser["stages"], 1):
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
        idx = np.linspace(0, st["regressor"].size - 1, min(st["regressor"].size, 4000)).astype(int)
        r, c = st["residual"][idx], st["contribution"][idx]
        ax[0].plot(st["regressor"][idx], r, ".", ms=2, color="0.6", label="residual before (train)")
        ax[0].plot(st["regressor"][idx], c, ".", ms=2, color="C3", label=f"{st['key']} fit")
        ax[0].set_xlabel(st["regressor_name"])
        ax[0].set_ylabel(f"{o} residual ({unit})")
        ax[0].legend(fontsize=8, markerscale=4)
        ax[1].plot(c, r, ".", ms=2, color="C0")
        lim = [min(c.min(), r.min()), max(c.max(), r.max())]
        ax[1].plot(lim, lim, "k--", lw=0.8, label="1:1")
        ax[1].set_xlabel(f"{st['key']} contribution ({unit})")
        ax[1].set_ylabel(f"residual before ({unit})")
        ax[1].legend(fontsize=8)
        fig.suptitle(f"{o} effect {k}: {st['key']}")
        fig.tight_layout()
        safe = _file_safe(st["key"])
        files.append(_savefig(fig, out / f"effect_{_file_safe(o)}_{k}_{safe}.png"))
        plt.close(fig)
    if ser["top_var"] is not None:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        ax.plot(ser["top_values"], ser["residual_val"], ".", ms=2, color="C0")
        ax.set_xlabel(ser["top_var"])
        ax.set_ylabel(f"{o} final residual ({unit})")
        ax.set_title(f"{o}: unexplained {100 * rep['unexplained_fraction']:.1f} % of variance")
        fig.tight_layout()
        files.append(_savefig(fig, out / f"unexplained_{_file_safe(o)}.png"))
        plt.close(fig)
    return files
