"""Bodies -> one conforming, region-tagged tetrahedral mesh, mm.

gmsh meshes the bodies' exact B-rep (deterministic, :mod:`designlab.mesh.brep`); fTetWild
meshes triangle soups and is the fallback when gmsh fails. Every attempt's region volumes are
checked against the bodies' B-rep volumes; a part no attempt meshes is a one-line
:class:`MeshingError` naming the body to blame. The method, envelopes and element sizes:
docs/reference/mesh.md.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import threading
import time
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from designlab.errors import MeshingError, ParameterError
from designlab.params import did_you_mean
from designlab.geometry.body import Body, FacetSelector
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh
from designlab.mesh.facets import interface_facets, select_facets

#: the meshers: gmsh from the B-rep (auto: gmsh, fTetWild if gmsh fails), fTetWild
MESHERS = ("auto", "gmsh", "tetwild")
#: quality presets: (edge length factor, fTetWild stop energy)
PRESETS = {"coarse": (2.0, 25.0), "default": (1.0, 15.0), "fine": (0.7, 10.0)}
#: linear cells a default edge length aims at (TET10 of that: ~1e5 DOF)
TARGET_CELLS = 12_000
#: cells per mm^3 of a mesh of regular-ish tetrahedra with unit edge length
_CELLS_PER_EDGE3 = 8.5


@dataclass(frozen=True)
class MeshResult:
    """A mesh with what it took to make it: settings of the successful attempt and log."""

    mesh: TetMesh
    edge_length: float
    epsilon: float
    stop_energy: float
    #: exact B-rep volume of each body, mm^3
    body_volumes: dict[str, float]
    attempts: list[str] = field(default_factory=list)
    seconds: float = 0.0
    #: "gmsh" (from the B-rep) or "tetwild" (fTetWild on the tessellation)
    mesher: str = "gmsh"
    #: facet sets taken from named B-rep faces (the others come from the facet predicates)
    named_sets: tuple[str, ...] = ()
    #: gmsh's curvature sizing of the successful attempt (elements per 2 pi of a curved face's
    #: radius; 0: the size field alone), and the refinement spheres it was given (centre,
    #: radius, edge; the quality preset applied): with ``edge_length``, the arguments that
    #: make the same mesh again (:func:`designlab.mesh.brep.curve_tet10`)
    curvature: int = 0
    refinement: tuple = ()

    def region_volumes(self) -> dict[str, float]:
        """Mesh volume of each region, mm^3."""
        v = self.mesh.corner_volumes
        return {name: float(v[self.mesh.region == rid].sum())
                for rid, name in self.mesh.region_names.items()}

    def report(self) -> dict:
        """JSON-ready summary: sizes, settings, quality, region volumes, facet set sizes."""
        from designlab.mesh.quality import mesh_quality

        m = self.mesh
        got = self.region_volumes()
        return {
            "mesher": self.mesher, "n_points": m.n_points, "n_cells": m.n_cells, "order": m.order,
            "dof": 3 * m.n_points, "edge_length_mm": self.edge_length,
            "epsilon_mm": self.epsilon, "stop_energy": self.stop_energy,
            "seconds": self.seconds, "attempts": list(self.attempts),
            "materials": dict(m.materials),
            "regions": {name: {"id": rid, "cells": int((m.region == rid).sum()),
                               "volume_mm3": got[name],
                               "body_volume_mm3": self.body_volumes[name],
                               "volume_error_percent":
                                   100.0 * (got[name] / self.body_volumes[name] - 1.0)}
                        for rid, name in m.region_names.items()},
            "facet_sets": {k: int(len(v)) for k, v in m.facet_sets.items()},
            "facet_sets_from_brep_faces": list(self.named_sets),
            "quality": mesh_quality(m).as_dict(),
        }


def save_mesh(result: MeshResult, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``mesh.vtu`` and ``mesh.json`` (:meth:`MeshResult.report`) into ``out_dir`` as a
    set: both or neither (a full disk leaves the previous pair and no empty folder)."""
    from designlab.atomic import FileSet
    from designlab.mesh.io import vtu_bytes

    out = Path(out_dir)
    report = result.report()
    data = vtu_bytes(result.mesh)
    with FileSet() as files:
        vtu = files.write_bytes(out / "mesh.vtu", data)
        files.write_json(out / "mesh.json", report, indent=2)
    return vtu, out / "mesh.json"


# --------------------------------------------------------------------------- geometry helpers

