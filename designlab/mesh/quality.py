"""Shape quality of tetrahedra: dihedral angles, radius ratio and a summary report.

Both measures use the corner tetrahedron of each cell (TET10 mid-nodes are straight).
The radius ratio is ``3 r_in / R_circ``: 1 for the regular tetrahedron, 0 for a flat one.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from designlab.errors import MeshingError
from designlab.mesh.tetmesh import TetMesh

#: the six edges of a tetrahedron and, for each, the two faces meeting there, named by the
#: vertex they are opposite to: edge (i, j) lies on the faces opposite k and l
_EDGE_FACES = np.array([[2, 3], [0, 3], [1, 3], [1, 2], [0, 2], [0, 1]])  # edges 01 12 20 03 13 23
_EDGE_PAIRS = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
#: face opposite vertex i (any winding; normals are made outward below)
_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def _corners(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    return np.asarray(points, float)[np.asarray(cells)[:, :4]]


def dihedral_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, 6) interior dihedral angles in degrees at the edges 01, 12, 20, 03, 13, 23."""
    p = _corners(points, cells)
    normals = []
    for i, (a, b, c) in enumerate(_FACES):
        n = np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a])
        # outward: pointing away from the opposite vertex i
        sign = np.sign(np.einsum("ij,ij->i", n, p[:, a] - p[:, i]))
        n = n * sign[:, None]
        normals.append(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300))
    normals = np.stack(normals, axis=1)  # (m, 4, 3)
    cos = -np.einsum("mij,mij->mi", normals[:, _EDGE_FACES[:, 0]], normals[:, _EDGE_FACES[:, 1]])
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def radius_ratios(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) normalised radius ratio ``3 r_in / R_circ`` in [0, 1] (1 = regular tetrahedron)."""
    p = _corners(points, cells)
    vol = np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                           p[:, 3] - p[:, 0])) / 6.0
    area = sum(0.5 * np.linalg.norm(np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a]), axis=1)
               for a, b, c in _FACES)
    r_in = 3.0 * vol / np.maximum(area, 1e-300)
    # circumradius from the products of opposite edge lengths (Crelle's formula)
    length = np.linalg.norm(p[:, _EDGE_PAIRS[:, 0]] - p[:, _EDGE_PAIRS[:, 1]], axis=2)
    a, b, c = length[:, 0] * length[:, 5], length[:, 1] * length[:, 3], length[:, 2] * length[:, 4]
    s = (a + b + c) * (a + b - c) * (a - b + c) * (-a + b + c)
    r_circ = np.sqrt(np.maximum(s, 0.0)) / np.maximum(24.0 * vol, 1e-300)
    return np.clip(3.0 * r_in / np.maximum(r_circ, 1e-300), 0.0, 1.0)


def edge_lengths(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, 6) corner edge lengths of each cell, mm."""
    p = _corners(points, cells)
    return np.linalg.norm(p[:, _EDGE_PAIRS[:, 0]] - p[:, _EDGE_PAIRS[:, 1]], axis=2)


@dataclass(frozen=True)
class MeshQuality:
    """Summary of a tetrahedral mesh's element shapes (angles in degrees, lengths in mm)."""

    n_cells: int
    n_points: int
    order: int
    min_dihedral_deg: float
    max_dihedral_deg: float
    radius_ratio_min: float
    radius_ratio_mean: float
    #: counts of cells per radius-ratio bin, edges ``radius_ratio_bins``
    radius_ratio_hist: tuple[int, ...]
    radius_ratio_bins: tuple[float, ...]
    #: cells with radius ratio below ``poor_threshold`` or a dihedral angle below 5 degrees
    n_poor: int
    poor_threshold: float
    edge_length_min: float
    edge_length_mean: float
    edge_length_max: float

    def as_dict(self) -> dict:
        d = asdict(self)
        d["radius_ratio_hist"] = list(self.radius_ratio_hist)
        d["radius_ratio_bins"] = list(self.radius_ratio_bins)
        return d


def mesh_quality(mesh: TetMesh, poor_threshold: float = 0.1, bins: int = 10) -> MeshQuality:
    """Quality report of ``mesh``: dihedral angles, radius ratios and edge lengths."""
    if mesh.n_cells == 0:
        raise MeshingError("mesh has no cells")
    ang = dihedral_angles(mesh.points, mesh.cells)
    rr = radius_ratios(mesh.points, mesh.cells)
    le = edge_lengths(mesh.points, mesh.cells)
    edges = np.linspace(0.0, 1.0, bins + 1)
    hist, _ = np.histogram(rr, bins=edges)
    poor = (rr < poor_threshold) | (ang.min(axis=1) < 5.0)
    return MeshQuality(
        n_cells=mesh.n_cells, n_points=mesh.n_points, order=mesh.order,
        min_dihedral_deg=float(ang.min()), max_dihedral_deg=float(ang.max()),
        radius_ratio_min=float(rr.min()), radius_ratio_mean=float(rr.mean()),
        radius_ratio_hist=tuple(int(h) for h in hist),
        radius_ratio_bins=tuple(float(e) for e in edges),
        n_poor=int(poor.sum()), poor_threshold=float(poor_threshold),
        edge_length_min=float(le.min()), edge_length_mean=float(le.mean()),
        edge_length_max=float(le.max()))
