"""Non-dominated (Pareto) sets of designs, all objectives minimised."""

from __future__ import annotations

import numpy as np


def non_dominated(F: np.ndarray) -> np.ndarray:
    """Boolean mask of the rows of ``F`` (n, k) that no other row dominates (<= in every
    objective and < in one). Rows with NaN are dominated."""
    F = np.asarray(F, float)
    n = len(F)
    ok = ~np.isnan(F).any(axis=1)
    mask = ok.copy()
    for i in np.flatnonzero(ok):
        others = F[ok]
        dominated = np.all(others <= F[i], axis=1) & np.any(others < F[i], axis=1)
        if dominated.any():
            mask[i] = False
    return mask if n else np.zeros(0, bool)