def _solid_angle_sum(points: np.ndarray, tri: np.ndarray, chunk: int = 400_000) -> np.ndarray:
    """Exact winding number of triangles ``tri`` (t, 3, 3) at ``points`` (van Oosterom-Strackee
    solid angles / 4 pi), vectorised in chunks of point x triangle pairs."""
    out = np.empty(len(points))
    step = max(1, chunk // max(len(tri), 1))
    for s in range(0, len(points), step):
        q = points[s:s + step, None, :]
        a, b, c = tri[None, :, 0] - q, tri[None, :, 1] - q, tri[None, :, 2] - q
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("...i,...i->...", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("...i,...i->...", a, b) * lc
               + np.einsum("...i,...i->...", b, c) * la + np.einsum("...i,...i->...", c, a) * lb)
        out[s:s + step] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def winding_number(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                   leaf: int = 16, beta: float = 2.0) -> np.ndarray:
    """Generalised winding number of a closed triangle surface at each point (1 inside, 0
    outside). Triangles are grouped in grid clusters of about ``leaf``; a cluster farther than
    ``beta`` times its radius contributes its dipole term (Barill et al. 2018 fast winding
    numbers, first order), nearer ones their exact solid angles."""
    points = np.asarray(points, float)
    tri = np.asarray(vertices, float)[np.asarray(faces)]
    if len(tri) <= 4 * leaf or len(points) == 0:
        return _solid_angle_sum(points, tri)
    cen = tri.mean(axis=1)
    lo, hi = cen.min(axis=0), cen.max(axis=0)
    vec_area = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(vec_area, axis=1) + 1e-300
    cell = max(float(np.sqrt(area.sum() * leaf / len(tri))), float((hi - lo).max()) / 128.0)
    key = np.floor((cen - lo) / cell).astype(np.int64)
    _, cluster = np.unique(key, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    order = np.argsort(cluster, kind="stable")
    bounds = np.searchsorted(cluster[order], np.arange(cluster.max() + 2))
    out = np.zeros(len(points))
    for c in range(len(bounds) - 1):
        members = order[bounds[c]:bounds[c + 1]]
        if len(members) == 0:
            continue
        w = area[members]
        centre = (cen[members] * w[:, None]).sum(axis=0) / w.sum()
        radius = np.linalg.norm(tri[members] - centre, axis=2).max()
        dipole = vec_area[members].sum(axis=0)
        r = centre - points
        dist = np.linalg.norm(r, axis=1)
        far = dist > beta * radius
        out[far] += (r[far] @ dipole) / (4.0 * np.pi * dist[far] ** 3)
        near = np.flatnonzero(~far)
        if len(near):
            out[near] += _solid_angle_sum(points[near], tri[members])
    return out


def sizing_field(lo: np.ndarray, hi: np.ndarray, edge_length: float,
                 refinement: Sequence[tuple], grading: float = 0.5,
                 max_points: int = 120_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Background tet grid over the box ``[lo, hi]`` with target edge length at each node:
    ``min(edge_length, e_k + grading * max(0, |x - c_k| - r_k))`` over the spheres k."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    size = hi - lo
    finest = min(min(r for _, r, _ in refinement) / 2.0, edge_length)
    spacing = max(finest, (np.prod(size) / max_points) ** (1.0 / 3.0))
    n = np.maximum(1, np.ceil(size / spacing).astype(int))
    grid = box_tet_mesh(*size, *n, origin=lo)
    pts = grid.points
    value = np.full(len(pts), float(edge_length))
    for centre, radius, e in refinement:
        d = np.linalg.norm(pts - np.asarray(centre, float), axis=1)
        value = np.minimum(value, e + grading * np.maximum(0.0, d - radius))
    return pts, grid.cells.astype(np.int32), value


def _check_refinement(refinement: Iterable) -> list[tuple[np.ndarray, float, float]]:
    out = []
    for k, item in enumerate(refinement):
        try:
            centre, radius, e = item
            centre = np.asarray(centre, float).reshape(3)
            radius, e = float(radius), float(e)
        except (TypeError, ValueError):
            raise ParameterError(f"refinement[{k}]", item,
                                 "(centre (3,), radius mm, edge length mm)") from None
        if not (np.isfinite(centre).all() and radius > 0 and e > 0):
            raise ParameterError(f"refinement[{k}]", item, "finite centre, radius > 0, edge > 0")
        out.append((centre, radius, e))
    return out


def _as_bodies(bodies: Mapping[str, Body] | Sequence[Body]) -> list[Body]:
    items = list(bodies.values()) if isinstance(bodies, Mapping) else list(bodies)
    if not items:
        raise MeshingError("nothing to mesh: no bodies given")
    names = [b.name for b in items]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise MeshingError(f"body names must be unique, repeated: {', '.join(sorted(dup))}")
    return items


def _tessellate(body: Body, tolerance: float, angular_tolerance: float):
    from designlab.geometry.tessellate import tessellate

    try:
        return tessellate(body.shape, tolerance, angular_tolerance)
    except MeshingError as exc:
        raise MeshingError(f"body {body.name!r}: {exc}") from None


def _union(bodies: list[Body], tolerance: float, angular_tolerance: float):
    """Tessellated boundary of the union of the bodies (OpenCascade fuse)."""
    from designlab.geometry.tessellate import tessellate

    from build123d import Compound

    shapes = [b.shape for b in bodies]
    fused = shapes[0].fuse(*shapes[1:]) if len(shapes) > 1 else shapes[0]
    if not hasattr(fused, "wrapped"):  # disjoint solids come back as a ShapeList
        fused = Compound(list(fused))
    try:
        return tessellate(fused, tolerance, angular_tolerance)
    except MeshingError as exc:
        raise MeshingError(f"union of bodies {', '.join(b.name for b in bodies)}: {exc}") from None


# --------------------------------------------------------------------------- meshing core

def _tetwild_call(vertices, faces, edge_length, epsilon, stop_energy, sizing, threads):
    import pytetwild

    diag = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    kw = {}
    if sizing is not None:
        kw = dict(bg_vertices=sizing[0], bg_tets=sizing[1], bg_values=sizing[2])
    points, cells = pytetwild.tetrahedralize(
        np.ascontiguousarray(vertices, float), np.ascontiguousarray(faces, np.int32),
        edge_length_abs=edge_length, epsilon=epsilon / diag, stop_energy=stop_energy,
        num_threads=threads, quiet=True, **kw)
    return np.asarray(points, float), np.asarray(cells, np.int64)


#: fTetWild writes ``__tracked_surface.stl`` into the working directory (no option to move it):
#: it runs in a temporary one, removed afterwards. The working directory is the process's, so
#: an in-process run (``isolate=False``) holds this lock while it is changed
_CWD_LOCK = threading.Lock()


@contextlib.contextmanager
def _in_temp_dir():
    """Run the body in a fresh temporary working directory, then go back and remove it."""
    with _CWD_LOCK, tempfile.TemporaryDirectory(prefix="designlab-tetwild-") as tmp:
        here = os.getcwd()
        os.chdir(tmp)
        try:
            yield tmp
        finally:
            os.chdir(here)


def _child(conn, args, parent_pid=None, call=None):
    from designlab.atomic import die_with_parent

    die_with_parent(parent_pid)            # a killed caller takes fTetWild with it
    call = call or _tetwild_call
    try:
        with _in_temp_dir():
            result = call(*args)
        conn.send(("ok", result))
    except BaseException as exc:  # reported to the parent, which decides
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _tetwild(vertices, faces, edge_length, epsilon, stop_energy, sizing, threads,
             isolate: bool = True):
    """fTetWild in a child process (``isolate``): a C++ abort inside fTetWild then becomes a
    ``MeshingError`` here instead of killing the caller. Either way it runs in a temporary
    working directory (``isolate=False``: this process's, changed while it runs; other threads
    that use relative paths meanwhile would see it), nothing is left in the caller's."""
    import multiprocessing as mp

    args = (vertices, faces, edge_length, epsilon, stop_energy, sizing, threads)
    if not isolate:
        with _in_temp_dir():
            return _tetwild_call(*args)
    # a fresh interpreter, not a fork: forking a process that runs solver/VTK threads can copy
    # a lock held by one of them into the child, which then waits for ever (seen in the tests)
    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, args, os.getpid(), _tetwild_call), daemon=True)
    proc.start()
    send.close()
    try:
        status, payload = recv.recv()
    except EOFError:
        proc.join()
        raise MeshingError(f"fTetWild crashed (exit code {proc.exitcode})") from None
    finally:
        recv.close()
    proc.join()
    if status != "ok":
        raise MeshingError(str(payload))
    return payload


def compact(points: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop unused nodes, renumber compactly and flip negatively oriented cells (swap 1, 2)."""
    used, inverse = np.unique(cells, return_inverse=True)
    pts, cells = points[used], inverse.reshape(cells.shape).astype(np.int64)
    p = pts[cells]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    cells[vol < 0] = cells[vol < 0][:, [0, 2, 1, 3]]
    return pts, cells


def tag_regions(points: np.ndarray, cells: np.ndarray, surfaces: Sequence, host: int,
                pad: float) -> np.ndarray:
    """Index of the body containing each cell's centroid; cells in none go to ``host``."""
    cen = points[cells].mean(axis=1)
    region = np.full(len(cells), host, np.int64)
    best = np.full(len(cells), 0.5)
    for k, s in enumerate(surfaces):
        if k == host:
            continue
        lo, hi = s.bounds[0] - pad, s.bounds[1] + pad
        idx = np.flatnonzero(np.all((cen >= lo) & (cen <= hi), axis=1))
        if len(idx) == 0:
            continue
        w = winding_number(cen[idx], s.vertices, s.faces)
        win = w > best[idx]
        region[idx[win]], best[idx[win]] = k, w[win]
    return region


def _attempts(h: float, eps: float, energy: float) -> list[tuple[float, float, float]]:
    """The settings tried in turn: as given, tighter envelope, then finer and more relaxed."""
    return [(h, eps, energy), (h, eps / 3.0, energy), (0.75 * h, eps / 3.0, 2.0 * energy)]


@dataclass
class _Job:
    """What every meshing attempt of one call shares: the bodies, their B-rep volumes and
    extent, the facet-set settings, the log and the start time."""

    items: list[Body]
    volumes: np.ndarray
    t_body: np.ndarray
    host: int
    lo: np.ndarray
    hi: np.ndarray
    refinement: list
    facet_sets: Mapping[str, FacetSelector] | None
    interfaces: bool
    order: int
    volume_rtol: float
    t0: float
    log: list[str] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [b.name for b in self.items]

    @property
    def diag(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))

    def failure(self, head: str, edge_length: float, refinement) -> str:
        return _failure(head, self.log, self.items, self.volumes, edge_length, refinement,
                        self.volume_rtol)


def _check_settings(order: int, quality: str, edge_length, epsilon, mesher: str) -> None:
    """One line for the first setting out of range."""
    if order not in (1, 2):
        raise ParameterError("order", order, "1 (TET4) or 2 (TET10)")
    if quality not in PRESETS:
        raise ParameterError("quality", quality, "one of " + ", ".join(PRESETS))
    if edge_length is not None and not (np.isfinite(edge_length) and edge_length > 0):
        raise ParameterError("edge_length", edge_length, "a number > 0 mm")
    if epsilon is not None and not (np.isfinite(epsilon) and epsilon > 0):
        raise ParameterError("epsilon", epsilon, "a number > 0 mm")
    if mesher not in MESHERS:
        raise ParameterError("mesher", mesher, "one of " + ", ".join(MESHERS)
                             + did_you_mean(mesher, MESHERS))


def _job_of(bodies, refinement: list, facet_sets, interfaces: bool, order: int,
            volume_rtol: float, t0: float) -> _Job:
    """The bodies with their B-rep volumes, thicknesses ``2 V / A``, host and bounding box;
    a body without volume -> one line."""
    items = _as_bodies(bodies)
    brep = np.array([(float(b.shape.volume), float(b.shape.area)) for b in items])
    if not (brep[:, 0] > 0).all():
        k = int(np.argmin(brep[:, 0]))
        raise MeshingError(f"body {items[k].name!r} has no volume ({brep[k, 0]:.4g} mm^3): "
                           f"not a solid")
    boxes = [b.shape.bounding_box() for b in items]
    lo = np.min([tuple(bb.min) for bb in boxes], axis=0)
    hi = np.max([tuple(bb.max) for bb in boxes], axis=0)
    return _Job(items, brep[:, 0], 2.0 * brep[:, 0] / brep[:, 1], int(np.argmax(brep[:, 0])),
                lo, hi, refinement, facet_sets, interfaces, order, volume_rtol, t0)


def _finish(job: _Job, points, cells, region, h, e, se, which, named=None,
            curvature=0) -> MeshResult:
    """The MeshResult of an accepted attempt: facet sets (named B-rep faces first, then the
    predicates, then the interfaces between regions), TET10 if asked."""
    names = job.names
    region_names = {k: n for k, n in enumerate(names)}
    mesh = TetMesh(points, cells, region, region_names, {b.name: b.material for b in job.items})
    boundary = mesh.boundary_facets()
    from_faces = boundary_sets(boundary, named or {})
    sets = select_facets(points, boundary, {k: v for k, v in (job.facet_sets or {}).items()
                                            if k not in from_faces})
    sets.update(from_faces)
    if job.interfaces and len(job.items) > 1:
        for name, tri in interface_facets(cells, region, region_names).items():
            sets.setdefault(name, tri)
    mesh = TetMesh(points, cells, region, region_names, dict(mesh.materials), sets)
    if job.order == 2:
        mesh = mesh.quadratic()
    return MeshResult(mesh, h, e, se, {n: float(v) for n, v in zip(names, job.volumes)},
                      job.log, time.perf_counter() - job.t0, which, tuple(sorted(from_faces)),
                      curvature=curvature, refinement=tuple(job.refinement))


def _volume_error(job: _Job, points, cells, region, what: str) -> bool:
    """True (and a log line) if a region's volume is off its body's by more than the
    tolerance."""
    p = points[cells]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                    p[:, 3] - p[:, 0]) / 6.0
    got = np.bincount(region, weights=vol, minlength=len(job.items))
    err = np.abs(got - job.volumes) / job.volumes
    if err.max() > job.volume_rtol:
        k = int(np.argmax(err))
        job.log.append(f"{what}: body {job.names[k]!r} meshed to {got[k]:.4g} mm^3 instead of "
                       f"{job.volumes[k]:.4g} mm^3")
        return True
    return False


