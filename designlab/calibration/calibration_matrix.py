"""Calibration matrix, its condition number and the ideal geometric matrix (seed 001 eqs. 4-9).

P = A S: applied force P (n, 3) in the sensor frame from readings S (n, 3) (one column per force
sensor). Least squares over all load sets gives A; ``condition_number`` is the 2-norm condition
number (ratio of extreme singular values), as the paper computes it (34.92 for A_opt).
"""

from __future__ import annotations

import numpy as np

from designlab.errors import ParameterError


def sensor_directions(azimuths_deg=(270.0, 30.0, 150.0), elevation_deg: float = 45.0) -> np.ndarray:
    """(3, k) unit force directions of sensors at the given azimuths, tilted ``elevation_deg``
    from the horizontal plane (the paper's sensor axes are 45 deg from the vertical).

    Seed 001 eqs. (4)-(6) write F_r = (0, -cos45, sin45), F_g = (cos45 cos30, cos45 sin30, sin45),
    F_b = (-cos45 cos30, cos45 sin30, sin45): the horizontal part points along the azimuth
    (r: 270 deg -> (0, -1)), so the columns are (cos el cos az, cos el sin az, sin el).
    """
    az = np.radians(np.asarray(azimuths_deg, float))
    el = np.radians(elevation_deg)
    return np.vstack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                      np.full_like(az, np.sin(el))])


def geometric_matrix(k=(1.0, 1.0, 1.0), azimuths_deg=(270.0, 30.0, 150.0),
                     elevation_deg: float = 45.0) -> np.ndarray:
    """Seed 001 eq. (8): A = [d_r d_g d_b] diag(k_r, k_g, k_b)."""
    return sensor_directions(azimuths_deg, elevation_deg) @ np.diag(np.asarray(k, float))


def condition_number(A: np.ndarray) -> float:
    """2-norm condition number sigma_max / sigma_min (inf when singular)."""
    s = np.linalg.svd(np.asarray(A, float), compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def fit_calibration_matrix(S: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, dict]:
    """Least-squares A with P ~ S A^T (rows are load sets), seed 001 eq. (7).

    Returns A (3, k) and a report: rms and max residual (N), per-axis R^2, condition number.
    """
    S, P = np.asarray(S, float), np.asarray(P, float)
    if S.ndim != 2 or P.ndim != 2 or len(S) != len(P):
        raise ParameterError("S/P", (S.shape, P.shape), "2-D arrays with the same number of rows")
    if len(S) < S.shape[1]:
        raise ParameterError("load sets", len(S), f">= {S.shape[1]} (one per sensor channel)")
    At, *_ = np.linalg.lstsq(S, P, rcond=None)
    A = At.T
    resid = P - S @ At
    ss_tot = ((P - P.mean(0)) ** 2).sum(0)
    r2 = np.where(ss_tot > 0, 1 - (resid ** 2).sum(0) / np.where(ss_tot > 0, ss_tot, 1), np.nan)
    return A, {"rms_residual_N": float(np.sqrt((resid ** 2).mean())),
               "max_residual_N": float(np.abs(resid).max()),
               "r2_per_axis": r2.tolist(), "condition_number": condition_number(A)}


def transfer_matrix(P_applied: np.ndarray, P_estimated: np.ndarray) -> np.ndarray:
    """3x3 M with P_estimated ~ P_applied M^T (least squares): identity for a perfect sensor."""
    Mt, *_ = np.linalg.lstsq(np.asarray(P_applied, float), np.asarray(P_estimated, float),
                             rcond=None)
    return Mt.T


def cross_talk_percent(P_applied: np.ndarray, P_estimated: np.ndarray) -> np.ndarray:
    """Per applied axis j: the largest |M_ij| (i != j) as % of |M_jj| (M = transfer matrix)."""
    M = np.abs(transfer_matrix(P_applied, P_estimated))
    off = M - np.diag(np.diag(M))
    with np.errstate(divide="ignore", invalid="ignore"):  # an axis not seen at all: inf (nan if 0/0)
        return 100.0 * off.max(axis=0) / np.diag(M)


def linearity_percent(load: np.ndarray, reading: np.ndarray) -> float:
    """Max deviation of readings from their least-squares line, % of the reading span
    (the FSS015 data-sheet definition of linearity, % span)."""
    x, y = np.asarray(load, float), np.asarray(reading, float)
    c = np.polyfit(x, y, 1)
    span = np.ptp(y)
    return float(100.0 * np.abs(y - np.polyval(c, x)).max() / span) if span > 0 else float("nan")
