"""Named triangle sets of a tetrahedral mesh: selector-defined boundary sets and interfaces.

Faces of a positively oriented cell are taken with the winding ``[1,2,3], [0,3,2], [0,1,3],
[0,2,1]`` so that their right-hand normals point out of the cell.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from designlab.errors import MeshingError
from designlab.geometry.body import FacetSelector

_CELL_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def cell_faces(cells: np.ndarray) -> np.ndarray:
    """(4m, 3) outward-wound corner faces of every cell, cell by cell."""
    return np.asarray(cells)[:, _CELL_FACES].reshape(-1, 3)


def centroids_normals(points: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroids (k, 3) and right-hand unit normals (k, 3) of triangles ``tri`` (k, >=3)."""
    p = np.asarray(points, float)[np.asarray(tri)[:, :3]]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return p.mean(axis=1), n


def select_facets(points: np.ndarray, boundary: np.ndarray,
                  selectors: Mapping[str, FacetSelector]) -> dict[str, np.ndarray]:
    """Apply each selector to the outward boundary triangles; an empty or malformed selection
    raises :class:`MeshingError` naming the set."""
    cen, nrm = centroids_normals(points, boundary)
    out = {}
    for name, selector in selectors.items():
        mask = np.asarray(selector(cen, nrm))
        if mask.shape != (len(boundary),) or mask.dtype != bool:
            raise MeshingError(f"facet set {name!r}: selector must return a boolean mask of "
                               f"shape ({len(boundary)},), got {mask.dtype} {mask.shape}")
        if not mask.any():
            raise MeshingError(f"facet set {name!r} selects none of the {len(boundary)} "
                               f"boundary triangles of the mesh (broken part or selector)")
        out[name] = boundary[mask]
    return out


def interface_facets(cells: np.ndarray, region: np.ndarray,
                     region_names: Mapping[int, str]) -> dict[str, np.ndarray]:
    """Triangles shared by cells of two different regions, as ``interface:A|B`` (names sorted),
    wound outward of region ``A``."""
    faces = cell_faces(cells[:, :4])
    owner = np.repeat(np.asarray(region), 4)
    key = np.sort(faces, axis=1)
    order = np.lexsort(key.T[::-1])
    ks = key[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    i, j = order[:-1][same], order[1:][same]  # the two cell faces of each interior triangle
    differ = owner[i] != owner[j]
    i, j = i[differ], j[differ]

    def name_of(r: int) -> str:
        return region_names.get(r, str(r))

    out = {}
    for ra, rb in sorted({tuple(sorted(x)) for x in zip(owner[i].tolist(), owner[j].tolist())}):
        if name_of(ra) > name_of(rb):
            ra, rb = rb, ra
        pair = ((owner[i] == ra) & (owner[j] == rb)) | ((owner[i] == rb) & (owner[j] == ra))
        fi, fj = i[pair], j[pair]
        out[f"interface:{name_of(ra)}|{name_of(rb)}"] = faces[np.where(owner[fi] == ra, fi, fj)]
    return out
