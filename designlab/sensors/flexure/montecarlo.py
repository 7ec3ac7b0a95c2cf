"""The flexure's Monte Carlo model (``Sensor.uncertainty``): its uncertain inputs, the FEM stage
(the built flexure's stiffness, once per design) and one virtual build (seed 002's force test
with the build's hysteresis and pose noise, :func:`designlab.sensors.flexure.force_error.
run_force_test`). Details: docs/models/flexure_modules.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from designlab.sensors.noise import (FLEXURE_HYSTERESIS_RANGE_PCT, FLEXURE_TABLE_I,
                                     POSE_MAX_ERROR_XY_MM, POSE_NOISE_SIGMA_MM)
from designlab.sensors.distributions import Distribution, Input, MonteCarloModel
from designlab.sensors.flexure.spring import TWIST

#: catalogue wire diameter tolerance, +- mm (source: the wire_diameter_offset_mm input)
WIRE_DIAMETER_TOLERANCE_MM = 0.015

INPUTS = (
    Input("hysteresis_percent",
          Distribution("uniform", lo=FLEXURE_HYSTERESIS_RANGE_PCT[0],
                       hi=FLEXURE_HYSTERESIS_RANGE_PCT[1],
                       source="seed 002 Sec. V-B-1: max error 2-5 % of the full range"),
          "hysteresis of the built flexure, % of range (Iwan model)"),
    Input("pose_noise_mm",
          Distribution("uniform", lo=POSE_NOISE_SIGMA_MM, hi=POSE_MAX_ERROR_XY_MM / 3.1,
                       source="seed 002 Sec. V-A: 20 um mean |error| (std 25.1 um) to max "
                              "|error| < 100 um over 530 estimates (std <= 100/3.1 = 32 um)"),
          "camera pose noise, std per translation, mm"),
    Input("wire_diameter_offset_mm",
          Distribution("uniform", lo=-WIRE_DIAMETER_TOLERANCE_MM, hi=WIRE_DIAMETER_TOLERANCE_MM,
                       source="catalogue spring wire diameter tolerance +-0.015 mm (a spring "
                              "maker's standard tolerance for its wire, e.g. springs3d.com/en/"
                              "tolerancias: 'Wire diameter +-0.0006 in / +-0.015 mm'; the wire "
                              "standards EN 10270-3 / ASTM A313 set classes of this order); "
                              "uniform over the band: only the bounds are known (GUM, JCGM "
                              "100:2008 Sec. 4.3.7)"),
          "deviation of the built spring's wire diameter from the nominal, mm (the built 6x6 "
          "and the wire stress follow it; the designer's closed form keeps the nominal wire)"),
    Input("wire_modulus_scale",
          Distribution("fixed", value=1.0,
                       source="part-to-part scatter of the spring wire's E and G, off by "
                              "default (no scatter is published for the Visiflex's spring); "
                              "Shigley Table 10-5 lists music wire E 196.5-203.4 GPa by "
                              "diameter (+-1.7 %): e.g. { dist = \"uniform\", lo = 0.983, "
                              "hi = 1.017 }"),
          "scale of the built spring's E and G (the stiffness scales exactly; the designer's "
          "closed form keeps the nominal wire)"),
)

METRICS = tuple(f"{k}.{a}" for k in ("force_error_std", "force_error_mean",
                                      "force_error_max_abs", "split_std.pose_noise",
                                      "split_std.hysteresis", "split_std.model_error",
                                      "closed_form_error_std")
                for a in "xyz") + tuple(f"K_f_diag.{a}" for a in TWIST) + ("min_safety_factor",)

#: relative step of the wire diameter at which the FEM stage evaluates the stiffness's slope
DIAMETER_STEP = 0.01


def stiffness_at_diameter(ctx: dict[str, Any], d: float) -> np.ndarray:
    """The built flexure's 6x6 (designlab units) with a wire of diameter ``d`` (mm), from the
    FEM stage's stiffness at ``d0`` and at ``d_lo < d_hi`` around it (``d0 (1 +-
    DIAMETER_STEP)``): per entry the power law ``K0 (d / d0)^p`` with ``p`` from the two (where
    the three share a sign and are not ~0), else the line through the two."""
    K0, Kl, Kh = ctx["K_true"], ctx["K_d_lo"], ctx["K_d_hi"]
    d0, dl, dh = ctx["d0_mm"], ctx["d_lo_mm"], ctx["d_hi_mm"]
    if d == d0:
        return K0.copy()
    scale = np.abs(K0).max()
    power = (np.sign(Kh) == np.sign(K0)) & (np.sign(Kl) == np.sign(K0)) & \
        (np.abs(K0) > 1e-9 * scale)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(power, np.log(np.abs(Kh) / np.abs(Kl)) / math.log(dh / dl), 0.0)
    lin = K0 + (Kh - Kl) / (dh - dl) * (d - d0)
    K = np.where(power, K0 * (d / d0) ** p, lin)
    return (K + K.T) / 2


def fem_stage(part, settings: dict | None, protocol: dict | None, cache) -> dict[str, Any]:
    """The built flexure's stiffness (truth) at the nominal wire and at ``d0 (1 +-
    DIAMETER_STEP)``, the designer's closed form, the wire's nominal section forces under the
    protocol's load cases."""
    import dataclasses

    from designlab.errors import ParameterError
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.stress import case_sections
    from designlab.sensors.flexure.model import FlexureModelSettings, run, spring_as_built
    from designlab.sensors.protocols import FlexureWrenchTest, protocol_for
    from designlab.sensors.sensor import settings_from

    proto = protocol_for(FlexureWrenchTest, None, protocol)
    sett = settings_from(FlexureModelSettings, settings)
    pred = run(part, proto, sett, wire_stress=False)
    d0 = 2 * part.wire_radius
    slope = sett if sett.truth != "fem" else dataclasses.replace(sett, truth="chain")
    K_at = {0.0: pred.K_true if slope is sett else run(part, proto, slope,
                                                        wire_stress=False).K_true}
    for s in (1.0, -1.0):
        try:       # a design at a limit of its ranges: the slope from the side that exists
            K_at[s] = run(dataclasses.replace(part, wire_radius=d0 * (1 + s * DIAMETER_STEP) / 2),
                          proto, slope, wire_stress=False).K_true
        except ParameterError:
            pass
    lo, hi = min(K_at), max(K_at)
    cs = ChainSettings(seat=sett.seat, seat_material=getattr(part, "disc_material", "PLA"))
    spring = spring_as_built(part)
    sections = case_sections(spring, proto, cs, chain=sett.truth != "timoshenko")
    if lo == hi:
        raise ParameterError("wire_radius", part.wire_radius,
                             f"a design whose wire can change by {100 * DIAMETER_STEP:g} %")
    rel = dict(K_at)
    if slope is not sett:       # a "fem" truth: the chain's relative change carries the slope
        K0 = K_at[0.0]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = {k: pred.K_true * np.where(K0 != 0, v / K0, 1.0) for k, v in K_at.items()}
    return {"K_true": pred.K_true, "K_design": pred.K_design, "K_d_lo": rel[lo],
            "K_d_hi": rel[hi], "d0_mm": d0, "d_lo_mm": d0 * (1 + lo * DIAMETER_STEP),
            "d_hi_mm": d0 * (1 + hi * DIAMETER_STEP), "spring": spring,
            "material": part.material, "sections": sections}


