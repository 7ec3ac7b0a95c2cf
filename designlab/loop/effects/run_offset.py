"""One offset per run."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import TARE_S, Context, Effect, Fitted, count


class RunOffset(Effect):
    """One offset per run (re-donning, preload), output units; the indicator of each training
    run is a regressor (no nuisance intercept). Runs not seen in training are tared on their
    first ``tare_s`` seconds of residual."""

    name = "run_offset"
    summary = "one offset per run (re-donning, preload)"
    regressors_doc = "one offset per run; unseen runs tared on their first 5 s of residual"
    applies_doc = ("not a candidate: with >= 2 training runs every fit has one intercept per "
                   "run, and the model ends with these offsets unless its last effect has them")
    intercept = False
    rank = 100

    @classmethod
    def applies(cls, train, output, base_inputs):
        if np.unique(train.segment).size >= 2:
            return ("per-run offsets are part of every fit with >= 2 training runs (one "
                    "intercept per run; a new run is tared on its first 5 s)")
        return "one training run: per-run offsets cannot be tested"

    def grid(self, ctx: Context) -> list[dict]:
        rows = ctx.cache.get("rows", np.ones(len(ctx.data), bool))
        paths = [ctx.data.segments[s]["path"] for s in np.unique(ctx.data.segment[rows])]
        return [{"runs": tuple(paths), "tare_s": TARE_S}]

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        paths = [d.segments[s]["path"] for s in d.segment]
        return np.column_stack([np.array([p == r for p in paths], float) for r in theta["runs"]])

    def extra(self, f: Fitted, ctx: Context, partial: np.ndarray) -> np.ndarray:
        """Offsets of runs not seen in training: the mean residual over each run's first
        ``tare_s`` seconds when the measured output is known (and ``tare_s`` > 0), else the mean
        trained offset."""
        d = ctx.data
        extra = np.zeros(len(d))
        tin = d.time_in_run()
        for s in np.unique(d.segment):
            if d.segments[s]["path"] in f.theta["runs"]:
                continue
            m = d.segment == s
            if ctx.measured is not None and f.theta["tare_s"] > 0:
                w = m & (tin <= f.theta["tare_s"])
                extra[m] = float(np.mean((ctx.measured - ctx.yhat - partial)[w]))
            else:
                extra[m] = float(np.mean(f.beta)) if f.beta else 0.0
        return extra

    def width(self, theta: dict) -> int:
        return count(theta, "runs")

    def describe(self, f: Fitted) -> dict:
        return {"offsets": dict(zip(f.theta["runs"], f.beta)), "tare_s": f.theta["tare_s"]}

    def regressor(self, f: Fitted, ctx: Context):
        return ctx.data.segment.astype(float), "run"
