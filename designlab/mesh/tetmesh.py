"""The tetrahedral mesh every analysis consumes: plain numpy arrays with names.

Node order of quadratic cells is CalculiX C3D10 / VTK_QUADRATIC_TETRA: the 4 corners, then the
mid-nodes of edges (0,1), (1,2), (2,0), (0,3), (1,3), (2,3). Facet sets are boundary triangles
(3 corner nodes, or 6 nodes for quadratic meshes: corners then mid-nodes of (0,1), (1,2), (2,0)).
Coordinates in mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

#: local corner pairs of the six TET10 mid-edge nodes (C3D10 order)
TET10_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
#: local corner pairs of the three TRI6 mid-edge nodes
TRI6_EDGES = np.array([[0, 1], [1, 2], [2, 0]])


def edge_keys(pairs: np.ndarray, n_points: int) -> np.ndarray:
    """One int64 key per edge given by its two corner nodes (..., 2), the same whichever way
    round: ``min * n_points + max`` (to match mid-nodes by corner pair)."""
    e = np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1)
    return e[:, 0] * np.int64(n_points) + e[:, 1]


@dataclass(frozen=True, eq=False)
class TetMesh:
    """A tagged tetrahedral mesh.

    points:      (n, 3) float, mm
    cells:       (m, 4) or (m, 10) int, positively oriented (det of the corner Jacobian > 0)
    region:      (m,) int, region id of each cell
    region_names: {region id: body name}
    materials:   {body name: material name} (names of :mod:`designlab.fem.materials`)
    facet_sets:  {name: (k, 3) or (k, 6) int boundary triangles}
    point_sets:  {name: (k,) int node indices} (e.g. load points snapped to nodes)
    """

    points: np.ndarray
    cells: np.ndarray
    region: np.ndarray
    region_names: dict[int, str] = field(default_factory=dict)
    materials: dict[str, str] = field(default_factory=dict)
    facet_sets: dict[str, np.ndarray] = field(default_factory=dict)
    point_sets: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def order(self) -> int:
        """1 for TET4, 2 for TET10."""
        return 1 if self.cells.shape[1] == 4 else 2

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    @cached_property
    def corner_volumes(self) -> np.ndarray:
        """(m,) signed volume of each cell's corner tetrahedron, mm^3."""
        p = self.points[self.cells[:, :4]]
        return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                         p[:, 3] - p[:, 0]) / 6.0

    @property
    def volume(self) -> float:
        return float(self.corner_volumes.sum())

    def region_id(self, name: str) -> int:
        for k, v in self.region_names.items():
            if v == name:
                return k
        from designlab.errors import ModelError

        raise ModelError(f"region '{name}' does not exist; available: "
                         f"{', '.join(self.region_names.values())}")

    def quadratic(self) -> "TetMesh":
        """TET10 version of a TET4 mesh: one shared straight mid-node per edge."""
        if self.order == 2:
            return self
        m = self.n_cells
        edges = self.cells[:, TET10_EDGES].reshape(-1, 2)
        key = np.sort(edges, axis=1)
        uniq, inverse = np.unique(key, axis=0, return_inverse=True)
        mid = 0.5 * (self.points[uniq[:, 0]] + self.points[uniq[:, 1]])
        new_ids = self.n_points + inverse.reshape(m, 6)
        cells = np.hstack([self.cells, new_ids])
        # facet mid-nodes from the same edge table
        lookup = {tuple(e): self.n_points + i for i, e in enumerate(uniq)}
        fsets = {}
        for name, tri in self.facet_sets.items():
            tri = np.asarray(tri)[:, :3]
            e = np.sort(tri[:, TRI6_EDGES].reshape(-1, 2), axis=1)
            mids = np.array([lookup[tuple(x)] for x in e], dtype=np.int64).reshape(-1, 3)
            fsets[name] = np.hstack([tri, mids]) if len(tri) else np.zeros((0, 6), np.int64)
        return TetMesh(np.vstack([self.points, mid]), cells, self.region, dict(self.region_names),
                       dict(self.materials), fsets, dict(self.point_sets))

    def boundary_facets(self) -> np.ndarray:
        """(k, 3) corner triangles on the outer boundary (faces used by exactly one cell)."""
        faces = self.cells[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(-1, 3)
        key = np.sort(faces, axis=1)
        _, idx, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        return faces[idx[counts == 1]]


def box_tet_mesh(lx: float, ly: float, lz: float, nx: int, ny: int, nz: int,
                 origin=(0.0, 0.0, 0.0), body: str = "block",
                 material: str = "ABS") -> TetMesh:
    """Structured TET4 mesh of a box (6 tets per hexahedron, Kuhn split), with facet sets
    ``xmin, xmax, ymin, ymax, zmin, zmax``. For verification cases and tests."""
    xs = np.linspace(0, lx, nx + 1) + origin[0]
    ys = np.linspace(0, ly, ny + 1) + origin[1]
    zs = np.linspace(0, lz, nz + 1) + origin[2]
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    nid = np.arange(len(pts)).reshape(nx + 1, ny + 1, nz + 1)
    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    c = [nid[i + a, j + b, k + d] for a, b, d in
         [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]]
    # Kuhn subdivision along the 0-6 diagonal: conforming across neighbouring hexes
    tets = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
    cells = np.vstack([np.column_stack([c[a], c[b], c[cc], c[d]]) for a, b, cc, d in tets])
    p = pts[cells]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    flip = vol < 0
    cells[flip] = cells[flip][:, [0, 2, 1, 3]]
    mesh = TetMesh(pts, cells, np.zeros(len(cells), np.int64), {0: body}, {body: material})
    bf = mesh.boundary_facets()
    cen = pts[bf].mean(axis=1)
    tol = 1e-9 * max(lx, ly, lz)
    lo, hi = np.asarray(origin, float), np.asarray(origin, float) + [lx, ly, lz]
    fsets = {}
    for ax, a in enumerate("xyz"):
        fsets[f"{a}min"] = bf[np.abs(cen[:, ax] - lo[ax]) < tol]
        fsets[f"{a}max"] = bf[np.abs(cen[:, ax] - hi[ax]) < tol]
    return TetMesh(pts, cells, mesh.region, {0: body}, {body: material}, fsets)
