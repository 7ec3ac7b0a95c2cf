"""Mullins softening: an elastomer is softer below the largest stretch it has seen."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import (
    Context, Effect, Fitted, _segments, robust_range, varying_drives)


def running_max(x: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """The largest ``x`` so far in each run (units of ``x``)."""
    out = np.empty_like(x, dtype=float)
    for s in _segments(segment):
        out[s] = np.maximum.accumulate(x[s])
    return out


class Mullins(Effect):
    """Mullins (strain-history) softening after Ogden and Roxburgh (1999): below the running
    maximum ``x_max`` of the input the response is scaled by a damage factor that grows with
    the distance below the maximum, ``-x_r * (1 - exp(-(x_max - x) / m))`` (``x_r = x - x_0``,
    ``x_0`` the training minimum; ``m`` in input units), plus a permanent set that grows with
    ``x_max``. Coefficients: softening (output unit per input unit) and set (output unit per
    input unit of ``x_max``). Source: R. W. Ogden, D. G. Roxburgh, Proc. R. Soc. A 455 (1999)."""

    name = "mullins"
    summary = "Mullins softening: softer below the largest input seen so far"
    regressors_doc = "`x_r (1 - exp(-(x_max - x)/m))`, `x_max` (running maximum in the run)"
    settings_doc = "`m` = 0.03/0.1/0.3/1 of the 1-99 % range, refined between its neighbours"
    applies_doc = "each varying drive input"
    per_input = True
    rank = 25
    refine = "m"

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        R = robust_range(x)
        return [{"m": f * R, "x0": float(np.min(x))} for f in (0.03, 0.1, 0.3, 1.0)]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        x = d.inputs[self.channel]
        xm = running_max(x, d.segment)
        return np.column_stack([(x - theta["x0"]) * (1 - np.exp(-(xm - x) / theta["m"])), xm])

    def width(self, theta: dict) -> int:
        return 2

    def describe(self, f: Fitted) -> dict:
        return {"m": f.theta["m"], "softening": f.beta[0], "set_per_max": f.beta[1],
                "x0": f.theta["x0"], "unit": "m in input units; softening and set in output "
                                             "unit per input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        d = ctx.data
        x = d.inputs[self.channel]
        return running_max(x, d.segment) - x, f"{self.channel}_max - {self.channel}"
