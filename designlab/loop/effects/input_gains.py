"""The measured sensor's linear response differs from a loaded model's in its input gains."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, count, varying_drives


class InputGains(Effect):
    """A model not fitted on the data (a ``designlab predict`` model) has some of its input
    gains wrong beyond one zero and one relative gain (:class:`GainOffset`): a cross-sensitivity,
    an entry of a stiffness or compliance matrix. Every varying drive input's gain is refitted,
    ``y += sum_i c_i (x_i - x_i,m)`` (``x_i,m`` the training means; ``c_i`` in output units per
    input unit). It is linear, so it names no mechanism: it is the part of the residual a
    linear map of the inputs explains, taken before the other candidates (``first``, after the
    model's own zero, gain and pose-frame errors) so that a nonlinear effect is credited only
    with what is not linear (one with a linear term in one input, a QLV or a Preisach
    identity envelope, would otherwise take that input's gain error). Offered only when the
    base is a loaded model: a base fitted on the data has least-squares gains already."""

    name = "input_gains"
    summary = "linear response differs from the model's: every input's gain refitted"
    regressors_doc = "`x_i - x_i,m` for every varying drive input"
    settings_doc = "- (`x_i,m`: training means)"
    applies_doc = "a loaded model as the base (`--base model.json`)"
    rank = 6
    first = True

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls()] if varying_drives(train) else "no varying drive input"

    def grid(self, ctx: Context) -> list[dict]:
        names = tuple(varying_drives(ctx.data))
        return [{"inputs": names,
                 "reference": tuple(float(np.mean(ctx.data.inputs[n])) for n in names)}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        return np.column_stack([ctx.data.inputs[n] - m
                                for n, m in zip(theta["inputs"], theta["reference"])])

    def width(self, theta: dict) -> int:
        n = count(theta, "inputs")
        if count(theta, "reference") != n:
            raise ValueError("inputs and reference differ in length")
        return n

    def describe(self, f: Fitted) -> dict:
        return {"gains": dict(zip(f.theta["inputs"], f.beta[:len(f.theta["inputs"])])),
                "reference": dict(zip(f.theta["inputs"], f.theta["reference"])),
                "unit": "output units per input unit, added to the model's gains"}

    def regressor(self, f: Fitted, ctx: Context):
        """The input whose refitted gain moves the output most over the data."""
        d = ctx.data
        names = f.theta["inputs"]
        k = int(np.argmax([abs(b) * np.std(d.inputs[n]) for n, b in zip(names, f.beta)]))
        return d.inputs[names[k]], f"{names[k]} ({d.units.get(names[k], '')})"
