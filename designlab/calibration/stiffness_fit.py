"""Seed 002 Section V: fit a symmetric 6x6 stiffness from (twist, wrench) pairs, and use it back.

``F = K X`` with twists ``X = (w, v)`` and wrenches ``F = (m, f)`` as rows of ``(k, 6)`` arrays. The
21 upper-triangular entries of ``K`` are the unknowns of one linear least-squares problem (the
paper's ``[F_1 ... F_k] = K [X_1 ... X_k]``); data for an axis the test rig cannot drive can be
added as "mirrored" virtual pairs through a symmetry of the flexure (:func:`mirror_pairs`).
The reverse use turns poses into wrenches and reports Table I statistics (mean and standard
deviation of the force error per axis). Units are the caller's (consistent with ``K``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from designlab.errors import DataError
from designlab.frames import adjoint, rotation_about, transform

#: (row, col) of the 21 unknowns, row-major over the upper triangle
UPPER = np.array([(i, j) for i in range(6) for j in range(i, 6)])
AXES = ("x", "y", "z")


def _pairs(X: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    X = np.asarray(X, float)
    F = np.asarray(F, float)
    if X.ndim != 2 or X.shape[1] != 6 or F.shape != X.shape:
        raise DataError(f"twists and wrenches must both be (k, 6) arrays, got {X.shape} and {F.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(F))):
        raise DataError("twists and wrenches must be finite (no NaN/inf)")
    return X, F


def design_matrix(X: np.ndarray) -> np.ndarray:
    """(6k, 21) matrix ``A`` with ``A theta = vec(F)`` (sample-major) for ``K = sym(theta)``."""
    X = np.asarray(X, float)
    k = len(X)
    A = np.zeros((k, 6, 21))
    for n, (i, j) in enumerate(UPPER):
        A[:, i, n] += X[:, j]
        if i != j:
            A[:, j, n] += X[:, i]
    return A.reshape(6 * k, 21)


def symmetric_from_upper(theta: np.ndarray) -> np.ndarray:
    """6x6 symmetric matrix from its 21 upper-triangular entries (row-major)."""
    K = np.zeros((6, 6))
    K[UPPER[:, 0], UPPER[:, 1]] = theta
    K[UPPER[:, 1], UPPER[:, 0]] = theta
    return K


def mirror_pairs(X: np.ndarray, F: np.ndarray, rotation: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Virtual pairs ``(Ad_R X, Ad_R F)`` through a symmetry rotation of the flexure.

    Default: 90 deg about z (an axisymmetric spring's x data stands in for an untested y).
    For a pure rotation ``Ad_R`` is orthogonal, so twists and wrenches map alike.
    """
    X, F = _pairs(X, F)
    R = rotation_about((0, 0, 1), np.pi / 2) if rotation is None else np.asarray(rotation, float)
    if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9):
        raise DataError("mirror rotation must be a 3x3 rotation matrix")
    A = adjoint(transform(R))
    return X @ A.T, F @ A.T


@dataclass(frozen=True)
class StiffnessFit:
    """A least-squares stiffness: ``K`` (6x6), its 21 ``entries`` with standard errors, residuals."""

    K: np.ndarray
    entries: np.ndarray
    std_errors: np.ndarray
    residual_rms: np.ndarray      #: (6,) RMS of F - K X per wrench component
    r2: np.ndarray                #: (6,) coefficient of determination per wrench component
    n_pairs: int
    n_mirrored: int
    condition_number: float       #: cond(K)
    design_condition: float       #: cond of the least-squares design matrix (identifiability)

    def report(self) -> dict:
        """Plain JSON-able summary."""
        return {"K": self.K.tolist(), "std_errors": symmetric_from_upper(self.std_errors).tolist(),
                "residual_rms": self.residual_rms.tolist(), "r2": self.r2.tolist(),
                "n_pairs": self.n_pairs, "n_mirrored": self.n_mirrored,
                "condition_number": self.condition_number,
                "design_condition": self.design_condition}


def fit_stiffness(X: np.ndarray, F: np.ndarray, mirror: bool | np.ndarray = False,
                  weights: np.ndarray | None = None) -> StiffnessFit:
    """Least squares for the 21 upper-triangular entries of a symmetric ``K`` with ``F = K X``.

    X, F:    (k, 6) twists (w, v) and wrenches (m, f).
    mirror:  True adds :func:`mirror_pairs` (90 deg about z); a 3x3 rotation picks another symmetry.
    weights: optional (6,) scale per wrench component (e.g. 1/noise std) to balance moments and
             forces of very different magnitudes; by default each component is scaled by its RMS.
    Raises DataError when the pairs do not excite all 21 entries (rank < 21).
    """
    X, F = _pairs(X, F)
    n_real = len(X)
    n_mirror = 0
    if mirror is not False and mirror is not None:
        Xm, Fm = mirror_pairs(X, F, None if mirror is True else mirror)
        X, F = np.vstack([X, Xm]), np.vstack([F, Fm])
        n_mirror = len(Xm)
    if weights is None:
        rms = np.sqrt(np.mean(F**2, axis=0))
        w = 1.0 / np.where(rms > 0, rms, 1.0)
    else:
        w = np.asarray(weights, float).reshape(6)
    A = design_matrix(X)
    Wrow = np.tile(w, len(X))
    Aw, bw = A * Wrow[:, None], F.reshape(-1) * Wrow
    theta, _, rank, sv = np.linalg.lstsq(Aw, bw, rcond=None)
    if rank < 21:
        raise DataError(f"the (twist, wrench) pairs excite only {rank} of the 21 stiffness entries;"
                        " add pairs along the missing axes or use mirror=True")
    K = symmetric_from_upper(theta)
    resid = F - X @ K.T
    dof = max(Aw.shape[0] - 21, 1)
    sigma2 = float(np.sum((resid.reshape(-1) * Wrow) ** 2)) / dof
    cov = sigma2 * np.linalg.inv(Aw.T @ Aw)
    ss_tot = np.sum((F - F.mean(axis=0)) ** 2, axis=0)
    ss_res = np.sum(resid**2, axis=0)
    r2 = np.where(ss_tot > 0, 1.0 - ss_res / np.where(ss_tot > 0, ss_tot, 1.0), np.nan)
    return StiffnessFit(K=K, entries=theta, std_errors=np.sqrt(np.diag(cov)),
                        residual_rms=np.sqrt(np.mean(resid**2, axis=0)), r2=r2,
                        n_pairs=n_real, n_mirrored=n_mirror,
                        condition_number=float(np.linalg.cond(K)),
                        design_condition=float(sv[0] / sv[-1]))


def wrench_from_twist(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``F = K X`` for one twist (6,) or many (k, 6)."""
    X = np.asarray(X, float)
    return X @ np.asarray(K, float).T


def force_error_stats(F_true: np.ndarray, F_est: np.ndarray) -> dict[str, dict[str, float]]:
    """Seed 002 Table I: mean and standard deviation of the force error ``F_true - F_est`` per axis.

    Only the force components (3:6) are reported; std is the sample standard deviation (ddof=1).
    """
    F_true, F_est = _pairs(F_true, F_est)
    e = F_true[:, 3:] - F_est[:, 3:]
    return {a: {"mean": float(e[:, i].mean()), "std": float(e[:, i].std(ddof=1) if len(e) > 1 else 0.0)}
            for i, a in enumerate(AXES)}