def _gmsh_try(job: _Job, h: float, curvature: int, named_in) -> tuple | None:
    """One gmsh attempt: (points, cells, region, named triangles) or None (logged); an
    intersection of regions is raised."""
    from designlab.mesh import brep

    what = f"gmsh: edge {h:.3g} mm, curvature {curvature}"
    shapes = [b.shape for b in job.items]
    try:
        if named_in:
            return brep.tetrahedralize(shapes, job.names, h, job.refinement,
                                       curvature=curvature, named_faces=named_in)
        return (*brep.tetrahedralize(shapes, job.names, h, job.refinement,
                                     curvature=curvature), None)
    except MeshingError as exc:
        job.log.append(f"{what}: {_one_line(exc, 300)}")
        if "regions must not intersect" in str(exc):
            raise
    except Exception as exc:  # gmsh reports its own failures as plain exceptions
        job.log.append(f"{what}: gmsh error ({type(exc).__name__}: {_one_line(exc, 300)})")
    return None


def _mesh_gmsh(job: _Job, edge_length: float, named_in) -> MeshResult | None:
    """gmsh from the B-rep: the size field alone, then curvature sizing, then finer; the
    first attempt whose regions have their bodies' volumes, or None."""
    for h, curvature in ((edge_length, 0), (edge_length, 12), (0.6 * edge_length, 12)):
        what = f"gmsh: edge {h:.3g} mm, curvature {curvature}"
        got = _gmsh_try(job, h, curvature, named_in)
        if got is None:
            continue
        points, cells, region, named = got
        if named:
            renumber = np.full(len(points), -1, np.int64)
            used = np.unique(cells)
            renumber[used] = np.arange(len(used))
            named = {k: renumber[t] for k, t in named.items()}
        points, cells = compact(points, cells)
        if _volume_error(job, points, cells, region, what):
            continue
        job.log.append(f"{what}: ok, {len(cells)} cells")
        try:
            return _finish(job, points, cells, region, h, 0.0, float("nan"), "gmsh", named,
                           curvature)
        except MeshingError as exc:  # a small facet set no triangle of this mesh hits
            job.log[-1] = f"{what}: {exc}"
    return None


