"""Curved (isoparametric) TET10 by projection: boundary mid-edge nodes onto the true surface (mm).

A straight TET10 (:meth:`~designlab.mesh.tetmesh.TetMesh.quadratic`) has every mid-edge node on
its edge's chord, so a round face is faceted and sags inside. :func:`curve_boundary` moves the
mid-node of every boundary edge onto the surface that edge lies on, with no mesher involved:

* the body's faces are planes (``(origin, unit normal)``, e.g. the B-rep's planar faces,
  :func:`designlab.mesh.brep.planar_faces`) and **one** curved surface, given as a closest-point
  projector (:class:`Tube`: a circle of radius ``r`` swept along a centreline ``c(u)``);
* a boundary triangle lies on plane ``k`` when its three corners do (within ``plane_tol``),
  otherwise on the curved surface;
* an edge whose boundary triangles are all on the curved surface: its mid-node goes to the
  surface point nearest to the chord midpoint; an edge shared by the curved surface and one
  plane (the rim where they meet): the mid-node moves within that plane onto the surface (both
  corners are on the plane, so the chord midpoint is too; Newton on the signed distance along
  the surface normal's in-plane part), so it ends on both; an edge on planes only stays on its
  chord (a plane, or the straight line where two planes meet). Interior edges stay straight.

Nothing else changes: corners, cells, regions and sets are the straight mesh's. Same input, same
output, bit for bit (no randomness, no threads). A corner of a curved-surface triangle farther
than ``surface_tol`` from the surface means the projector is not this mesh's surface:
:class:`MeshingError`. Cells the curving inverts are the caller's (e.g. put their mid-nodes back
on the chords); this module does not evaluate Jacobians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from designlab.errors import MeshingError
from designlab.mesh.tetmesh import TET10_EDGES, TetMesh, edge_keys

Curve = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Tube:
    """A circle of radius ``radius`` (mm) swept along the centreline ``centre(u)``, ``u`` in
    ``[u_lo, u_hi]`` (any parameter), with its first and second derivatives ``d_centre``,
    ``dd_centre`` ((n,) -> (n, 3), mm per unit u). Beyond the ends the nearest centreline point
    is the end point (the tube closes with half spheres, which planar end faces cut off).
    ``seeds``: centreline samples for the nearest-point search's start (a KD-tree), enough that
    the sample nearest to a point on the tube is on the right stretch of the centreline."""

    centre: Curve
    d_centre: Curve
    dd_centre: Curve
    radius: float
    u_lo: float
    u_hi: float
    seeds: int = 4096
    #: Newton steps on u at most (they stop once every step is below 1e-13 of the u range)
    newton_steps: int = 12

    def nearest_u(self, x: np.ndarray) -> np.ndarray:
        """(n,) parameter of the centreline point nearest to each point of ``x`` (n, 3): the
        nearest of :attr:`seeds` samples, then Newton on ``(x - c(u)) . c'(u) = 0``, clamped to
        the ends."""
        from scipy.spatial import cKDTree

        x = np.asarray(x, float)
        us = np.linspace(self.u_lo, self.u_hi, int(self.seeds))
        _, k = cKDTree(self.centre(us)).query(x)
        u = us[k]
        tol = 1e-13 * max(1.0, abs(self.u_hi - self.u_lo))
        for _ in range(int(self.newton_steps)):
            e = x - self.centre(u)
            d1, d2 = self.d_centre(u), self.dd_centre(u)
            g = -np.einsum("ij,ij->i", e, d1)
            h = np.einsum("ij,ij->i", d1, d1) - np.einsum("ij,ij->i", e, d2)
            h = np.maximum(h, 0.1 * np.einsum("ij,ij->i", d1, d1))   # far from the curve
            step = g / h
            u = np.clip(u - step, self.u_lo, self.u_hi)
            if np.abs(step).max() < tol:
                break
        return u

    def closest(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest surface points (n, 3) of ``x`` (n, 3) and the outward unit normals there."""
        x = np.asarray(x, float)
        off = x - self.centre(self.nearest_u(x))
        n = off / np.maximum(np.linalg.norm(off, axis=1, keepdims=True), 1e-300)
        return x - off + self.radius * n, n


