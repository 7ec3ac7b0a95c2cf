"""Noise and error sources of the three sensors, each with the value and the source it comes from.
Details: docs/models/sensors_shared.md.
"""

from __future__ import annotations

import math

import numpy as np

# ---------------------------------------------------------------------------- seed 002 (flexure)

#: Seed 002 Sec. V-A: "The average absolute error in the dome pose estimate was around 20 um"
#: (265 random poses visited twice, LIPMM as ground truth). Max |error| < 100 um in x, y and
#: < 300 um in z.
POSE_MEAN_ABS_ERROR_MM = 0.020
POSE_MAX_ERROR_XY_MM = 0.100
POSE_MAX_ERROR_Z_MM = 0.300


def sigma_from_mean_abs(mean_abs: float) -> float:
    """Standard deviation of a zero-mean normal whose mean absolute value is ``mean_abs``
    (E|x| = sigma sqrt(2/pi))."""
    return float(mean_abs) * math.sqrt(math.pi / 2.0)


#: the pose noise as a normal standard deviation per translation: 20 um mean |error| -> 25.1 um
POSE_NOISE_SIGMA_MM = sigma_from_mean_abs(POSE_MEAN_ABS_ERROR_MM)
#: Seed 002 Sec. V-B-1: "a maximum error of 2-5% of the full range of force/torque magnitudes
#: compared to the median value of the force/torque reading at each angle" (hysteresis loops of
#: the LIPMM cycling each axis between its extremes). The default is the middle of that range.
FLEXURE_HYSTERESIS_RANGE_PCT = (2.0, 5.0)
FLEXURE_HYSTERESIS_PCT = 0.5 * sum(FLEXURE_HYSTERESIS_RANGE_PCT)
#: Seed 002 Sec. V-B-3 and Table I: 502 (pose, wrench) points, 92 fit K_c (least squares), 410
#: test it; force error mean / std per axis (N)
FLEXURE_TABLE_I = {"x": {"mean": 0.07473, "std": 0.30461},
                   "y": {"mean": -0.06030, "std": 0.29745},
                   "z": {"mean": -0.07051, "std": 0.33911}}
FLEXURE_MODEL_POINTS = 92
FLEXURE_TEST_POINTS = 410

# --------------------------------------------------------------------------- seed 001 (fingertip)

#: Seed 001 Table I (Honeywell FSS015WNSX): sensitivity 2.2 / 2.4 / 2.6 mV/V/N (min / typ / max).
#: Read as a uniform unit-to-unit spread over [min, max] (a datasheet min/max is a bound, not a
#: standard deviation).
FSS015_SENSITIVITY_MV_PER_V_PER_N = (2.2, 2.4, 2.6)


def iwan_loop_amplitude(x_full: float, n_elements: int) -> float:
    """Half the largest up/down gap (the largest deviation from the median branch) of a full
    loop 0 -> +x_full -> -x_full -> +x_full of an Iwan model with ``n_elements`` unit-stiffness
    Jenkins elements whose slip displacements are spread uniformly over (0, x_full]. The model is
    linear in the element stiffness, so ``k = target / iwan_loop_amplitude(...)``."""
    d = x_full * np.arange(1, n_elements + 1) / n_elements
    z = np.zeros(n_elements)
    grid = np.linspace(x_full, -x_full, 401)

    def path(xs, z):
        out, x0 = [], xs[0]
        for x in xs:
            z = np.clip(z + (x - x0), -d, d)
            x0 = x
            out.append(z.sum())
        return np.array(out), z

    _, z = path(np.linspace(0.0, x_full, 101), z)
    down, z = path(grid, z)
    up, _ = path(grid[::-1], z)
    return float(np.max(np.abs(down - up[::-1])) / 2.0)


class IwanHysteresis:
    """Rate-independent hysteresis of one axis: ``n`` Jenkins elements (a spring of stiffness
    ``k`` in series with a Coulomb slider) in parallel, slip displacements uniform over
    (0, x_full] (Iwan 1966, the standard model of micro-slip in bolted and bonded joints: the
    Visiflex's PLA housings and epoxy interfaces, seed 002 Sec. V-B-1). ``k`` is set so that the
    full loop +-x_full deviates at most ``amplitude`` from its median branch, the paper's
    definition of its 2-5 %. The output is the extra force on top of the flexure's linear one."""

    def __init__(self, x_full: float, amplitude: float, n_elements: int = 40):
        self.d = x_full * np.arange(1, n_elements + 1) / n_elements
        self.k = amplitude / iwan_loop_amplitude(x_full, n_elements) if x_full > 0 else 0.0
        self.z = np.zeros(n_elements)
        self.x = 0.0

    def move(self, x: float) -> float:
        """Move straight to ``x`` (from the last position) and return the hysteretic force."""
        self.z = np.clip(self.z + (x - self.x), -self.d, self.d)
        self.x = x
        return float(self.k * self.z.sum())
