"""Cheap evaluators for sweep tests (importable by worker processes)."""

import time


def quadratic(task):
    """Analytic 'prediction': a bowl with its minimum at h=2, r=8; fails when h == 4."""
    p = task["params"]
    if p["h"] == 4.0:
        raise ValueError("h=4 is a deliberately failing design")
    return {"condition_number": 1.0 + (p["h"] - 2.0) ** 2 + (p["r"] - 8.0) ** 2,
            "hysteresis_percent": {"overall": 0.5 + 0.1 * p["h"]},
            "printed_volume_mm3": 100.0 * p["r"], "printable": True,
            "calibration_matrix": [[1.0, 0.0], [0.0, 1.0]]}


def slow_quadratic(task):
    time.sleep(0.3)
    return quadratic(task)
