"""The backward pass after the forward selection: one mechanism, one effect.

The forward selection adds the best candidate each round; an effect added early can leave a
small structured mismatch that later effects fit (and extrapolate badly), or an effect added
later can take over what an earlier one explained. The backward pass refits the selected
effects together, as the forward pass fitted them (consecutive effects with regressors of the
data alone in one least squares with the base's affine part; an effect that depends on the
prediction or has its own solver fitted on top of what comes before it), with each effect left
out in turn, in the same blocked cross-validation as the selection. An effect is removed when
the held-out RMS it accounts for, ``sqrt(mean(e_without^2) - mean(e_with^2))`` over the held-out
blocks, is no larger than the noise floor of the training data (it lowers the held-out error by
no more than the noise), when the others already leave only noise without it, or when it no
longer passes the forward acceptance rule beside the others. The one that accounts for least
goes first; the rest are refitted on all the training data, and the pass repeats until every
effect left holds up. Also the helpers the selection shares with it: :func:`joint`,
:func:`chain`, :class:`Affine`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from designlab.calibration.metrics import rmse
from designlab.errors import ModelError
from designlab.loop import effects as fx

#: what a failing fit raises (a singular or non-finite system, NNLS out of iterations)
FIT_ERRORS = (ModelError, np.linalg.LinAlgError, FloatingPointError, ValueError, RuntimeError)


class Affine(fx.Effect):
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


def chain(fitted: list[fx.Fitted], ctx: fx.Context) -> np.ndarray:
    """Prediction of ``ctx.yhat`` plus ``fitted`` applied in order."""
    y = ctx.yhat
    for f in fitted:
        c = fx.Context(ctx.data, ctx.output, y, ctx.base_inputs, ctx.measured, ctx.cache,
                       per_run=ctx.per_run, tare=ctx.tare)
        y = y + fx.contribution(f, c)
    return y


Contexts = Callable[[np.ndarray], fx.Context]   # prediction -> the context of a fit on top of it


@dataclass
class Refit:
    """Effects refitted on some rows: the fitted effects in order, the prediction of every
    sample, and where the last open joint group starts in ``fitted``."""

    fitted: list[fx.Fitted]
    prediction: np.ndarray
    open_start: int


def refit_chain(effects: list[fx.Fitted], frozen: np.ndarray, context: Contexts,
                y: np.ndarray, rows: np.ndarray, affine: bool) -> Refit:
    """``effects`` (their settings kept) refitted on ``rows`` on top of ``frozen`` as the
    forward selection fits them: a joint effect in one least squares with the open group before
    it (the group closes after a member with its own solver), any other effect on top of the
    prediction so far. No effects and ``affine``: the base's affine part alone is refitted."""
    if not effects:
        if not affine:
            return Refit([], frozen, 0)
        ctx = context(frozen)
        group = fx.fit_group([Affine()], ctx, y - frozen, rows, [None])
        return Refit([], chain(group, ctx), 0)
    out: list[fx.Fitted] = []
    tail: list[fx.Fitted] = []
    for f in effects:
        e = f.effect
        if joint(e):
            members = [g.effect for g in tail] + [e]
            group = fx.fit_group(members, context(frozen), y - frozen, rows,
                                 [[g.theta] for g in tail] + [[f.theta]])
            if fx.group_member(e):
                tail = group
                continue
            frozen = chain(group, context(frozen))
            out += group
            tail = []
            continue
        if tail:
            frozen = chain(tail, context(frozen))
            out += tail
            tail = []
        ctx = context(frozen)
        g = fx.fit(e, ctx, y - frozen, rows, [f.theta])
        frozen = frozen + fx.contribution(g, ctx)
        out.append(g)
    start = len(out)
    if tail:
        frozen = chain(tail, context(frozen))
        out += tail
    return Refit(out, frozen, start)


@dataclass(frozen=True)
class Rule:
    """The backward pass's thresholds: the noise floor of the training data (output unit),
    the forward pass's floor factor and acceptance rule (``acceptable(cv) -> bool``)."""

    floor: float
    at_floor: float
    acceptable: Callable[[dict], bool]


def held_out(effects: list[fx.Fitted], frozen: np.ndarray, context: Contexts, y: np.ndarray,
             blocks, affine: bool) -> np.ndarray:
    """Held-out RMSE per cross-validation block of ``effects`` refitted on the other rows."""
    out = []
    for rows, held in blocks:
        with np.errstate(all="raise"):
            pred = refit_chain(effects, frozen, context, y, rows, affine).prediction
        if not np.all(np.isfinite(pred[held])):
            raise FloatingPointError("non-finite held-out prediction")
        out.append(rmse(y[held], pred[held]))
    return np.array(out)


def check(e_with: np.ndarray, e_without: np.ndarray, rule: Rule) -> dict:
    """The record of one effect left out: held-out errors with and without it, the RMS it
    accounts for, the forward rule's numbers and whether it is removed and why."""
    rel = (e_without - e_with) / np.maximum(e_without, 1e-300)
    se = float(np.std(rel, ddof=1) / math.sqrt(rel.size)) if rel.size > 1 else float("inf")
    w, wo = float(np.sqrt(np.mean(e_with ** 2))), float(np.sqrt(np.mean(e_without ** 2)))
    accounts = float(math.sqrt(max(wo ** 2 - w ** 2, 0.0)))
    cv = {"relative": float(rel.mean()), "standard_error": se,
          "blocks_improved": int(np.sum(rel > 0)), "blocks": int(rel.size),
          "error_with": w, "error_without": wo, "accounts_for": accounts,
          "noise_floor": rule.floor, "per_block_with": e_with.tolist(),
          "per_block_without": e_without.tolist()}
    why = []
    if accounts <= rule.floor:
        why.append(f"it accounts for {accounts:.4g} of the held-out error (RMS), no more than "
                   f"the noise floor {rule.floor:.4g}")
    if wo <= rule.at_floor * rule.floor:
        why.append(f"the others leave {wo:.4g} without it, within {rule.at_floor:g}x the noise "
                   f"floor {rule.floor:.4g}")
    if not rule.acceptable(cv):
        why.append(f"beside the others it lowers the held-out error by {100 * cv['relative']:.2f}"
                   f" % ({cv['relative'] / se if se > 0 else float('inf'):.2g} standard "
                   "errors): the forward rule no longer accepts it")
    cv["removed"] = bool(why)
    cv["why"] = "; ".join(why) if why else "holds up"
    return cv


def backward_step(effects: list[fx.Fitted], removable: set[str], frozen: np.ndarray,
                  context: Contexts, y: np.ndarray, blocks, affine: bool, rule: Rule
                  ) -> tuple[int, dict] | None:
    """One step of the pass: the index in ``effects`` of the effect to remove (of those whose
    key is in ``removable``, the one that accounts for least) and its record, or None when each
    holds up (or the model cannot be refitted)."""
    try:
        e_with = held_out(effects, frozen, context, y, blocks, affine)
    except FIT_ERRORS:
        return None
    found = []
    for j, f in enumerate(effects):
        if f.effect.key not in removable:
            continue
        try:
            e_wo = held_out(effects[:j] + effects[j + 1:], frozen, context, y, blocks, affine)
        except FIT_ERRORS:
            continue
        cv = check(e_with, e_wo, rule)
        if cv["removed"]:
            found.append((cv["accounts_for"], j, cv))
    if not found:
        return None
    _, j, cv = min(found, key=lambda c: c[0])
    return j, cv
