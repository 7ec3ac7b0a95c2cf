"""Error metrics of seed 000: RMSE, normalised cross-correlation at zero lag, Wilcoxon test."""

from __future__ import annotations

import numpy as np


def rmse(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Root-mean-square error, in the signals' units."""
    d = np.asarray(measured, float) - np.asarray(predicted, float)
    return float(np.sqrt(np.mean(d * d)))


def ncc(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Normalised cross-correlation at zero lag (Pearson correlation of the two signals), -1..1."""
    a = np.asarray(measured, float) - np.mean(measured)
    b = np.asarray(predicted, float) - np.mean(predicted)
    den = np.sqrt(np.sum(a * a) * np.sum(b * b))
    return float(np.sum(a * b) / den) if den > 0 else 0.0


def wilcoxon(errors_a: np.ndarray, errors_b: np.ndarray) -> dict:
    """Wilcoxon signed-rank test of paired errors (e.g. per-task RMSE of two models)."""
    from scipy import stats                # imported here: 0.4 s that predict does not need

    res = stats.wilcoxon(np.asarray(errors_a, float), np.asarray(errors_b, float))
    return {"statistic": float(res.statistic), "p_value": float(res.pvalue)}
