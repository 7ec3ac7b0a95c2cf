"""Friction hysteresis whose size scales with the moment arm (seed 001)."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, dahl, robust_range, varying_drives


class FrictionArm(Effect):
    """Friction x moment arm: a Dahl friction state ``z`` in [-1, 1] of the drive input (the
    hanging weight, characteristic travel ``x_c`` in input units) times the location ``loc``
    of the load, ``loc * z`` (friction per unit of arm, output units per location unit) and
    ``z`` (friction at zero arm): the reading of seed 001's fingertip carries a friction
    moment proportional to the moment arm of the load. Source: Xu et al. 2014 (seed 001)."""

    name = "friction_arm"
    summary = "friction hysteresis proportional to the moment arm (seed 001)"
    regressors_doc = "`loc * z`, `z` (z: Dahl state of the drive input)"
    settings_doc = "`x_c` = 0.01/0.03/0.1/0.3 of the 1-99 % range"
    applies_doc = "each varying drive input, when there is a location input"
    per_input = True
    uses_prediction = False
    rank = 85

    @classmethod
    def applies(cls, train, output, base_inputs):
        locs = [n for n in train.inputs if train.kinds.get(n) == "location"]
        if not locs:
            return "no location input"
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        d = ctx.data
        loc = next(n for n in d.inputs if d.kinds.get(n) == "location")
        R = robust_range(d.inputs[self.channel])
        return [{"location": loc, "xc": f * R} for f in (0.01, 0.03, 0.1, 0.3)]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        z = dahl(d.inputs[self.channel], np.array([theta["xc"]]), d.segment)[:, 0]
        return np.column_stack([d.inputs[theta["location"]] * z, z])

    def width(self, theta: dict) -> int:
        return 2

    def describe(self, f: Fitted) -> dict:
        return {"location": f.theta["location"], "x_c": f.theta["xc"],
                "friction_per_arm": f.beta[0], "friction_at_zero_arm": f.beta[1],
                "unit": "x_c in input units; friction in output units (per location unit)"}

    def regressor(self, f: Fitted, ctx: Context):
        d = ctx.data
        z = dahl(d.inputs[self.channel], np.array([f.theta["xc"]]), d.segment)[:, 0]
        return d.inputs[f.theta["location"]] * z, f"{f.theta['location']} x friction state"
