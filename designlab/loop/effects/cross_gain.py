"""An input the base does not use changes the sensor's gain (cross-axis x gain)."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, varying_drives


class CrossGain(Effect):
    """Cross-axis gain coupling: a drive input ``x`` the base does not use scales the
    prediction, ``(x - x_m) * yhat`` (relative gain per input unit; ``x_m`` the training
    mean); its additive cross-talk ``(x - x_m)`` is :class:`CrossAxis`, as the gain product of
    temperature is :class:`Thermal` (TCR)."""

    name = "cross_gain"
    summary = "cross-axis input scales the gain"
    regressors_doc = "`(x - x_m) * yhat`"
    settings_doc = "- (`x_m`: training mean)"
    applies_doc = "each varying drive input the base does not use (the base uses one)"
    per_input = True
    uses_prediction = True
    rank = 55

    @classmethod
    def applies(cls, train, output, base_inputs):
        if not base_inputs:
            return "the base uses no input: no gain to scale"
        out = [cls(x) for x in varying_drives(train) if x not in base_inputs]
        return out or "every varying drive input is in the base"

    def grid(self, ctx: Context) -> list[dict]:
        return [{"reference": float(np.mean(ctx.data.inputs[self.channel]))}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        dx = ctx.data.inputs[self.channel] - theta["reference"]
        return dx * ctx.yhat

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"relative_gain_per_unit": f.beta[0], "reference": f.theta["reference"],
                "unit": "relative gain per input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