def _tetwild_surface(job: _Job, tol: float, angular_tolerance: float):
    """fTetWild's input: the bodies' tessellations, and one triangle soup of their union's
    boundary with every body's surface but the host's; overlapping bodies -> one line."""
    items, host = job.items, job.host
    surfaces = [_tessellate(b, tol, angular_tolerance) for b in items]
    if len(items) == 1:
        return surfaces, np.asarray(surfaces[0].vertices), np.asarray(surfaces[0].faces)
    union = _union(items, tol, angular_tolerance)
    tess_sum = sum(s.volume for s in surfaces)
    overlap = tess_sum - union.volume
    if overlap > 1e-3 * tess_sum + 1e-9:
        raise MeshingError(f"bodies {', '.join(b.name for b in items)} overlap by "
                           f"{overlap:.4g} mm^3; regions must not intersect")
    parts = [union] + [s for k, s in enumerate(surfaces) if k != host]
    verts = np.vstack([s.vertices for s in parts])
    offsets = np.cumsum([0] + [len(s.vertices) for s in parts[:-1]])
    faces = np.vstack([s.faces + o for s, o in zip(parts, offsets)])
    return surfaces, verts, faces


def _mesh_tetwild(job: _Job, edge_length: float, eps: float, energy: float, surface,
                  threads: int, isolate: bool) -> MeshResult | None:
    """fTetWild on the tessellation over :func:`_attempts`; regions by winding number; the
    first attempt whose regions have their bodies' volumes, or None."""
    surfaces, verts, faces = surface
    for h, e, se in _attempts(edge_length, eps, energy):
        sizing = None
        if job.refinement:
            pad = 2.0 * h
            sizing = sizing_field(job.lo - pad, job.hi + pad, h, job.refinement)
        what = f"edge {h:.3g} mm, epsilon {e:.3g} mm, stop energy {se:g}"
        try:
            points, cells = _tetwild(verts, faces, h, e, se, sizing, threads, isolate)
        except Exception as exc:  # fTetWild reports failures as generic C++ exceptions
            job.log.append(f"{what}: fTetWild failed ({type(exc).__name__}: "
                           f"{_one_line(exc, 300)})")
            continue
        if len(cells) == 0:
            job.log.append(f"{what}: fTetWild returned no cells")
            continue
        points, cells = compact(points, cells)
        region = tag_regions(points, cells, surfaces, job.host, pad=e)
        if _volume_error(job, points, cells, region, f"fTetWild: {what}"):
            continue
        job.log.append(f"fTetWild: {what}: ok, {len(cells)} cells")
        return _finish(job, points, cells, region, h, e, se, "tetwild")
    return None


