"""Named faces and regions of a sensor definition on its tetrahedral mesh: the boundary facets a
:class:`~designlab.sensors.definition.Face` selects, the nodes of a
:class:`~designlab.sensors.definition.Region`."""

from __future__ import annotations

import numpy as np

from designlab.errors import ParameterError
from designlab.mesh.tetmesh import TET10_EDGES, TetMesh
from designlab.sensors.definition import Face, Region

_LOCAL_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
_EDGE = {tuple(sorted(e)): 4 + i for i, e in enumerate(TET10_EDGES.tolist())}
#: the six local nodes (corners, then mid-edge nodes of (0,1), (1,2), (2,0)) of each TET10 face
_LOCAL_FACES6 = np.array([[a, b, c, _EDGE[tuple(sorted((a, b)))], _EDGE[tuple(sorted((b, c)))],
                           _EDGE[tuple(sorted((c, a)))]] for a, b, c in _LOCAL_FACES.tolist()])


def outer_facets(mesh: TetMesh) -> tuple[np.ndarray, np.ndarray]:
    """(triangles (k, 3) or (k, 6) with outward corner order, owning cell (k,)) of the mesh's
    outer boundary; found once per mesh (every face of a definition selects from them)."""
    memo = mesh.__dict__.get("_outer_facets")
    if memo is None:
        memo = mesh.__dict__["_outer_facets"] = _outer_facets(mesh)
    return memo


def _outer_facets(mesh: TetMesh) -> tuple[np.ndarray, np.ndarray]:
    local = _LOCAL_FACES if mesh.order == 1 else _LOCAL_FACES6
    faces = mesh.cells[:, local].reshape(-1, local.shape[1])
    owner = np.repeat(np.arange(mesh.n_cells), 4)
    key = np.sort(faces[:, :3], axis=1)
    _, idx, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    keep = np.sort(idx[counts == 1])
    return faces[keep], owner[keep]


def face_key(face: Face) -> str:
    """A stable set name for a face (its fields)."""
    box = "" if face.box is None else "_box" + "_".join(f"{v:g}" for c in face.box for v in c)
    at = "" if face.at is None else f"_at{face.at:g}"
    n = "_".join(f"{v:g}" for v in face.normal)
    return f"{face.body}_n{n}{at}{box}_a{face.angle_deg:g}"


def select(mesh: TetMesh, face: Face, what: str) -> np.ndarray:
    """The outer facets (k, 3) of ``face``; a one-line error naming ``what`` when the body does
    not exist or the face selects nothing."""
    return select_owned(mesh, face, what)[0]


def select_owned(mesh: TetMesh, face: Face, what: str) -> tuple[np.ndarray, np.ndarray]:
    """:func:`select`'s facets and the cell each belongs to."""
    names = list(mesh.region_names.values())
    if face.body not in names:
        raise ParameterError(f"{what}.body", face.body, "a body of the sensor: " + ", ".join(names))
    tri, owner = outer_facets(mesh)
    rid = mesh.region_id(face.body)
    on_body = mesh.region[owner] == rid
    tri, owner = tri[on_body], owner[on_body]
    ok = pick(mesh.points, tri, face, what)
    return tri[ok], owner[ok]


def pick(points: np.ndarray, tri: np.ndarray, face: Face, what: str) -> np.ndarray:
    """Which triangles (k, >= 3 corner ids into ``points``, outward order) of one body's
    boundary ``face`` selects; a one-line error naming ``what`` when none."""
    p = points
    c = p[tri[:, :3]].mean(axis=1)
    nrm = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    n = np.asarray(face.normal, float)
    n = n / np.linalg.norm(n)
    ok = nrm @ n >= np.cos(np.radians(face.angle_deg))
    if face.box is not None:
        lo, hi = (np.asarray(b, float) for b in face.box)
        ok &= np.all((c >= lo - 1e-9) & (c <= hi + 1e-9), axis=1)
    if not ok.any():
        raise ParameterError(what, _describe(face), "a face of the body with outward normal "
                             f"within {face.angle_deg:g} deg of {tuple(face.normal)}"
                             + (" inside the box" if face.box is not None else ""))
    d = c @ n
    tol = 1e-3 * float(np.linalg.norm(p.max(0) - p.min(0)))
    ref = d[ok].max() if face.at is None else float(face.at)
    ok &= np.abs(d - ref) <= tol
    if not ok.any():
        raise ParameterError(what, _describe(face), f"a plane x . n = at where the body has facets "
                             f"(they lie at {np.unique(np.round(d[nrm @ n > 0.98], 3))[:6].tolist()})")
    return ok


def region_nodes(mesh: TetMesh, where: Face | Region, what: str) -> np.ndarray:
    """Node ids of a face's facets or of a body's cells."""
    if isinstance(where, Face):
        return np.unique(select(mesh, where, what))
    names = list(mesh.region_names.values())
    if where.body not in names:
        raise ParameterError(f"{what}.body", where.body, "a body of the sensor: " + ", ".join(names))
    return np.unique(mesh.cells[mesh.region == mesh.region_id(where.body)])


def _describe(face: Face) -> str:
    return f"{face.body} face towards {tuple(face.normal)}"
