"""The flexure's Monte Carlo model (``Sensor.uncertainty``): its uncertain inputs, the FEM stage
(the built flexure's stiffness, once per design) and one virtual build (seed 002's force test
with the build's hysteresis and pose noise, :func:`designlab.sensors.flexure.force_error.
run_force_test`)."""

from __future__ import annotations

from typing import Any

from designlab.sensors.noise import (FLEXURE_HYSTERESIS_RANGE_PCT, FLEXURE_TABLE_I,
                                     POSE_MAX_ERROR_XY_MM, POSE_NOISE_SIGMA_MM)
from designlab.sensors.uncertainty import Distribution, Input, MonteCarloModel

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
                                      "split_std.hysteresis", "split_std.model_error")
                for a in "xyz")


def fem_stage(part, settings: dict | None, protocol: dict | None, cache) -> dict[str, Any]:
    """The built flexure's stiffness (truth) and the designer's closed form."""
    from designlab.sensors.flexure.virtual import run
    from designlab.sensors.predict import model_settings, protocol_from

    pred = run(part, protocol_from("flexure", None, protocol), model_settings("flexure", settings))
    return {"K_true": pred.K_true, "K_design": pred.K_design}


def build(ctx: dict[str, Any], values: dict[str, Any], seed: int) -> dict[str, Any]:
    """One build: the force test with the build's hysteresis and pose noise."""
    from designlab.sensors.flexure.force_error import FlexureForceTest, run_force_test

    t = FlexureForceTest(hysteresis_percent=values["hysteresis_percent"],
                         pose_noise_mm=values["pose_noise_mm"], seed=seed)
    # an input left out of ``values`` keeps its default (the nominal wire)
    r = run_force_test(values.get("wire_modulus_scale", 1.0) * ctx["K_true"], ctx["K_design"], t)
    out = {}
    for a in ("x", "y", "z"):
        out[f"force_error_std.{a}"] = r["per_axis"][a]["std"]
        out[f"force_error_mean.{a}"] = r["per_axis"][a]["mean"]
        out[f"force_error_max_abs.{a}"] = r["per_axis"][a]["max_abs"]
        for m, s in r["split_std"][a].items():
            out[f"split_std.{m}.{a}"] = s
    return out


MONTE_CARLO = MonteCarloModel(
    INPUTS, METRICS, fem_stage, build,
    paper={"source": "seed 002 Table I: force error over 410 test points, N",
           **{f"force_error_std.{a}": FLEXURE_TABLE_I[a]["std"] for a in "xyz"},
           **{f"force_error_mean.{a}": FLEXURE_TABLE_I[a]["mean"] for a in "xyz"}})
