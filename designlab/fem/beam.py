"""Two-node 3-D Timoshenko beam stiffness (12 x 12) for bought slender parts coupled to the mesh
(the M2.5 cantilever bolt of seed 001), in global coordinates.

Dofs per end: (u_x, u_y, u_z, theta_x, theta_y, theta_z); units mm, N, MPa -> N/mm, N mm/rad.
"""

from __future__ import annotations

import numpy as np

from designlab.errors import ParameterError


def circular_section(d: float) -> dict[str, float]:
    """Area (mm^2), second moments I (mm^4), polar J (mm^4) and shear area of a solid round bar
    of diameter ``d`` (mm); shear coefficient 0.9 (Cowper, nu ~ 0.3)."""
    if not d > 0:
        raise ParameterError("d", d, "> 0 mm")
    A = np.pi * d ** 2 / 4
    I = np.pi * d ** 4 / 64
    return {"A": A, "Iy": I, "Iz": I, "J": 2 * I, "As": 0.9 * A}


def beam_stiffness(xa, xb, E: float, G: float, A: float, Iy: float, Iz: float, J: float,
                   As: float | None = None, up=None) -> np.ndarray:
    """12 x 12 stiffness of a straight Timoshenko beam from ``xa`` to ``xb`` (mm).

    ``Iy``/``Iz`` about the local y/z axes (local x along the beam; local y from ``up``,
    default the global axis least aligned with the beam). ``As`` shear area (None: Euler-
    Bernoulli)."""
    xa, xb = np.asarray(xa, float), np.asarray(xb, float)
    L = float(np.linalg.norm(xb - xa))
    if not L > 0:
        raise ParameterError("beam length", L, "> 0 mm (distinct end points)")
    ex = (xb - xa) / L
    if up is None:
        up = np.eye(3)[int(np.argmin(np.abs(ex)))]
    ey = np.cross(np.asarray(up, float), ex)
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    R = np.vstack([ex, ey, ez])                         # global -> local
    phi_y = 0.0 if As is None else 12 * E * Iz / (G * As * L ** 2)   # bending in local xy
    phi_z = 0.0 if As is None else 12 * E * Iy / (G * As * L ** 2)   # bending in local xz
    k = np.zeros((12, 12))
    ea, gj = E * A / L, G * J / L
    k[np.ix_([0, 6], [0, 6])] = ea * np.array([[1, -1], [-1, 1]])
    k[np.ix_([3, 9], [3, 9])] = gj * np.array([[1, -1], [-1, 1]])

    def bend(EI, phi, v, t, sign):
        c = EI / (L ** 3 * (1 + phi))
        m = c * np.array([[12, sign * 6 * L, -12, sign * 6 * L],
                          [sign * 6 * L, (4 + phi) * L ** 2, -sign * 6 * L, (2 - phi) * L ** 2],
                          [-12, -sign * 6 * L, 12, -sign * 6 * L],
                          [sign * 6 * L, (2 - phi) * L ** 2, -sign * 6 * L, (4 + phi) * L ** 2]])
        idx = [v, t, v + 6, t + 6]
        k[np.ix_(idx, idx)] += m

    bend(E * Iz, phi_y, 1, 5, +1)     # v_y with theta_z
    bend(E * Iy, phi_z, 2, 4, -1)     # v_z with theta_y
    T = np.kron(np.eye(4), R)
    return T.T @ k @ T
