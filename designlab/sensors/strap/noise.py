"""The strap's noise and error budget (seed 000): divider, Johnson and ADC noise -> force error
per axis, in the shape of the flexure's (:mod:`designlab.sensors.flexure.force_error`) and the
fingertip's (:mod:`designlab.sensors.fingertip.calibration`) budgets. Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.params import rng, validate

AXES = ("F_n", "F_x")
MECHANISMS = ("johnson", "adc", "model_error")
PAPER = {"source": "seed 000 Sec. IV, Fig. 10: linear fit on task 1, RMSE per task as box plots "
                   "(no values in the text); the error is dominated by drift, relaxation and "
                   "amplitude loss (Sec. V), none of them electrical",
         "fit": "first-order polyfit: F_n from Ch1 + Ch2, F_x from Ch1 - Ch2"}


@dataclass(frozen=True)
class StrapForceTest:
    """The strap's calibration test with its electrical noise (defaults: the protocol's
    amplitudes, :class:`designlab.sensors.protocols.StrapLoadTest`)."""

    model_points: int = field(default=200, metadata=rng(
        3, 10 ** 6, doc="loads that fit the lines (the paper's task 1)"))
    test_points: int = field(default=800, metadata=rng(2, 10 ** 6, doc="held-out loads"))
    normal_N: float = field(default=5.0, metadata=rng(0, 100, lo_open=True, unit="N"))
    shear_N: float = field(default=0.5, metadata=rng(0, 100, unit="N"))
    noise_scale: float = field(default=1.0, metadata=rng(
        0, 1e6, doc="multiplies the Johnson and ADC noise (0: noise-free)"))
    seed: int = field(default=0, metadata=rng(0, 2 ** 32 - 1))

    def __post_init__(self):
        validate(self)


def _sensitivity_matrix(report: dict[str, Any]) -> np.ndarray:
    """(2 channels, 2 loads) V per N from a strap report's ``sensitivity.V_per_N``."""
    try:
        s = report["sensitivity"]["V_per_N"]
        M = np.array([[s[c]["F_n"], s[c]["F_x"]] for c in ("Ch1", "Ch2")], float)
    except (KeyError, TypeError) as exc:
        raise ParameterError("report", type(report).__name__,
                             "a strap prediction's report (sensitivity.V_per_N of Ch1, Ch2)"
                             ) from exc
    if not np.all(np.isfinite(M)):
        raise ParameterError("report.sensitivity.V_per_N", M.tolist(), "finite numbers")
    return M


def _noise(report: dict[str, Any]) -> tuple[float, float]:
    try:
        n = report["electrical"]["noise"]
        return float(n["johnson_V_rms"]), float(n["adc_quantisation_V_rms"])
    except (KeyError, TypeError) as exc:
        raise ParameterError("report", type(report).__name__,
                             "a strap prediction's report (electrical.noise)") from exc


def _stats(e: np.ndarray) -> dict[str, float]:
    return {"mean": float(e.mean()), "std": float(e.std(ddof=1)),
            "rms": float(np.sqrt(np.mean(e ** 2))), "max_abs": float(np.abs(e).max())}


