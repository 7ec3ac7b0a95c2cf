"""Loading/unloading loops and the midpoint hysteresis of seed 001 eq. (1).

    Hysteresis% = | (S_mp - S_mn) / (S_start - S_end) | x 100

S_mp, S_mn: readings at the loop's midpoint load going up and going down; S_start, S_end: the
readings at the start (lowest load) and end (highest load) of the loop. Readings between the
discrete weights are interpolated linearly in load.
"""

from __future__ import annotations

import numpy as np

from designlab.errors import ParameterError


def hysteresis_percent(load_up: np.ndarray, s_up: np.ndarray, load_down: np.ndarray,
                       s_down: np.ndarray) -> float | np.ndarray:
    """Midpoint hysteresis (%) of one loop, seed 001 eq. (1).

    ``load_up`` increasing, ``load_down`` the same loads in any order (typically decreasing);
    ``s_up``/``s_down`` readings of shape (n,) or (n, channels) -> float or (channels,).
    """
    lu, ld = np.asarray(load_up, float), np.asarray(load_down, float)
    su, sd = np.asarray(s_up, float), np.asarray(s_down, float)
    if lu.ndim != 1 or len(lu) < 3 or np.any(np.diff(lu) <= 0):
        raise ParameterError("load_up", lu.tolist(), "at least 3 strictly increasing loads")
    order = np.argsort(ld)
    ld, sd = ld[order], sd[order]
    if len(ld) != len(lu) or not np.allclose(ld, lu):
        raise ParameterError("load_down", ld.tolist(), "the same loads as load_up")
    mid = 0.5 * (lu[0] + lu[-1])
    squeeze = su.ndim == 1
    su2, sd2 = su.reshape(len(lu), -1), sd.reshape(len(ld), -1)
    s_mp = _interp_columns(mid, lu, su2)
    s_mn = _interp_columns(mid, ld, sd2)
    span = su2[0] - su2[-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.abs((s_mp - s_mn) / span) * 100.0
    return float(h[0]) if squeeze else h


def _interp_columns(x: float, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp(x, xp, fp[:, c])`` for every column c at once, with numpy's own arithmetic
    (``slope * (x - xp[j]) + fp[j]``, ``xp[j] <= x < xp[j + 1]``; at or beyond the ends the end
    values): the same numbers, without a Python loop over thousands of loops."""
    if x <= xp[0]:
        return fp[0].copy()
    if x >= xp[-1]:
        return fp[-1].copy()
    j = int(np.searchsorted(xp, x, side="right")) - 1
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[j]
    bad = np.isnan(out)
    if bad.any():                       # numpy's fallback for an infinite slope
        out[bad] = (slope * (x - xp[j + 1]) + fp[j + 1])[bad]
        bad = np.isnan(out) & (fp[j] == fp[j + 1])
        out[bad] = fp[j][bad]
    return out


def loop_from_steps(weights: np.ndarray, readings: np.ndarray):
    """Split readings of an up-then-down weight sequence (``w0..wn..w0``, length 2n+1 or 2n)
    into (load_up, s_up, load_down, s_down)."""
    w = np.asarray(weights, float)
    k = int(np.argmax(w))
    up = slice(0, k + 1)
    down = slice(k, len(w))
    return w[up], np.asarray(readings)[up], w[down], np.asarray(readings)[down]
