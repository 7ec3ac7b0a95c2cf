"""Relaxation of a piezoresistive (electrical) output."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, count, highpass
from designlab.loop.effects.relaxation import prony_grid
from designlab.measured.card import ELECTRICAL


class PiezoRelaxation(Effect):
    """Piezoresistive relaxation: Prony terms on the predicted resistance/voltage,
    ``h_i = highpass(yhat, tau_i)``, ``g_i`` relative to the prediction's high-pass, time
    constants ``tau_i`` (s). Electrical outputs; mechanical ones get :class:`Relaxation`."""

    name = "piezo_relaxation"
    summary = "piezoresistive relaxation: Prony terms on the predicted output"
    regressors_doc = "Prony terms on the prediction: `highpass(yhat, tau_i)`"
    settings_doc = "same as `relaxation`"
    applies_doc = "electrical outputs (resistance, voltage, current)"
    uses_prediction = True
    rank = 60

    @classmethod
    def applies(cls, train, output, base_inputs):
        if train.quantities.get(output, "") in ELECTRICAL:
            return [cls()]
        return "output is not electrical (resistance/voltage/current)"

    def grid(self, ctx: Context) -> list[dict]:
        return prony_grid(ctx)

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        cols = []
        for tau in theta["tau"]:
            if tau not in ctx.pred_cache:
                ctx.pred_cache[tau] = highpass(ctx.yhat, tau, ctx.data.dt, ctx.data.segment)
            cols.append(ctx.pred_cache[tau])
        return np.column_stack(cols)

    def width(self, theta: dict) -> int:
        return count(theta, "tau")

    def describe(self, f: Fitted) -> dict:
        return {"tau_s": list(f.theta["tau"]), "g": list(f.beta),
                "g_unit": "relative (of the predicted output's high-pass)"}
