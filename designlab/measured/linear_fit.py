"""First-order (linear) calibration of seed 000, generalised to any number of channels.

Seed 000 fits Matlab ``polyfit(..., 1)`` on the training task: the normal force from the sum of
the two gauge channels (Ch1 + Ch2) and the shear force from their difference (Ch1 - Ch2). Here
each output j is a first-order polynomial of its own *channel* ``c_j = mix[j] . u``; with
``mix="full"`` each output is instead an affine function of all inputs (multivariate least
squares). Units: y in the reference unit (e.g. N) per input unit (e.g. V or ohm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from designlab.errors import DataError, ParameterError

SUM_DIFF = ((1.0, 1.0), (1.0, -1.0))  # seed 000: F_n <- Ch1 + Ch2, F_x <- Ch1 - Ch2
MIXES = ("auto", "full", "identity", "sum-diff")


def as_2d(x, name: str) -> np.ndarray:
    """Samples as a (T, channels) float array; NaN/inf raise a one-line DataError."""
    a = np.asarray(x, float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0 or a.shape[1] == 0:
        raise DataError(f"{name} must be (samples,) or (samples, channels), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"{name} contains NaN or infinite samples")
    return a


def mix_matrix(n_in: int, n_out: int, mix="auto") -> np.ndarray | None:
    """Channel matrix (n_out, n_in) mapping inputs to one channel per output; None = full fit.

    ``"auto"``: sum/difference for 2 inputs -> 2 outputs (seed 000), identity when square,
    else ``"full"``.
    """
    if isinstance(mix, str):
        if mix not in MIXES:
            raise ParameterError("mix", mix, "one of " + ", ".join(MIXES) + " or a matrix")
        if mix == "full":
            return None
        if mix == "sum-diff" or (mix == "auto" and n_in == n_out == 2):
            if not n_in == n_out == 2:
                raise ParameterError("mix", mix, "sum-diff needs 2 inputs and 2 outputs")
            return np.array(SUM_DIFF)
        if n_in == n_out:
            return np.eye(n_in)
        if mix == "identity":
            raise ParameterError("mix", mix, "identity needs as many inputs as outputs")
        return None
    m = np.asarray(mix, float)
    if m.shape != (n_out, n_in) or not np.all(np.isfinite(m)):
        raise ParameterError("mix", m.tolist(), f"a finite {n_out}x{n_in} matrix (outputs x inputs)")
    return m


@dataclass(frozen=True)
class LinearFit:
    """y = A u + b; ``channels`` holds the channel matrix used (None for a full fit)."""

    A: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    channels: tuple[tuple[float, ...], ...] | None = None

    def predict(self, u) -> np.ndarray:
        """Estimates (T, n_out) for inputs (T, n_in)."""
        u = as_2d(u, "u")
        A = np.array(self.A)
        if u.shape[1] != A.shape[1]:
            raise DataError(f"u has {u.shape[1]} channels, the linear fit expects {A.shape[1]}")
        return u @ A.T + np.array(self.b)


def fit_linear(u, y, mix="auto") -> LinearFit:
    """First-order least-squares fit of outputs y (T, n_out) on inputs u (T, n_in)."""
    u, y = as_2d(u, "u"), as_2d(y, "y")
    if u.shape[0] != y.shape[0]:
        raise DataError(f"u and y lengths differ ({u.shape[0]} vs {y.shape[0]} samples)")
    n_in, n_out = u.shape[1], y.shape[1]
    if u.shape[0] < n_in + 2:
        raise DataError(f"linear fit needs more than {n_in + 1} samples, got {u.shape[0]}")
    m = mix_matrix(n_in, n_out, mix)
    if m is None:
        X = np.column_stack([u, np.ones(len(u))])
        with np.errstate(all="ignore"):   # an extreme scale fails as LinAlgError, said as data
            coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        return LinearFit(A=_tup(coef[:-1].T), b=tuple(coef[-1].tolist()))
    c = u @ m.T                                         # (T, n_out) one channel per output
    A = np.empty((n_out, n_in))
    b = np.empty(n_out)
    for j in range(n_out):
        if np.ptp(c[:, j]) == 0:
            raise DataError(f"channel {j} (mix {m[j].tolist()}) is constant: nothing to fit")
        with np.errstate(all="ignore"):   # values near 1e-300: polyfit's column scale
            slope, icpt = np.polyfit(c[:, j], y[:, j], 1)   # underflows, SVD fails (LinAlgError)
        A[j], b[j] = slope * m[j], icpt
    return LinearFit(A=_tup(A), b=tuple(b.tolist()), channels=_tup(m))


def _tup(a: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(x) for x in row) for row in np.asarray(a))