def run_strap_force_test(report: dict[str, Any], test: StrapForceTest | None = None
                         ) -> dict[str, Any]:
    """Force error per axis (F_n, F_x) on held-out virtual loads (mean, std, rms, max |e|, N)
    with its exact split into Johnson noise, ADC noise and model error; the noise-only std
    predicted from the budget (resolution) beside it."""
    test = test or StrapForceTest()
    if not isinstance(test, StrapForceTest):
        raise ParameterError("test", test, "a StrapForceTest")
    M = _sensitivity_matrix(report)
    v_j, v_q = _noise(report)
    ss = np.random.SeedSequence(test.seed)
    r_f, r_j, r_q = (np.random.default_rng(s) for s in ss.spawn(3))
    n = test.model_points + test.test_points
    F = np.column_stack([r_f.uniform(0.0, test.normal_N, n),
                         r_f.uniform(-test.shear_N, test.shear_N, n)])
    Nj = r_j.standard_normal((n, 2)) * v_j * test.noise_scale
    Nq = r_q.standard_normal((n, 2)) * v_q * test.noise_scale
    V0 = F @ M.T
    T = np.array([[1.0, 1.0], [1.0, -1.0]])                   # (sum, diff) of (Ch1, Ch2)
    S0, Sj, Sq = V0 @ T.T, Nj @ T.T, Nq @ T.T
    S = S0 + Sj + Sq
    m = test.model_points
    out: dict[str, Any] = {"per_axis": {}, "split_std": {}, "split_variance_share": {},
                           "fit": {}}
    for i, a in enumerate(AXES):
        A = np.column_stack([S[:m, i], np.ones(m)])
        (g, b), *_ = np.linalg.lstsq(A, F[:m, i], rcond=None)
        sl = slice(m, None)
        err = F[sl, i] - (g * S[sl, i] + b)
        terms = {"model_error": F[sl, i] - g * S0[sl, i] - b, "johnson": -g * Sj[sl, i],
                 "adc": -g * Sq[sl, i]}
        assert np.allclose(err, sum(terms.values()), atol=1e-9 * max(1.0, np.abs(err).max()))
        out["per_axis"][a] = _stats(err)
        out["split_std"][a] = {k: float(t.std(ddof=1)) for k, t in terms.items()}
        var = err.var(ddof=1)
        out["split_variance_share"][a] = {k: float(t.var(ddof=1) / var) if var > 0 else 0.0
                                          for k, t in terms.items()}
        out["fit"][a] = {"N_per_V": float(g), "offset_N": float(b),
                         "channel": "Ch1 + Ch2" if a == "F_n" else "Ch1 - Ch2"}
        # noise only, from the budget: |g| sqrt(2) sigma_channel (the resolution)
        out["fit"][a]["noise_std_predicted_N"] = float(
            abs(g) * np.sqrt(2.0) * np.hypot(v_j, v_q) * test.noise_scale)
    el = report.get("electrical", {})
    out["budget"] = {
        "johnson_V_rms": v_j, "adc_quantisation_V_rms": v_q,
        "channel_V_rms": float(np.hypot(v_j, v_q)),
        "bandwidth_hz": (el.get("noise") or {}).get("bandwidth_hz"),
        "divider": {k: (el.get("divider") or {}).get(k)
                    for k in ("R_fixed_ohm", "supply_V", "V_per_unit_dR_R")},
        "sensitivity_V_per_N": {c: {"F_n": float(M[j, 0]), "F_x": float(M[j, 1])}
                                for j, c in enumerate(("Ch1", "Ch2"))},
        "sources": "Johnson: sqrt(4 k T (R || R_f) B), T 305 K, B 10 Hz (seed 000 Sec. III-D); "
                   "ADC: LSB/sqrt(12), 16 bit over 5 V (assumed: the Saga AUX noise is not "
                   "given); divider 2.2 kOhm on 5 V (seed 000 Fig. 3)",
        "not_modelled": "1/f noise of the composite, drift, relaxation, amplitude loss, "
                        "temperature (no data for PI-ETPU)",
        "loads": {"normal_N": test.normal_N, "shear_N": test.shear_N},
        "model_points": m, "test_points": test.test_points, "noise_scale": test.noise_scale,
        "seed": test.seed}
    out["paper"] = PAPER
    out["units"] = "N; error = applied - estimated"
    return out


def strap_force_budget(part=None, protocol=None, settings=None,
                       test: StrapForceTest | None = None) -> dict[str, Any]:
    """The designed strap's prediction (:func:`designlab.sensors.strap.model.run`: meshing and a
    viscoelastic history, about 1.5 min) through :func:`run_strap_force_test`, the loads at
    the protocol's amplitudes."""
    import dataclasses

    from designlab.sensors.protocols import StrapLoadTest
    from designlab.sensors.strap.model import run

    protocol = protocol or StrapLoadTest()
    pred = run(part, protocol, settings)
    test = test or StrapForceTest()
    test = dataclasses.replace(test, normal_N=protocol.normal_N, shear_N=protocol.shear_N)
    return run_strap_force_test(pred.report, test)
