"""What a sweep measures of one design: geometry (printed volume, printability, thinnest wall)
plus its virtual-test prediction; and the export of a chosen design.

Task settings (the sweep config's ``[settings]`` table)::

    model = { edge_length = 3.0 }       # the virtual test's model settings (see predict)
    K_f_target_N_per_m = 4000.0         # flexure: adds K_f_target_error (max relative error
                                        # of the three translational stiffnesses)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def geometry_metrics(part_name: str, part) -> dict[str, Any]:
    """Printed volume (mm^3), printable (all printed bodies pass), thinnest wall (mm)."""
    from designlab.geometry.printability import check_part

    reports = [r for r in check_part(part_name, part.build()) if r.printed]
    walls = [r.min_wall_mm for r in reports if np.isfinite(r.min_wall_mm)]
    return {"printed_volume_mm3": float(sum(r.volume_mm3 for r in reports)),
            "printable": bool(all(r.ok for r in reports)),
            "min_wall_mm": float(min(walls)) if walls else float("nan"),
            "printability_problems": [f"{r.body}: {p}" for r in reports for p in r.problems]}


def evaluate_design(task: dict[str, Any]) -> dict[str, Any]:
    """One design of a sweep -> flat-ish metrics dict (see module docstring)."""
    from designlab.predict.run import predict
    from designlab.geometry.parts import make_part

    from designlab.sensors.registry import resolve

    part_name, params = resolve(task["part"]), task["params"]   # a definition: loaded here too
    settings = dict(task.get("settings") or {})
    part = make_part(part_name, params)
    out = geometry_metrics(part_name, part)
    pred = predict(part_name, params, protocol=task.get("protocol") or None,
                   settings=settings.get("model"), fem_cache=task.get("fem_cache"))
    # sections a sensor may not report are left out (None); predict sets the others always
    sections = {"hysteresis_percent": pred.hysteresis, "condition_number": pred.condition_number,
                "geometric_condition_number": pred.geometric_condition_number,
                "sensitivity": pred.sensitivity,
                "linearity_percent_span": pred.linearity_percent_span,
                "timings_s": pred.timings_s, "warnings": list(pred.warnings),
                "mesh_convergence": pred.mesh_convergence, "fem_key": pred.fem_key,
                "electrical": pred.electrical}
    always = ("condition_number", "geometric_condition_number", "timings_s", "warnings",
              "mesh_convergence")
    out.update({k: v for k, v in sections.items() if k in always or v is not None})
    if pred.stress is not None:
        out["min_safety_factor"] = pred.min_safety_factor
    from designlab.sensors.registry import get_sensor

    out.update({k: pred.metrics[k] for k in get_sensor(part_name).row_metrics
                if k in pred.metrics})
    if pred.K_f is not None:
        K = pred.K_f
        out["K_f"] = K.tolist()
        lin = np.diag(K)[3:]
        out["k_x_N_per_m"], out["k_y_N_per_m"], out["k_z_N_per_m"] = map(float, lin)
        target = settings.get("K_f_target_N_per_m")
        if target is not None:
            out["K_f_target_error"] = float(np.max(np.abs(lin - target) / target))
    if pred.axial_share_through_sensors is not None:
        out["axial_share_through_sensors"] = pred.axial_share_through_sensors
    return out


def export_design(part_name: str, params: dict[str, Any], out: str | Path, *,
                  formats: str = "stl,3mf,step", settings: dict[str, Any] | None = None,
                  protocol: dict[str, Any] | None = None,
                  fem_cache: str | Path | None = None) -> list[Path]:
    """Export the chosen design for printing and write its full prediction report. The
    prediction runs first; files to print are written only for a design it predicted, and are
    removed again when its report cannot be written (a full disk): no print files without
    their prediction."""
    from designlab.predict.record import write_prediction
    from designlab.predict.run import predict
    from designlab.geometry.export import export_parts
    from designlab.geometry.parts import make_part

    from designlab.sensors.registry import resolve

    out = Path(out)
    part_name = resolve(part_name)
    part = make_part(part_name, params)
    pred = predict(part_name, params, protocol=protocol or None,
                   settings=(settings or {}).get("model"), fem_cache=fem_cache)
    res = export_parts({part_name: part}, out, formats=formats, png=True)
    try:
        return list(res.files) + write_prediction(pred, out / "prediction")
    except BaseException:
        for f in res.files:
            Path(f).unlink(missing_ok=True)
        raise
