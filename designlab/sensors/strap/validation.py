"""The strap beside seed 000 (``designlab validate strap``): the paper's strap on the default
finger through the virtual test, and the goal rows its report gives against the paper's
numbers (the gauges' signs under F_n and F_x, the gauge resistance, the divider, the
temperature drift, hysteresis). No measured strap run is in the repository: the comparison is
with the paper's numbers and statements.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from designlab.sensors.sensor import Goal
from designlab.sensors.strap.electrical import PAPER_GAUGE_OHM

#: the paper's divider resistor, ohm (seed 000 Fig. 3)
PAPER_DIVIDER_OHM = 2200.0
#: the gauge resistance counts as the paper's within this share
RESISTANCE_TOLERANCE = 0.10
#: the paper's divider counts as well chosen when it keeps this share of the optimum gain
DIVIDER_GAIN_GOAL = 0.95

#: the report's sections the comparison reads (``validation.json``'s details)
DETAILS = ("premise", "electrical", "hysteresis_percent", "cross_talk_percent", "slots",
           "sensitivity")


def quantities(report: dict[str, Any]) -> dict[str, Any]:
    """The numbers the goal rows read, by name, from a strap report."""
    el = report["electrical"]
    pre = report["premise"]
    heat = el["self_heating"]
    r = el["resistance_at_rest_ohm"]
    slots = report.get("slots") or {}
    return {
        "normal": pre["normal_same_sign"], "shear": pre["shear_opposite_sign"], "yes": True,
        "none": 0.0,
        "signs_n": pre["signs"]["F_n"], "signs_x": pre["signs"]["F_x"],
        "r_kohm": r / 1e3, "r_paper": PAPER_GAUGE_OHM / 1e3,
        "r_met": bool(abs(r / PAPER_GAUGE_OHM - 1) <= RESISTANCE_TOLERANCE),
        "rho": el["effective_resistivity_ohm_mm"], "rho_source": el["resistivity_source"],
        "gain": el["divider"]["gain_vs_optimum"],
        "gain_met": bool(el["divider"]["gain_vs_optimum"] >= DIVIDER_GAIN_GOAL),
        "r_opt": el["divider"]["optimal_R_fixed_ohm"] / 1e3,
        "heat_x": heat["F_x_equivalent_mN"], "heat_n_per_K": heat["F_n_equivalent_per_K_mN"],
        "heat_met": bool(heat["F_x_equivalent_mN"] == 0 and heat["F_n_equivalent_mN"] > 0),
        "hyst": report["hysteresis_percent"]["overall"],
        "hyst_met": bool(report["hysteresis_percent"]["overall"] > 0),
        "cross": report["cross_talk_percent"]["F_x_in_sum_per_N_percent"],
        "cross_diff": report["cross_talk_percent"]["F_n_in_diff_per_N_percent"],
        "cv": slots.get("sum_sensitivity_cv_percent"), "strain_cv":
            slots.get("initial_strain_cv_percent", float("nan")),
    }


#: the strap's goals: name (unit), the keys of :func:`quantities` for the value and the
#: paper's number (None: the paper prints none), the target, the key saying whether it is met
#: (None: shown for reference) and the sentence (``str.format`` on the quantities)
GOAL_ROWS = (
    ("Ch1 and Ch2 answer F_n with the same sign (-)", "normal", "yes",
     "same sign (Sec. II: the sum reads F_n)", "normal",
     "Both gauges stretch under a normal load on the pad: signs {signs_n}."),
    ("Ch1 and Ch2 answer F_x with opposite signs (-)", "shear", "yes",
     "opposite signs (Sec. II: the difference reads F_x)", "shear",
     "A shear load along the strap stretches one gauge and relaxes the other: signs "
     "{signs_x}."),
    ("gauge resistance at rest (kOhm)", "r_kohm", "r_paper",
     f"within {100 * RESISTANCE_TOLERANCE:g} % of the paper's 'around 1.8 kOhm'", "r_met",
     "The printed resistivity ({rho:.3g} ohm mm, {rho_source}) comes from this number on the "
     "default meander, so the row checks the meander's squares only."),
    ("gain of the paper's 2.2 kOhm divider over the optimum (-)", "gain", None,
     f">= {DIVIDER_GAIN_GOAL:g} of the optimum gain", "gain_met",
     "The optimum fixed resistor equals the gauge's {r_opt:.3g} kOhm and the gain is flat "
     "near it."),
    ("self-heating drift read as F_x (mN)", "heat_x", "none",
     "0: drift in the normal channel only (Sec. V-E)", "heat_met",
     "Both gauges warm alike, so the drift cancels in the difference and reads "
     "{heat_n_per_K:.3g} mN of F_n per kelvin in the sum."),
    ("staircase hysteresis, eq. 1 (%)", "hyst", None,
     "> 0: hysteresis is among the effects the paper names", "hyst_met",
     "The printed TPUs' relaxation (a Prony stand-in) through the load history; the paper "
     "prints no number."),
    ("F_x read in the sum channel, per N (%)", "cross", None, "none: the paper fits F_n on the "
     "sum alone", None,
     "The pad load's lever about the gauges couples the channels; F_n in the difference is "
     "{cross_diff:.3g} % per N."),
    ("sum sensitivity spread over the paper's three slots, cv (%)", "cv", None,
     "none: the paper names the spread, no number", None,
     "The slots' initial strains (cv {strain_cv:.3g} %) change the gauges' operating point on "
     "one finger."),
)


def goal_rows(report: dict[str, Any]) -> list[Goal]:
    """The goals (:data:`GOAL_ROWS`) of a strap report."""
    q = quantities(report)
    return [Goal(name, q[value], None if paper is None else q[paper], target,
                 None if met is None else q[met], why.format(**q))
            for name, value, paper, target, met, why in GOAL_ROWS]


def validate(details: dict[str, Any], out: str | Path | None = None,
             progress: Callable[[str], None] | None = None) -> list[Goal]:
    """``designlab validate strap``: the paper's strap on the default finger
    (:func:`designlab.sensors.strap.model.run` at its defaults) and its goal rows; ``details``
    gets the report's sections the rows read (:data:`DETAILS`). No figure (``out`` unused)."""
    from designlab.fem.cache import FEMCache
    from designlab.sensors.strap.model import run

    report = run(progress=progress, cache=FEMCache()).report
    details.update({k: report[k] for k in DETAILS if k in report})
    return goal_rows(report)