def mesh_bodies_detailed(bodies: Mapping[str, Body] | Sequence[Body],
                         facet_sets: Mapping[str, FacetSelector] | None = None, *,
                         edge_length: float | None = None, refinement: Iterable = (),
                         order: int = 2, quality: str = "default",
                         epsilon: float | None = None, stop_energy: float | None = None,
                         tessellation_tolerance: float | None = None,
                         angular_tolerance: float = 0.5, volume_rtol: float = 0.05,
                         interfaces: bool = True, threads: int = 1, isolate: bool = True,
                         target_cells: int = TARGET_CELLS, mesher: str = "auto",
                         named_faces: Mapping[str, Sequence[tuple[str, Any]]] | None = None
                         ) -> MeshResult:
    """Mesh bodies into one conforming TET4/TET10 mesh (the method: docs/reference/mesh.md).

    mesher:      ``auto`` (gmsh from the B-rep, fTetWild if gmsh fails), ``gmsh`` or ``tetwild``
    named_faces: ``{set name: [(body name, B-rep face), ...]}``: on the gmsh path these sets are
                 the boundary triangles on those faces, replacing a predicate of the same name
                 in ``facet_sets`` (which stays the fallback, e.g. for fTetWild)

    edge_length: ideal edge length, mm (default: the smaller of 1.5 x the host's thickness
                 ``2 V / A`` and the size for ``target_cells``; scaled by the ``quality`` preset)
    refinement:  ``(centre (3,) mm, radius mm, edge_length mm)`` spheres of finer elements
    quality:     ``coarse`` (fast, tests), ``default`` or ``fine``: scales the default and the
                 refinement edge lengths (x2, x1, x0.7) and sets fTetWild's stop energy
    epsilon:     fTetWild envelope, mm (default a tenth of the thinnest body, <= 1e-3 diagonal)
    tessellation_tolerance: chordal tolerance of the surfaces, mm (default epsilon / 2,
                 >= 0.01); ``angular_tolerance`` in rad
    volume_rtol: largest accepted relative error of a region's volume
    threads:     fTetWild threads (0 = all cores)
    isolate:     run fTetWild in a forked process so that a crash in it is a MeshingError
    """
    t0 = time.perf_counter()
    _check_settings(order, quality, edge_length, epsilon, mesher)
    factor, energy = PRESETS[quality]
    refinement = [(c, r, factor * e) for c, r, e in _check_refinement(refinement)]
    job = _job_of(bodies, refinement, facet_sets, interfaces, order, volume_rtol, t0)
    if edge_length is None:
        h_vol = (_CELLS_PER_EDGE3 * job.volumes.sum() / target_cells) ** (1.0 / 3.0)
        edge_length = factor * min(1.5 * job.t_body[job.host], h_vol)
    edge_length = float(edge_length)
    names = job.names
    named_in = _named_faces_by_index(named_faces, names)
    if mesher in ("auto", "gmsh"):
        result = _mesh_gmsh(job, edge_length, named_in)
        if result is not None:
            return result
        if mesher == "gmsh":
            raise MeshingError(job.failure(f"meshing bodies {', '.join(names)} with gmsh failed",
                                           edge_length, refinement))
    eps = float(epsilon) if epsilon is not None else float(
        np.clip(0.1 * job.t_body.min(), 1e-5 * job.diag, 1e-3 * job.diag))
    tol = float(tessellation_tolerance) if tessellation_tolerance else max(0.5 * eps, 0.01)
    surface = _tetwild_surface(job, tol, angular_tolerance)
    if stop_energy is not None:
        energy = float(stop_energy)
    result = _mesh_tetwild(job, edge_length, eps, energy, surface, threads, isolate)
    if result is not None:
        return result
    raise MeshingError(job.failure(f"meshing bodies {', '.join(names)} failed", edge_length,
                                   refinement if mesher != "tetwild" else None))


