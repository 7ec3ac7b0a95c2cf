"""Electrical design of the seed 000 strap from its geometry: trace resistance, divider, self-
heating, noise and resolution. Details: docs/models/strap_modules.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from designlab.fem.transducers import (DIVIDER_OHM, StrainGauge, SUPPLY_V, divider_current, divider_slope,
                                       johnson_noise_vrms, optimal_divider_resistor,
                                       quantization_noise_vrms, resistivity_from,
                                       sheet_resistance)

#: seed 000 Sec. III-A: "The resistance measured between the contact pads of the strain gauges
#: is around 1.8 kOhm" (../shared/data/papers/fingertip_strap_tpu.json strap.gauge_resistance)
PAPER_GAUGE_OHM = 1800.0
#: seed 000 Sec. III-D: signals low-pass filtered at 10 Hz
BANDWIDTH_HZ = 10.0
#: fingertip skin temperature for the Johnson noise, K (about 32 C at room temperature;
#: the noise scales with sqrt(T): 10 K change it by 1.6 %)
SKIN_T_K = 305.0
#: thermal conductivity of TPU, W/(m K): 0.19-0.25 for polyurethane elastomers (polymer
#: handbooks); 0.2 used (not measured on NinjaFlex/PI-ETPU)
K_TPU = 0.2
#: thermal conductivity of skin/pulp tissue, W/(m K): 0.37 (F. A. Duck, Physical Properties of
#: Tissue, 1990, skin); perfusion (which lowers the rise) is neglected
K_TISSUE = 0.37
#: natural-convection coefficient of still air on a small body, W/(m^2 K): 10 (textbook range
#: 2-25, Incropera, Fundamentals of Heat and Mass Transfer, Table 1.1)
H_AIR = 10.0


def effective_resistivity(contact_ohm: float = 0.0) -> float:
    """rho_eff (ohm*mm) of printed PI-ETPU, back-calculated from the paper's 1.8 kOhm on its
    gauge geometry (the default ArchStrap) with ``contact_ohm`` per pad taken off."""
    from designlab.errors import ParameterError
    from designlab.geometry.strap import ArchStrap

    if not 0 <= contact_ohm < PAPER_GAUGE_OHM / 2:
        raise ParameterError("contact_ohm", contact_ohm,
                             f"0 <= value < {PAPER_GAUGE_OHM / 2:g} ohm (half the paper's "
                             "1.8 kOhm)")
    paper = ArchStrap()
    return resistivity_from(PAPER_GAUGE_OHM - 2 * contact_ohm,
                            paper.trace_squares()["total"], paper.trace_thickness)


def measured_resistivity(material) -> float | None:
    """The trace material's resistivity (ohm*mm) when it comes from a measured record
    (``material.measured`` lists ``resistivity``), else None (the library value is the
    filament's Table I bound, not the printed trace's: never used for the resistance)."""
    if material is None or "resistivity" not in getattr(material, "measured", ()):
        return None
    return float(material.resistivity)


def resistivity_in_use(contact_ohm: float = 0.0, material=None) -> tuple[float, str]:
    """(rho ohm*mm, source): the measured resistivity of ``material`` when it has one, else
    the back-calculated rho_eff (``"measured"`` / ``"back-calculated"``)."""
    rho = measured_resistivity(material)
    if rho is not None:
        return rho, "measured"
    return effective_resistivity(contact_ohm), "back-calculated"


def gauge_resistance(part, contact_ohm: float = 0.0, material=None) -> dict[str, float]:
    """Resistance of one meander of ``part`` (ohm) and its parts: legs, turns, leads, pads,
    contacts (2 x ``contact_ohm``), total; with the measured resistivity of ``material``
    when it has one (:func:`measured_resistivity`), else the back-calculated rho_eff."""
    rho, _ = resistivity_in_use(contact_ohm, material)
    rs = sheet_resistance(rho, part.trace_thickness)
    sq = part.trace_squares()
    out = {k: rs * v for k, v in sq.items() if k != "total"}
    out["contacts"] = 2 * contact_ohm
    out["total"] = rs * sq["total"] + 2 * contact_ohm
    return out


def gauge_footprint_mm2(part) -> float:
    """Area (mm^2) of the strap covered by one meander: legs + turns across the leg span."""
    span = (part.legs - 1) * (part.trace_width + part.trace_gap) + part.trace_width
    return (part.gauge_length + 2 * part.trace_width) * span


def self_heating(part, R: float, R_fixed: float, V_s: float) -> dict[str, float]:
    """Power and steady temperature rise of one gauge (W, K)."""
    I = float(divider_current(R, R_fixed, V_s))
    P = I * I * R
    A = gauge_footprint_mm2(part) * 1e-6                                      # m^2
    a = math.sqrt(A / math.pi)
    r_down = part.trace_cover * 1e-3 / (K_TPU * A) + 1.0 / (4 * K_TISSUE * a)   # K/W
    r_up = 1.0 / (H_AIR * A)
    r = 1.0 / (1.0 / r_down + 1.0 / r_up)
    return {"current_mA": 1e3 * I, "power_mW": 1e3 * P, "thermal_resistance_K_per_W": r,
            "temperature_rise_K": P * r}


def channel_noise(R: float, R_fixed: float = DIVIDER_OHM, adc_bits: int = 16,
                  adc_full_scale_V: float = SUPPLY_V, bandwidth_hz: float = BANDWIDTH_HZ
                  ) -> tuple[float, float]:
    """(Johnson noise of the divider's source resistance at skin temperature over the readout
    bandwidth, the ADC's quantisation noise), V rms, of one channel: a gauge of ``R`` ohm over
    ``R_fixed``. Their root sum of squares is the channel's noise."""
    r_src = R * R_fixed / (R + R_fixed)
    return (johnson_noise_vrms(r_src, bandwidth_hz, SKIN_T_K),
            quantization_noise_vrms(adc_full_scale_V, adc_bits))


def electrical_report(part, material, sens_sum_Fn: float, sens_diff_Fx: float, *,
                      contact_ohm: float = 0.0, R_fixed: float = DIVIDER_OHM,
                      V_s: float = SUPPLY_V, adc_bits: int = 16,
                      adc_full_scale_V: float = SUPPLY_V, bandwidth_hz: float = BANDWIDTH_HZ,
                      R_rest: float | None = None) -> dict[str, Any]:
    """The electrical design of ``part``: resistance, divider, self-heating, noise and the
    F_n / F_x resolution (mN) from the sum/difference sensitivities (V per N). ``R_rest``: the
    gauge resistance at the worn operating point (default: unstrained)."""
    Rg = gauge_resistance(part, contact_ohm, material)
    R0 = Rg["total"]
    R = R0 if R_rest is None else float(R_rest)
    slope = float(divider_slope(R, R_fixed, V_s))
    rf_opt = optimal_divider_resistor(R)
    gain = R * slope                                      # V per unit dR/R
    gain_opt = R * float(divider_slope(R, rf_opt, V_s))
    heat = self_heating(part, R, R_fixed, V_s)
    tcr = float(material.tcr)
    # both gauges: the same self-heating -> sum channel only
    dV_heat_sum = 2 * gain * tcr * heat["temperature_rise_K"]
    dV_per_K_sum = 2 * gain * tcr
    v_j, v_q = channel_noise(R, R_fixed, adc_bits, adc_full_scale_V, bandwidth_hz)
    v_ch = math.hypot(v_j, v_q)
    v_sd = math.sqrt(2.0) * v_ch                          # sum and difference of 2 channels
    rho, rho_source = resistivity_in_use(contact_ohm, material)
    rho_back = effective_resistivity(contact_ohm)

    def mN(v, s):
        return float(1e3 * v / abs(s)) if s else None

    return {
        "resistance_ohm": Rg,
        "resistance_at_rest_ohm": R,
        "squares": part.trace_squares(),
        "effective_resistivity_ohm_mm": rho,
        "resistivity_source": rho_source,
        "back_calculated_resistivity_ohm_mm": rho_back,
        "effective_resistivity_note": (
            f"rho = {rho:.4g} ohm*mm ({rho / 10:.4g} ohm*cm) MEASURED on the printed material "
            f"({_measured_source(material)}); it replaces the rho_eff back-calculated from seed "
            f"000's 1.8 kOhm ({rho_back:.3g} ohm*mm), which would give "
            f"{gauge_resistance(part, contact_ohm)['total']:.4g} ohm on this meander"
            if rho_source == "measured" else
            f"rho_eff = {rho:.3g} ohm*mm ({rho / 10:.3g} ohm*cm) back-calculated from seed 000's "
            "'around 1.8 kOhm' between the pads on its gauge geometry (the default ArchStrap, "
            "our estimate of the paper's meander), printed and annealed PI-ETPU along the "
            f"raster, contacts {'lumped in' if contact_ohm == 0 else f'{contact_ohm:g} ohm each'}"
            f"; Table I's '< 800 ohm*cm' ({material.resistivity:g} ohm*mm in the library) would "
            f"give {sheet_resistance(material.resistivity, part.trace_thickness) * part.trace_squares()['total'] / 1e6:.3g} MOhm"
            if material.resistivity else "rho_eff back-calculated from seed 000's 1.8 kOhm"),
        "divider": {"R_fixed_ohm": R_fixed, "supply_V": V_s,
                    "rest_voltage_V": float(V_s * R / (R + R_fixed)),
                    "dV_dR_V_per_ohm": slope, "V_per_unit_dR_R": gain,
                    "optimal_R_fixed_ohm": rf_opt,
                    "gain_vs_optimum": float(gain / gain_opt),
                    "source": "seed 000 Fig. 3: gauge + 2.2 kOhm on 5 V, voltage across the "
                              "gauge"},
        "self_heating": heat | {
            "tcr_per_K": tcr,
            "drift_dR_R": tcr * heat["temperature_rise_K"],
            "F_n_equivalent_mN": mN(dV_heat_sum, sens_sum_Fn),
            "F_n_equivalent_per_K_mN": mN(dV_per_K_sum, sens_sum_Fn),
            "F_x_equivalent_mN": 0.0,
            "note": "steady rise after switch-on (both gauges alike: in the sum, cancels in the "
                    "difference); F_n_equivalent_per_K: a 1 K change of skin/ambient "
                    "temperature read as normal force (seed 000 Sec. V-E)"},
        "noise": {"bandwidth_hz": bandwidth_hz, "johnson_V_rms": v_j,
                  "adc_bits": int(adc_bits), "adc_full_scale_V": adc_full_scale_V,
                  "adc_quantisation_V_rms": v_q, "channel_V_rms": v_ch,
                  "sum_or_diff_V_rms": v_sd,
                  "adc_note": "ADC: our assumption (16 bit over the 5 V supply); the paper's "
                              "TMSi Saga AUX-input noise is not given",
                  "not_modelled": "1/f (excess) noise of the carbon-black composite: no data "
                                  "for PI-ETPU"},
        "resolution_mN": {"F_n": mN(v_sd, sens_sum_Fn), "F_x": mN(v_sd, sens_diff_Fx),
                          "definition": "rms noise of the sum (difference) channel / its "
                                        "sensitivity"},
        "sensitivity_V_per_N": {"sum_F_n": sens_sum_Fn, "diff_F_x": sens_diff_Fx},
    }


def _measured_source(material) -> str:
    """The measured-records part of a material's source line (who measured what, when)."""
    src = str(getattr(material, "source", ""))
    i = src.find("measured: ")
    return src[i + len("measured: "):] if i >= 0 else "source not given"


def scale_sensitivity(sens: float, R0_old: float, R0_new: float, R_fixed: float) -> float:
    """Sensitivity (V per N) of the same strain response read through a gauge of rest
    resistance ``R0_new`` instead of ``R0_old`` (the divider gain R dV/dR changes only)."""
    g_old = R0_old * float(divider_slope(R0_old, R_fixed))
    g_new = R0_new * float(divider_slope(R0_new, R_fixed))
    return float(sens * g_new / g_old)


def trade_off(part, strain_per_N: dict[str, dict[str, float]], material, **kw) -> dict:
    """Resistance, sensitivity and resolution of ``part`` from gauge strains per newton
    (``{"Ch1": {"F_n": .., "F_x": ..}, "Ch2": ..}``) without a new FEM run: the sum/difference
    sensitivities through this geometry's divider gain."""
    R_fixed = kw.get("R_fixed", DIVIDER_OHM)
    V_s = kw.get("V_s", SUPPLY_V)
    R = gauge_resistance(part, kw.get("contact_ohm", 0.0), material)["total"]
    gain = R * float(divider_slope(R, R_fixed, V_s)) * float(material.gauge_factor)
    e = strain_per_N
    s_sum = gain * (e["Ch1"]["F_n"] + e["Ch2"]["F_n"])
    s_diff = gain * (e["Ch1"]["F_x"] - e["Ch2"]["F_x"])
    rep = electrical_report(part, material, s_sum, s_diff, **kw)
    return {"R_ohm": R, "sum_F_n_V_per_N": s_sum, "diff_F_x_V_per_N": s_diff,
            "resolution_F_n_mN": rep["resolution_mN"]["F_n"],
            "resolution_F_x_mN": rep["resolution_mN"]["F_x"],
            "power_mW": rep["self_heating"]["power_mW"],
            "temperature_rise_K": rep["self_heating"]["temperature_rise_K"],
            "F_n_equivalent_per_K_mN": rep["self_heating"]["F_n_equivalent_per_K_mN"]}


__all__ = ["PAPER_GAUGE_OHM", "effective_resistivity", "measured_resistivity",
           "resistivity_in_use", "gauge_resistance", "electrical_report", "self_heating",
           "trade_off", "scale_sensitivity"]


@dataclass(frozen=True)
class DividerGauge:
    """A channel's readout after the FEM stage of the strap: :class:`~designlab.fem.transducers.StrainGauge`'s
    own resistance and divider formulas (borrowed below) on the stored gauge factor, without
    the model the gauge was measured on."""

    gauge_factor: float
    gauge_quadratic: float
    R0: float
    R_fixed: float
    V_s: float
    tcr: float = 0.0
    T0: float = 20.0

    dR_R = StrainGauge.dR_R
    resistance = StrainGauge.resistance
    voltage = StrainGauge.voltage
