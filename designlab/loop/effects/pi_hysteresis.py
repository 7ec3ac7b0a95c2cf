"""Nonlinear rate-independent hysteresis: a generalised Prandtl-Ishlinskii operator."""

from __future__ import annotations

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted, play, varying_drives

N_OPERATORS = 8


class PrandtlIshlinskii(Effect):
    """Generalised Prandtl-Ishlinskii hysteresis: ``sign * sum_j p_j S_rj[gamma(x)]`` with
    8 stop operators ``S_r = x - play_r(x)`` of thresholds ``r_j`` log-spaced from 0.5 % to
    50 % of the input's range, an envelope ``gamma`` (identity or the square of the normalised
    input: a loop that widens with the input), and a fitted density ``p_j >= 0``
    (non-negative least squares; output units per input unit) with one sign: a consistent
    loop direction. Rate-independent: only the order of the input's turning points matters.
    Source: M. Al Janaideh, S. Rakheja, C.-Y. Su, Mechatronics 19 (2009)."""

    name = "pi_hysteresis"
    summary = "nonlinear rate-independent hysteresis (generalised Prandtl-Ishlinskii)"
    regressors_doc = ("8 stop operators `x - play_r(gamma(x))`, density `p_j >= 0` (NNLS) "
                      "and one sign")
    settings_doc = "envelope `gamma` = identity or square; sign +-1"
    applies_doc = "each varying drive input"
    per_input = True
    rank = 22

    @classmethod
    def applies(cls, train, output, base_inputs):
        return [cls(x) for x in varying_drives(train)]

    def grid(self, ctx: Context) -> list[dict]:
        x = ctx.data.inputs[self.channel]
        lo, hi = np.percentile(x, [1, 99])
        ref = {"x0": float(np.min(x)), "R": float(max(hi - lo, 1e-12))}
        return [{"envelope": e, "sign": s, **ref} for e in ("identity", "square")
                for s in (1.0, -1.0)]

    def envelope(self, ctx: Context, theta: dict) -> np.ndarray:
        x = ctx.data.inputs[self.channel]
        if theta["envelope"] == "identity":
            return x
        return theta["R"] * ((x - theta["x0"]) / theta["R"]) ** 2

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        ck = (id(d), "pi", self.channel, theta["envelope"], theta["x0"], theta["R"])
        if ck not in ctx.cache:
            widths = theta["R"] * np.geomspace(0.005, 0.5, N_OPERATORS)
            ctx.cache[ck] = play(self.envelope(ctx, theta), widths, d.segment)
        return theta["sign"] * ctx.cache[ck]

    def solve(self, X: np.ndarray, target: np.ndarray, k: int) -> np.ndarray:
        """Density ``p >= 0`` of the first ``k`` columns, nuisance free: NNLS on the
        nuisance-projected problem."""
        F, N = X[:, :k], X[:, k:]
        if N.shape[1]:
            Q, _ = np.linalg.qr(N)
            Fp, tp = F - Q @ (Q.T @ F), target - Q @ (Q.T @ target)
        else:
            Fp, tp = F, target
        from scipy.optimize import nnls

        p, _ = nnls(Fp, tp, maxiter=50 * k)
        alpha = np.linalg.lstsq(N, target - F @ p, rcond=None)[0] if N.shape[1] else []
        return np.r_[p, alpha]

    def width(self, theta: dict) -> int:
        return N_OPERATORS

    def describe(self, f: Fitted) -> dict:
        widths = f.theta["R"] * np.geomspace(0.005, 0.5, N_OPERATORS)
        return {"envelope": f.theta["envelope"], "sign": f.theta["sign"],
                "thresholds": widths.tolist(), "density": list(f.beta),
                "unit": "thresholds in input units (of gamma(x)); density in output unit per "
                        "input unit"}

    def regressor(self, f: Fitted, ctx: Context):
        return self.input_axis(ctx)
