"""Baseline drift in the time since a run started."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, whole


#: the settling variant's time constants over the longest run: a geometric grid fine enough
#: that a settling between two of them is not left half explained
SETTLING_TAUS = tuple(float(v) for v in np.geomspace(0.02, 2.0, 21))


class Drift(Effect):
    """Baseline drift in the time ``t`` (s) since the run started: polynomial ``t/T``,
    ``(t/T)^2`` over the longest run ``T``, or an exponential settling ``exp(-t / tau_d)``
    (warm-up, conditioning; extrapolates flat)."""

    name = "drift"
    summary = "baseline drift in time since the run started"
    regressors_doc = "`t/T`, `(t/T)^2`, or `exp(-t/tau_d)` (time since the run began)"
    settings_doc = ("order 1 or 2, or `tau_d` from 0.02 to 2 T in 21 geometric steps "
                    "(T: longest run)")
    applies_doc = "always"
    rank = 70

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls()]

    def grid(self, ctx: Context) -> list[dict]:
        T = float(max(np.max(ctx.data.time_in_run()), 1e-9))
        return ([{"variant": "polynomial", "order": 1, "duration_s": T},
                 {"variant": "polynomial", "order": 2, "duration_s": T}]
                + [{"variant": "settling", "tau_s": f * T} for f in SETTLING_TAUS])

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        if theta["variant"] == "settling":
            return np.exp(-ctx.data.time_in_run() / theta["tau_s"])
        s = ctx.data.time_in_run() / theta["duration_s"]
        return np.column_stack([s ** k for k in range(1, theta["order"] + 1)])

    def width(self, theta: dict) -> int:
        if theta["variant"] == "settling":
            return 1
        return whole(theta, "order", 1)

    def describe(self, f: Fitted) -> dict:
        th, b = f.theta, list(f.beta)
        if th["variant"] == "settling":
            return {"variant": "settling", "amplitude": b[0], "tau_s": th["tau_s"],
                    "form": "amplitude * exp(-t_run / tau)"}
        return {"variant": "polynomial", "order": th["order"], "coefficients": b,
                "duration_s": th["duration_s"], "form": "sum_k c_k (t_run / duration)^k"}

    def regressor(self, f: Fitted, ctx: Context):
        return ctx.data.time_in_run(), "time in run (s)"
