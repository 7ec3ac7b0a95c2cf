"""A time lag between the output channel and the inputs."""

from __future__ import annotations

import math

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, rate, shift


class Lag(Effect):
    """Channel lag (clock synchronisation): ``yhat(t - delay) - yhat(t)`` with a fitted
    coefficient (1 when the base's gains are right; a base fitted on delayed data has its gains
    biased low, and the coefficient restores them on the delayed input), a fractional
    ``delay`` (s) at the peak of the cross-correlation of the measured output with
    the shifted prediction (one-sample grid within +-min(2 s, 5 % of the longest run), then a
    parabola through the peak)."""

    name = "lag"
    summary = "channel lag (clock synchronisation)"
    regressors_doc = ("`yhat(t - delay) - yhat(t)`, delay from the cross-correlation peak "
                      "(parabolic, fractional)")
    settings_doc = "one: the delay at the peak, within +-min(2 s, T/20)"
    applies_doc = "always"
    uses_prediction = True
    rank = 110

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls()]

    def grid(self, ctx: Context) -> list[dict]:
        d = ctx.data
        y = ctx.measured
        rows = ctx.cache.get("rows", np.ones(len(d), bool))
        dt = d.dt
        max_lag = min(2.0, 0.05 * float(np.max(d.time_in_run())))
        lags = np.arange(-math.floor(max_lag / dt), math.floor(max_lag / dt) + 1) * dt
        if lags.size < 3:
            return [{"delay": 0.0}]
        cc = np.array([np.corrcoef(y[rows], shift(ctx.yhat, L, d.t, d.segment)[rows])[0, 1]
                       for L in lags])
        cc = np.nan_to_num(cc, nan=-1.0)
        i = int(np.argmax(cc))
        delay = float(lags[i])
        if 0 < i < lags.size - 1:
            a, b, c = cc[i - 1], cc[i], cc[i + 1]
            den = a - 2 * b + c
            if den < 0:
                delay += 0.5 * (a - c) / den * dt
        return [{"delay": delay, "max_lag_s": float(max_lag)}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        return shift(ctx.yhat, theta["delay"], d.t, d.segment) - ctx.yhat

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"delay_s": f.theta["delay"], "max_lag_s": f.theta.get("max_lag_s"),
                "coefficient": float(f.beta[0])}

    def regressor(self, f: Fitted, ctx: Context):
        d = ctx.data
        return rate(ctx.yhat, d.dt, d.segment), "rate of the prediction (per s)"