def boundary_edges(mesh: TetMesh) -> dict:
    """The boundary triangles of a TET10 mesh and their edges: ``triangles`` (k, 3) corner
    nodes, ``pairs`` (e, 2) corner nodes of each distinct edge, ``mid`` (e,) its mid-node,
    ``edge_of`` (k, 3) the edge index of each triangle side (:data:`TRI6_EDGES` order)."""
    from designlab.mesh.tetmesh import TRI6_EDGES

    if mesh.order != 2:
        raise MeshingError("curving needs a TET10 mesh (TetMesh.quadratic())")
    n = np.int64(mesh.n_points)
    tri = mesh.boundary_facets()
    keys, edge_of = np.unique(edge_keys(tri[:, TRI6_EDGES], n), return_inverse=True)
    uk, first = np.unique(edge_keys(mesh.cells[:, TET10_EDGES], n), return_index=True)
    pos = np.searchsorted(uk, keys)
    mid = mesh.cells[:, 4:].reshape(-1)[first[pos]]
    return {"triangles": tri, "pairs": np.column_stack([keys // n, keys % n]), "mid": mid,
            "edge_of": edge_of.reshape(-1, 3)}


def triangle_planes(points: np.ndarray, triangles: np.ndarray,
                    planes: Sequence[tuple], tol: float) -> np.ndarray:
    """(k,) index of the plane (``(origin, unit normal)``) holding all three corners of each
    triangle within ``tol`` mm, -1 for none (the first plane that does)."""
    out = np.full(len(triangles), -1, np.int64)
    p = np.asarray(points, float)[triangles]                    # (k, 3, 3)
    for i, (o, nrm) in enumerate(planes):
        nrm = np.asarray(nrm, float) / np.linalg.norm(nrm)
        dist = np.abs((p - np.asarray(o, float)) @ nrm).max(axis=1)
        out[(out < 0) & (dist <= tol)] = i
    return out


def onto_surface_in_plane(surface, x: np.ndarray, origin, normal, tol: float = 1e-10,
                          steps: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Points ``x`` (n, 3) on a plane moved within it onto ``surface``: Newton on the signed
    distance ``(p - q) . n`` (``q, n`` = ``surface.closest(p)``) along the in-plane part ``g`` of
    the normal, ``p -= d g / |g|^2``. Returns the points and whether each converged (|d| <=
    ``tol`` mm); a point whose ``g`` vanishes (surface tangent to the plane) stops where it is."""
    m = np.asarray(normal, float) / np.linalg.norm(normal)
    p = np.array(x, float)
    ok = np.zeros(len(p), bool)
    live = np.arange(len(p))
    for _ in range(int(steps)):
        if not len(live):
            break
        q, n = surface.closest(p[live])
        d = np.einsum("ij,ij->i", p[live] - q, n)
        g = n - np.outer(n @ m, m)
        gg = np.einsum("ij,ij->i", g, g)
        done = np.abs(d) <= tol
        ok[live[done]] = True
        stuck = gg < 1e-12
        move = ~done & ~stuck
        p[live[move]] -= (d[move] / gg[move])[:, None] * g[move]
        live = live[move]
    if len(live):                                               # the last step's check
        q, n = surface.closest(p[live])
        ok[live] = np.abs(np.einsum("ij,ij->i", p[live] - q, n)) <= tol
    return p, ok


def curve_boundary(mesh: TetMesh, surface, planes: Sequence[tuple] = (),
                   plane_tol: float = 1e-6, surface_tol: float | None = None,
                   max_move: float = 0.5) -> tuple[np.ndarray, dict]:
    """Points of ``mesh`` (straight TET10) with its boundary mid-edge nodes on ``surface`` and
    ``planes`` (module docstring). ``surface``: an object with ``closest(x) -> (points,
    normals)``; ``planes``: ``[(origin (3,), unit normal (3,)), ...]`` mm; ``plane_tol``: corner
    distance from a plane that counts as on it, mm; ``surface_tol``: largest distance of a
    curved-surface triangle's corner from ``surface`` (default ``1e-3`` of the mesh's bounding
    box diagonal), else :class:`MeshingError`; ``max_move``: a mid-node that would move more
    than this fraction of its edge's length stays on the chord (counted as ``kept_far``).

    Info: ``surface_mid_nodes`` (moved onto the surface), ``rim_mid_nodes`` (moved within a
    plane onto the surface), ``plane_mid_nodes`` (on planes only, unchanged), ``kept_far``,
    ``rim_not_converged`` (left on the chord), ``largest_move_mm``, ``corner_distance_mm``
    (largest corner distance from the surface: the projector against the mesh's own surface)."""
    b = boundary_edges(mesh)
    pts = mesh.points
    tri, edge_of, pairs, mid = b["triangles"], b["edge_of"], b["pairs"], b["mid"]
    plane_of = triangle_planes(pts, tri, planes, plane_tol)
    n_e = len(pairs)
    side_edge = edge_of.reshape(-1)
    side_plane = np.repeat(plane_of, 3)
    curved_sides = np.bincount(side_edge[side_plane < 0], minlength=n_e)
    big = np.iinfo(np.int64).max
    lo = np.full(n_e, big, np.int64)
    hi = np.full(n_e, -1, np.int64)
    np.minimum.at(lo, side_edge[side_plane >= 0], side_plane[side_plane >= 0])
    np.maximum.at(hi, side_edge[side_plane >= 0], side_plane[side_plane >= 0])
    has_plane = hi >= 0
    free = (curved_sides > 0) & ~has_plane
    rim = (curved_sides > 0) & has_plane & (lo == hi)

    # the projector against the mesh: corners of the curved-surface triangles on the surface
    corners = np.unique(tri[plane_of < 0])
    if surface_tol is None:
        surface_tol = 1e-3 * float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    corner_dist = 0.0
    if len(corners):
        q, _ = surface.closest(pts[corners])
        corner_dist = float(np.linalg.norm(q - pts[corners], axis=1).max())
        if corner_dist > surface_tol:
            raise MeshingError(f"curving: a corner of the curved boundary is {corner_dist:.3g} mm "
                               f"off the surface given (tolerance {surface_tol:.3g} mm): not "
                               "this mesh's surface")
    out = pts.copy()
    length = np.linalg.norm(pts[pairs[:, 1]] - pts[pairs[:, 0]], axis=1)
    x0 = 0.5 * (pts[pairs[:, 0]] + pts[pairs[:, 1]])
    target = x0.copy()
    moved = np.zeros(n_e, bool)
    idx = np.nonzero(free)[0]
    if len(idx):
        target[idx], _ = surface.closest(x0[idx])
        moved[idx] = True
    not_converged = 0
    for k in np.unique(lo[rim]):
        idx = np.nonzero(rim & (lo == k))[0]
        o, nrm = planes[int(k)]
        target[idx], ok = onto_surface_in_plane(surface, x0[idx], o, nrm)
        target[idx[~ok]] = x0[idx[~ok]]
        moved[idx[ok]] = True
        not_converged += int((~ok).sum())
    step = np.linalg.norm(target - x0, axis=1)
    far = moved & (step > max_move * length)
    moved &= ~far
    out[mid[moved]] = target[moved]
    info = {"surface_mid_nodes": int((moved & free).sum()),
            "rim_mid_nodes": int((moved & rim).sum()),
            "plane_mid_nodes": int((~(curved_sides > 0)).sum()), "kept_far": int(far.sum()),
            "rim_not_converged": not_converged,
            "largest_move_mm": float(step[moved].max()) if moved.any() else 0.0,
            "corner_distance_mm": corner_dist}
    return out, info
