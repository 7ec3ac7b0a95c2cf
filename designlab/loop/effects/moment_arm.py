"""An output that scales with where the load acts."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted


class MomentArm(Effect):
    """The output scales with a location input (a moment arm): ``(loc - loc_m) * yhat``
    (relative gain per location unit) and ``(loc - loc_m)`` (offset per unit), ``loc_m`` the
    mean training location."""

    name = "moment_arm"
    summary = "output scales with the load location"
    regressors_doc = "`(loc - loc_m) * yhat`, `(loc - loc_m)`"
    settings_doc = "- (`loc_m`: training mean)"
    applies_doc = "each input of kind location"
    uses_prediction = True
    rank = 90

    @classmethod
    def applies(cls, train, output, base_inputs):
        locs = [n for n in train.inputs if train.kinds.get(n) == "location"]
        return [cls(loc) for loc in locs] if locs else "no location input"

    def grid(self, ctx: Context) -> list[dict]:
        return [{"reference": float(np.mean(ctx.data.inputs[self.channel]))}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        dl = ctx.data.inputs[self.channel] - theta["reference"]
        return np.column_stack([dl * ctx.yhat, dl])

    def width(self, theta: dict) -> int:
        return 2

    def describe(self, f: Fitted) -> dict:
        return {"relative_gain_per_unit": f.beta[0], "offset_per_unit": f.beta[1],
                "reference": f.theta["reference"]}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
