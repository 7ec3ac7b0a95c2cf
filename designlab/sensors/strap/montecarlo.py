"""The strap's Monte Carlo model (``Sensor.uncertainty``): its uncertain inputs, the FEM stage
(the gauges' strain per newton on a few finger-support stiffnesses, once per design) and one
virtual build (the readout of seed 000 through the build's divider, gauge factor and
resistance, then the paper's sum/difference calibration with its electrical noise,
:func:`designlab.sensors.strap.noise.run_strap_force_test`). Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from designlab.sensors.distributions import Distribution, Input, MonteCarloModel
from designlab.sensors.strap.model import elastic_materials

#: the finger-support stiffnesses (N/mm^3) solved once per design; a build's k / s must lie
#: inside (the default distributions stay inside: 0.007 / 1.15 ... 0.05 / 0.85)
TISSUE_GRID = (0.005, 0.01, 0.02, 0.04, 0.08)

INPUTS = (
    Input("tpu_modulus_scale",
          Distribution("uniform", lo=0.85, hi=1.15,
                       source="assumed: +-15 % part-to-part modulus of the printed TPUs "
                              "(seed 000 Table I gives one value, 12 MPa, for NinjaFlex and "
                              "PI-ETPU; no scatter is published for either); both bodies "
                              "scale together (exact on the FEM stage)"),
          "scale of both printed TPUs' moduli (band and traces together)"),
    Input("tissue_stiffness",
          Distribution("lognormal", mean=0.02, std=0.008, lo=0.007, hi=0.05,
                       source="assumed: the strap model's 0.02 N/mm^3 (pulp ~2 N/mm under "
                              "~1 cm^2, StrapModelSettings) with a 40 % subject-to-subject "
                              "spread, bounded to 0.35-2.5x; no survey of fingertip pulp "
                              "stiffness is cited in the repository"),
          "finger support under the strap (Winkler springs), N/mm^3"),
    Input("gauge_factor_scale",
          Distribution("uniform", lo=0.8, hi=1.2,
                       source="assumed: +-20 % on the gauge factor (a stand-in itself: 3.8 of "
                              "the stretch-rig elastomer, fem/materials.py; seed 000 gives "
                              "none for PI-ETPU)"),
          "scale of the traces' piezoresistive response (GF and its quadratic term)"),
    Input("resistivity_scale",
          Distribution("lognormal", mean=1.0, std=0.2, lo=0.5, hi=2.0,
                       source="assumed: 20 % print-to-print scatter of the effective "
                              "resistivity of printed PI-ETPU around the value back-calculated "
                              "from seed 000's 1.8 kOhm (strap_electrical)"),
          "scale of the traces' effective resistivity (rho_eff)"),
    Input("trace_width_scale",
          Distribution("uniform", lo=0.9375, hi=1.0625,
                       source="assumed: +-0.05 mm extrusion-width scatter of a 0.8 mm FDM "
                              "trace (0.4 mm nozzle)"),
          "printed trace width over the designed one (resistance only)"),
    Input("finger_perimeter_scale",
          Distribution("uniform", lo=0.95, hi=1.05,
                       source="assumed: +-5 % perimeter under the strap (where along the "
                              "distal phalanx it sits); acts only with a slot or wrap_length "
                              "(the wrap's initial strain, strap_fit)"),
          "finger perimeter at the strap over the model's 2 pi finger_radius"),
)

METRICS = ("sensitivity.sum_F_n", "sensitivity.diff_F_x", "resistance_ohm", "initial_strain",
           "resolution_mN.F_n", "resolution_mN.F_x", "force_error_std.F_n",
           "force_error_std.F_x", "cross_talk.F_x_in_sum_per_N_percent",
           "cross_talk.F_n_in_diff_per_N_percent", "wrap_stress_MPa")


def fem_stage(part, settings: dict | None, protocol: dict | None, cache) -> dict[str, Any]:
    """The elastic strain per newton (channel x case) at every :data:`TISSUE_GRID` stiffness
    (one cached FEM each) with the settings and protocol."""
    from designlab.sensors.protocols import StrapLoadTest, protocol_for
    from designlab.sensors.sensor import settings_from
    from designlab.sensors.strap.model import GAUGE_REGIONS, StrapModelSettings, run

    sett = settings_from(StrapModelSettings, settings)
    if getattr(sett, "finger_model", "winkler") != "winkler":
        from designlab.errors import ParameterError

        raise ParameterError("finger_model", sett.finger_model,
                             "'winkler' with --samples (the Monte Carlo scatters the Winkler "
                             "support's tissue_stiffness; the solid pulp has no scatter model)")
    proto = protocol_for(StrapLoadTest, None, protocol)      # the strap has no design_protocol
    mats = elastic_materials(part)
    units = []
    for k in TISSUE_GRID:
        s = dataclasses.replace(sett, tissue_stiffness=k, mesh_convergence=False, slot=0,
                                wrap_length=0.0)
        r = run(part, proto, s, materials=mats, cache=cache).report["strain_per_N"]
        units.append([[r[c]["F_n"], r[c]["F_x"]] for c in ("Ch1", "Ch2")])
    return {"part": part, "settings": sett, "protocol": proto,
            "unit": np.array(units, float), "trace_material": mats[GAUGE_REGIONS[0]],
            "band_material": mats["strap"]}


def unit_at(ctx: dict[str, Any], tissue_stiffness: float) -> np.ndarray:
    """(channel, case) strain per newton at a support stiffness inside the grid (PCHIP in
    log k); outside -> ValueError (the build is recorded as failed)."""
    from scipy.interpolate import PchipInterpolator

    lo, hi = TISSUE_GRID[0], TISSUE_GRID[-1]
    if not lo <= tissue_stiffness <= hi:
        raise ValueError(f"tissue_stiffness / tpu_modulus_scale = {tissue_stiffness:.4g} "
                         f"N/mm^3 outside the FEM grid [{lo:g}, {hi:g}]")
    x = np.log(np.asarray(TISSUE_GRID))
    U = ctx["unit"].reshape(len(TISSUE_GRID), -1)
    return PchipInterpolator(x, U, axis=0)(math.log(tissue_stiffness)).reshape(2, 2)


def build(ctx: dict[str, Any], values: dict[str, Any], seed: int) -> dict[str, Any]:
    """One build: its strain per newton, resistance, operating point and divider readout over
    the protocol (sensitivities as the virtual test fits them), its electrical budget and the
    paper's calibration with readout noise from ``seed``."""
    import designlab.sensors.strap.electrical as el
    import designlab.sensors.strap.prestrain as ps
    from designlab.sensors.strap.electrical import DividerGauge
    from designlab.sensors.strap.model import CHANNELS, _fit_transfer
    from designlab.sensors.strap.noise import StrapForceTest, run_strap_force_test

    part, sett, proto = ctx["part"], ctx["settings"], ctx["protocol"]
    s_E = float(values.get("tpu_modulus_scale", 1.0))
    unit = unit_at(ctx, float(values.get("tissue_stiffness", 0.02)) / s_E) / s_E
    # resistance: the rho_eff scale, and the printed width over the designed one on the
    # meander's lines (legs, turns, leads: squares = length / width); the 2 x 3 mm pads are
    # not printed at the trace width and keep their squares
    Rg = el.gauge_resistance(part, sett.contact_ohm, ctx["trace_material"])
    lines = sum(v for k, v in Rg.items() if k not in ("pads", "contacts", "total"))
    R0 = ((lines / float(values.get("trace_width_scale", 1.0)) + Rg.get("pads", 0.0))
          * float(values.get("resistivity_scale", 1.0)) + Rg["contacts"])
    g = float(values.get("gauge_factor_scale", 1.0))
    mat = ctx["trace_material"]
    mat = dataclasses.replace(mat, gauge_factor=mat.gauge_factor * g,
                              gauge_quadratic=mat.gauge_quadratic * g)
    eps0, mech = 0.0, 1.0
    if sett.prestrained:
        per = 2 * math.pi * sett.finger_radius * float(values.get("finger_perimeter_scale", 1.0))
        pre = ps.prestrain_state(part, per, mat, R0, sett.divider_ohm,
                                 slot=sett.slot or None, length=sett.wrap_length or None)
        if pre["initial_strain"] > 0:
            eps0, mech = pre["initial_strain"], pre["mechanical_factor"]
    gauge = DividerGauge(mat.gauge_factor, mat.gauge_quadratic, R0, sett.divider_ohm, sett.supply_V)
    _, fn, fx = proto.time_history()
    F = np.column_stack([fn, fx])
    strain = F @ (unit * mech).T
    dV = np.column_stack([gauge.voltage(eps0 + strain[:, i]) - gauge.voltage(eps0)
                          for i in range(len(CHANNELS))])
    M = _fit_transfer(F, dV)
    sd = np.column_stack([dV[:, 0] + dV[:, 1], dV[:, 0] - dV[:, 1]])
    M_sd = _fit_transfer(F, sd)
    rep = el.electrical_report(part, mat, float(M_sd[0, 0]), float(M_sd[1, 1]),
                               contact_ohm=sett.contact_ohm, R_fixed=sett.divider_ohm,
                               V_s=sett.supply_V, adc_bits=sett.adc_bits,
                               adc_full_scale_V=sett.supply_V, bandwidth_hz=sett.bandwidth_hz,
                               R_rest=float(gauge.resistance(eps0)))
    report = {"sensitivity": {"V_per_N": {c: {"F_n": float(M[i, 0]), "F_x": float(M[i, 1])}
                                          for i, c in enumerate(CHANNELS)}},
              "electrical": rep}
    test = run_strap_force_test(report, StrapForceTest(normal_N=float(proto.normal_N),
                                                       shear_N=float(proto.shear_N),
                                                       seed=int(seed) % 2 ** 32))
    # the wrap's membrane stress in the band (strap.wrap_stress: neo-Hookean stand-in, the
    # build's instantaneous modulus); 0 without a slot or wrap_length
    band = ctx["band_material"]
    wrap = float(band.E * s_E * eps0 * ps.neo_hooke(eps0)["stress_over_linear"])
    return {"wrap_stress_MPa": wrap, "sensitivity.sum_F_n": float(M_sd[0, 0]), "sensitivity.diff_F_x": float(M_sd[1, 1]),
            "resistance_ohm": float(R0), "initial_strain": float(eps0),
            "resolution_mN.F_n": rep["resolution_mN"]["F_n"],
            "resolution_mN.F_x": rep["resolution_mN"]["F_x"],
            "force_error_std.F_n": test["per_axis"]["F_n"]["std"],
            "force_error_std.F_x": test["per_axis"]["F_x"]["std"],
            "cross_talk.F_x_in_sum_per_N_percent": float(100 * abs(M_sd[0, 1])
                                                         / abs(M_sd[0, 0])),
            "cross_talk.F_n_in_diff_per_N_percent": float(100 * abs(M_sd[1, 0])
                                                          / abs(M_sd[1, 1]))}


MONTE_CARLO = MonteCarloModel(
    INPUTS, METRICS, fem_stage, build,
    paper={"source": "seed 000: 'around 1.8 kOhm' per gauge between the pads; "
                     "no sensitivity or force error is given as a number (Fig. 10: box plots)",
           "resistance_ohm": 1800.0})
