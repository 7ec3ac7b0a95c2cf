"""The noise floor of an output, estimated from the data: the error no model can go below.

The measurement noise is taken from the high-frequency part of the output: the output is
differenced within each run, the same difference of the inputs is taken out of it by least
squares (what the inputs drive from one sample to the next, however fast they move), and the
robust scale of what is left over ``sqrt(C(2k, k))`` is the standard deviation of white noise
(a smooth signal leaves little in a difference; the median absolute deviation ignores the
kinks of ramps and steps). No effect and no peer enters the estimate. The whiteness of a
residual (its lag-1 autocorrelation) is reported beside it.
"""

from __future__ import annotations

from math import comb

import numpy as np

#: the difference order of the estimate (orders 1-3 are reported beside it)
ORDER = 2
#: 1 / Phi^-1(3/4): the median absolute deviation of a normal variable over its sigma
MAD_TO_SIGMA = 1.482602218505602

#: the floor of a noiseless record, relative to the output's RMS (numerical resolution)
RESOLUTION = 1e-9

METHOD = ("robust (median absolute deviation) scale of the order-{k} difference of the output "
          "within each run, less its least-squares fit on the same difference of the inputs, "
          "over sqrt(C({k2}, {k})): the standard deviation of the white part of the output, "
          "from every sample of the data")


def run_differences(r: np.ndarray, segment: np.ndarray, k: int) -> np.ndarray:
    """The ``k``-th differences of ``r`` within each run, concatenated."""
    parts = []
    for s in np.unique(segment):
        x = r[segment == s]
        if x.size > k:
            parts.append(np.diff(x, n=k))
    return np.concatenate(parts) if parts else np.zeros(0)


def difference_sigma(y: np.ndarray, segment: np.ndarray, k: int = ORDER,
                     inputs: np.ndarray | None = None) -> float:
    """White-noise standard deviation from the robust scale of the ``k``-th difference of
    ``y``, less its least-squares fit on the ``k``-th difference of ``inputs`` (columns)."""
    segment = np.asarray(segment)
    d = run_differences(np.asarray(y, float), segment, k)
    if d.size < 3:
        return float("nan")
    if inputs is not None and inputs.size:
        D = np.column_stack([run_differences(c, segment, k) for c in np.asarray(inputs, float).T])
        D = D[:, np.any(D != 0, axis=0)]
        if D.shape[1] and D.shape[0] > 2 * D.shape[1]:
            d = d - D @ np.linalg.lstsq(D, d, rcond=None)[0]
    mad = float(np.median(np.abs(d - np.median(d))))
    return MAD_TO_SIGMA * mad / np.sqrt(comb(2 * k, k))


def lag1_autocorrelation(r: np.ndarray, segment: np.ndarray) -> float:
    """Lag-1 autocorrelation of ``r`` within runs (0 for white noise, near 1 for structure)."""
    a, b = [], []
    for s in np.unique(segment):
        x = r[segment == s]
        x = x - x.mean()
        a.append(x[1:])
        b.append(x[:-1])
    a, b = np.concatenate(a), np.concatenate(b)
    den = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return float(np.sum(a * b) / den) if den > 0 else 0.0


def noise_floor(y: np.ndarray, inputs: np.ndarray, segment: np.ndarray) -> dict:
    """loop.json's ``noise_floor`` of one output: the estimate (``sigma``, output unit), its
    method, the other orders' estimates as a check, and the samples it used. ``inputs``: one
    column per input."""
    by_order = {str(k): float(difference_sigma(y, segment, k, inputs)) for k in (1, 2, 3)}
    # a noiseless record: the floor is the numbers' own resolution, not zero
    resolution = RESOLUTION * float(np.sqrt(np.mean(np.square(y)))) if np.size(y) else 0.0
    return {"sigma": max(by_order[str(ORDER)], resolution), "method": METHOD.format(k=ORDER, k2=2 * ORDER),
            "order": ORDER, "by_order": by_order, "samples": int(np.asarray(y).size)}
