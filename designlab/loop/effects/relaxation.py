"""Viscoelastic relaxation and creep of a mechanical output."""

from __future__ import annotations

import itertools

import numpy as np

from designlab.loop.effects.base import (
    Context,
    Effect,
    Fitted,
    count,
    highpass,
    varying_drives,
)
from designlab.measured.card import ELECTRICAL


def prony_grid(ctx: Context) -> list[dict]:
    """1 or 2 of 8 time constants (s), log-spaced from 3 dt to a quarter of the longest run
    (capped at 600 s), at least 6 dt."""
    d = ctx.data
    dur = min(float(np.max(d.time_in_run())), 600.0)
    lo, hi = 3 * d.dt, max(dur / 4, 6 * d.dt)
    taus = [float(v) for v in np.geomspace(lo, hi, 8)]
    return [{"tau": (t,)} for t in taus] + [{"tau": (a, b)}
                                           for a, b in itertools.combinations(taus, 2)]


class Relaxation(Effect):
    """Viscoelastic relaxation/creep: Prony terms on the input history,
    ``h_i = highpass(x, tau_i)`` (exact exponential recursion, ramp-invariant), one coefficient
    ``g_i`` (output unit per input unit) per time constant ``tau_i`` (s). Mechanical outputs;
    electrical ones get :class:`PiezoRelaxation`."""

    name = "relaxation"
    summary = "viscoelastic relaxation/creep: Prony terms on the input history"
    regressors_doc = ("Prony terms on the input history: `h_i = highpass(x, tau_i)` (exact "
                      "exponential recursion)")
    settings_doc = "1 or 2 of 8 `tau` from 3 dt to T/4 (T: longest run, <= 600 s)"
    applies_doc = "each varying drive input; mechanical outputs"
    per_input = True
    rank = 10

    @classmethod
    def applies(cls, train, output, base_inputs):
        if train.quantities.get(output, "") in ELECTRICAL:
            return "electrical output: see piezo_relaxation"
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        return prony_grid(ctx)

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        x = ctx.data.inputs[self.channel]
        cols = []
        for tau in theta["tau"]:
            ck = (id(ctx.data), "hp", self.channel, tau)   # shared by every tau pair
            if ck not in ctx.cache:
                ctx.cache[ck] = highpass(x, tau, ctx.data.dt, ctx.data.segment)
            cols.append(ctx.cache[ck])
        return np.column_stack(cols)

    def width(self, theta: dict) -> int:
        return count(theta, "tau")

    def describe(self, f: Fitted) -> dict:
        return {"tau_s": list(f.theta["tau"]), "g": list(f.beta),
                "g_unit": "output unit per input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
