"""The worn strap's initial strain and what it puts on the linear sensitivity (seed 000 Sec. V-E):
the wrap's path, the neo-Hookean stand-in, the gauge's operating point and the paper's slots on
one finger. Details: docs/models/strap_modules.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from designlab.errors import ParameterError

#: the one spread measure of the strap's fit (slot table here, strap_fit's size
#: table): coefficient of variation
SPREAD_DEFINITION = ("cv = population standard deviation / mean (ddof 0), in percent of the "
                     "mean")
#: nonlinear analysis is called for when the neo-Hookean stress at eps0 differs from the
#: linear one by more than this (relative)
NONLINEAR_THRESHOLD = 0.05


def spread_percent(values) -> float | None:
    """Coefficient of variation (:data:`SPREAD_DEFINITION`) of the values that are not None,
    percent; None when there are none."""
    v = np.array([x for x in values if x is not None], float)
    return float(100 * np.std(v) / abs(np.mean(v))) if len(v) else None


def wrap_path(part, perimeter: float) -> float:
    """Centreline path between the engaged slot centres on a finger of ``perimeter`` (mm,
    at the skin): the mid-plane perimeter (+ pi t) plus the lug spacing (tabs cross over)."""
    return perimeter + math.pi * part.thickness + part.lug_spacing


def initial_strain(part, perimeter: float, slot: int | None = None,
                   length: float | None = None) -> float:
    """Initial membrane strain of the worn strap (rigid finger): engaged slot ``slot``
    (1 = nearest the strap end) or a custom engaged ``length`` (mm)."""
    L = part.engaged_length(slot) if length is None else float(length)
    if not L > 0:
        raise ParameterError("wrap_length", length, "> 0 mm")
    return wrap_path(part, perimeter) / L - 1.0


def neo_hooke(eps0: float) -> dict[str, float]:
    """Incompressible neo-Hookean uniaxial response at nominal strain eps0 (stand-in for the
    printed TPU's unmeasured curve): stress and tangent relative to the linear law."""
    lam = 1.0 + eps0
    stress = (lam - lam ** -2) / 3.0                     # / E (E = 3 mu)
    tangent = (1.0 + 2.0 * lam ** -3) / 3.0              # / E
    lin = eps0 if eps0 else 1.0
    return {"stress_over_linear": stress / lin if eps0 else 1.0,
            "tangent_over_E": tangent,
            "nonlinear_needed": bool(abs(stress / lin - 1.0) > NONLINEAR_THRESHOLD) if eps0
            else False}


def operating_point(eps0: float, R0: float, gauge_factor: float, gauge_quadratic: float,
                    R_fixed: float) -> dict[str, float]:
    """Gauge resistance at eps0 and the divider's voltage per unit strain there relative to
    the unstrained gauge."""
    from designlab.fem.transducers import divider_slope

    R = R0 * (1.0 + gauge_factor * eps0 + gauge_quadratic * eps0 ** 2)
    d = R0 * (gauge_factor + 2 * gauge_quadratic * eps0) * float(divider_slope(R, R_fixed))
    d0 = R0 * gauge_factor * float(divider_slope(R0, R_fixed))
    return {"R_ohm": R, "electrical_factor": d / d0}


def prestrain_state(part, perimeter: float, material, R0: float, R_fixed: float, *,
                    slot: int | None = None, length: float | None = None) -> dict[str, Any]:
    """Initial strain, its checks and the factors it puts on the linear sensitivity."""
    eps0 = initial_strain(part, perimeter, slot, length)
    if material.max_elongation is not None and eps0 >= material.max_elongation:
        raise ParameterError("initial strain", round(eps0, 4),
                             f"< {material.max_elongation:g} ({material.name} elongation at "
                             "break, seed 000 Table I)")
    nh = neo_hooke(max(eps0, 0.0))
    op = operating_point(max(eps0, 0.0), R0, material.gauge_factor, material.gauge_quadratic,
                         R_fixed)
    mech = 1.0 / nh["tangent_over_E"]
    r = perimeter / (2 * math.pi)
    return {"slot": slot, "engaged_length_mm": part.engaged_length(slot) if length is None
            else float(length),
            "path_mm": wrap_path(part, perimeter), "finger_perimeter_mm": perimeter,
            "initial_strain": eps0, "slack": bool(eps0 < 0),
            "wrap_bending_strain_faces": part.thickness / 2 / r,
            "neo_hooke_stress_over_linear": nh["stress_over_linear"],
            "geometrically_nonlinear_needed": nh["nonlinear_needed"],
            "mechanical_factor": mech, "electrical_factor": op["electrical_factor"],
            "sensitivity_factor": mech * op["electrical_factor"],
            "R_rest_ohm": op["R_ohm"],
            "stress_stiffening": stress_stiffening(part, perimeter, material, max(eps0, 0.0),
                                                   mech),
            "notes": ["rigid finger: an upper bound on eps0 (the pulp compresses under the "
                      "tension: strap_fit.compliant_initial_strain estimates it, not applied)",
                      "mechanical_factor = E / tangent of an incompressible neo-Hookean law at "
                      "eps0: a stand-in for the printed TPU's unmeasured stress-strain curve",
                      "a slack strap (eps0 < 0) reads with the stress-free factors"]}


def stress_stiffening(part, perimeter: float, material, eps0: float,
                      mechanical_factor: float) -> dict[str, Any]:
    """An estimate of the geometric (stress) stiffness of the worn band, not applied to the
    sensitivity. The band (width b, thickness t) carries the membrane tension T = sigma0 b t
    (sigma0: nominal neo-Hookean stress at eps0, the stand-in law) on the mid-plane radius R.
    Ring mode: a radial displacement w of the band changes its line load on the finger by
    T / R^2 per unit length from the tension alone (q = T / R at fixed T) against E_t b t / R^2
    from stretching, a ratio sigma0 / E_t: the stiffness along the band rises by that fraction,
    and the strain per newton falls by 1 / (1 + sigma0 / E_t). Pad mode: a dent over the pad
    (length l, half-sine) has geometric stiffness T (pi / l)^2 against bending E_t t^3 / 12 x
    (pi / l)^4 per unit width, a ratio 12 sigma0 l^2 / (pi^2 E_t t^2)."""
    E = float(material.E)
    nh = neo_hooke(eps0)
    lam = 1.0 + eps0
    sigma0 = E * (lam - lam ** -2) / 3.0                      # MPa, nominal
    Et = E * nh["tangent_over_E"]
    b, t, l = float(part.strap_width), float(part.thickness), float(part.contact_length)
    R = perimeter / (2 * math.pi) + t / 2
    T = sigma0 * b * t                                          # N
    ring = sigma0 / Et
    pad = 12 * sigma0 * l ** 2 / (math.pi ** 2 * Et * t ** 2)
    return {"membrane_tension_N": T, "tension_per_width_N_per_mm": sigma0 * t,
            "line_load_on_finger_N_per_mm": T / R, "pressure_on_finger_kPa": 1e3 * T / R / b,
            "ring_geometric_stiffness_N_per_mm2": T / R ** 2,
            "ring_material_stiffness_N_per_mm2": Et * b * t / R ** 2,
            "ring_geometric_over_material": ring,
            "pad_geometric_over_bending": pad,
            "softening_factor_in_use": mechanical_factor,
            "factor_with_ring_stiffening_estimate": mechanical_factor / (1.0 + ring),
            "applied": False,
            "assumptions": ["uniaxial incompressible neo-Hookean stand-in (E of the trace "
                            "material) for sigma0 and E_t; rigid finger; friction-free wrap",
                            "ring mode: uniform radial motion of the whole band; pad mode: a "
                            "half-sine dent over the contact length with the band's own "
                            "bending stiffness; neither is the FEM's load path",
                            "an estimate of the size of the missing term, not a geometrically "
                            "nonlinear solve: the sensitivity uses softening_factor_in_use"]}


def slot_table(part, perimeter: float, material, R0: float, R_fixed: float,
               sens_sum_Fn: float, sens_diff_Fx: float) -> dict[str, Any]:
    """The paper's slots on one finger: eps0, sensitivities and their spread."""
    rows = []
    for k in range(1, part.slot_count + 1):
        s = prestrain_state(part, perimeter, material, R0, R_fixed, slot=k)
        ss = s["stress_stiffening"]
        stiff = ss["factor_with_ring_stiffening_estimate"] * s["electrical_factor"]
        rows.append({"slot": k, "initial_strain": s["initial_strain"],
                     "sensitivity_factor": s["sensitivity_factor"],
                     "sum_F_n_V_per_N": sens_sum_Fn * s["sensitivity_factor"],
                     "diff_F_x_V_per_N": sens_diff_Fx * s["sensitivity_factor"],
                     "geometrically_nonlinear_needed": s["geometrically_nonlinear_needed"],
                     "membrane_tension_N": ss["membrane_tension_N"],
                     "ring_geometric_over_material": ss["ring_geometric_over_material"],
                     "sum_F_n_V_per_N_with_ring_stiffening_estimate": sens_sum_Fn * stiff})
    return {"finger_perimeter_mm": perimeter, "slots": rows,
            "initial_strain_cv_percent": spread_percent(r["initial_strain"] for r in rows),
            "sum_sensitivity_cv_percent": spread_percent(r["sum_F_n_V_per_N"] for r in rows),
            "sum_sensitivity_cv_percent_with_ring_stiffening_estimate": spread_percent(
                r["sum_F_n_V_per_N_with_ring_stiffening_estimate"] for r in rows),
            "stress_stiffening_note": "estimate only (strap_fit.stress_stiffening: ring mode, "
                                     "neo-Hookean stand-in, rigid finger); the sensitivities "
                                     "above do not include it",
            "spread_definition": SPREAD_DEFINITION + " over the slots",
            "definition": "the stress-free FEM's sensitivity times each slot's prestrain "
                          "factor"}
