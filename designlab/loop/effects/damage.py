"""Softening in the damage form: the gain falls with the largest input seen so far."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import (
    Context,
    Effect,
    Fitted,
    robust_range,
    varying_drives,
)
from designlab.loop.effects.mullins import running_max

#: the damage saturation scales ``eta`` over the 1-99 % range of the input; None is the
#: linear limit (``eta`` much larger than the range: a damage far from saturation)
ETA_FACTORS = (0.1, 0.3, 1.0, 3.0, None)


def damage(alpha: np.ndarray, eta: float | None, R: float) -> np.ndarray:
    """The damage variable over ``d_inf``: ``1 - exp(-alpha / eta)``, or ``alpha / R`` in the
    linear limit (``eta`` None); ``alpha`` and ``eta`` in input units, ``R`` the range."""
    if eta is None:
        return alpha / R
    return 1.0 - np.exp(-alpha / eta)


class Damage(Effect):
    """Strain-history softening in the continuum-damage form: the response is scaled by
    ``1 - d(alpha)``, where ``alpha = max_{s <= t} (x(s) - x_0)`` is the largest input reached
    so far in the run (``x_0`` the training minimum) and ``d(alpha) = d_inf (1 - exp(-alpha /
    eta))`` grows with it and saturates at ``d_inf``. The gain depends on the running maximum
    alone, not on how far below it the input is: the softened response is reversible below the
    maximum (loading and unloading on one softer line), unlike the recovery form of
    ``mullins``, where the softening vanishes back at the maximum. Regressor ``x_r d(alpha) /
    d_inf`` (``x_r = x - x_0``): its coefficient is ``-d_inf`` times the base's gain (output unit
    per input unit). The damage variable is the running maximum of the input instead of the
    undamaged strain energy (the energy is a monotone function of a uniaxial input). Source:
    C. Miehe, Discontinuous and continuous damage evolution in Ogden-type large-strain elastic
    materials, Eur. J. Mech. A/Solids 14 (1995) 697-720, eq. for ``d(alpha)``; after J. C.
    Simo, Comput. Methods Appl. Mech. Eng. 60 (1987) 153-173."""

    name = "damage"
    summary = "damage softening: the gain falls with the largest input seen so far"
    regressors_doc = ("`x_r (1 - exp(-alpha/eta))`, `alpha` the running maximum of `x_r` in the "
                      "run (linear limit `x_r alpha / R`)")
    settings_doc = ("`eta` = 0.1/0.3/1/3 of the 1-99 % range `R` (refined between its "
                    "neighbours), or the linear limit")
    applies_doc = "each varying drive input"
    per_input = True
    rank = 26
    refine = "eta"

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        R = robust_range(x)
        return [{"eta": None if f is None else f * R, "R": R, "x0": float(np.min(x))}
                for f in ETA_FACTORS]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        xr = d.inputs[self.channel] - theta["x0"]
        alpha = np.maximum(running_max(xr, d.segment), 0.0)
        return xr * damage(alpha, theta["eta"], theta["R"])

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        th = f.theta
        linear = th["eta"] is None
        return {"eta": th["eta"], "linear_limit": linear,
                "softening": f.beta[0], "x0": th["x0"], "R": th["R"],
                "form": ("softening * x_r * alpha / R" if linear else
                         "softening * x_r * (1 - exp(-alpha / eta))"),
                "unit": "eta, x0 and R in input units; softening (-d_inf x the base's gain) in "
                        "output unit per input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        d = ctx.data
        x = d.inputs[self.channel]
        return running_max(x, d.segment), f"running maximum of {self.channel}"
