"""Closing the loop: residual -> effect -> better model, by greedy forward selection.

:func:`run_loop` starts from a base model (:mod:`designlab.loop.base_models`, or a saved
:mod:`designlab.loop.model`), tries every applicable mechanism of the effect library
(:mod:`designlab.loop.effects`) on the residual of the training data and adds the best one
that cross-validation shows to lower the held-out error by more than noise, until nothing
helps; the backward pass (:mod:`designlab.loop.backward`) then removes the effects that no
longer account for more than noise beside the others. How the comparison is made is in ``docs/models/loop_selection.md``; loop.json and the
plots are :mod:`designlab.loop.report`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from designlab.calibration.metrics import rmse
from designlab.errors import DataError, ModelError
from designlab.loop import effects as fx
from designlab.loop.backward import (
    FIT_ERRORS,
    Affine,
    Rule,
    backward_step,
    chain,
    joint,
    refit_chain,
)
from designlab.loop.base_models import fit_base
from designlab.loop.model import SensorModel, convert_units
from designlab.loop.peers import fit_peers
from designlab.loop.noise_floor import difference_sigma, noise_floor
from designlab.loop.report import (
    LoopResult,
    Selected,
    add_verdict,
    data_summary,
    effect_entry,
    loop_report,
    output_report,
    selection_record,
    tare_rule,
)
from designlab.measured.dataset import Dataset

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
#: the selection stops when the model's held-out error in cross-validation is within this
#: factor of the noise floor of the training data: what remains is noise
AT_FLOOR = 1.1



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


def _members(effect: fx.Effect, tail: list[fx.Fitted]) -> tuple[list[fx.Effect], list]:
    """The members and settings of a joint fit of ``effect`` (its grid) with ``tail`` (their
    settings kept); an effect with its own solver (a constrained density) goes first."""
    return [f.effect for f in tail] + [effect], [[f.theta] for f in tail] + [None]


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
                    pred = chain(fitted, ctx)
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
        members = [f.effect for f in tail] + [Affine()]
        fitted = fx.fit_group(members, ctx, y - ctx.yhat, rows,
                              [[f.theta] for f in tail] + [None])
        out.append(chain(fitted, ctx))
    return out


# --------------------------------------------------------------------------- the loop


Progress = Callable[[str, int, int, str], None]   # (output, done, total, what)


def run_loop(data: Dataset, base: str | SensorModel = "linear", outputs: list[str] | None = None,
             folds: int = 10, max_effects: int = 8, n_se: float = 2.0,
             min_relative: float = 0.01, gap_s: float = 2.0,
             progress: Progress | None = None, peer: bool = True,
             max_fit_samples: int = FIT_SAMPLES) -> LoopResult:
    """Greedy forward selection of effects on top of ``base`` (see the module docstring).

    Args:
        data: training and validation samples (card roles or split).
        base: a base kind (``linear``, ``stretch-fem``, ...) fitted on the training data, or a
            loaded :class:`SensorModel` to continue from (its parameters are kept).
        outputs: the outputs to analyse (default: all of ``data``).
        folds: blocks of the time-series CV (one training run).
        max_effects: stop after this many effects per output.
        n_se: required improvement in standard errors.
        min_relative: required mean relative improvement (0.01 = 1 %).
        gap_s: guard gap (s) around a held-out block.
        progress: called with (output, done, total, what).
        peer: also fit the NARX peer and give the verdict against it.
        max_fit_samples: the fits' budget (see :data:`FIT_SAMPLES`; more training samples are
            decimated, loop.json's ``budget``).

    Returns:
        The improved model, loop.json's report and the series of the plots.
    """
    _check_budget(max_fit_samples, folds)
    val = data.validate()
    _check_runs(data, peer)
    train, budget = fit_samples(data.train(), max_fit_samples)
    if len(train) < 10 * folds:
        raise DataError(f"{len(train)} training samples are too few for {folds}-fold "
                        "cross-validation; give more data or a larger [split] train")
    if len(val) == 0:
        raise DataError("no validation samples: give a file role = \"validate\" or a "
                        "[split] train fraction")
    outs = _outputs(data, outputs)
    model, base_name = _start_model(base, data, train, outs)
    if np.unique(train.segment).size >= 2:
        blocks, cv_kind = cv_runs(train), "leave-one-run-out"
    else:
        blocks = cv_blocks(len(train), folds, int(round(gap_s / train.dt)))
        cv_kind = "blocked in time"
    selection = selection_record(cv_kind, len(blocks), folds, gap_s, n_se, min_relative)
    budget = {**budget, "validation_samples": len(val), "peer_rows": PEER_ROWS if peer else None}
    reports: dict[str, dict] = {}
    series: dict[str, Any] = {}
    cache_tr: dict = {}
    for o in outs:
        sel = _Selection(model, o, data, train, val, blocks, cache_tr,
                         fitted_base=not isinstance(base, SensorModel))
        # thousands of small least squares: BLAS threads only cost time (and on a loaded
        # machine much more than the fits themselves)
        with threadpool_limits(1, user_api="blas"):
            sel.run(max_effects, n_se, min_relative, progress)
        reports[o], series[o] = output_report(sel.result(max_effects), val)
        if peer and progress:
            progress(o, 0, 1, "peers")
        add_verdict(reports[o], series[o], data, o,
                    noise_floor(sel.y_all, np.column_stack(list(data.inputs.values())),
                                data.segment),
                    fit_peers(data, o, PEER_ROWS) if peer else [])
    report = loop_report(base_name, reports, selection, data_summary(data), budget)
    conv = model.provenance.get("unit_conversions") if isinstance(base, SensorModel) else None
    errors = {o: {"before": r["error_before"], "after": r["error_after"]}
              for o, r in report["outputs"].items()}
    model.provenance = {**({"unit_conversions": conv} if conv else {}),
                        "loop": {"base": base_name, "card": data.report.get("card"),
                                 "errors": errors}}
    return LoopResult(model, report, series)


def _check_budget(max_fit_samples: Any, folds: int) -> None:
    if isinstance(max_fit_samples, bool) or not isinstance(max_fit_samples, int) \
            or max_fit_samples < 10 * folds:
        raise DataError(f"max_fit_samples={max_fit_samples!r} is not allowed: an integer >= "
                        f"{10 * folds} (10 x folds)")


def _outputs(data: Dataset, outputs: list[str] | None) -> list[str]:
    """The outputs to analyse, each one of the data's."""
    outs = list(outputs or data.outputs)
    for o in outs:
        if o not in data.outputs:
            raise DataError(f"output '{o}' is not in the data; it has {', '.join(data.outputs)}")
    return outs


