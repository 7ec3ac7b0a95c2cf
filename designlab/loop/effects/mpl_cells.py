"""Seed 000's modified power-law (mPL) recurrent cells as a loop effect."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, robust_range, varying_drives
from designlab.measured import mpl


class MPLCells(Effect):
    """Seed 000's mPL recurrent model (Schouten, Kosmas, Krijnen; :mod:`designlab.measured.mpl`):
    cells ``ds/dt = P_S (exp((x - s)/P_T) - exp(-(x - s)/P_T))`` driven by the input (exact
    update, at rest at the start of every run); the output gains ``w (x - s)``, the cell's lag
    behind the input. ``P_T`` (input units) sets how nonlinear the cell is (small: a soft play
    operator, creep-like hysteresis; large: a linear first-order lag), ``tau = P_T / (2 P_S)``
    (s) its small-signal time constant. One cell; ``w`` in output units per input unit."""

    name = "mpl_cells"
    summary = "seed 000's mPL recurrent cell (sinh-law creep/hysteresis)"
    regressors_doc = "`x - s` of one mPL cell driven by the input"
    settings_doc = "`P_T` = 0.01/0.03/0.1 of the 1-99 % range x `tau` = 1, 5, 30 s"
    applies_doc = "each varying drive input"
    per_input = True
    rank = 32

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        R = robust_range(ctx.data.inputs[self.channel])
        return [{"P_T": f * R, "tau": tau} for f in (0.01, 0.03, 0.1) for tau in (1.0, 5.0, 30.0)]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        x = d.inputs[self.channel]
        starts = np.r_[True, np.diff(d.segment) != 0]
        pt = theta["P_T"]
        ps = pt / (2 * theta["tau"])
        s = mpl.cell_states(x, np.array([pt]), np.array([ps]), d.dt, "exact", starts=starts)
        return x - s[0]

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"P_T": f.theta["P_T"], "P_S_per_s": f.theta["P_T"] / (2 * f.theta["tau"]),
                "tau_s": f.theta["tau"], "w": f.beta[0],
                "unit": "P_T in input units, P_S in input units per s, w in output unit per "
                        "input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