def _named_faces_by_index(named_faces, names: list[str]) -> dict[str, list[tuple[int, Any]]]:
    """``named_faces`` with body names turned into body indices; an unknown body -> one line."""
    out: dict[str, list[tuple[int, Any]]] = {}
    for set_name, items in (named_faces or {}).items():
        for body, face in items:
            if body not in names:
                raise MeshingError(f"named face set {set_name!r}: body {body!r} is not meshed "
                                   f"(meshed: {', '.join(names)})")
            out.setdefault(set_name, []).append((names.index(body), face))
    return out


def boundary_sets(boundary: np.ndarray, triangles: Mapping[str, np.ndarray]
                  ) -> dict[str, np.ndarray]:
    """``{name: the rows of boundary}`` (outward corner triangles) whose three corners are those
    of a triangle of ``triangles[name]`` (any winding); a name none of whose triangles is on the
    boundary (an interface between two bodies) is left out."""
    if not triangles:
        return {}
    n = int(max(boundary.max(), max(int(t.max()) for t in triangles.values() if len(t)))) + 1

    def key(t):
        s = np.sort(np.asarray(t)[:, :3], axis=1).astype(np.int64)
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]

    kb = key(boundary)
    out = {}
    for name, tri in triangles.items():
        mask = np.isin(kb, key(tri))
        if mask.any():
            out[name] = boundary[mask]
    return out


