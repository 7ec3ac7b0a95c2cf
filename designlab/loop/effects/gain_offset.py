"""The measured sensor's zero and sensitivity differ from a model it did not fit."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted


class GainOffset(Effect):
    """Offset and gain error of a base that was not fitted on this data (a ``designlab
    predict`` model: the design's FEM): ``y = (1 + g) yhat + o``. ``o`` (output units) is a zero
    shift of the reading (a tracker's or amplifier's zero, a preload), ``g`` the relative
    sensitivity error (a printed part stiffer or softer than its model, a gauge factor). Both
    carry over to another design as relative corrections. Offered only when the base is a loaded
    model (a base fitted on the data already has least-squares offset and gains)."""

    name = "gain_offset"
    summary = "zero offset and relative gain error of a model not fitted on this data"
    regressors_doc = "`1`, `yhat` (the base's prediction): `y = (1 + g) yhat + o`"
    applies_doc = "a loaded model as the base (`--base model.json`)"
    uses_prediction = True
    intercept = False
    rank = 5
    first = True

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls()]

    def grid(self, ctx: Context) -> list[dict]:
        return [{}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        return np.column_stack([np.ones(len(ctx.data)), ctx.yhat])

    def solve(self, X: np.ndarray, target: np.ndarray, k: int) -> np.ndarray:
        """Offset and gain alone: the base's input gains are not refitted beside them (the
        gain error is one relative number, not a new affine map)."""
        coef = np.zeros(X.shape[1])
        coef[:k] = np.linalg.lstsq(X[:, :k], target, rcond=None)[0]
        return coef

    def width(self, theta: dict) -> int:
        return 2

    def describe(self, f: Fitted) -> dict:
        return {"offset": f.beta[0], "relative_gain": f.beta[1],
                "unit": "offset in output units; gain relative to the model's (0.08 = +8 %)"}

    def regressor(self, f: Fitted, ctx: Context):
        return ctx.yhat, "model prediction"
