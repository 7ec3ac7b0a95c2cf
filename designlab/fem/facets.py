"""Surface integration on facet sets (TRI3 / TRI6 boundary triangles of a TetMesh).

Facets are oriented outward (against their owning cell) before integrating, so a positive
pressure pushes into the body. Quadrature: 3 points for TRI3, 6 points (degree 4) for TRI6,
isoparametric (curved quadratic faces are integrated on their true geometry).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from designlab.errors import ModelError
from designlab.fem.elements import Element, tri_element
from designlab.mesh.tetmesh import TetMesh

#: local faces of a tetrahedron, face k is opposite local node k
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
_FACE_KEYS: "weakref.WeakKeyDictionary[TetMesh, tuple]" = weakref.WeakKeyDictionary()


def _face_table(mesh: TetMesh):
    tab = _FACE_KEYS.get(mesh)
    if tab is None:
        f = np.sort(mesh.cells[:, _TET_FACES].reshape(-1, 3), axis=1).astype(np.int64)
        n = mesh.n_points
        key = (f[:, 0] * n + f[:, 1]) * n + f[:, 2]
        order = np.argsort(key, kind="stable")
        tab = (key[order], order)
        _FACE_KEYS[mesh] = tab
    return tab


def orient_outward(mesh: TetMesh, tri: np.ndarray) -> np.ndarray:
    """Copy of ``tri`` with every triangle ordered so its normal points out of its cell
    (facets between two cells, e.g. region interfaces: out of the first cell found)."""
    tri = np.asarray(tri, np.int64)
    if len(tri) == 0:
        return tri
    keys, order = _face_table(mesh)
    s = np.sort(tri[:, :3], axis=1)
    n = mesh.n_points
    k = (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
    pos = np.clip(np.searchsorted(keys, k), 0, len(keys) - 1)
    found = keys[pos] == k
    if not found.all():
        raise ModelError(f"{int((~found).sum())} facets are not faces of any cell "
                         f"(first: nodes {tri[~found][0, :3].tolist()})")
    face = order[pos]
    cell, local = face // 4, face % 4
    opp = mesh.points[mesh.cells[cell, local]]
    p = mesh.points[tri[:, :3]]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", nrm, opp - p[:, 0]) > 0
    out = tri.copy()
    out[flip, 1], out[flip, 2] = tri[flip, 2], tri[flip, 1]
    if tri.shape[1] == 6:                 # mid-nodes (01, 12, 20) -> (02, 21, 10)
        out[flip, 3], out[flip, 5] = tri[flip, 5], tri[flip, 3]
    return out


@dataclass(frozen=True, eq=False)
class FacetBasis:
    """Quadrature on oriented triangles: N (nq, nn); nodes (k, nn); x (k, nq, 3) points (mm);
    n (k, nq, 3) outward normal scaled by the area element times weight (mm^2),
    dA (k, nq) = |n|."""

    element: Element
    nodes: np.ndarray
    N: np.ndarray
    x: np.ndarray
    n: np.ndarray
    dA: np.ndarray

    @property
    def area(self) -> float:
        return float(self.dA.sum())


def facet_basis(mesh: TetMesh, tri: np.ndarray) -> FacetBasis:
    """Facet quadrature of the triangles ``tri`` ((k, 3) or (k, 6)); TET10 meshes need TRI6."""
    tri = np.asarray(tri, np.int64)
    if tri.ndim != 2 or tri.shape[1] not in (3, 6):
        raise ModelError(f"facets must be (k, 3) or (k, 6) node arrays, got shape {tri.shape}")
    if mesh.order == 2 and tri.shape[1] == 3:
        raise ModelError("quadratic mesh needs 6-node facets: build facet sets before "
                         "TetMesh.quadratic() so they get their mid-nodes")
    if mesh.order == 1 and tri.shape[1] == 6:
        tri = tri[:, :3]
    tri = orient_outward(mesh, tri)
    el = tri_element(tri.shape[1])
    q = el.quadrature
    N, dN = el.N(q.points), el.dN(q.points)            # (nq, nn), (nq, nn, 2)
    X = mesh.points[tri]                                # (k, nn, 3)
    x = np.einsum("qa,kai->kqi", N, X)
    t = np.einsum("qad,kai->kqdi", dN, X)               # tangents (k, nq, 2, 3)
    n = np.cross(t[:, :, 0], t[:, :, 1]) * q.weights[None, :, None]
    return FacetBasis(el, tri, N, x, n, np.linalg.norm(n, axis=-1))


def _scatter(fb: FacetBasis, fq: np.ndarray, n_points: int) -> np.ndarray:
    """Nodal forces (3 n,) from force densities times area weights fq (k, nq, 3)."""
    fe = np.einsum("qa,kqi->kai", fb.N, fq)
    dofs = 3 * fb.nodes[:, :, None] + np.arange(3)
    return np.bincount(dofs.ravel(), weights=fe.ravel(), minlength=3 * n_points)


def traction_load(mesh: TetMesh, fb: FacetBasis, t) -> np.ndarray:
    """Consistent nodal forces (3 n,) of a traction ``t`` (MPa): (3,) vector or callable
    ``t(x) -> (..., 3)`` of the quadrature point coordinates."""
    tq = t(fb.x) if callable(t) else np.broadcast_to(np.asarray(t, float), fb.x.shape)
    return _scatter(fb, tq * fb.dA[..., None], mesh.n_points)


def pressure_load(mesh: TetMesh, fb: FacetBasis, p) -> np.ndarray:
    """Consistent nodal forces (3 n,) of a pressure ``p`` (MPa, positive pushes inward):
    scalar or callable ``p(x) -> (...)``."""
    pq = p(fb.x) if callable(p) else np.broadcast_to(np.asarray(p, float), fb.dA.shape)
    return _scatter(fb, -pq[..., None] * fb.n, mesh.n_points)


def area_weights(mesh: TetMesh, fb: FacetBasis) -> np.ndarray:
    """(n_points,) consistent nodal areas int N_a dA (zero off the facets; TRI6 corners of a
    flat face get zero), mm^2."""
    w = np.einsum("qa,kq->ka", fb.N, fb.dA)
    return np.bincount(fb.nodes.ravel(), weights=w.ravel(), minlength=mesh.n_points)