def _one_line(text: str, limit: int = 200) -> str:
    """``text`` on one line (whitespace runs -> one space), cut to ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _failure(head: str, log: list[str], items: list[Body], volumes: np.ndarray,
             edge_length: float, refinement, volume_rtol: float) -> str:
    """One line for a part no mesher could mesh: which body fails and why, how many attempts
    of each mesher, the last one's reason. The body is the one an attempt named (a volume check,
    an import); else, when gmsh was tried (``refinement`` not None), the first body gmsh cannot
    mesh on its own; if each meshes alone, their interfaces are to blame."""
    import re

    named = [m.group(1) for line in log for m in [re.search(r"body '([^']+)'", line)] if m]
    culprit = None
    if named:
        body = max(dict.fromkeys(named), key=named.count)       # the most blamed, first named
        why = next(_one_line(line.split(f"body {body!r}", 1)[1].lstrip(": "), 120)
                   for line in reversed(log) if f"body {body!r}" in line)
        culprit = f"body {body!r}: {why}"
    elif refinement is not None and len(items) > 1:
        culprit = _gmsh_alone(items, volumes, edge_length, refinement, volume_rtol)
    n_gmsh = sum(line.startswith("gmsh") for line in log)
    tried = ", ".join(f"{n} {what} attempt{'s' * (n != 1)}" for n, what in
                      ((n_gmsh, "gmsh"), (len(log) - n_gmsh, "fTetWild")) if n)
    last = _one_line(log[-1]) if log else "no attempt"
    return f"{head}: {culprit or 'no single body to blame'} ({tried}; last: {last})"


def _gmsh_alone(items: list[Body], volumes: np.ndarray, edge_length: float, refinement,
                volume_rtol: float) -> str | None:
    """The first body gmsh cannot mesh on its own, with the reason (for the error message);
    None without gmsh."""
    from designlab.mesh import brep

    if not brep.available():
        return None
    for k, b in enumerate(items):
        try:
            points, cells, _ = brep.tetrahedralize([b.shape], [b.name], edge_length, refinement)
        except Exception as exc:  # MeshingError, or gmsh's own
            return f"body {b.name!r} fails on its own ({_one_line(exc, 120)})"
        p = points[cells]
        vol = abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                            p[:, 3] - p[:, 0]).sum()) / 6.0
        if abs(vol / volumes[k] - 1.0) > volume_rtol:
            return (f"body {b.name!r} meshes on its own to {vol:.4g} mm^3 instead of "
                    f"{volumes[k]:.4g} mm^3")
    return "each body meshes on its own, not together (their interfaces)"


def mesh_bodies(bodies: Mapping[str, Body] | Sequence[Body],
                facet_sets: Mapping[str, FacetSelector] | None = None, **kw: Any) -> TetMesh:
    """Mesh bodies into one conforming, region-tagged TetMesh; keywords of
    :func:`mesh_bodies_detailed`."""
    return mesh_bodies_detailed(bodies, facet_sets, **kw).mesh


def mesh_part_detailed(part: Any, *, refine: bool = True, names: Sequence[str] | None = None,
                       **kw: Any) -> MeshResult:
    """Mesh ``part.mesh_bodies()`` (or the bodies ``names``) of ``part.build()`` with the part's
    facet sets and, with ``refine``, its refinement spheres (added to any ``refinement``
    given)."""
    built = part.build()
    try:
        bodies = [built[name] for name in (part.mesh_bodies() if names is None else names)]
    except KeyError as exc:
        raise MeshingError(f"part {type(part).__name__} names mesh body {exc} that build() "
                           f"does not return (has {', '.join(built)})") from None
    refinement = (list(part.refinement()) if refine else []) + list(kw.pop("refinement", ()))
    named = part.named_faces(built) if hasattr(part, "named_faces") else None
    return mesh_bodies_detailed(bodies, part.facet_sets(), refinement=refinement,
                                named_faces=named, **kw)


def mesh_stl(path: str | Path, *, edge_length: float | None = None, order: int = 2,
             material: str = "ABS", quality: str = "default", threads: int = 1) -> MeshResult:
    """Tetrahedral mesh of a closed triangle surface from elsewhere (an STL, a scan) with
    fTetWild, one region named after the file. An open surface -> one line with how many
    open edges it has."""
    import trimesh

    t0 = time.perf_counter()
    path = Path(path)
    try:
        soup = trimesh.load_mesh(path, process=True)
    except Exception as exc:
        raise MeshingError(f"{path}: not a readable triangle surface ({type(exc).__name__})") from None
    if not isinstance(soup, trimesh.Trimesh) or len(soup.faces) == 0:
        raise MeshingError(f"{path}: no triangles")
    edges = soup.edges_sorted
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = int(np.sum(counts == 1))
    if open_edges or not soup.is_watertight:
        raise MeshingError(f"{path}: the surface is not closed: {open_edges} open edges "
                           "(a volume mesh needs a watertight surface)")
    if quality not in PRESETS:
        raise ParameterError("quality", quality, "one of " + ", ".join(PRESETS))
    factor, energy = PRESETS[quality]
    volume = float(abs(soup.volume))
    if edge_length is None:
        edge_length = factor * (_CELLS_PER_EDGE3 * volume / TARGET_CELLS) ** (1.0 / 3.0)
    diag = float(np.linalg.norm(soup.extents))
    eps = 1e-3 * diag
    points, cells = _tetwild(np.asarray(soup.vertices, float), np.asarray(soup.faces), edge_length,
                             eps, energy, None, threads)
    points, cells = compact(points, cells)
    name = path.stem
    mesh = TetMesh(points, cells, np.zeros(len(cells), np.int64), {0: name}, {name: material})
    if order == 2:
        mesh = mesh.quadratic()
    return MeshResult(mesh, float(edge_length), eps, energy, {name: volume},
                      [f"fTetWild on {path.name}: {len(cells)} cells"], time.perf_counter() - t0,
                      "tetwild")


def mesh_part(part: Any, *, order: int = 2, edge_length: float | None = None,
              **kw: Any) -> TetMesh:
    """TetMesh of a part (see :func:`mesh_part_detailed`)."""
    return mesh_part_detailed(part, order=order, edge_length=edge_length, **kw).mesh
