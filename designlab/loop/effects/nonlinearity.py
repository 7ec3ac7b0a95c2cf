"""Load nonlinearity: a polynomial in the input."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, varying_drives, whole


class Nonlinearity(Effect):
    """Load nonlinearity: ``u^2`` (and ``u^3``) of the normalised input
    ``u = (x - center) / scale``, center and half-width of the 1-99 % range (input units)."""

    name = "nonlinearity"
    summary = "load nonlinearity (polynomial in the input)"
    regressors_doc = "`u^2 (, u^3)` of the normalised input"
    settings_doc = "order 2 or 3"
    applies_doc = "each varying drive input"
    per_input = True
    rank = 30

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        lo, hi = np.percentile(ctx.data.inputs[self.channel], [1, 99])
        c, s = float((lo + hi) / 2), float(max((hi - lo) / 2, 1e-12))
        return [{"order": o, "center": c, "scale": s} for o in (2, 3)]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        u = (ctx.data.inputs[self.channel] - theta["center"]) / theta["scale"]
        return np.column_stack([u ** k for k in range(2, theta["order"] + 1)])

    def width(self, theta: dict) -> int:
        return whole(theta, "order", 2) - 1

    def describe(self, f: Fitted) -> dict:
        th = f.theta
        return {"order": th["order"], "center": th["center"], "scale": th["scale"],
                "coefficients": list(f.beta), "form": "sum_k c_k ((x - center)/scale)^k, k >= 2"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
