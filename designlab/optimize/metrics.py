"""The members a family of sweep-row metrics can have, and the metrics that need a setting:
objectives and constraints are checked against them before any design runs (a name no row
ever has would run the whole sweep for nothing). A row is
:func:`designlab.optimize.evaluate.evaluate_design`'s: the CAD's metrics, the prediction's
sections flattened (``hysteresis_percent.overall``...) and the sensor's extras.

Names are dotted paths; ``*`` stands for one component that the protocol or design names (a
load location, a channel, a load group). The families listed in :data:`GRAMMAR` are checked
member by member (the hysteresis section and the electrical report have the same members
whatever the sensor); the other families of :data:`designlab.optimize.space.METRIC_FAMILIES`
by their prefix.
"""

from __future__ import annotations

import re
from typing import Any

_ELECTRICAL = tuple(f"electrical.{n}" for n in (
    *(f"resistance_ohm.{p}" for p in ("legs", "turns", "leads", "pads", "contacts", "total")),
    "resistance_at_rest_ohm",
    *(f"squares.{p}" for p in ("legs", "turns", "leads", "pads", "total")),
    "effective_resistivity_ohm_mm", "back_calculated_resistivity_ohm_mm",
    *(f"divider.{p}" for p in ("R_fixed_ohm", "supply_V", "rest_voltage_V", "dV_dR_V_per_ohm",
                               "V_per_unit_dR_R", "optimal_R_fixed_ohm", "gain_vs_optimum")),
    *(f"self_heating.{p}" for p in ("current_mA", "power_mW", "thermal_resistance_K_per_W",
                                    "temperature_rise_K", "tcr_per_K", "drift_dR_R",
                                    "F_n_equivalent_mN", "F_n_equivalent_per_K_mN",
                                    "F_x_equivalent_mN")),
    *(f"noise.{p}" for p in ("bandwidth_hz", "johnson_V_rms", "adc_bits", "adc_full_scale_V",
                             "adc_quantisation_V_rms", "channel_V_rms", "sum_or_diff_V_rms")),
    "resolution_mN.F_n", "resolution_mN.F_x", "sensitivity_V_per_N.sum_F_n",
    "sensitivity_V_per_N.diff_F_x"))

#: the members of a family that are numbers of a row (the family's other keys are text)
GRAMMAR: dict[str, tuple[str, ...]] = {
    "hysteresis_percent.": ("hysteresis_percent.overall", "hysteresis_percent.overall_noise_free",
                            "hysteresis_percent.by_location.*",
                            "hysteresis_percent.by_location_noise_free.*",
                            "hysteresis_percent.by_group.*",
                            "hysteresis_percent.by_group_noise_free.*"),
    "electrical.": _ELECTRICAL,
}
#: metrics a row has only with a sweep setting: {name: the [settings] key}
WITH_SETTING = {"K_f_target_error": "K_f_target_N_per_m"}


def _matches(name: str, pattern: str) -> bool:
    return re.fullmatch(re.escape(pattern).replace(r"\*", r"[^.]+"), name) is not None


def check_metric_names(settings: dict[str, Any] | None, names: dict[str, list[str]]) -> None:
    """Refuse an objective or constraint (``names``: {"objectives": [...], ...}) that no row
    has: a member its family (:data:`GRAMMAR`) never has, or a metric whose sweep setting is
    not given; one line naming the key, the name and the names allowed."""
    from designlab.errors import ParameterError
    from designlab.params import did_you_mean

    for where, given in names.items():
        for name in given:
            key = WITH_SETTING.get(name)
            if key is not None and key not in (settings or {}):
                raise ParameterError(f"{where}.{name}", name, f"a metric of a row: {name} is "
                                     f"computed only with [settings] {key} (a sensor with a "
                                     "stiffness matrix K_f)")
            family = next((f for f in GRAMMAR if name.startswith(f)), None)
            if family is None or any(_matches(name, p) for p in GRAMMAR[family]):
                continue
            members = GRAMMAR[family]
            raise ParameterError(
                f"{where}.{name}", name, f"a member of {family[:-1]} a row has: "
                + ", ".join(members) + " (* a location, channel or group name)"
                + did_you_mean(name, [p for p in members if "*" not in p]))
