"""Direction-dependent friction hysteresis of the output against an input."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import (
    Context,
    Effect,
    Fitted,
    count,
    dahl,
    play,
    rate,
    robust_range,
    varying_drives,
)


class Hysteresis(Effect):
    """Direction-dependent friction: Coulomb ``tanh(xdot / v0)`` (``v0`` in input units per
    s), a Dahl state (characteristic travel ``x_c``, input units), or Maxwell-slip (4 parallel
    elasto-slide elements = play operators of half-widths ``widths``, input units)."""

    name = "hysteresis"
    summary = "direction-dependent friction hysteresis"
    regressors_doc = "Coulomb `tanh(xdot/v0)`, Dahl state, or 4 Maxwell-slip (play) elements"
    settings_doc = ("`v0` = 0.03/0.1/0.3 sd(xdot), `x_c` = 0.01/0.03/0.1/0.3 of the 1-99 % "
                    "range, or all four as widths")
    applies_doc = "each varying drive input"
    per_input = True
    rank = 20

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        R = robust_range(x)
        v = rate(x, ctx.data.dt, ctx.data.segment)
        vs = float(np.std(v)) or 1.0
        g = [{"variant": "coulomb", "v0": f * vs} for f in (0.03, 0.1, 0.3)]
        g += [{"variant": "dahl", "xc": f * R} for f in (0.01, 0.03, 0.1, 0.3)]
        g += [{"variant": "maxwell_slip", "widths": tuple(f * R for f in (0.01, 0.03, 0.1, 0.3))}]
        return g

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        x = d.inputs[self.channel]
        if theta["variant"] == "coulomb":
            return np.tanh(rate(x, d.dt, d.segment) / theta["v0"])
        if theta["variant"] == "dahl":
            return dahl(x, np.array([theta["xc"]]), d.segment)
        return play(x, np.array(theta["widths"]), d.segment)

    def width(self, theta: dict) -> int:
        return count(theta, "widths") if theta["variant"] == "maxwell_slip" else 1

    def describe(self, f: Fitted) -> dict:
        th, b = f.theta, list(f.beta)
        out = {"variant": th["variant"], **{k: v for k, v in th.items() if k != "variant"}}
        out["amplitude" if len(b) == 1 else "stiffness"] = b[0] if len(b) == 1 else b
        out["unit"] = ("v0 in input unit per s, amplitude in output unit" if th["variant"] ==
                       "coulomb" else "x_c in input unit, amplitude in output unit" if
                       th["variant"] == "dahl" else
                       "widths in input unit, stiffness in output unit per input unit")
        return out

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
