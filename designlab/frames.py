"""SE(3) helpers in the twist order (w, v) and wrench order (m, f) of Modern Robotics / seed 002.

Pure numpy. A pose ``T`` is a 4x4 homogeneous transform; a twist or exponential-coordinate vector
``X = (w_x, w_y, w_z, v_x, v_y, v_z)``; a wrench ``F = (m_x, m_y, m_z, f_x, f_y, f_z)``. Lengths are
in whatever unit the caller uses (mm inside designlab); a stiffness ``K`` maps twists to wrenches
(``F = K X``) and moves between frames with seed 002 eq. 3:

    K_a = [Ad_{T_af}]^-T K_f [Ad_{T_af}]^-1

where ``T_af`` is the configuration of frame {f} seen from {a} and
``Ad_T = [[R, 0], [[p] R, R]]``.
"""

from __future__ import annotations

import numpy as np

from designlab.errors import ParameterError

_EPS = 1e-12


def skew(v: np.ndarray) -> np.ndarray:
    """3x3 skew-symmetric matrix ``[v]`` with ``[v] u = v x u``."""
    x, y, z = np.asarray(v, float).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def unskew(S: np.ndarray) -> np.ndarray:
    """Vector of a skew-symmetric 3x3 matrix (inverse of :func:`skew`)."""
    S = np.asarray(S, float)
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def transform(rotation: np.ndarray | None = None, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform from a 3x3 rotation (default identity) and a translation."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = np.asarray(rotation, float)
    T[:3, 3] = np.asarray(translation, float).reshape(3)
    return T


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a homogeneous transform, ``[[R^T, -R^T p], [0, 1]]``."""
    R, p = T[:3, :3], T[:3, 3]
    return transform(R.T, -R.T @ p)


def rotation_about(axis, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about ``axis`` (Rodrigues)."""
    a = np.asarray(axis, float).reshape(3)
    n = np.linalg.norm(a)
    if n < _EPS:
        raise ParameterError("axis", axis, "a non-zero rotation axis")
    return exp_so3(a / n * angle)


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp([w])`` of a rotation vector ``w`` (rad)."""
    w = np.asarray(w, float).reshape(3)
    th = np.linalg.norm(w)
    W = skew(w)
    if th < 1e-8:
        return np.eye(3) + W + 0.5 * W @ W
    return np.eye(3) + np.sin(th) / th * W + (1 - np.cos(th)) / th**2 * W @ W


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector ``w`` (rad, |w| <= pi) with ``exp_so3(w) = R``."""
    R = np.asarray(R, float)
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(c)
    if th < 1e-8:
        return unskew(R - R.T) / 2.0
    if np.pi - th < 1e-6:
        # near pi: axis from the symmetric part R = 2 n n^T - I
        B = (R + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(B)))
        n = B[:, k] / np.sqrt(max(B[k, k], _EPS))
        return n / np.linalg.norm(n) * th
    return unskew(R - R.T) * th / (2.0 * np.sin(th))


def _left_jacobian(w: np.ndarray) -> np.ndarray:
    th = np.linalg.norm(w)
    W = skew(w)
    if th < 1e-8:
        return np.eye(3) + 0.5 * W + W @ W / 6.0
    return np.eye(3) + (1 - np.cos(th)) / th**2 * W + (th - np.sin(th)) / th**3 * W @ W


def exp_se3(X: np.ndarray) -> np.ndarray:
    """Homogeneous transform ``exp([X])`` of exponential coordinates ``X = (w, v)``."""
    X = np.asarray(X, float).reshape(6)
    w, v = X[:3], X[3:]
    return transform(exp_so3(w), _left_jacobian(w) @ v)


def log_se3(T: np.ndarray) -> np.ndarray:
    """Exponential coordinates ``X = (w, v)`` with ``exp_se3(X) = T``."""
    w = log_so3(T[:3, :3])
    v = np.linalg.solve(_left_jacobian(w), T[:3, 3])
    return np.concatenate([w, v])


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint ``Ad_T = [[R, 0], [[p] R, R]]`` mapping twists (w, v) of {b} into {a}, T = T_ab."""
    R, p = T[:3, :3], T[:3, 3]
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[3:, 3:] = R
    A[3:, :3] = skew(p) @ R
    return A


def transform_stiffness(K_f: np.ndarray, T_af: np.ndarray) -> np.ndarray:
    """Stiffness of frame {f} expressed in frame {a}: ``Ad^-T K_f Ad^-1`` (seed 002 eq. 3).

    Units follow the translation of ``T_af``: with mm, translational entries are N/mm, couplings N
    (N*mm/mm), rotational N*mm/rad.
    """
    K_f = np.asarray(K_f, float)
    Ainv = adjoint(inverse(T_af))  # [Ad_T]^-1 = Ad_{T^-1}
    return Ainv.T @ K_f @ Ainv


def transform_compliance(C_f: np.ndarray, T_af: np.ndarray) -> np.ndarray:
    """Compliance of frame {f} expressed in frame {a}: ``Ad C_f Ad^T`` (inverse of the stiffness rule)."""
    A = adjoint(T_af)
    return A @ np.asarray(C_f, float) @ A.T


def transform_wrench(F_f: np.ndarray, T_af: np.ndarray) -> np.ndarray:
    """Wrench (m, f) given in {f} expressed in {a}: ``Ad_{T_af}^-T F_f`` (= Ad_{T_fa}^T F_f)."""
    return adjoint(inverse(T_af)).T @ np.asarray(F_f, float)


def transform_twist(X_f: np.ndarray, T_af: np.ndarray) -> np.ndarray:
    """Twist (w, v) given in {f} expressed in {a}: ``Ad_{T_af} X_f``."""
    return adjoint(T_af) @ np.asarray(X_f, float)


def pose_twist(T_cd: np.ndarray, T_cr: np.ndarray) -> np.ndarray:
    """Seed 002 displacement ``X_c = log(T_cd T_cr^-1)`` of the dome {d} from rest {r}, in {c}."""
    return log_se3(np.asarray(T_cd, float) @ inverse(T_cr))


def offset_along_z(K_f: np.ndarray, K_c: np.ndarray) -> dict:
    """Offset ``h`` along z of {f} seen from {c} that best explains ``K_c`` from a diagonal ``K_f``.

    Uses the translation/rotation couplings ``K_c[0, 4] = -h K_f[4, 4]`` and
    ``K_c[1, 3] = +h K_f[3, 3]`` (and the rotational gain ``K_c[0,0] - K_f[0,0] = h^2 K_f[4,4]``)
    of eq. 3 for ``T_cf = transform(translation=(0, 0, h))``. Returns each estimate in the units of
    the inputs' lengths.
    """
    K_f = np.asarray(K_f, float)
    K_c = np.asarray(K_c, float)
    from_coupling_x = -K_c[0, 4] / K_f[4, 4]
    from_coupling_y = K_c[1, 3] / K_f[3, 3]
    gain = K_c[0, 0] - K_f[0, 0]
    from_rotation = float(np.sqrt(gain / K_f[4, 4])) if gain > 0 else float("nan")
    return {"from_coupling_x": float(from_coupling_x), "from_coupling_y": float(from_coupling_y),
            "from_rotational_gain": from_rotation}
