"""What a built-in sensor reports, from any definition's readings: calibration matrix by least
squares, condition number, sensitivity, cross-talk, hysteresis (seed 001 eq. 1), the noise
budget and the force error with its spread over noise draws."""

from __future__ import annotations

from typing import Any

import numpy as np

from designlab.calibration.calibration_matrix import condition_number, cross_talk_percent
from designlab.calibration.hysteresis import hysteresis_percent


def active_loads(P: np.ndarray, names: list[str]) -> tuple[np.ndarray, list[str]]:
    """The load components the protocol varies (columns with a spread)."""
    span = P.max(axis=0) - P.min(axis=0)
    keep = span > 1e-9 * max(float(np.abs(P).max()), 1e-30)
    return P[:, keep], [n for n, k in zip(names, keep) if k]


def fit_matrix(S: np.ndarray, P: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, int]:
    """C with P ~ S C by least squares over the directions of the readings that stand above
    their noise: the channels scaled by their noise, reading directions whose singular value
    is below the noise's own over the states (sqrt(n_states)) are left out (more channels than
    loads: the extra directions carry no load, only what a model adds there). Returns (C, the
    number of directions used)."""
    sd = np.where(noise > 0, noise, 1.0)
    U, sv, Vt = np.linalg.svd(S / sd[None, :], full_matrices=False)
    keep = sv > np.sqrt(len(S))
    if not keep.any():
        keep = sv >= sv.max()
    Cw = Vt[keep].T @ ((U[:, keep].T @ P) / sv[keep][:, None])
    return Cw / sd[:, None], int(keep.sum())


def calibration(S: np.ndarray, P: np.ndarray, moment_cols: list[int],
                moment_scale_mm: float | None, noise: np.ndarray | None = None
                ) -> dict[str, Any]:
    """P ~ S C (:func:`fit_matrix`): C, its condition number (raw, and with moments divided by
    ``moment_scale_mm``), the fit residual and the cross-talk."""
    noise = np.ones(S.shape[1]) if noise is None else np.asarray(noise, float)
    C, rank = fit_matrix(S, P, noise)
    est = S @ C
    out = {"matrix": C.tolist(), "condition_number": condition_number(C), "directions": rank,
           "fit_rms": np.sqrt(np.mean((est - P) ** 2, axis=0)).tolist(),
           "cross_talk_percent": cross_talk_percent(P, est).tolist()}
    if moment_scale_mm and moment_cols:
        scale = np.ones(P.shape[1])
        scale[moment_cols] = 1.0 / moment_scale_mm
        out["condition_number_scaled"] = condition_number(C * scale[None, :])
        out["moment_scale_mm"] = float(moment_scale_mm)
    return out


def sensitivity(S: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(n_channels, n_loads) readings per unit load, S ~ P K^T by least squares."""
    K, *_ = np.linalg.lstsq(P, S, rcond=None)
    return K.T


def noise_budget(C: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Standard deviation of each estimated load from the channels' noise through C."""
    cov = C.T @ np.diag(noise ** 2) @ C
    return np.sqrt(np.clip(np.diag(cov), 0.0, None))


def force_error(S: np.ndarray, P: np.ndarray, noise: np.ndarray, repeats: int,
                seed: int) -> dict[str, Any]:
    """Calibrate on the protocol's readings with one noise draw and estimate the loads of
    another: RMS error per load over ``repeats`` such pairs (mean and standard deviation)."""
    rng = np.random.default_rng(seed)
    errs = []
    for _ in range(repeats):
        S1 = S + rng.standard_normal(S.shape) * noise
        S2 = S + rng.standard_normal(S.shape) * noise
        C1, _ = fit_matrix(S1, P, noise)
        errs.append(np.sqrt(np.mean((S2 @ C1 - P) ** 2, axis=0)))
    e = np.asarray(errs)
    rel = e.mean(0) / np.maximum(np.abs(P).max(0), 1e-300) * 100.0
    return {"rms": e.mean(0).tolist(), "rms_std": e.std(0, ddof=1).tolist(),
            "rms_percent_of_range": rel.tolist(), "repeats": int(repeats), "seed": int(seed)}


def hysteresis(loops, readings: np.ndarray) -> dict[str, Any] | None:
    """Midpoint hysteresis (%) of every channel over the staircase's loops; None without loops."""
    if not loops:
        return None
    zero = np.zeros(readings.shape[1])
    per = []
    for loads_up, up, loads_down, down in loops:
        su = np.array([zero if i < 0 else readings[i] for i in up])
        sd = np.array([zero if i < 0 else readings[i] for i in down])
        per.append(hysteresis_percent(loads_up, su, loads_down, sd))
    h = np.asarray(per)
    h = np.where(np.isfinite(h), h, np.nan)
    return {"per_loop": h.tolist(), "mean": np.nanmean(h, axis=0).tolist(),
            "max": np.nanmax(h, axis=0).tolist(), "overall": float(np.nanmean(h))}


def sensitivity_shapes(K: np.ndarray, channels: list[str], active: list[str],
                       moment_cols: list[int], moment_scale_mm: float | None,
                       normalise_by: str | None) -> dict[str, Any]:
    """The sensitivity K's condition number (raw, and with the moment columns in load per
    ``moment_scale_mm``) and, with ``normalise_by`` (a load component such as ``"Fz"``), each
    channel's row divided by its entry for that load: the shape of the sensitivity that does
    not depend on each channel's gain."""
    out: dict[str, Any] = {"sensitivity_condition_number": condition_number(K)}
    if moment_scale_mm and moment_cols:
        scale = np.ones(K.shape[1])
        scale[moment_cols] = moment_scale_mm
        out["sensitivity_condition_number_scaled"] = condition_number(K * scale[None, :])
    if normalise_by:
        cols = [i for i, n in enumerate(active) if n.replace(".", "_").rsplit("_", 1)[-1]
                == normalise_by]
        if len(cols) != 1:
            from designlab.errors import ParameterError

            raise ParameterError("normalise_rows_by", normalise_by, "a load component the "
                                 "protocol varies at one load point: " + ", ".join(active))
        Kn = K / K[:, cols]
        out["sensitivity_normalised_by"] = active[cols[0]]
        out["sensitivity_normalised"] = {c: dict(zip(active, map(float, Kn[i])))
                                         for i, c in enumerate(channels)}
    return out