def closed_form_error(K_true: np.ndarray, K_design: np.ndarray, test) -> dict[str, float]:
    """Std per force axis (N) of the noise-free error of the designer's closed form on the
    force test's wrenches: ``W - K_design K_true^-1 W`` (no calibration: what a user who
    trusts the nominal closed form sees)."""
    rs = np.random.default_rng(np.random.SeedSequence(test.seed).spawn(1)[0])
    n = test.model_points + test.test_points
    W = rs.uniform(-1.0, 1.0, (n, 6)) * np.r_[[test.max_moment_Nmm] * 3, [test.max_force_N] * 3]
    E = W - W @ np.linalg.solve(K_true, K_design.T)
    return {a: float(E[:, 3 + i].std(ddof=1)) for i, a in enumerate("xyz")}


def build(ctx: dict[str, Any], values: dict[str, Any], seed: int) -> dict[str, Any]:
    """One build: the built wire's stiffness and stress, the force test with the build's
    hysteresis and pose noise."""
    import dataclasses

    from designlab.errors import ParameterError
    from designlab.sensors.flexure.force_error import FlexureForceTest, run_force_test
    from designlab.sensors.flexure.spring import SI_SCALE
    from designlab.sensors.flexure.stress import stress_report

    t = FlexureForceTest(hysteresis_percent=values["hysteresis_percent"],
                         pose_noise_mm=values["pose_noise_mm"], seed=seed)
    # an input left out of ``values`` keeps its default centre (the nominal wire)
    dd = float(values.get("wire_diameter_offset_mm", 0.0))
    K = ctx["K_true"]
    if dd != 0.0:
        d0, D = ctx["d0_mm"], ctx["spring"].mean_diameter
        if not -d0 < dd < D - d0:
            raise ParameterError("wire_diameter_offset_mm", dd,
                                 f"between {-d0:g} and {D - d0:g} mm (a wire of diameter "
                                 f"{d0:g} + offset, > 0 and below the mean coil diameter "
                                 f"{D:g} mm)")
        K = stiffness_at_diameter(ctx, d0 + dd)
    K = values.get("wire_modulus_scale", 1.0) * K
    r = run_force_test(K, ctx["K_design"], t)
    out = {}
    for a in ("x", "y", "z"):
        out[f"force_error_std.{a}"] = r["per_axis"][a]["std"]
        out[f"force_error_mean.{a}"] = r["per_axis"][a]["mean"]
        out[f"force_error_max_abs.{a}"] = r["per_axis"][a]["max_abs"]
        for m, s in r["split_std"][a].items():
            out[f"split_std.{m}.{a}"] = s
    for a, s in closed_form_error(K, ctx["K_design"], t).items():
        out[f"closed_form_error_std.{a}"] = s
    for i, a in enumerate(TWIST):
        out[f"K_f_diag.{a}"] = float(K[i, i] * SI_SCALE[i, i])
    if "sections" in ctx:       # a stage without the wire's sections: no stress metric
        spring = dataclasses.replace(ctx["spring"], wire_radius=(ctx["d0_mm"] + dd) / 2)
        out["min_safety_factor"] = stress_report(ctx["sections"], spring,
                                                 ctx["material"])["min_safety_factor"]
    return out


MONTE_CARLO = MonteCarloModel(
    INPUTS, METRICS, fem_stage, build,
    paper={"source": "seed 002 Table I: force error over 410 test points, N",
           **{f"force_error_std.{a}": FLEXURE_TABLE_I[a]["std"] for a in "xyz"},
           **{f"force_error_mean.{a}": FLEXURE_TABLE_I[a]["mean"] for a in "xyz"}})
