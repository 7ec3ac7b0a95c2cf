"""Printability checks of a part's bodies before export (FDM, build direction = model +z, mm).

Each printed body must be a valid, watertight solid whose walls are at least a nozzle wide and
whose skins at least a layer thick (measured by rays over the surface area); printed bodies must
not overlap. Bought bodies are not checked. What is measured and why the limits are what they
are: docs/reference/mesh.md.
"""

from __future__ import annotations

import hashlib
import io
import threading
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np
import trimesh

from designlab.errors import DesignlabError, MeshingError
from designlab.geometry.body import Body
from designlab.geometry.tessellate import tessellate, topods

#: a sample's normal with |n_z| above this measures a skin (vertical thickness), else a wall
SKIN_NZ = 0.7
#: embedded bodies of a second extruder need this many nozzle widths (the slicer measurement:
#: docs/reference/mesh.md)
MM_WALL_FACTOR = 2.0
#: a ray measures a wall only where it reaches a face turned back towards it (normals more than
#: 120 deg apart): the chord facets of a curved side meeting a flat bottom at 90 deg are a
#: corner, not a thin wall (without it the default fingertip dome reads 0.8 mm^2 "thin")
WALL_OPPOSED = 0.5
#: thin regions up to this surface area (mm^2) are slivers/wedge tips: a warning, not a failure
THIN_AREA_MM2 = 0.5
#: thinner than this fraction of the required wall/skin a feature is a knife edge or sliver that
#: the slicer leaves out (an opening between two voids, reported as a warning), not a weak wall:
#: a 45 deg wedge where a sensor well meets the ball cavity has 0.6-0.9 mm^2 below one layer,
#: all of it in that band
SLIVER_FRACTION = 0.25
#: overlaps smaller than this fraction of the smaller body (or 1e-3 mm^3) are tessellation noise
OVERLAP_REL = 1e-4


@dataclass(frozen=True)
class BodyReport:
    """Printability of one body. Lengths mm, volumes mm^3."""

    part: str
    body: str
    printed: bool
    extruder: int
    volume_mm3: float = float("nan")
    watertight: bool = False
    manifold: bool = False
    valid_brep: bool = False
    min_wall_mm: float = float("nan")
    min_skin_mm: float = float("nan")
    nozzle_mm: float = 0.4
    layer_mm: float = 0.1
    wall_required_mm: float = 0.4
    #: surface area (mm^2) whose wall / skin is thinner than required (failure above THIN_AREA_MM2)
    thin_wall_mm2: float = float("nan")
    thin_skin_mm2: float = float("nan")
    problems: tuple[str, ...] = field(default_factory=tuple)
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return not self.problems


class PrintabilityError(DesignlabError):
    """Some bodies are not printable; ``reports`` holds every body's report."""

    def __init__(self, reports: list[BodyReport]):
        self.reports = reports
        bad = [f"{r.part}/{r.body}: {'; '.join(r.problems)}" for r in reports if not r.ok]
        super().__init__("not printable, nothing written: " + " | ".join(bad))


def brep_problems(shape) -> list[str]:
    """Problems OpenCascade finds in a solid: invalid topology/geometry, self-intersection."""
    from OCP.BOPAlgo import BOPAlgo_ArgumentAnalyzer
    from OCP.BRepCheck import BRepCheck_Analyzer

    s = topods(shape)
    out = []
    if not BRepCheck_Analyzer(s).IsValid():
        out.append("invalid B-rep (BRepCheck)")
    aa = BOPAlgo_ArgumentAnalyzer()
    aa.SetShape1(s)
    aa.SelfInterMode = True  # all other checks are off by default
    aa.Perform()
    if aa.HasFaulty():
        out.append("self-intersecting solid (BOPAlgo_ArgumentAnalyzer)")
    return out


def manifold_of(mesh: trimesh.Trimesh):
    """``manifold3d.Manifold`` of a merged triangle mesh (status tells whether it is valid)."""
    import manifold3d as m3

    return m3.Manifold(m3.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                               tri_verts=np.asarray(mesh.faces, np.uint32)))


