"""Quasi-linear viscoelasticity (Fung): relaxation of a nonlinear elastic response."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, count, highpass, varying_drives
from designlab.loop.effects.relaxation import prony_grid
from designlab.measured.card import ELECTRICAL


class QuasiLinearViscoelastic(Effect):
    """Fung's quasi-linear viscoelasticity: ``y = int G(t - s) d sigma_e(x(s))`` with a
    nonlinear elastic response ``sigma_e = c1 u + c2 u^2 + c3 u^3`` (``u = (x - x_0)/R``,
    ``x_0`` the training minimum, ``R`` the 1-99 % range) and a Prony relaxation function
    ``G = G_inf + sum g_i exp(-t / tau_i)``. Linear in its coefficients: the static terms
    ``u^2, u^3`` (the relaxed nonlinear response; ``u`` is in the base) and the Prony terms
    ``highpass(u^k, tau_i)``, k = 1..3 (the part that relaxes, with time constants ``tau_i``
    in s, at most T/20 of the longest run T: with its three Prony terms per time constant a
    slower one fits a run's drift and does not carry over to another run). Source: Y. C.
    Fung, Biomechanics (1993), ch. 7. Mechanical outputs (the matrix's stress)."""

    name = "qlv"
    summary = "quasi-linear viscoelasticity: a nonlinear elastic response that relaxes"
    regressors_doc = ("`u^2, u^3` and Prony terms `highpass(u^k, tau_i)`, k = 1..3 "
                      "(u: input normalised to its range)")
    settings_doc = "1 or 2 `tau` of the `relaxation` grid up to T/20"
    applies_doc = "each varying drive input; mechanical outputs"
    per_input = True
    rank = 12

    @classmethod
    def applies(cls, train, output, base_inputs):
        if train.quantities.get(output, "") in ELECTRICAL:
            return ("electrical output: its 9 free Prony coefficients fit one run's drift "
                    "(stretch resistance: 204 -> 452 ohm on another run); see piezo_relaxation")
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        lo, hi = np.percentile(x, [1, 99])
        ref = {"x0": float(np.min(x)), "R": float(max(hi - lo, 1e-12))}
        top = float(np.max(ctx.data.time_in_run())) / 20
        return [{**g, **ref} for g in prony_grid(ctx) if max(g["tau"]) <= top]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        u = (d.inputs[self.channel] - theta["x0"]) / theta["R"]
        cols = [u ** 2, u ** 3]
        for tau in theta["tau"]:
            for k in (1, 2, 3):
                ck = (id(d), "qlv", self.channel, k, tau, theta["x0"], theta["R"])
                if ck not in ctx.cache:
                    ctx.cache[ck] = highpass(u ** k, tau, d.dt, d.segment)
                cols.append(ctx.cache[ck])
        return np.column_stack(cols)

    def width(self, theta: dict) -> int:
        return 2 + 3 * count(theta, "tau")

    def describe(self, f: Fitted) -> dict:
        b = list(f.beta)
        taus = list(f.theta["tau"])
        return {"tau_s": taus, "elastic_u2_u3": b[:2],
                "relaxing_u_u2_u3": [b[2 + 3 * i:5 + 3 * i] for i in range(len(taus))],
                "u": f"(x - {f.theta['x0']:.4g}) / {f.theta['R']:.4g} (input units)",
                "unit": "output unit per unit of u^k"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
