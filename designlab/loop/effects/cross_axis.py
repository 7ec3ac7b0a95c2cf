"""Coupling to an input the base model does not use."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, varying_drives


class CrossAxis(Effect):
    """Cross-axis coupling: the output depends on an input the base does not use,
    ``x - x_m`` (``x_m`` the mean training value), coupling in output units per input unit."""

    name = "cross_axis"
    summary = "cross-axis coupling to an input the base does not use"
    regressors_doc = "`x - x_m`, an input the base does not use"
    settings_doc = "- (`x_m`: training mean)"
    applies_doc = "each varying drive input the base does not use"
    per_input = True
    rank = 50

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train) if x not in base_inputs]

    def grid(self, ctx: Context) -> list[dict]:
        return [{"reference": float(np.mean(ctx.data.inputs[self.channel]))}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        return ctx.data.inputs[self.channel] - theta["reference"]

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"coupling": f.beta[0], "reference": f.theta["reference"]}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