def _surface_samples(mesh: trimesh.Trimesh, max_faces: int,
                     seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Face centroids (all, or a random subset of ``max_faces``) and their outward unit normals:
    the tessellation is finest on small features, so they find the thinnest spot (the *minimum*
    reported; the thin *area* comes from :func:`_area_samples`)."""
    rng = np.random.default_rng(seed)
    nf = len(mesh.faces)
    idx = np.arange(nf) if nf <= max_faces else rng.choice(nf, max_faces, replace=False)
    return mesh.triangles_center[idx], mesh.face_normals[idx]


def _area_samples(mesh: trimesh.Trimesh, per_mm2: float, n_min: int, n_max: int,
                  seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Points drawn uniformly over the surface area (``trimesh.sample.sample_surface``, fixed
    seed), their outward normals and the area (mm^2) each one stands for."""
    n = int(np.clip(mesh.area * per_mm2, n_min, n_max))
    pts, fi = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return pts, mesh.face_normals[fi], float(mesh.area) / max(len(pts), 1)


def ray_backend() -> str:
    """``"embree"`` when the ``embreex`` package is importable (rays cast all at once), else
    ``"vtk"`` (a VTK cell locator, one ray at a time)."""
    try:
        import embreex.rtcore_scene  # noqa: F401
    except ImportError:
        return "vtk"
    return "embree"


def _first_hits_embree(mesh: trimesh.Trimesh, starts: np.ndarray,
                       directions: np.ndarray) -> np.ndarray:
    """Index of the first triangle each ray hits (-1: none), Embree (float32 geometry)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(mesh.triangles, dtype=np.float32))
    return np.asarray(scene.run(np.ascontiguousarray(starts, dtype=np.float32),
                                np.ascontiguousarray(directions, dtype=np.float32)))


def _first_hits_vtk(mesh: trimesh.Trimesh, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Index of the first triangle each segment ``starts -> ends`` hits (-1: none), VTK."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import reference, vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData, vtkStaticCellLocator

    pd = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(mesh.vertices, dtype=np.float64), deep=True))
    pd.SetPoints(pts)
    conn = np.hstack([np.full((len(mesh.faces), 1), 3), mesh.faces]).astype(np.int64).ravel()
    cells = vtkCellArray()
    cells.SetCells(len(mesh.faces), numpy_to_vtkIdTypeArray(conn, deep=True))
    pd.SetPolys(cells)
    loc = vtkStaticCellLocator()
    loc.SetDataSet(pd)
    loc.BuildLocator()
    t, sub, cid = reference(0.0), reference(0), reference(0)
    x, pc = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    out = np.full(len(starts), -1, dtype=np.int64)
    for i in range(len(starts)):
        if loc.IntersectWithLine(starts[i], ends[i], 1e-9, t, x, pc, sub, cid):
            out[i] = cid.get()
    return out


def ray_thickness(mesh: trimesh.Trimesh, points: np.ndarray, normals: np.ndarray,
                  max_depth: float | None = None, opposed: float | None = None,
                  backend: str | None = None) -> np.ndarray:
    """Distance (mm) from each surface point along its inward normal to the opposite wall
    (inf when the ray leaves the bounding box without a hit). With ``opposed``, a hit counts
    only when the wall it reaches faces back (``n_start . n_hit < -opposed``): a ray that
    grazes out through a face at a corner (a 90 deg edge, tessellated with chords) is a corner,
    not a wall; sharp wedges (faces closer than ``acos(opposed)`` to antiparallel) still count;
    without it any wall facing back at all counts.

    ``backend`` (default :func:`ray_backend`) finds the first triangle hit; the distance is that
    of the hit triangle's plane along the ray, in float64, for both backends."""
    backend = backend or ray_backend()
    if backend not in ("embree", "vtk"):
        raise DesignlabError(f"backend={backend!r}: allowed 'embree' or 'vtk'")
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    out = np.full(len(points), np.inf)
    if not len(points):
        return out
    depth = float(max_depth or np.linalg.norm(mesh.extents) * 1.01)
    eps = 1e-5 * max(1.0, depth)
    starts = points - eps * normals
    if backend == "embree":
        hit = _first_hits_embree(mesh, starts, -normals)
    else:
        hit = _first_hits_vtk(mesh, starts, points - depth * normals)
    rays = np.flatnonzero(hit >= 0)
    tri = hit[rays]
    fn = np.asarray(mesh.face_normals)[tri]
    v0 = np.asarray(mesh.triangles)[tri, 0]
    cos = np.einsum("ij,ij->i", fn, normals[rays])       # n_hit . n_start
    keep = cos < 0 if opposed is None else cos <= -opposed
    rays, fn, v0, cos = rays[keep], fn[keep], v0[keep], cos[keep]
    # the ray p - s n reaches the hit plane n_hit . (x - v0) = 0 at s = n_hit.(p - v0) / cos
    dist = eps + np.einsum("ij,ij->i", fn, starts[rays] - v0) / cos
    inside = dist <= depth
    out[rays[inside]] = dist[inside]
    return out


@dataclass(frozen=True)
class FeatureSizes:
    """Smallest wall width and skin thickness seen (mm) and the surface area (mm^2) whose
    wall/skin is thinner than required, measured over the area (even surface samples)."""

    min_wall: float
    min_skin: float
    thin_wall_area: float
    thin_skin_area: float
    samples: int = 0


#: even surface samples per mm^2 for the thin areas (each stands for ~0.02 mm^2), and bounds
AREA_SAMPLES_PER_MM2 = 50.0
AREA_SAMPLES_MIN, AREA_SAMPLES_MAX = 20000, 200000


def feature_sizes(mesh: trimesh.Trimesh, min_wall: float = 0.4, min_skin: float = 0.1,
                  max_faces: int = 20000, seed: int = 0,
                  per_mm2: float = AREA_SAMPLES_PER_MM2) -> FeatureSizes:
    """Thicknesses along the inward normal of surface points whose normal is mostly horizontal
    (wall width) or mostly vertical (skin thickness); ``inf`` when there are none.

    The thin *areas* are measured over the area: points spread evenly over the surface
    (:func:`_area_samples`, fixed seed), each standing for an equal share of the surface area
    (a ray counts only where it reaches a wall facing back, ``WALL_OPPOSED``);
    a point thinner than ``0.99 * min_wall`` / ``0.99 * min_skin`` (1 % slack for tessellation
    chords on exact-size features) adds its share. The minima also include every face centroid
    (the tessellation is finest on small features)."""
    pa, na, share = _area_samples(mesh, per_mm2, AREA_SAMPLES_MIN, AREA_SAMPLES_MAX, seed)
    pc, nc = _surface_samples(mesh, max_faces, seed)
    p, n = np.vstack([pa, pc]), np.vstack([na, nc])
    d = ray_thickness(mesh, p, n, opposed=WALL_OPPOSED)
    skin = np.abs(n[:, 2]) >= SKIN_NZ
    wall = float(d[~skin].min()) if (~skin).any() else float("inf")
    skin_t = float(d[skin].min()) if skin.any() else float("inf")
    k = len(pa)
    da, sa = d[:k], skin[:k]
    # a point thinner than SLIVER_FRACTION of the requirement is a knife edge (two cuts meeting
    # at an angle, a sliver): it does not print at all and opens one void into the other, so
    # it is not a weak wall; the thin area counts the printable-but-weak band above it
    thin_w = share * int(np.count_nonzero(~sa & (da < 0.99 * min_wall)
                                          & (da >= SLIVER_FRACTION * min_wall)))
    thin_s = share * int(np.count_nonzero(sa & (da < 0.99 * min_skin)
                                          & (da >= SLIVER_FRACTION * min_skin)))
    return FeatureSizes(wall, skin_t, thin_w, thin_s, k)


def check_body(part: str, body: Body, nozzle: float = 0.4, layer: float = 0.1,
               mesh: trimesh.Trimesh | None = None, tolerance: float = 0.01,
               angular_tolerance: float = 0.2, min_wall: float | None = None) -> BodyReport:
    """Report on one body; ``mesh`` is its tessellation if already computed; walls must be at
    least ``min_wall`` (default: the nozzle diameter) wide, skins one ``layer`` thick."""
    min_wall = nozzle if min_wall is None else min_wall
    base = dict(part=part, body=body.name, printed=body.printed, extruder=body.extruder,
                nozzle_mm=nozzle, layer_mm=layer, wall_required_mm=min_wall)
    if not body.printed:
        return BodyReport(**base)
    problems = brep_problems(body.shape)
    valid_brep = not problems
    try:
        mesh = mesh if mesh is not None else tessellate(body.shape, tolerance,
                                                        angular_tolerance, check=False)
    except MeshingError as exc:
        return BodyReport(**base, problems=tuple(problems + [str(exc)]))
    watertight = bool(mesh.is_watertight and mesh.is_winding_consistent)
    if not watertight:
        problems.append("mesh not watertight")
    import manifold3d as m3

    is_manifold = manifold_of(mesh).status() == m3.Error.NoError
    if not is_manifold:
        problems.append("not a manifold (manifold3d)")
    volume = float(mesh.volume)
    if not volume > 0:
        problems.append(f"volume {volume:.3g} mm^3 is not positive")
    wall = skin = thin_w = thin_s = float("nan")
    warnings = []
    if watertight and volume > 0:
        fs = feature_sizes(mesh, min_wall, layer)
        wall, skin = fs.min_wall, fs.min_skin
        thin_w, thin_s = fs.thin_wall_area, fs.thin_skin_area
        what = (f"the {nozzle:g} mm nozzle" if min_wall == nozzle else
                f"{min_wall:g} mm ({min_wall / nozzle:g} nozzle widths, embedded extruder "
                f"{body.extruder} body)")
        for kind, value, need, area, text in (
                ("wall", wall, min_wall, fs.thin_wall_area, what),
                ("skin", skin, layer, fs.thin_skin_area, f"a {layer:g} mm layer")):
            if not value < 0.99 * need:
                continue
            # the thin area first and the thinnest point named as such (a bare value after
            # "wall" reads as a shortfall of a few micrometres)
            msg = f"{kind} thinner than {text} over {area:.3g} mm^2 (thinnest {value:.3g} mm)"
            # slivers and wedge tips where two cuts meet: the slicer drops them harmlessly
            (problems if area > THIN_AREA_MM2 else warnings).append(msg)
    return BodyReport(**base, volume_mm3=volume, watertight=watertight, manifold=is_manifold,
                      valid_brep=valid_brep, min_wall_mm=wall, min_skin_mm=skin,
                      thin_wall_mm2=thin_w, thin_skin_mm2=thin_s,
                      problems=tuple(problems), warnings=tuple(warnings))


def overlaps(meshes: Mapping[str, trimesh.Trimesh]) -> dict[tuple[str, str], float]:
    """Intersection volume (mm^3) of every pair of meshes that overlap beyond tessellation noise."""
    names = list(meshes)
    mani = {k: manifold_of(m) for k, m in meshes.items()}
    out = {}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            va = mani[a].volume()
            vb = mani[b].volume()
            inter = (mani[a] ^ mani[b]).volume()
            if inter > max(1e-3, OVERLAP_REL * min(va, vb)):
                out[(a, b)] = float(inter)
    return out


#: per-body reports (with their tessellation) kept in this process, newest last
_BODY_CACHE: "OrderedDict[str, tuple[BodyReport, trimesh.Trimesh | None]]" = OrderedDict()
_BODY_CACHE_SIZE = 24
#: Dask's threaded workers may check parts at the same time
_BODY_LOCK = threading.Lock()


def _body_key(part: str, body: Body, nozzle: float, layer: float, min_wall: float) -> str:
    """SHA-256 of what a body's report depends on: its B-rep (binary, no triangulation), names,
    the check's settings and this module's rule constants (tests patch them). A few flag bits of
    the binary form change once a shape is tessellated or checked: the same body has one key
    before and one after, both point to the same report."""
    from OCP.BinTools import BinTools, BinTools_FormatVersion

    buf = io.BytesIO()
    BinTools.Write_s(topods(body.shape), buf, False, False,
                     BinTools_FormatVersion.BinTools_FormatVersion_CURRENT)
    h = hashlib.sha256(buf.getvalue())
    h.update(repr((part, body.name, body.printed, body.extruder, nozzle, layer, min_wall,
                   SKIN_NZ, WALL_OPPOSED, THIN_AREA_MM2, SLIVER_FRACTION, AREA_SAMPLES_PER_MM2,
                   AREA_SAMPLES_MIN, AREA_SAMPLES_MAX, ray_backend())).encode())
    return h.hexdigest()


def clear_cache() -> None:
    """Forget the per-body reports kept in this process."""
    with _BODY_LOCK:
        _BODY_CACHE.clear()


def _checked(part: str, body: Body, nozzle: float, layer: float, min_wall: float,
             mesh: trimesh.Trimesh | None) -> tuple[BodyReport, trimesh.Trimesh | None]:
    """(report, tessellation) of a printed body; a body with no ``mesh`` given comes from the
    cache when the same B-rep was checked with the same settings in this process."""
    key = None
    if mesh is None:
        key = _body_key(part, body, nozzle, layer, min_wall)
        with _BODY_LOCK:
            hit = _BODY_CACHE.get(key)
            if hit is not None:
                _BODY_CACHE.move_to_end(key)
                return hit
        try:
            mesh = tessellate(body.shape, check=False)
        except MeshingError:
            mesh = None  # check_body reports it
    report = check_body(part, body, nozzle, layer, mesh, min_wall=min_wall)
    if key is not None:
        # tessellating and checking a shape flip flags of its edges in OpenCascade's binary form:
        # the same body seen again after either is found under its second key
        keys = {key, _body_key(part, body, nozzle, layer, min_wall)}
        with _BODY_LOCK:
            for k in keys:
                _BODY_CACHE[k] = (report, mesh)
            while len(_BODY_CACHE) > _BODY_CACHE_SIZE:
                _BODY_CACHE.popitem(last=False)
    return report, mesh


def check_part(part: str, bodies: Mapping[str, Body], nozzle: float = 0.4, layer: float = 0.1,
               meshes: Mapping[str, trimesh.Trimesh] | None = None) -> list[BodyReport]:
    """Reports for every body of a part (bought bodies included, unchecked), with overlaps of
    printed bodies added to both bodies' problems. Bodies without a mesh in ``meshes`` are
    tessellated here (and their reports cached per process, docs/reference/mesh.md)."""
    given = dict(meshes or {})
    host = min((b.extruder for b in bodies.values() if b.printed), default=1)
    reports, meshes = {}, {}
    for name, b in bodies.items():
        min_wall = nozzle * (MM_WALL_FACTOR if b.extruder != host else 1.0)
        if not b.printed:
            reports[name] = check_body(part, b, nozzle, layer, min_wall=min_wall)
            continue
        reports[name], mesh = _checked(part, b, nozzle, layer, min_wall, given.get(name))
        if mesh is not None:
            meshes[name] = mesh
    printed = {n: meshes[n] for n, r in reports.items()
               if r.printed and r.watertight and r.manifold and n in meshes}
    for (a, b), vol in overlaps(printed).items():
        for x, y in ((a, b), (b, a)):
            r = reports[x]
            reports[x] = replace(r, problems=r.problems + (f"overlaps {y} by {vol:.3g} mm^3",))
    return list(reports.values())


def reports_table(reports: list[BodyReport]):
    """A rich table of printability reports (one row per body)."""
    from rich.table import Table

    def mm(x: float) -> str:
        return "-" if x != x else ("inf" if x == float("inf") else f"{x:.3g}")

    t = Table(title="printability (build direction +z)")
    for col in ("part", "body", "ext.", "volume mm^3", "watertight", "manifold",
                "min wall mm", "min skin mm", "status"):
        t.add_column(col, justify="right" if "mm" in col else "left")
    for r in reports:
        if not r.printed:
            t.add_row(r.part, r.body, "-", "-", "-", "-", "-", "-", "[dim]bought, not printed[/]")
            continue
        status = "[green]ok[/]" if r.ok else "[red]" + "; ".join(r.problems) + "[/]"
        if r.warnings:
            status += " [yellow](" + "; ".join(r.warnings) + ")[/]"
        t.add_row(r.part, r.body, str(r.extruder), f"{r.volume_mm3:.4g}",
                  "yes" if r.watertight else "no", "yes" if r.manifold else "no",
                  f"{mm(r.min_wall_mm)} (>= {r.wall_required_mm:g})",
                  f"{mm(r.min_skin_mm)} (>= {r.layer_mm:g})", status)
    return t
