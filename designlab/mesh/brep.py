"""Bodies -> one conforming tetrahedral mesh straight from their B-rep, with gmsh (mm).

Each body's OpenCascade solid goes to gmsh as an exact B-rep (``.brep`` in a temporary folder,
never the working directory), ``occ.fragment`` splits the bodies where they touch so that the
regions share their faces and nodes, and each body becomes one physical group (region id = its
index, its material from the body). Element size: ``edge_length`` is the largest edge; the
part's refinement spheres become ``Ball`` size fields (edge ``e`` inside the sphere, grading
back to ``edge_length`` over a shell of ``(edge_length - e) / grading``), combined by ``Min``.

Same input, same mesh, bit for bit: one thread, a fixed random seed, the 2-D Frontal-Delaunay
and 3-D Delaunay algorithms, no configuration files read. Linear tetrahedra come out; the
caller makes TET10 with straight mid-edge nodes. Opt-in curved TET10 (:func:`curve_tet10`):
the same gmsh mesh made again, raised to order 2 by gmsh (``setOrder(2)``, new nodes on the
B-rep, ``Mesh.SecondOrderLinear`` 0), and its mid-edge nodes copied onto the straight mesh's by
corner pair; nothing else changes (node and cell numbering, facet sets). The same without a second
gmsh run, by projecting the boundary mid-nodes onto a known surface: :mod:`designlab.mesh.curve`
(with the B-rep's planes from :func:`planar_faces`).

Named faces: a part can name B-rep faces of its bodies (``{set name: [(body index, face), ...]}``,
the faces as build123d/OCP shapes). Each becomes a physical surface group; after ``fragment``
(which may split a face where bodies touch) a gmsh surface belongs to a named face when a point
inside it (the projection of the centroid of its largest triangle onto the surface) lies on that
face (OpenCascade distance below ``NAMED_TOL``). The group's triangles are returned per name.
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
import threading
from typing import Any, Mapping, Sequence

import numpy as np

from designlab.errors import MeshingError

#: gmsh options that make the mesh a function of the input alone
DETERMINISTIC = {
    "General.Terminal": 0, "General.Verbosity": 0, "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1, "Mesh.MaxNumThreads2D": 1, "Mesh.MaxNumThreads3D": 1,
    "Mesh.RandomSeed": 1, "Mesh.Algorithm": 6, "Mesh.Algorithm3D": 1,
    "Mesh.MeshSizeFromPoints": 0, "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.Optimize": 1, "Mesh.OptimizeNetgen": 0, "Mesh.ElementOrder": 1,
}


#: gmsh's 10-node tetrahedron (element type 11: corners, then the mid-nodes of (0,1), (1,2),
#: (2,0), (3,0), (3,2), (3,1)) -> C3D10 order (corners, then (0,1), (1,2), (2,0), (0,3), (1,3),
#: (2,3)); checked on an all-flat body (tests/mesh/test_mesh_curved.py: every mid-node on its edge's
#: midpoint to 1e-9 mm)
GMSH_TET10_TO_C3D10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])

#: a gmsh surface lies on a named B-rep face when a point inside it is this close (mm)
NAMED_TOL = 1e-6

#: gmsh is one global state per process (its model, options, initialisation): threads that mesh
#: at the same time (Dask's threaded workers) take turns
_LOCK = threading.Lock()


def available() -> bool:
    try:
        import gmsh  # noqa: F401
    except ImportError:
        return False
    return True


def tetrahedralize(shapes: Sequence, names: Sequence[str], edge_length: float,
                   refinement: Sequence[tuple] = (), grading: float = 0.5,
                   min_edge: float | None = None, curvature: int = 0,
                   named_faces: Mapping[str, Sequence[tuple[int, Any]]] | None = None):
    """(points (n, 3) mm, cells (m, 4), region (m,) = index of the body) of the solids
    ``shapes`` (build123d/OCP), conforming where they touch. ``curvature``: elements per
    2 pi of a curved face's radius (0 = size from ``edge_length`` alone). Overlapping bodies, a body that
    gmsh cannot import or mesh -> :class:`MeshingError` naming it. One call at a time per
    process (:data:`_LOCK`: gmsh's state is global).

    With ``named_faces`` (``{name: [(body index, B-rep face), ...]}``) a fourth item is
    returned: ``{name: (k, 3) triangles}`` (point indices, gmsh's winding) of the gmsh surfaces
    lying on those faces (see the module docstring); a name none of whose faces is found ->
    :class:`MeshingError` naming it."""
    with _LOCK:
        return _tetrahedralize(shapes, names, edge_length, refinement, grading, min_edge,
                               curvature, named_faces)


def curve_tet10(mesh, shapes: Sequence, names: Sequence[str], edge_length: float,
                refinement: Sequence[tuple] = (), grading: float = 0.5,
                min_edge: float | None = None, curvature: int = 0,
                optimize: int = 0):
    """``mesh`` (a straight TET10 :class:`~designlab.mesh.tetmesh.TetMesh` that
    :func:`tetrahedralize` made from these arguments) with its mid-edge nodes on the B-rep.

    gmsh meshes the bodies again with the same arguments (the same TET4 mesh: the options of
    :data:`DETERMINISTIC`), ``setOrder(2)`` puts each new node of a boundary edge on its B-rep
    curve or surface (``Mesh.SecondOrderLinear`` 0; interior edges stay straight), and each
    mid-node of ``mesh`` takes the position of gmsh's mid-node of the same corner pair. Node
    and cell numbering, regions and facet sets are ``mesh``'s. ``optimize``: gmsh's
    ``Mesh.HighOrderOptimize`` (0 none, the default; 2 elastic + optimisation), which may also
    move interior mid-nodes. A corner or an edge of ``mesh`` not in gmsh's mesh (other
    arguments than the straight mesh's) -> :class:`MeshingError`."""
    from designlab.mesh.tetmesh import TET10_EDGES, TetMesh, edge_keys

    if mesh.order != 2:
        raise MeshingError("curve_tet10 needs a TET10 mesh (TetMesh.quadratic())")
    with _LOCK:
        pts, cells, _ = _tetrahedralize(shapes, names, edge_length, refinement, grading,
                                        min_edge, curvature, None, cell_order=2, optimize=optimize)
    # gmsh corner node -> mesh node, by exact coordinates (the same gmsh run made both)
    corner = np.unique(cells[:, :4])
    ours = np.unique(mesh.cells[:, :4])
    key_g = {pts[i].tobytes(): i for i in corner}
    to_mesh = np.full(len(pts), -1, np.int64)
    missing = 0
    for j in ours:
        i = key_g.get(mesh.points[j].tobytes())
        if i is None:
            missing += 1
        else:
            to_mesh[i] = j
    if missing or len(corner) != len(ours):
        raise MeshingError(f"curve_tet10: gmsh's mesh is not the straight mesh's ({missing} of "
                           f"{len(ours)} corners not found, {len(corner)} gmsh corners): pass "
                           "the arguments that made it")
    n = mesh.n_points
    g_key = edge_keys(to_mesh[cells[:, TET10_EDGES]], n)
    g_mid = cells[:, 4:].reshape(-1)
    m_key = edge_keys(mesh.cells[:, TET10_EDGES], n)
    m_mid = mesh.cells[:, 4:].reshape(-1)
    uk, first = np.unique(g_key, return_index=True)
    pos = np.searchsorted(uk, m_key)
    pos = np.minimum(pos, len(uk) - 1)
    if not np.array_equal(uk[pos], m_key):
        raise MeshingError("curve_tet10: an edge of the straight mesh is not in gmsh's mesh")
    points = mesh.points.copy()
    points[m_mid] = pts[g_mid[first[pos]]]
    return TetMesh(points, mesh.cells, mesh.region, dict(mesh.region_names),
                   dict(mesh.materials), dict(mesh.facet_sets), dict(mesh.point_sets))


def planar_faces(shape) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(point (3,), unit normal (3,)), ...]`` mm of the planar faces of a build123d/OCP
    shape, in the order of its faces (the planes a mesh of it can be curved against:
    :func:`designlab.mesh.curve.curve_boundary`)."""
    from build123d import GeomType, Plane

    out = []
    for face in shape.faces():
        if face.geom_type == GeomType.PLANE:
            pl = Plane(face)
            out.append((np.array(tuple(pl.origin), float), np.array(tuple(pl.z_dir), float)))
    return out


def _face_points(tags: Sequence[int], node_tags: np.ndarray, points: np.ndarray
                 ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Per gmsh surface: its triangles (point indices) and a point inside it (the centroid of
    its largest triangle projected onto the surface)."""
    import gmsh

    tris, inside = {}, {}
    for s in tags:
        types, _, enodes = gmsh.model.mesh.getElements(2, s)
        t = [np.asarray(n, np.int64).reshape(-1, 3) for ty, n in zip(types, enodes) if ty == 2]
        if not t:
            continue
        tri = np.searchsorted(node_tags, np.vstack(t))
        p = points[tri]
        area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        c = p[int(np.argmax(area))].mean(axis=0)
        q, _ = gmsh.model.getClosestPoint(2, s, c.tolist())
        tris[s], inside[s] = tri, np.asarray(q, float)
    return tris, inside


def _named_triangles(named_faces, volumes_of, node_tags, points, diag: float
                     ) -> dict[str, np.ndarray]:
    """``{name: triangles}`` of the gmsh surfaces that lie on each name's B-rep faces."""
    import gmsh
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    from designlab.geometry.tessellate import topods

    # the boundary surfaces of each body's volumes (a named face is one of its own body's)
    surf_of: dict[int, list[int]] = {}
    for k, vols in enumerate(volumes_of):
        faces = gmsh.model.getBoundary([(3, v) for v in vols], combined=False, oriented=False)
        surf_of[k] = sorted({abs(t) for d, t in faces if d == 2})
    tris, inside = _face_points(sorted({s for v in surf_of.values() for s in v}), node_tags,
                                points)
    tol = NAMED_TOL * max(1.0, diag)
    out = {}
    for name, items in named_faces.items():
        found: list[int] = []
        for k, face in items:
            f = topods(face)
            box = Bnd_Box()
            BRepBndLib.Add_s(f, box)
            box.Enlarge(10 * tol)
            for s in surf_of.get(int(k), []):
                if s not in inside or s in found:
                    continue
                q = gp_Pnt(*inside[s])
                if box.IsOut(q):
                    continue
                dist = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(q).Vertex(), f)
                if dist.IsDone() and dist.Value() <= tol:
                    found.append(s)
        if not found:
            raise MeshingError(f"named face set {name!r}: none of its {len(items)} B-rep faces "
                               "is a surface of the meshed bodies")
        found.sort()
        gmsh.model.addPhysicalGroup(2, found, name=name)
        out[name] = np.vstack([tris[s] for s in found])
    return out