def _start_model(base: str | SensorModel, data: Dataset, train: Dataset, outs: list[str]
                 ) -> tuple[SensorModel, str]:
    """The model the selection starts from and its name in loop.json: a loaded model (its
    outputs checked, rescaled to the data's units) or a base of that kind fitted on ``train``;
    its units and inputs those of ``data``."""
    if isinstance(base, SensorModel):
        model = base
        missing = [o for o in outs if o not in model.outputs]
        if missing:
            raise ModelError(f"the model has no output {missing[0]!r}; it has "
                             f"{', '.join(model.outputs)}")
        model.effects = {o: list(model.effects.get(o, [])) for o in model.outputs}
        base_name = f"model ({model.base.kind})"
        convert_units(model, data, outs)
    else:
        model = SensorModel(fit_base(base, train, outs), {o: [] for o in outs})
        base_name = base
    model.units.update({o: data.units.get(o, "") for o in outs})
    model.inputs = {n: {"unit": data.units.get(n, ""), "quantity": data.quantities.get(n, ""),
                        "kind": data.kinds.get(n, "drive")} for n in data.inputs}
    return model, base_name


class _Selection:
    """The greedy selection for one output: the model so far, its predictions (training data,
    the whole record, the validation part of it), the candidates left and the rounds.
    Validation predictions are made on the whole record (then masked), so filters and run
    offsets carry over from a run's training part."""

    def __init__(self, model: SensorModel, o: str, data: Dataset, train: Dataset,
                 val: Dataset, blocks, cache: dict, fitted_base: bool):
        self.model, self.o, self.data, self.train, self.val = model, o, data, train, val
        self.blocks, self.cache, self.fitted_base = blocks, cache, fitted_base
        self.y, self.yv, self.y_all = train.outputs[o], val.outputs[o], data.outputs[o]
        self.vmask = data.role == "validate"
        base_inputs = tuple(model.base.inputs[o])
        self._predicted(model.predict(train, o, self.y), model.predict(data, o, self.y_all))
        # the noise floor of the data the fits see (decimated training data have less noise)
        self.floor_fit = difference_sigma(self.y, train.segment,
                                          inputs=np.column_stack(list(train.inputs.values())))
        self.y0_val = self.yhat_v.copy()
        self.start_tr = model.predict(train, o, self.y, upto=0)
        self.cands, self.skipped = fx.library(train, o, base_inputs)
        # the base's input gains are refitted beside each effect only when the base was fitted
        # on this data (its least-squares gains took up part of what the effect explains); a
        # loaded model keeps its gains (their error is gain_offset's, one relative number):
        # refitting them would credit any effect with a new affine map of the inputs
        self.nuisance = base_inputs if fitted_base else ()
        if fitted_base:
            for c in [c for c in self.cands if type(c).first]:
                self.skipped[c.key] = ("the base is fitted on this data (least-squares offset "
                                       "and gains)")
            self.cands = [c for c in self.cands if not type(c).first]
        have = {f.effect.key for f in model.effects[o]}
        self.cands = [c for c in self.cands if c.key not in have]
        self.per_run = np.unique(train.segment).size >= 2
        self.n_loaded = len(model.effects[o])
        self.tare = True   # selection: each held-out run is tared (re-zeroed) on its start
        self.accepted: list[dict] = []
        self.rounds: list[dict] = []
        self.stages: list[dict] = []
        self.tail_start = self.n_loaded   # effects from here on are refitted with each candidate
        self.run_offsets: dict | None = None
        self.dropped: list[dict] = []    # effects the backward pass removed

    def _predicted(self, yhat: np.ndarray, yhat_all: np.ndarray) -> None:
        self.yhat, self.yhat_all = yhat, yhat_all
        self.yhat_v = yhat_all[self.vmask]

    def _context(self, yhat: np.ndarray) -> fx.Context:
        return fx.Context(self.train, self.o, yhat, self.nuisance, self.y, self.cache,
                          per_run=self.per_run, tare=self.tare)

    def run(self, max_effects: int, n_se: float, min_relative: float,
            progress: Progress | None) -> None:
        """Rounds until nothing helps, then the runs' offsets (several training runs)."""
        while len(self.accepted) < max_effects and self.cands:
            if not self._round(n_se, min_relative, progress):
                break
        while self._backward(n_se, min_relative):
            pass
        if self.per_run:
            self._finish_runs()

    def _backward(self, n_se: float, min_relative: float) -> bool:
        """One step of the backward pass (:mod:`designlab.loop.backward`): the selected effects
        refitted together with each left out in turn; the one that accounts for least of the
        held-out error is removed when that is no more than the noise floor (or the others
        leave only noise, or the forward rule no longer accepts it), the others refitted on all
        the training data. A loaded model's own effects and those taken first stay. False when
        none is removed."""
        o, y = self.o, self.y
        effects = self.model.effects[o][self.n_loaded:]
        removable = {a["key"] for a in self.accepted} - {
            f.effect.key for f in effects if type(f.effect).first}
        if not removable:
            return False
        frozen = self.model.predict(self.train, o, y, upto=self.n_loaded)
        affine = self.fitted_base or self.per_run
        rule = Rule(self.floor_fit, AT_FLOOR, lambda cv: acceptable(cv, n_se, min_relative))
        step = backward_step(effects, removable, frozen, self._context, y, self.blocks, affine,
                             rule)
        if step is None:
            return False
        j, cv = step
        rest = effects[:j] + effects[j + 1:]
        try:
            refit = refit_chain(rest, frozen, self._context, y, np.ones(len(self.train), bool),
                                affine=False)
            trial = SensorModel(self.model.base, {
                **self.model.effects, o: self.model.effects[o][:self.n_loaded] + refit.fitted})
            with np.errstate(all="raise"):
                yhat, yhat_all = trial.predict(self.train, o, y), trial.predict(self.data, o,
                                                                                 self.y_all)
        except FIT_ERRORS:
            return False
        self.model.effects[o] = trial.effects[o]
        self.tail_start = self.n_loaded + refit.open_start
        self._predicted(yhat, yhat_all)
        self._dropped(effects[j].effect.key, cv)
        self._refitted_parameters(refit.fitted)
        return True

    def _dropped(self, key: str, cv: dict) -> None:
        """Record an effect the backward pass removed, with its numbers and why."""
        self.dropped.append({"key": key, "why": cv["why"], "cv": cv})
        self.accepted = [a for a in self.accepted if a["key"] != key]
        self.stages = [st for st in self.stages if st["key"] != key]

    def _round(self, n_se: float, min_relative: float, progress: Progress | None) -> bool:
        """Every candidate cross-validated; the best acceptable one fitted on all the training
        data and added. False when the selection stops."""
        tail = self.model.effects[self.o][self.tail_start:]
        frozen = (self.model.predict(self.train, self.o, self.y, upto=self.tail_start) if tail
                  else self.yhat)
        ctx = self._context(frozen)
        refit = self.fitted_base or bool(tail) or self.per_run
        try:
            base_k = baselines(ctx, self.y, self.blocks, tail) if refit else None
            # every candidate but a `first` one is fitted with an intercept (and a fitted
            # base's input gains) beside it: on a loaded base its baseline needs that refit
            # too, or it is credited with the base's own zero error (which the `first`
            # effects, gain_offset, measure against the base as loaded)
            base_affine = base_k if refit else baselines(ctx, self.y, self.blocks, [])
        except FIT_ERRORS as exc:
            self.rounds.append({"candidates": {}, "best": None, "accepted": None,
                                "failed": f"the current model cannot be refitted "
                                          f"({type(exc).__name__}: {exc})".splitlines()[0]})
            return False
        results = self._evaluate(ctx, tail, base_k, base_affine, n_se, min_relative, progress)
        chosen = self._choose(results)
        if chosen is None:
            return False
        fitted = self._fit_all(chosen, ctx, tail, frozen)
        if fitted is not None:
            self._accept(chosen, results[chosen.key], *fitted)
        return True

    def _evaluate(self, ctx: fx.Context, tail: list[fx.Fitted], base_k, base_affine,
                  n_se: float, min_relative: float, progress: Progress | None) -> dict:
        """Each candidate's cross-validation, by key."""
        o, n = self.o, len(self.cands)
        results = {}
        for i, c in enumerate(self.cands):
            if progress:
                progress(o, i, n, f"round {len(self.rounds) + 1}: {c.key}")
            cv = cross_validate(c, ctx, self.y, self.blocks, tail,
                                base_k if type(c).first else base_affine)
            cv["accepted_rule"] = acceptable(cv, n_se, min_relative)
            cv["fit"] = ("jointly with " + ", ".join(f.effect.key for f in tail)
                         if joint(c) and tail else "alone" if joint(c)
                         else "on top of the model")
            results[c.key] = cv
        if progress:
            progress(o, n, n, f"round {len(self.rounds) + 1} done")
        return results

    def _choose(self, results: dict) -> fx.Effect | None:
        """The candidate to add (None: stop), the round recorded."""
        passing = [c for c in self.cands if results[c.key]["accepted_rule"]]
        scored = [c for c in self.cands if not results[c.key].get("skipped")]
        if not scored:
            self.rounds.append({"candidates": results, "best": None, "accepted": None})
            return None
        best = max(scored, key=lambda c: results[c.key]["relative"])
        chosen = max(passing, key=lambda c: results[c.key]["relative"]) if passing else None
        held = results[best.key]["error_without"]
        if chosen is not None and not type(chosen).first and held <= AT_FLOOR * self.floor_fit:
            # what the model leaves in cross-validation is noise: a further effect could only
            # fit noise (one mechanism, one effect)
            self.rounds.append({"candidates": results, "best": best.key, "accepted": None,
                                "at_floor": {"held_out_error": held,
                                             "noise_floor": self.floor_fit,
                                             "factor": AT_FLOOR}})
            return None
        # a loaded model's own zero and gain error go first: any other effect would absorb
        # them in its refit of the base's affine part and be credited with them
        chosen = next((c for c in passing if type(c).first), chosen)
        self.rounds.append({"candidates": results, "best": best.key,
                            "accepted": chosen.key if chosen else None})
        return chosen

    def _fit_all(self, chosen: fx.Effect, ctx: fx.Context, tail: list[fx.Fitted],
                 frozen: np.ndarray) -> tuple[list[fx.Fitted], np.ndarray, np.ndarray] | None:
        """``chosen`` fitted on all the training data (jointly with ``tail`` when it joins):
        the new effects and predictions, or None when the fit failed (recorded, dropped)."""
        o, y, effects = self.o, self.y, self.model.effects[self.o]
        rows = np.ones(len(self.train), bool)
        try:
            with np.errstate(all="raise"):
                if joint(chosen):
                    members, thetas = _members(chosen, tail)
                    group = fx.fit_group(members, ctx, y - frozen, rows, thetas)
                    group = _retune(group, ctx, y - frozen, rows)
                    new_effects = effects[:self.tail_start] + group
                else:
                    c0 = self._context(self.yhat)
                    new_effects = effects + [fx.fit(chosen, c0, y - self.yhat, rows)]
                trial = SensorModel(self.model.base, {**self.model.effects, o: new_effects})
                yhat_new = trial.predict(self.train, o, y)
                yhat_all_new = trial.predict(self.data, o, self.y_all)
            if not (np.all(np.isfinite(yhat_new)) and np.all(np.isfinite(yhat_all_new))):
                raise ValueError("non-finite prediction")
        except FIT_ERRORS as exc:
            self.rounds[-1]["accepted"] = None
            self.rounds[-1]["failed"] = (f"{chosen.key}: the fit on all training data failed "
                                         f"({type(exc).__name__}: {exc})").splitlines()[0]
            self.cands = [c for c in self.cands if c.key != chosen.key]
            return None
        return new_effects, yhat_new, yhat_all_new

    def _accept(self, chosen: fx.Effect, cv: dict, new_effects: list[fx.Fitted],
                yhat_new: np.ndarray, yhat_all_new: np.ndarray) -> None:
        """Add ``chosen`` to the model: its report entry and plot stage, the refitted group's
        parameters as they are now."""
        y, yv, yhat, yhat_v = self.y, self.yv, self.yhat, self.yhat_v
        c_tr, c_all = yhat_new - yhat, yhat_all_new - self.yhat_all
        c_v = c_all[self.vmask]
        r_before = y - yhat
        corr = float(np.corrcoef(r_before, c_tr)[0, 1]) if np.std(c_tr) > 0 else 0.0
        e_b, e_a = rmse(yv, yhat_v), rmse(yv, yhat_v + c_v)
        group = new_effects[self.tail_start:]
        f = new_effects[-1] if not joint(chosen) else next(
            g for g in group if g.effect.key == chosen.key)
        reg, reg_name = fx.regressor(f, self._context(yhat))
        self.stages.append({"key": chosen.key, "residual": r_before, "contribution": c_tr,
                            "regressor": reg, "regressor_name": reg_name})
        refitted = [g.effect.key for g in group if g.effect.key != chosen.key]
        self.accepted.append(effect_entry(
            chosen, f, cv, corr, rmse(y, yhat), rmse(y, yhat_new),
            refitted if joint(chosen) else [], e_b, e_a))
        self.model.effects[self.o] = new_effects
        if joint(chosen) and fx.group_member(chosen):
            self._refitted_parameters(group)
        else:
            self.tail_start = len(new_effects)
        self._predicted(yhat_new, yhat_all_new)
        self.cands = [c for c in self.cands if c.key != chosen.key]

    def _refitted_parameters(self, group: list[fx.Fitted]) -> None:
        """The accepted effects' parameters as they are now, after a joint refit."""
        for g in self.accepted:
            h = next((e for e in group if e.effect.key == g["key"]), None)
            if h is not None:
                g["parameters"] = fx.describe(h)

    def _finish_runs(self) -> None:
        """Several training runs: how a new run gets its offset (tare or the runs' mean), the
        runs' own offsets when the model has none last, and the base's error with them."""
        model, o, train, y = self.model, self.o, self.train, self.y
        tare, tare_cv = _choose_tare(model, train, o, y, self.nuisance, self.blocks,
                                     self.cache, self.tail_start)
        if not tare:
            model.effects[o] = model.effects[o][:self.n_loaded] + [
                dataclasses.replace(f, tare=False) if f.runs else f
                for f in model.effects[o][self.n_loaded:]]
            self._predicted(model.predict(train, o, y), model.predict(self.data, o, self.y_all))
        offsets = {"runs": fx.run_paths(train), "tare_s": fx.TARE_S if tare else 0.0}
        rep = {}
        if not (model.effects[o] and model.effects[o][-1].runs):
            # the runs' own zeros: one offset per training run, a new run tared on its start
            c0 = fx.Context(train, o, self.yhat, self.nuisance, y, self.cache)
            f = fx.fit(fx.EFFECTS["run_offset"](), c0, y - self.yhat, np.ones(len(train), bool),
                       [offsets])
            model.effects[o].append(f)
            self._predicted(model.predict(train, o, y), model.predict(self.data, o, self.y_all))
            rep = {"effect": "run_offset", "parameters": fx.describe(f)}
        b0 = SensorModel(model.base, {o: []})
        c0 = fx.Context(train, o, b0.predict(train, o), self.nuisance, y, {})
        f0 = fx.fit(fx.EFFECTS["run_offset"](), c0, y - c0.yhat, np.ones(len(train), bool),
                    [dict(offsets)])
        b0.effects[o] = [f0]
        self.run_offsets = {
            **rep, "tare": tare, "choice_cv": tare_cv,
            "error_base_with_offsets": rmse(self.yv, b0.predict(self.data, o,
                                                                self.y_all)[self.vmask]),
            "rule": tare_rule(tare)}

    def result(self, max_effects: int) -> Selected:
        """What the selection leaves for its report."""
        return Selected(
            unit=self.val.units.get(self.o, ""), accepted=self.accepted, rounds=self.rounds,
            stages=self.stages, not_applicable=self.skipped, candidates_left=len(self.cands),
            max_effects=max_effects, run_offsets=self.run_offsets,
            base_parameters=self.model.base.parameters.get(self.o, {}),
            y_train=self.y, start_train=self.start_tr, final_train=self.yhat,
            y_val=self.yv, base_val=self.y0_val, final_val=self.yhat_v, dropped=self.dropped)


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
