"""Baseline drift in the time since a run started."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted


class Drift(Effect):
    """Baseline drift in the time ``t`` (s) since the run started: polynomial ``t/T``,
    ``(t/T)^2`` over the longest run ``T``, or an exponential settling ``exp(-t / tau_d)``
    (warm-up, conditioning; extrapolates flat)."""

    name = "drift"
    summary = "baseline drift in time since the run started"
    regressors_doc = "`t/T`, `(t/T)^2`, or `exp(-t/tau_d)` (time since the run began)"
    settings_doc = "order 1 or 2, or `tau_d` = 0.03/0.1/0.3/1 T (T: longest run)"
    applies_doc = "always"
    rank = 70

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls()]

    def grid(self, ctx: Context) -> list[dict]:
        T = float(max(np.max(ctx.data.time_in_run()), 1e-9))
        return ([{"variant": "polynomial", "order": 1, "duration_s": T},
                 {"variant": "polynomial", "order": 2, "duration_s": T}]
                + [{"variant": "settling", "tau_s": f * T} for f in (0.03, 0.1, 0.3, 1.0)])

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        if theta["variant"] == "settling":
            return np.exp(-ctx.data.time_in_run() / theta["tau_s"])
        s = ctx.data.time_in_run() / theta["duration_s"]
        return np.column_stack([s ** k for k in range(1, theta["order"] + 1)])

    def describe(self, f: Fitted) -> dict:
        th, b = f.theta, list(f.beta)
        if th["variant"] == "settling":
            return {"variant": "settling", "amplitude": b[0], "tau_s": th["tau_s"],
                    "form": "amplitude * exp(-t_run / tau)"}
        return {"variant": "polynomial", "order": th["order"], "coefficients": b,
                "duration_s": th["duration_s"], "form": "sum_k c_k (t_run / duration)^k"}

    def regressor(self, f: Fitted, ctx: Context):
        return ctx.data.time_in_run(), "time in run (s)"
