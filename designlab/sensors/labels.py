"""Readable names with units: metric keys (``hysteresis_percent.overall``) and part/settings
parameters (from their dataclass metadata), for plot axes, reports and ``designlab params``.

Nothing here names a sensor kind: metric keys are the generic keys of ``prediction.json`` and of
a sweep's table (``designlab.optimize.evaluate``); parameters are read from the field metadata
(:func:`designlab.params.rng`: unit, range, doc).
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

from designlab.params import fmt_bound

#: metric key -> (readable name, unit); "" unit: dimensionless
METRICS: dict[str, tuple[str, str]] = {
    "hysteresis_percent.overall": ("hysteresis (eq. 1, overall)", "% of span"),
    "hysteresis_percent": ("hysteresis (eq. 1)", "% of span"),
    "hysteresis_percent.by_group_noise_free.G1": (
        "friction hysteresis of the lateral loads G1 (eq. 1, no readout noise)", "% of span"),
    "hysteresis_percent.by_group_noise_free.G2": (
        "friction hysteresis of the radial loads G2 (eq. 1, no readout noise)", "% of span"),
    "hysteresis_percent.by_group.G1": ("hysteresis of the lateral loads G1 (eq. 1)", "% of span"),
    "hysteresis_percent.by_group.G2": ("hysteresis of the radial loads G2 (eq. 1)", "% of span"),
    "condition_number": ("condition number of the calibration matrix", ""),
    "geometric_condition_number": ("condition number of the ideal geometry", ""),
    "printed_volume_mm3": ("printed volume", "mm³"),
    "min_wall_mm": ("thinnest wall", "mm"),
    "printable": ("printable", "yes/no"),
    # one number over several channels: its definition goes with it
    "linearity_percent_span": ("non-linearity (largest loading-branch deviation from a line "
                               "over every channel, in % of that channel's span, noise-only "
                               "channels included)", "% of span"),
    "axial_share_through_sensors": ("share of an axial force reaching the sensors", ""),
    "K_f_target_error": ("largest relative error of k_x, k_y, k_z vs the target", ""),
    "k_x_N_per_m": ("stiffness k_x", "N/m"),
    "k_y_N_per_m": ("stiffness k_y", "N/m"),
    "k_z_N_per_m": ("stiffness k_z", "N/m"),
    "electrical.resolution_mN.F_n": ("resolution of the normal force F_n", "mN"),
    "electrical.resolution_mN.F_x": ("resolution of the shear force F_x", "mN"),
    "sensitivity.V_per_N.x": ("sensitivity along x", "V/N"),
    "sensitivity.V_per_N.y": ("sensitivity along y", "V/N"),
    "sensitivity.V_per_N.z": ("sensitivity along z", "V/N"),
    "stress.min_safety_factor": ("smallest safety factor against the material strength", ""),
    "stress.max_von_mises_MPa": ("largest von Mises stress", "MPa"),
    "elapsed_s": ("time to evaluate", "s"),
}

#: unit suffixes of metric keys that the table above does not list
_SUFFIX_UNITS = [("_percent", "%"), ("_mm3", "mm³"), ("_mm2", "mm²"), ("_mm", "mm"),
                 ("_N_per_m", "N/m"), ("_N_per_mm", "N/mm"), ("_MPa", "MPa"), ("_mN", "mN"),
                 ("_mV", "mV"), ("_V_per_N", "V/N"), ("_ohm", "ohm"), ("_N", "N"), ("_s", "s"),
                 ("_deg", "deg"), ("_g", "g")]


def metric_name_unit(key: str) -> tuple[str, str]:
    """(readable name, unit) of a metric key; unknown keys: the key with ``_``/``.`` as spaces
    and the unit read from a suffix such as ``_mm3`` (``""`` when none)."""
    if key in METRICS:
        return METRICS[key]
    if key.startswith("param."):
        return key[len("param."):], ""
    parts = key.split(".")
    unit = ""
    for i, p in enumerate(parts):
        for suf, u in _SUFFIX_UNITS:
            if p.endswith(suf) and len(p) > len(suf):
                unit, parts[i] = u, p[: -len(suf)]
                break
    return " ".join(" ".join(parts).split("_")), unit


def metric_label(key: str, direction: str | None = None) -> str:
    """Axis/table label of a metric: ``hysteresis (eq. 1, overall), % of span``, with
    ``(lower is better)`` for an objective to minimise."""
    name, unit = metric_name_unit(key)
    text = f"{name} ({unit})" if unit else name
    if direction in ("min", "max"):
        text += f", {'lower' if direction == 'min' else 'higher'} is better"
    return text


def param_label(cls: type | None, name: str) -> str:
    """Axis label of a part parameter: ``h (mm)`` plus its meaning when the metadata has one."""
    unit, doc = "", ""
    if cls is not None and dataclasses.is_dataclass(cls):
        for f in dataclasses.fields(cls):
            if f.name == name:
                unit, doc = f.metadata.get("unit", ""), f.metadata.get("doc", "")
    text = f"{name} ({unit})" if unit else name
    if doc and len(doc) <= 40:
        text = f"{text}: {doc}"
    return text


def fmt_value(v: Any) -> str:
    """A value as a table shows it: 4 significant digits for floats, tuples as lists."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return fmt_bound(float(f"{v:.4g}")) if abs(v) >= 1e-12 or v == 0 else "0"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt_value(x) for x in v) + "]"
    return "" if v is None else str(v)


_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def slug(text: str) -> str:
    """A file-name/field-name safe version of ``text``."""
    return _SAFE.sub("_", text).strip("_") or "x"