def ignore_sigpipe() -> None:
    """Ignore SIGPIPE again, as Python does from its start (a write to a pipe whose reader is
    gone raises BrokenPipeError): gmsh's initialize sets it back to the default, which ends the
    process at such a write without a word (a forked helper killed while a job was on its way
    to it; ``designlab ... | head``). From any thread (``signal.signal`` is the main thread's
    only), through the C library."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return
    libc.signal.restype = ctypes.c_void_p
    libc.signal.argtypes = (ctypes.c_int, ctypes.c_void_p)
    libc.signal(int(signal.SIGPIPE), 1)                 # 1 = SIG_IGN


def _import_bodies(gmsh, shapes, names) -> list[list[tuple[int, int]]]:
    """Each body's B-rep imported into gmsh: its solids' (dim, tag); a body gmsh cannot
    import, or without a solid -> one line naming it."""
    from build123d import export_brep

    inputs: list[list[tuple[int, int]]] = []
    with tempfile.TemporaryDirectory(prefix="designlab-gmsh-") as tmp:
        for i, (shape, name) in enumerate(zip(shapes, names)):
            path = os.path.join(tmp, f"{i}.brep")
            export_brep(shape, path)
            try:
                tags = gmsh.model.occ.importShapes(path, highestDimOnly=True)
            except Exception as exc:
                raise MeshingError(f"body {name!r}: gmsh cannot import its B-rep ({exc})") from None
            tags = [t for t in tags if t[0] == 3]
            if not tags:
                raise MeshingError(f"body {name!r}: no solid in its B-rep")
            inputs.append(tags)
    return inputs


def _fragment(gmsh, inputs, names) -> list[list[int]]:
    """The bodies fragmented into conforming volumes: each body's volume tags, one physical
    group per body; two bodies sharing a volume -> one line with their overlap."""
    flat = [t for tags in inputs for t in tags]
    if len(flat) > 1:
        _, omap = gmsh.model.occ.fragment(flat, [])
    else:
        omap = [flat]
    gmsh.model.occ.synchronize()
    volumes_of: list[list[int]] = []
    pos = 0
    for tags in inputs:
        volumes_of.append(sorted({t for m in omap[pos:pos + len(tags)] for d, t in m if d == 3}))
        pos += len(tags)
    owner: dict[int, int] = {}
    for k, vols in enumerate(volumes_of):
        for v in vols:
            if v in owner:
                mass = gmsh.model.occ.getMass(3, v)
                raise MeshingError(f"bodies {names[owner[v]]!r} and {names[k]!r} overlap by "
                                   f"{mass:.4g} mm^3; regions must not intersect")
            owner[v] = k
    for k, vols in enumerate(volumes_of):
        gmsh.model.addPhysicalGroup(3, vols, tag=k + 1, name=names[k])
    return volumes_of


def _size_field(gmsh, edge_length, refinement, grading, min_edge, curvature) -> None:
    """gmsh's element size: curvature sizing, the global bounds and one Ball field per
    refinement sphere, graded back to the global size."""
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", int(curvature))
    h = float(edge_length)
    finest = min([h] + [float(e) for _, _, e in refinement])
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", float(min_edge) if min_edge else 0.05 * finest)
    if not refinement:
        return
    balls = []
    for c, r, e in refinement:
        f = gmsh.model.mesh.field.add("Ball")
        for key, value in (("XCenter", c[0]), ("YCenter", c[1]), ("ZCenter", c[2]),
                           ("Radius", r), ("VIn", e), ("VOut", h)):
            gmsh.model.mesh.field.setNumber(f, key, float(value))
        gmsh.model.mesh.field.setNumber(f, "Thickness", max((h - e) / grading, 1e-6))
        balls.append(f)
    fmin = gmsh.model.mesh.field.add("Min")
    gmsh.model.mesh.field.setNumbers(fmin, "FieldsList", balls)
    gmsh.model.mesh.field.setAsBackgroundMesh(fmin)


def _generate(gmsh, names, cell_order, optimize) -> None:
    """The 3-D mesh, raised to TET10 with curved mid-side nodes if ``cell_order`` is 2."""
    try:
        gmsh.model.mesh.generate(3)
    except Exception as exc:
        raise MeshingError(f"gmsh failed on bodies {', '.join(names)}: {exc}") from None
    if cell_order == 2:
        gmsh.option.setNumber("Mesh.SecondOrderLinear", 0)
        gmsh.option.setNumber("Mesh.HighOrderOptimize", int(optimize))
        gmsh.model.mesh.setOrder(2)
        if gmsh.option.getNumber("Mesh.SecondOrderLinear") != 0:
            raise MeshingError("gmsh: Mesh.SecondOrderLinear is not 0")


def _cells_of(gmsh, volumes_of, names, cell_order):
    """(node tags sorted, points, cells, region) of the generated mesh; cells index the
    sorted nodes (TET10 in CalculiX's node order)."""
    node_tags, xyz, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, np.int64)
    order = np.argsort(node_tags)
    node_tags = node_tags[order]
    points = np.asarray(xyz, float).reshape(-1, 3)[order]
    cells, region = [], []
    for k, vols in enumerate(volumes_of):
        for v in vols:
            types, _, enodes = gmsh.model.mesh.getElements(3, v)
            for t, nodes in zip(types, enodes):
                if t != (4 if cell_order == 1 else 11):
                    raise MeshingError(f"body {names[k]!r}: gmsh made elements of type {t}, "
                                       f"not tetrahedra of order {cell_order}")
                c = np.searchsorted(node_tags, np.asarray(nodes, np.int64))
                c = (c.reshape(-1, 4) if cell_order == 1
                     else c.reshape(-1, 10)[:, GMSH_TET10_TO_C3D10])
                cells.append(c)
                region.append(np.full(len(c), k, np.int64))
    if not cells or not sum(len(c) for c in cells):
        raise MeshingError(f"gmsh made no tetrahedra for bodies {', '.join(names)}")
    return node_tags, points, np.vstack(cells), np.concatenate(region)


@contextlib.contextmanager
def _gmsh_session():
    """gmsh, initialised here (and finalised after) unless it already is; SIGPIPE stays
    ignored if it was."""
    import gmsh

    own = not gmsh.isInitialized()
    if own:
        ignored = signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        if ignored:
            ignore_sigpipe()
    try:
        yield gmsh
    finally:
        if own:
            gmsh.finalize()
        else:
            gmsh.model.remove()


def _tetrahedralize(shapes, names, edge_length, refinement, grading, min_edge, curvature,
                    named_faces=None, cell_order=1, optimize=0):
    with _gmsh_session() as gmsh:
        for k, v in DETERMINISTIC.items():
            gmsh.option.setNumber(k, v)
        gmsh.model.add("designlab")
        volumes_of = _fragment(gmsh, _import_bodies(gmsh, shapes, names), names)
        _size_field(gmsh, edge_length, refinement, grading, min_edge, curvature)
        _generate(gmsh, names, cell_order, optimize)
        node_tags, points, cells, region = _cells_of(gmsh, volumes_of, names, cell_order)
        if named_faces is None:
            return points, cells, region
        diag = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
        named = _named_triangles(named_faces, volumes_of, node_tags, points, diag)
        return points, cells, region, named
