"""The finger pulp under the strap as a solid layer (``finger_model = "solid"``): its mesh, its
material and its principal strain, below the strap's model. Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from designlab.mesh.tetmesh import TET10_EDGES, TRI6_EDGES, TetMesh

PULP = "pulp"
BONE = "pulp_bone"


def pulp_material(E: float, nu: float):
    """The pulp's linear material (E MPa, nu)."""
    from designlab.fem.materials import Material

    return Material("pulp", E=float(E), nu=float(nu),
                    source="fingertip pulp, linear elastic (finger_model = solid): E and nu "
                           "are settings (pulp_modulus, pulp_poisson), not a library value")


def extrude(points: np.ndarray, tri: np.ndarray, depth: float, layers: int,
            direction=(0.0, 0.0, -1.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Extrude corner triangles ``tri`` (ids into ``points``) by ``depth`` along ``direction``
    in ``layers`` layers. Returns (new points (k, 3), TET4 cells (ids into points + new
    points, positively oriented), far-face triangles). Layer 0 reuses the given nodes."""
    if layers < 1 or not depth > 0:
        raise ValueError("extrude: layers >= 1 and depth > 0")
    tri = np.sort(np.asarray(tri, np.int64), axis=1)           # diagonal rule: sorted ids
    base = np.unique(tri)
    n0 = len(points)
    local = np.full(n0, -1, np.int64)
    local[base] = np.arange(len(base))
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    new = np.vstack([points[base] + (j * depth / layers) * d for j in range(1, layers + 1)])

    def lay(ids, j):
        return ids if j == 0 else n0 + (j - 1) * len(base) + local[ids]

    cells = []
    for j in range(layers):
        a0, b0, c0 = (lay(tri[:, k], j) for k in range(3))
        a1, b1, c1 = (lay(tri[:, k], j + 1) for k in range(3))
        cells += [np.column_stack(c) for c in ((a0, b0, c0, a1), (b0, c0, a1, b1),
                                               (c0, a1, b1, c1))]
    cells = np.vstack(cells)
    allp = np.vstack([points, new])
    p = allp[cells]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    flip = vol < 0
    cells[flip] = cells[flip][:, [0, 2, 1, 3]]
    far = np.column_stack([lay(tri[:, k], layers) for k in range(3)])
    return new, cells, far


def _edge_table(cells10: np.ndarray) -> dict[tuple[int, int], int]:
    e = np.sort(cells10[:, TET10_EDGES].reshape(-1, 2), axis=1)
    m = cells10[:, 4:].reshape(-1)
    return dict(zip(map(tuple, e.tolist()), m.tolist()))


def add_pulp(mesh: TetMesh, tri: np.ndarray, depth: float, layers: int,
             direction=(0.0, 0.0, -1.0), body: str = PULP) -> TetMesh:
    """``mesh`` with the pulp body extruded from its boundary triangles ``tri`` (corner ids):
    region ``body`` (material name ``body``: give the Material to the Model), facet set
    :data:`BONE` (the far face). TET10 meshes keep their mid-edge nodes on the shared face."""
    new, c4, far = extrude(mesh.points, tri, depth, layers, direction)
    pts = np.vstack([mesh.points, new])
    if mesh.order == 2:
        known = _edge_table(mesh.cells)
        e = np.sort(c4[:, TET10_EDGES].reshape(-1, 2), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        ids = np.empty(len(uniq), np.int64)
        extra = []
        for i, (a, b) in enumerate(uniq.tolist()):
            k = known.get((a, b))
            if k is None:
                k = len(pts) + len(extra)
                extra.append(0.5 * (pts[a] + pts[b]))
            ids[i] = k
        if extra:
            pts = np.vstack([pts, np.array(extra)])
        cells = np.hstack([c4, ids[inv.reshape(-1)].reshape(-1, 6)])
        lookup = dict(zip(map(tuple, uniq.tolist()), ids.tolist()))
        fe = np.sort(far[:, TRI6_EDGES].reshape(-1, 2), axis=1)
        far = np.hstack([far, np.array([lookup[tuple(x)] for x in fe.tolist()],
                                       np.int64).reshape(-1, 3)])
    else:
        cells = c4
    rid = max(mesh.region_names, default=int(mesh.region.max())) + 1
    return TetMesh(pts, np.vstack([mesh.cells, cells]),
                   np.r_[mesh.region, np.full(len(cells), rid, mesh.region.dtype)],
                   {**mesh.region_names, rid: body}, {**mesh.materials, body: body},
                   {**mesh.facet_sets, BONE: far}, dict(mesh.point_sets))


def principal_strain(model, U: np.ndarray, body: str = PULP, q: float = 100.0) -> float:
    """The ``q``-th percentile (100: the largest) over the quadrature points of ``body``'s
    cells of the largest |principal strain| under the displacement ``U`` (3 n_points,). The
    largest sits at the bonded edge next to the pad (a corner: it grows as the mesh is
    refined); a percentile below 100 is the robust measure."""
    eps = np.asarray(model.B @ U).reshape(-1, 6)
    nq = len(eps) // model.mesh.n_cells
    rid = model.mesh.region_id(body)
    mask = np.repeat(model.mesh.region == rid, nq)
    a = _principal_abs(eps[mask])
    return float(np.percentile(a, q)) if len(a) else 0.0


def _principal_abs(e: np.ndarray) -> np.ndarray:
    """Per row, the largest |eigenvalue| of engineering-strain rows (xx, yy, zz, xy, xz, yz:
    the order of :func:`designlab.fem.assembly.strain_operator`)."""
    T = np.zeros((len(e), 3, 3))
    for k in range(3):
        T[:, k, k] = e[:, k]
    for col, (i, j) in zip(range(3, 6), ((0, 1), (0, 2), (1, 2))):
        T[:, i, j] = T[:, j, i] = 0.5 * e[:, col]
    return np.abs(np.linalg.eigvalsh(T)).max(axis=1)


def layer_closed_form(E: float, nu: float, depth: float, p: float) -> dict[str, Any]:
    """Compression (mm) of a layer of ``depth`` under a uniform pressure ``p`` (MPa): confined
    (no lateral strain, the P-wave modulus M = E (1 - nu) / ((1 + nu)(1 - 2 nu))) and
    unconfined with frictionless faces (uniaxial stress, E)."""
    M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    return {"confined_mm": p * depth / M, "unconfined_mm": p * depth / E, "M_MPa": M}
