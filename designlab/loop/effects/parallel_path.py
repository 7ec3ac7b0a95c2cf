"""A parallel load path that engages above a level of the input."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import (
    Context,
    Effect,
    Fitted,
    robust_range,
    varying_drives,
)


class ParallelPath(Effect):
    """A parallel load path that steals sensitivity above an engagement level ``x_s`` (input
    units): ``max(x - x_s, 0) / range``; the fitted gain change is in output units per input
    unit."""

    name = "parallel_path"
    summary = "parallel load path stealing sensitivity above an engagement level"
    regressors_doc = "`max(x - x_s, 0)`: a path that steals sensitivity above x_s"
    settings_doc = "x_s at the 30, 50, 70, 85 % quantiles"
    applies_doc = "each varying drive input"
    per_input = True
    rank = 40

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        s = robust_range(x)
        return [{"engage": float(np.quantile(x, q)), "scale": s} for q in (0.3, 0.5, 0.7, 0.85)]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        x = ctx.data.inputs[self.channel]
        return np.maximum(x - theta["engage"], 0.0) / theta["scale"]

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"engage": f.theta["engage"], "gain_change": f.beta[0] / f.theta["scale"],
                "form": "gain_change * max(x - engage, 0)"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
