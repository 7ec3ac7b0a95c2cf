"""Temperature acting on the output through a temperature coefficient."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted


class Thermal(Effect):
    """Temperature through a TCR: ``(T - T_m) * yhat`` (coefficient: TCR, 1/C) and
    ``(T - T_m)`` (offset per C), ``T_m`` the mean training temperature (C)."""

    name = "thermal"
    summary = "temperature through a TCR"
    regressors_doc = "`(T - T_m) * yhat`, `(T - T_m)` (TCR)"
    settings_doc = "- (`T_m`: training mean)"
    applies_doc = "each input of kind temperature"
    uses_prediction = True
    rank = 80

    @classmethod
    def applies(cls, train, output, base_inputs):
        temps = [n for n in train.inputs if train.kinds.get(n) == "temperature"]
        return [cls(T) for T in temps] if temps else "no temperature input"

    def grid(self, ctx: Context) -> list[dict]:
        return [{"reference": float(np.mean(ctx.data.inputs[self.channel]))}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        dT = ctx.data.inputs[self.channel] - theta["reference"]
        return np.column_stack([dT * ctx.yhat, dT])

    def width(self, theta: dict) -> int:
        return 2

    def describe(self, f: Fitted) -> dict:
        return {"tcr_per_C": f.beta[0], "offset_per_C": f.beta[1],
                "reference_C": f.theta["reference"]}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
