"""The fingertip's Monte Carlo model (``Sensor.uncertainty``): its uncertain inputs, the FEM
stage (the condensed structure, once per design) and one virtual build (the paper's calibration
with the build's scattered inputs and readout noise,
:func:`designlab.sensors.fingertip.calibration.calibration_test`)."""

from __future__ import annotations

import dataclasses
from typing import Any

from designlab.sensors.noise import FSS015_SENSITIVITY_MV_PER_V_PER_N
from designlab.sensors.distributions import Distribution, Input, MonteCarloModel
from designlab.sensors.fingertip.model import DEFAULT_BOLT_PRELOAD_N, FRICTION_CHROMIUM_ON_STEEL

_ABS_SCATTER = ("assumed: printed ABS modulus between the datasheet's across-layer and "
                "in-plane ratio (ABSplus-P430 yield strength 26 MPa ZX / 31 MPa XZ = 0.84) and "
                "the datasheet value (scale 1.0); no modulus scatter is published for ABSplus")

INPUTS = (
    Input("printed_modulus_scale",
          Distribution("uniform", lo=0.84, hi=1.0, source=_ABS_SCATTER),
          "scale of the printed material's moduli (exact on the condensed FEM)"),
    Input("fss015_sensitivity",
          Distribution("uniform", lo=FSS015_SENSITIVITY_MV_PER_V_PER_N[0],
                       hi=FSS015_SENSITIVITY_MV_PER_V_PER_N[2],
                       source="FSS015 min/max 2.2-2.6 mV/V/N (seed 001 Table I), each of the "
                              "three units drawn independently"),
          "FSS015 sensitivity, mV/V/N, one draw per sensor", per_build=3),
    Input("bolt_preload_N",
          Distribution("uniform", lo=0.7 * DEFAULT_BOLT_PRELOAD_N,
                       hi=1.3 * DEFAULT_BOLT_PRELOAD_N,
                       source="20 N from T = K F d at 0.01 N m (fingertip_model); torque "
                              "tightening scatters the preload about +-30 % through the nut "
                              "factor (Shigley, Mechanical Engineering Design, Sec. 8-8)"),
          "bolt tension after tightening, N (sets the Hertz contact stiffnesses)"),
    Input("friction_coefficient",
          Distribution("uniform", lo=0.21, hi=FRICTION_CHROMIUM_ON_STEEL,
                       source="chromium on steel, kinetic 0.21 to static 0.25 (Wypych 2018, "
                              "Table 11.1; fingertip_model)"),
          "ball/sensor Coulomb coefficient (decides the stick margin)"),
)

METRICS = ("force_error_std.x", "force_error_std.y", "force_error_std.z",
           "force_error_max_abs.x", "force_error_max_abs.y", "force_error_max_abs.z",
           "relative_rms_error.x", "relative_rms_error.y", "relative_rms_error.z",
           "Pz_error_over_xy", "worst_axis_is_z", "condition_number", "stick_margin",
           "share_through_sensors.z")


def fem_stage(part, settings: dict | None, protocol: dict | None, cache) -> dict[str, Any]:
    """The condensed structure of the design (cached) with the settings and protocol."""
    from designlab.sensors.fingertip.calibration import structure
    from designlab.sensors.fingertip.model import FingertipModelSettings, design_protocol
    from designlab.sensors.protocols import HangingWeightTest, protocol_for
    from designlab.sensors.sensor import settings_from

    sett = settings_from(FingertipModelSettings, settings)
    proto = (protocol_for(HangingWeightTest, None, protocol, part, design_protocol) if protocol
             else HangingWeightTest.preset("optimized"))
    fem = structure(part, sett, proto, cache)
    return {"part": part, "fem": fem, "settings": sett, "protocol": proto}


def build(ctx: dict[str, Any], values: dict[str, Any], seed: int) -> dict[str, Any]:
    """One build: the paper's calibration with the build's inputs and readout noise."""
    from designlab.sensors.fingertip.calibration import calibration_test, nominal_build

    b = dataclasses.replace(nominal_build(), printed_modulus_scale=values["printed_modulus_scale"],
                            sensitivity_mV_per_V_per_N=tuple(values["fss015_sensitivity"]),
                            bolt_preload_N=values["bolt_preload_N"],
                            friction_coefficient=values["friction_coefficient"], seed=seed)
    r = calibration_test(ctx["part"], ctx["fem"], ctx["settings"], ctx["protocol"], b)
    out = {}
    for a in ("x", "y", "z"):
        out[f"force_error_std.{a}"] = r["per_axis"][a]["std"]
        out[f"force_error_max_abs.{a}"] = r["per_axis"][a]["max_abs"]
        out[f"relative_rms_error.{a}"] = r["relative_rms_error"][a]
    out["Pz_error_over_xy"] = r["Pz_error_over_xy"]
    out["worst_axis_is_z"] = float(r["worst_axis"] == "z")
    out["condition_number"] = r["condition_number"]
    out["stick_margin"] = r["stick_margin"]
    out["share_through_sensors.z"] = r["share_through_sensors"]["z"]
    return out


MONTE_CARLO = MonteCarloModel(
    INPUTS, METRICS, fem_stage, build,
    paper={"worst_axis": "z (seed 001 Fig. 9: P_z estimated worst)"})
