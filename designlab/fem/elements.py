"""Reference elements: shape functions, their derivatives and quadrature rules.

Tetrahedra use natural coordinates ``(r, s, t)`` with barycentric ``L = (1-r-s-t, r, s, t)``;
triangles use ``(r, s)`` with ``L = (1-r-s, r, s)``. Node order follows C3D10 / VTK:
corners, then mid-edges (0,1), (1,2), (2,0), (0,3), (1,3), (2,3) (triangles: (0,1), (1,2), (2,0)).
Every function is vectorised over points: ``N(X)`` is (nq, nn), ``dN(X)`` is (nq, nn, dim).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from designlab.mesh.tetmesh import TET10_EDGES, TRI6_EDGES


def _bary_grad(dim: int) -> np.ndarray:
    """(dim+1, dim) derivative of the barycentric coordinates w.r.t. natural coordinates."""
    return np.vstack([-np.ones(dim), np.eye(dim)])


def _bary(X: np.ndarray) -> np.ndarray:
    X = np.atleast_2d(X)
    return np.column_stack([1.0 - X.sum(axis=1), X])


def _linear_N(X):
    return _bary(X)


def _linear_dN(X):
    X = np.atleast_2d(X)
    d = X.shape[1]
    return np.broadcast_to(_bary_grad(d), (len(X), d + 1, d)).copy()


def _quadratic(edges: np.ndarray):
    def N(X):
        L = _bary(X)
        corner = L * (2.0 * L - 1.0)
        mid = 4.0 * L[:, edges[:, 0]] * L[:, edges[:, 1]]
        return np.hstack([corner, mid])

    def dN(X):
        L = _bary(X)
        dL = _bary_grad(L.shape[1] - 1)                       # (nc, d)
        corner = (4.0 * L - 1.0)[:, :, None] * dL[None]       # (nq, nc, d)
        a, b = edges[:, 0], edges[:, 1]
        mid = 4.0 * (L[:, a, None] * dL[None, b] + L[:, b, None] * dL[None, a])
        return np.concatenate([corner, mid], axis=1)

    return N, dN


@dataclass(frozen=True)
class Quadrature:
    """Points (nq, dim) in natural coordinates and weights (nq,) summing to the reference
    measure (1/6 for the tetrahedron, 1/2 for the triangle)."""

    points: np.ndarray
    weights: np.ndarray
    degree: int


@dataclass(frozen=True, eq=False)
class Element:
    """A reference element: ``N(X) -> (nq, nn)``, ``dN(X) -> (nq, nn, dim)``."""

    name: str
    dim: int
    n_nodes: int
    N: Callable[[np.ndarray], np.ndarray]
    dN: Callable[[np.ndarray], np.ndarray]
    quadrature: Quadrature          # default rule: exact for the stiffness of straight elements

    @property
    def order(self) -> int:
        return 1 if self.n_nodes in (3, 4) else 2


# --- quadrature rules (Keast / Strang-Fix, symmetric) ---

def _tet_rule(degree: int) -> Quadrature:
    if degree <= 1:
        return Quadrature(np.array([[0.25, 0.25, 0.25]]), np.array([1.0 / 6.0]), 1)
    if degree == 2:
        a, b = 0.5854101966249685, 0.1381966011250105
        pts = np.array([[b, b, b], [a, b, b], [b, a, b], [b, b, a]])
        return Quadrature(pts, np.full(4, 1.0 / 24.0), 2)
    if degree == 3:          # 5-point Keast rule (one negative weight), exact to degree 3
        pts = np.array([[0.25, 0.25, 0.25], [0.5, 1 / 6, 1 / 6], [1 / 6, 0.5, 1 / 6],
                        [1 / 6, 1 / 6, 0.5], [1 / 6, 1 / 6, 1 / 6]])
        w = np.array([-4 / 30, 9 / 120, 9 / 120, 9 / 120, 9 / 120])
        return Quadrature(pts, w, 3)
    # higher degrees: collapsed (Duffy) Gauss-Legendre product rule, positive weights
    n = (degree + 3) // 2 + 1
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    u, v, z = np.meshgrid(x, x, x, indexing="ij")
    wu, wv, wz = np.meshgrid(w, w, w, indexing="ij")
    r = u
    s = v * (1.0 - u)
    t = z * (1.0 - u) * (1.0 - v)
    W = wu * wv * wz * (1.0 - u) ** 2 * (1.0 - v)
    return Quadrature(np.column_stack([r.ravel(), s.ravel(), t.ravel()]), W.ravel(), degree)


def _tri_rule(degree: int) -> Quadrature:
    if degree <= 1:
        return Quadrature(np.array([[1 / 3, 1 / 3]]), np.array([0.5]), 1)
    if degree == 2:
        pts = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
        return Quadrature(pts, np.full(3, 1 / 6), 2)
    # Dunavant 6-point rule, exact to degree 4
    a, wa = 0.445948490915965, 0.223381589678011
    b, wb = 0.091576213509771, 0.109951743655322
    pts = np.array([[a, a], [1 - 2 * a, a], [a, 1 - 2 * a],
                    [b, b], [1 - 2 * b, b], [b, 1 - 2 * b]])
    return Quadrature(pts, 0.5 * np.array([wa, wa, wa, wb, wb, wb]), 4)


def tet_quadrature(degree: int) -> Quadrature:
    """Symmetric tetrahedron rule exact for polynomials of ``degree`` (1..5)."""
    return _tet_rule(degree)


def tri_quadrature(degree: int) -> Quadrature:
    """Symmetric triangle rule exact for polynomials of ``degree`` (1..4)."""
    return _tri_rule(degree)


_N10, _dN10 = _quadratic(TET10_EDGES)
_N6, _dN6 = _quadratic(TRI6_EDGES)

#: linear tetrahedron, 1-point rule (constant strain)
TET4 = Element("TET4", 3, 4, _linear_N, _linear_dN, tet_quadrature(1))
#: quadratic tetrahedron (C3D10), 4-point rule (exact stiffness for straight edges)
TET10 = Element("TET10", 3, 10, _N10, _dN10, tet_quadrature(2))
#: linear triangle (TET4 faces), 3-point rule
TRI3 = Element("TRI3", 2, 3, _linear_N, _linear_dN, tri_quadrature(2))
#: quadratic triangle (TET10 faces), 6-point degree-4 rule
TRI6 = Element("TRI6", 2, 6, _N6, _dN6, tri_quadrature(4))


def tet_element(n_nodes: int) -> Element:
    """TET4 or TET10 from the number of nodes per cell."""
    return {4: TET4, 10: TET10}[n_nodes]


def tri_element(n_nodes: int) -> Element:
    """TRI3 or TRI6 from the number of nodes per facet."""
    return {3: TRI3, 6: TRI6}[n_nodes]


def tet10_jacobians(points: np.ndarray, cells: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """(m, q) determinants of the TET10 (C3D10) map's Jacobian at reference points ``xi``
    (q, 3) (mm^3 per unit reference volume; > 0 for a valid, positively oriented cell)."""
    dN = tet_element(10).dN(np.asarray(xi, float))               # (q, 10, 3)
    J = np.einsum("eai,qaj->eqij", points[cells], dN, optimize=True)
    return np.linalg.det(J)


#: reference coordinates of the 10 C3D10 nodes
TET10_NODES_XI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, 0, 0], [.5, .5, 0],
                           [0, .5, 0], [0, 0, .5], [.5, 0, .5], [0, .5, .5]], float)


def tet10_volume(points: np.ndarray, cells: np.ndarray) -> float:
    """Volume of a TET10 mesh with its mid-nodes where they are (mm^3): the Jacobian (a cubic
    of the reference coordinates) integrated exactly (degree-3 rule)."""
    q = tet_quadrature(3)
    return float((tet10_jacobians(points, cells, q.points) @ q.weights).sum())
