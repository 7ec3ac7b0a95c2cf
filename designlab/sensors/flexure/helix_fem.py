"""FEM 6x6 stiffness of a flexure: base clamped, tip coupled to a rigid 6-dof master (mm, N, MPa).

Six unit load cases at the master (three moments, three forces) give the columns of the
compliance ``C`` (twist (w, v) per wrench (m, f)); ``K = C^-1``. The compliance of a symmetric
linear model is symmetric, so ``||C - C^T|| / ||C||`` measures round-off and solver error only;
``K`` is returned symmetrised. :func:`stiffness_6x6` works on any mesh with a base and a tip set;
:func:`fem_stiffness` meshes a helical spring flexure (the parts helper's ``SpringFlexure``) and
expresses the result at the spring centre, as the closed form (:mod:`designlab.sensors.flexure.spring`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.sensors.flexure.spring import HelicalSpring, to_si
from designlab.fem.static import solve_static
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import TetMesh

Progress = Callable[[str, int, int], None]
_CASES = (("m_x", (0, 0, 0), (1, 0, 0)), ("m_y", (0, 0, 0), (0, 1, 0)), ("m_z", (0, 0, 0), (0, 0, 1)),
          ("f_x", (1, 0, 0), (0, 0, 0)), ("f_y", (0, 1, 0), (0, 0, 0)), ("f_z", (0, 0, 1), (0, 0, 0)))


@dataclass(frozen=True)
class FlexureFEM:
    """FEM 6x6 of a flexure. ``K`` (N*mm/rad, N/mm, N) in a frame at ``master`` (global axes);
    ``C_raw`` the unsymmetrised compliance; ``centre`` the point where :attr:`K_centre` sits."""

    K: np.ndarray
    C_raw: np.ndarray
    master: np.ndarray
    centre: np.ndarray
    asymmetry: float
    n_nodes: int
    n_cells: int
    cell_nodes: int
    solver: str

    def at(self, point) -> np.ndarray:
        """K expressed in a frame at ``point`` (mm, global axes)."""
        return transform_stiffness(self.K, transform(translation=self.master - np.asarray(point, float)))

    @property
    def K_centre(self) -> np.ndarray:
        """K at the spring centre, designlab units."""
        return self.at(self.centre)

    @property
    def K_centre_si(self) -> np.ndarray:
        """K at the spring centre, SI (N*m/rad, N/m, N)."""
        return to_si(self.K_centre)

    def summary(self) -> dict:
        return {"n_nodes": self.n_nodes, "n_cells": self.n_cells, "cell_nodes": self.cell_nodes,
                "asymmetry": self.asymmetry, "master_mm": self.master.tolist(),
                "centre_mm": self.centre.tolist(), "solver": self.solver,
                "K_master": self.K.tolist(), "K_centre_si": self.K_centre_si.tolist()}


def stiffness_6x6(mesh: TetMesh, base: str, tip: str, master=None, centre=None,
                  materials: dict | None = None, solver: str = "auto",
                  progress: Progress | None = None) -> FlexureFEM:
    """6x6 stiffness of ``mesh`` with the set ``base`` clamped and ``tip`` rigid to a master.

    master: point of the 6-dof master (mm; default the centroid of the tip nodes).
    centre: reference point reported as :attr:`FlexureFEM.K_centre` (default midway between the
            base and tip centroids).
    """
    step = progress or (lambda text, done, total: None)
    step("assembling", 0, 3)
    model = Model(mesh, materials=materials)
    model.fix(base)
    ref = model.rigid("tip_master", tip, ref_point=master)
    for name, f, m in _CASES:
        model.force(ref, force=f, moment=m, case=name)
    step("solving 6 load cases", 1, 3)
    res = solve_static(model, solver=solver)
    step("compliance", 2, 3)
    C = np.column_stack([res.twist(ref, name) for name, _, _ in _CASES])
    asym = float(np.linalg.norm(C - C.T) / np.linalg.norm(C))
    Cs = (C + C.T) / 2
    try:
        K = np.linalg.inv(Cs)
    except np.linalg.LinAlgError:
        raise ModelError("FEM compliance of the flexure is singular: check the base/tip sets") from None
    K = (K + K.T) / 2
    base_c = mesh.points[model.nodes(base)].mean(axis=0)
    tip_c = mesh.points[model.nodes(tip)].mean(axis=0)
    cen = (base_c + tip_c) / 2 if centre is None else np.asarray(centre, float)
    step("done", 3, 3)
    return FlexureFEM(K=K, C_raw=C, master=np.asarray(ref.x, float), centre=cen, asymmetry=asym,
                      n_nodes=mesh.n_points, n_cells=mesh.n_cells, cell_nodes=mesh.cells.shape[1],
                      solver=type(res.solver).__name__)


def flexure_from_spring(spring: HelicalSpring, **kw):
    """The parts helper's ``SpringFlexure`` with this spring's wire, diameter, pitch and coils.

    ``inactive_coils`` 0 -> plain ends, 2 -> closed-and-ground ends (one dead coil each end);
    other values have no geometry and raise ParameterError. ``kw`` sets disc parameters (by
    default the part's, widened/narrowed to clear the coil; the discs are not meshed).
    """
    from designlab.geometry.flexure import SpringFlexure

    ends = {0.0: "plain", 2.0: "closed_ground"}.get(float(spring.inactive_coils))
    if ends is None:
        raise ParameterError("inactive_coils", spring.inactive_coils,
                             "0 (plain ends) or 2 (closed and ground ends) for the FEM geometry")
    R, r = spring.mean_radius, spring.wire_radius
    defaults = {f.name: f.default for f in dataclasses.fields(SpringFlexure)}
    kw.setdefault("disc_radius", max(defaults["disc_radius"], R + r + 1.0))
    kw.setdefault("disc_bore", max(0.0, min(defaults["disc_bore"], R - r - 1.0)))
    return SpringFlexure(wire_radius=r, mean_diameter=spring.mean_diameter,
                         pitch_angle=spring.pitch_angle, active_coils=spring.active_coils,
                         ends=ends, **kw)


def spring_material(spring: HelicalSpring) -> Material:
    """Isotropic wire material with the spring's E and G (nu = E / 2G - 1)."""
    return Material("spring_wire", E=spring.E, nu=spring.E / (2.0 * spring.G) - 1.0,
                    source="HelicalSpring E, G")


#: curved (isoparametric) TET10 for the helix by default (:func:`helix_mesh` ``curved``,
#: :func:`fem_stiffness`, :func:`fem_contact_stiffness`): the wire surface's mid-edge nodes
#: projected onto the swept circle, ~0.5 s on the default mesh; docs/flexure.md, "Solid FEM:
#: contact discretisation"
CURVED_DEFAULT = True


def fem_stiffness(spring, edge_length: float | None = None, order: int = 2,
                  quality: str = "default", solver: str = "direct",
                  progress: Progress | None = None,
                  curved: bool = CURVED_DEFAULT) -> FlexureFEM:
    """FEM 6x6 of a spring flexure: mesh the helix, clamp ``flexure_base``, rigid ``flexure_tip``.

    spring:      a :class:`~designlab.sensors.flexure.spring.HelicalSpring` (its E, G are used for the wire)
                 or a ``SpringFlexure`` (its material name is used).
    edge_length: tet edge length, mm (default: the wire radius).
    solver:      "direct" by default: a slender wire has little fill-in (114k TET10 dofs of the
                 Visiflex helix factor in ~10 s) while AMG-CG converges slowly on it.
    curved:      TET10 (``order`` 2) with the wire surface's mid-edge nodes on the swept circle
                 (:func:`helix_mesh` ``curved``, by projection; cells it inverts straightened):
                 the round section not faceted, 6.9 % stiffer in k_wx than straight on the
                 Visiflex default mesh (docs/flexure.md, "Solid FEM: contact discretisation").
    The master sits on the axis at the tip face (``z = length``); :attr:`FlexureFEM.K_centre` is
    at the spring centre ``(0, 0, length / 2)``, the closed form's frame.
    """
    from designlab.mesh.meshing import mesh_part_detailed

    step = progress or (lambda text, done, total: None)
    if isinstance(spring, HelicalSpring):
        flexure, materials = flexure_from_spring(spring), {"spring": spring_material(spring)}
    else:
        flexure, materials = spring, None
    h = flexure.wire_radius if edge_length is None else float(edge_length)
    if not (np.isfinite(h) and h > 0):
        raise ParameterError("edge_length", edge_length, "a number > 0 mm")
    step("meshing the helix (gmsh)", 0, 4)
    res = mesh_part_detailed(flexure, order=order, edge_length=h, quality=quality, mesher="gmsh")
    mesh = res.mesh
    if curved and order == 2:
        mesh, _, _ = _curve(flexure, mesh, res)
    L = float(flexure.length)

    def sub(text, done, total):
        step(text, 1 + done, 4)

    return stiffness_6x6(mesh, "flexure_base", "flexure_tip", master=(0.0, 0.0, L),
                         centre=(0.0, 0.0, L / 2), materials=materials, solver=solver,
                         progress=sub)


# ------------------------------------------------------------------ the helix mesh

#: largest relative error of the meshed wire volume against the B-rep's (the mesher's own check,
#: ``mesh_bodies_detailed(volume_rtol=0.05)``)
WIRE_VOLUME_RTOL = 0.05


def helix_mesh(flexure, edge_length: float | None = None, order: int = 2,
               quality: str = "default", curved: bool = CURVED_DEFAULT,
               curve_by: str = "projection") -> tuple[TetMesh, dict]:
    """TET4/TET10 mesh of the spring part's wire (gmsh) and how it was sized.

    ``edge_length`` None: the default mesh of ``designlab flexure --fem`` (asked at the wire
    radius; gmsh's first try at that size facets the wire section and loses more than 5 % of
    its volume, so the mesher's fallback sizes the wire from its curvature, 12 edges per 2 pi
    of radius: median corner edge 0.54 mm on the Visiflex wire, r = 1.015 mm, for every edge
    asked from 0.7 mm up; docs/flexure.md, "Solid FEM: contact discretisation"). ``edge_length``
    given (mm): that size, honoured (the mesher's first try, whatever the volume), and a mesh
    whose wire volume is off the B-rep's by more than :data:`WIRE_VOLUME_RTOL` (the section
    too coarse to carry it: 0.7 mm and up on the Visiflex wire; 0.65 mm passes) is a
    ParameterError naming the volume lost, instead of the same fallback mesh for every size.
    The part's end refinement (edge r / 2 within 4 r of the wire ends) applies where it is finer.
    ``curved`` (TET10 only, ignored for TET4; :data:`CURVED_DEFAULT`): the mid-edge nodes of
    the wire's surface on that surface (the same corners, cells and sets), instead of
    straight. ``curve_by="projection"`` (default): each projected onto the circle swept
    along the part's centreline (:func:`wire_surface`), those on the part's flat faces (ground
    faces, wire end faces) kept on their plane and those on a rim projected within the plane
    (:func:`designlab.mesh.curve.curve_boundary`; ~0.5 s with the Jacobian check on the
    default mesh, within 3.7e-3 mm of gmsh's nodes, the no-contact 6x6 diagonal within 1e-5
    of gmsh's); ``"gmsh"``: gmsh's second-order nodes on the B-rep
    (:func:`designlab.mesh.brep.curve_tet10`, a second gmsh run: ~80 s CPU on the default
    mesh). A cell that curving inverts (Jacobian <= 0 at a node or quadrature point) gets its
    mid-nodes back on the chords (:func:`straighten_inverted`; ``straightened_cells`` in the
    info). The 5 % check above stays on the corner volume.
    Info: ``edge_asked_mm``, ``median_edge_mm`` (corner edges), ``sized_by``, ``curved``,
    ``curve_by`` and ``curving`` (the projection's counts, :func:`curve_boundary`),
    ``volume_error`` (of the mesh returned: TET10 volume integrated exactly, the corner
    tetrahedra for TET4), ``volume_error_corners`` and, for TET10, ``min_jacobian_ratio``
    (smallest Jacobian determinant at the nodes and the element's quadrature points over the
    cell's corner-tetrahedron one; <= 0 is an inverted cell).
    """
    from designlab.mesh.meshing import mesh_part_detailed

    if curve_by not in ("projection", "gmsh"):
        raise ParameterError("curve_by", curve_by, "projection or gmsh")
    if edge_length is None:
        res = mesh_part_detailed(flexure, order=order, edge_length=flexure.wire_radius,
                                 quality=quality, mesher="gmsh")
    else:
        h = float(edge_length)
        if not (np.isfinite(h) and h > 0):
            raise ParameterError("edge_length", edge_length, "a number > 0 mm")
        # volume_rtol 1: the first try (this size, no curvature sizing) is taken as it comes
        res = mesh_part_detailed(flexure, order=order, edge_length=h, quality=quality,
                                 mesher="gmsh", volume_rtol=1.0)
    mesh = res.mesh
    cinfo = {}
    curved = bool(curved) and order == 2
    if curved:
        mesh, n_straightened, cinfo = _curve(flexure, mesh, res, curve_by)
    v_mesh = float(mesh.corner_volumes.sum())
    v_brep = float(sum(res.body_volumes.values()))
    err = v_mesh / v_brep - 1.0
    pc = mesh.points[mesh.cells[:, :4]]
    info = {"edge_asked_mm": None if edge_length is None else float(edge_length),
            "median_edge_mm": float(np.median(np.linalg.norm(pc[:, 1] - pc[:, 0], axis=1))),
            "sized_by": res.attempts[-1] if res.attempts else "", "curved": bool(curved),
            "volume_error": err, "volume_error_corners": err,
            "straightened_cells": n_straightened if curved else 0,
            "curve_by": curve_by if curved else None, "curving": cinfo}
    if mesh.order == 2:
        from designlab.fem import elements
        from designlab.fem.elements import tet_element

        info["volume_error"] = elements.tet10_volume(mesh.points, mesh.cells) / v_brep - 1.0
        xi = np.vstack([elements.TET10_NODES_XI, tet_element(10).quadrature.points])
        det = elements.tet10_jacobians(mesh.points, mesh.cells, xi)
        info["min_jacobian_ratio"] = float((det.min(axis=1) / (6 * mesh.corner_volumes)).min())
    if edge_length is not None and (len(res.attempts) != 1 or abs(err) > WIRE_VOLUME_RTOL):
        raise ParameterError(
            "edge_length", edge_length,
            f"an edge that meshes the wire section (r = {flexure.wire_radius:g} mm) within "
            f"{100 * WIRE_VOLUME_RTOL:g} % of its volume: at {float(edge_length):g} mm the "
            f"mesh has {100 * err:+.1f} % (about 10 edges around the section, <= "
            f"{2 * np.pi * flexure.wire_radius / 10:.2g} mm, pass); or None for the default "
            "mesh sized by the wire's curvature")
    return mesh, info


def _curve(flexure, mesh: TetMesh, res, by: str = "projection") -> tuple[TetMesh, int, dict]:
    """``mesh`` (straight TET10 of ``res``, :func:`mesh_part_detailed` on ``flexure``) with
    its surface mid-nodes on the wire's surface, then :func:`straighten_inverted`.

    ``by="projection"``: onto the swept circle of :func:`wire_surface` and the part's planar
    faces (ground faces, wire end faces; :func:`designlab.mesh.curve.curve_boundary`), no
    second mesher run. ``by="gmsh"``: gmsh's successful attempt (its edge, curvature sizing and
    refinement, as ``res`` records them) made again at order 2, its mid-nodes on the B-rep
    (:func:`designlab.mesh.brep.curve_tet10`; ~13x the straight mesh's CPU on the Visiflex
    helix). Returns the mesh, the cells straightened and the curving's info."""
    from designlab.mesh import brep

    names = list(flexure.mesh_bodies())
    built = flexure.build()
    if by == "gmsh":
        if res.mesher != "gmsh":
            raise ParameterError("curved", True, f"a helix meshed by gmsh (this one: {res.mesher})")
        curved = brep.curve_tet10(mesh, [built[n].shape for n in names], names, res.edge_length,
                                  list(res.refinement), curvature=res.curvature)
        points, cinfo = curved.points, {}
    elif by == "projection":
        from designlab.mesh.curve import curve_boundary

        if len(names) != 1:
            raise ParameterError("curved", True, f"one meshed wire body (this part: {names})")
        planes = brep.planar_faces(built[names[0]].shape)
        points, cinfo = curve_boundary(mesh, wire_surface(flexure), planes,
                                       plane_tol=CURVE_PLANE_TOL,
                                       surface_tol=CURVE_SURFACE_RTOL * flexure.wire_radius)
    else:
        raise ParameterError("curve_by", by, "projection or gmsh")
    points, n_straightened = straighten_inverted(points, mesh.points, mesh.cells)
    return dataclasses.replace(mesh, points=points), n_straightened, cinfo


#: a boundary triangle of the wire lies on one of the part's planar faces when its corners are
#: this close to it, mm (gmsh places them on the plane to round-off)
CURVE_PLANE_TOL = 1e-6
#: largest distance of a wire-surface corner of the mesh (on the B-rep) from :func:`wire_surface`,
#: as a fraction of the wire radius: the part sweeps the wire along a spline through 24 points
#: per turn of :meth:`SpringFlexure.centerline_z`, within 2.5e-3 mm of it on the Visiflex helix
#: (docs/flexure.md, "Solid FEM: contact discretisation")
CURVE_SURFACE_RTOL = 0.02


def wire_surface(flexure):
    """The spring wire's surface in the mesh frame (base seat at z = 0): a circle of radius
    ``wire_radius`` swept along ``(R cos 2 pi u, R sin 2 pi u, centerline_z(u) - z_lo)``,
    ``u`` in ``[0, total_coils]`` turns, ``R`` the mean radius and ``z_lo`` the base cut plane
    (:class:`designlab.mesh.curve.Tube`; the centreline of :func:`_wire_coordinates`)."""
    from designlab.mesh.curve import Tube

    R = flexure.mean_diameter / 2
    lo = flexure._cut_planes()[0]
    N = float(flexure.total_coils)
    w = 2 * np.pi

    def centre(u):
        u = np.asarray(u, float)
        return np.column_stack([R * np.cos(w * u), R * np.sin(w * u),
                                flexure.centerline_z(u) - lo])

    def d_centre(u):
        u = np.asarray(u, float)
        return np.column_stack([-w * R * np.sin(w * u), w * R * np.cos(w * u),
                                flexure.pitch_profile(u)])

    def dd_centre(u, h=1e-6):
        u = np.asarray(u, float)
        dP = (flexure.pitch_profile(u + h) - flexure.pitch_profile(u - h)) / (2 * h)
        return np.column_stack([-w * w * R * np.cos(w * u), -w * w * R * np.sin(w * u), dP])

    return Tube(centre, d_centre, dd_centre, float(flexure.wire_radius), 0.0, N,
                seeds=int(np.ceil(N * 720)) + 1)


def straighten_inverted(points: np.ndarray, straight: np.ndarray, cells: np.ndarray
                        ) -> tuple[np.ndarray, int]:
    """``points`` of a curved TET10 mesh with the mid-nodes of every cell whose Jacobian
    determinant is not positive at one of its nodes or quadrature points (degree 2) put back
    where ``straight`` has them (the chord midpoints), repeated until no cell is inverted
    (a node moved back is shared by its neighbours). Returns the points and how many cells
    were straightened (0: ``points`` unchanged)."""
    from designlab.fem import elements
    from designlab.fem.elements import tet_element

    xi = np.vstack([elements.TET10_NODES_XI, tet_element(10).quadrature.points])
    points = points.copy()
    done = np.zeros(len(cells), bool)
    check = np.arange(len(cells))
    while len(check):
        det = elements.tet10_jacobians(points, cells[check], xi)
        bad = check[~(det.min(axis=1) > 0)]
        if not len(bad):
            break
        done[bad] = True
        mids = np.unique(cells[bad, 4:])
        points[mids] = straight[mids]
        check = np.nonzero(np.isin(cells[:, 4:], mids).any(axis=1))[0]
    return points, int(done.sum())


# ------------------------------------------------------------------ contact in the solid FEM

@dataclass(frozen=True)
class ContactFEM:
    """Solid FEM 6x6 with unilateral coil and seat contact, unloaded (``K``) and at the axial
    working load (``K_loaded``), at the tip master ``master`` (global axes, N*mm/rad, N/mm, N);
    ``K_free`` the same condensed model with every contact open (no contact)."""

    K: np.ndarray
    K_loaded: np.ndarray | None
    K_free: np.ndarray
    master: np.ndarray
    centre: np.ndarray
    info: dict
    mesh: TetMesh | None = None

    def at(self, point, which: str = "unloaded") -> np.ndarray:
        K = {"unloaded": self.K, "loaded": self.K_loaded, "free": self.K_free}[which]
        return transform_stiffness(K, transform(translation=self.master - np.asarray(point, float)))

    def centre_si(self, which: str = "unloaded") -> np.ndarray:
        return to_si(self.at(self.centre, which))


def _wire_coordinates(mesh: TetMesh, flexure, samples_per_turn: int = 720):
    """Turn count ``u`` of the nearest centreline point and the offset from it for every mesh
    node (the part's centreline in the mesh frame: base seat at z = 0)."""
    from scipy.spatial import cKDTree

    N = flexure.total_coils
    u = np.linspace(0.0, N, int(N * samples_per_turn) + 1)
    c = wire_surface(flexure).centre(u)
    _, k = cKDTree(c).query(mesh.points)
    return u[k], mesh.points - c[k]


def contact_candidates(mesh: TetMesh, flexure, stations_per_turn: int = 36,
                       line_angle: float = np.radians(30.0)) -> dict:
    """Nodes of the solid helix on its top and bottom contact lines, one per station.

    A node is on the top (bottom) line when it lies on the wire surface (``|offset| > 0.9 r``)
    within ``line_angle`` of the section's top (bottom), ``offset`` being its position relative
    to the nearest centreline point; per station (``1 / stations_per_turn`` turn of wire) the
    node closest to the top (bottom) represents it. Returns ``u``, ``top`` and ``bottom`` (node
    per station or -1) and the station turn counts."""
    r = flexure.wire_radius
    u, off = _wire_coordinates(mesh, flexure)
    rad = np.linalg.norm(off, axis=1)
    on = rad > 0.9 * r
    cz = np.where(on, off[:, 2] / np.maximum(rad, 1e-12), 0.0)
    n_st = int(np.ceil(flexure.total_coils * stations_per_turn))
    st = np.minimum((u * stations_per_turn).astype(int), n_st - 1)
    top, bottom = np.full(n_st, -1), np.full(n_st, -1)
    best_t, best_b = np.full(n_st, np.cos(line_angle)), np.full(n_st, np.cos(line_angle))
    for i in np.nonzero(on)[0]:
        if cz[i] > best_t[st[i]]:
            best_t[st[i]], top[st[i]] = cz[i], i
        if -cz[i] > best_b[st[i]]:
            best_b[st[i]], bottom[st[i]] = -cz[i], i
    return {"u": u, "top": top, "bottom": bottom,
            "station_u": (np.arange(n_st) + 0.5) / stations_per_turn}


#: share of the contact FEM's wall time per stage (progress units of 1/1000 of the run), so the
#: progress bar's ETA is a time estimate: `designlab flexure --fem` on the Visiflex catalogue
#: spring with the line contacts (timings_s of its JSON, 2026-11-25, 131.5 s: mesh 8 %,
#: assembly 3 %, factorisation 3 %, back-substitutions 44 %, contact active sets 41 %;
#: docs/flexure.md "Solid FEM: contact discretisation")
_STAGES = (("mesh", 80), ("assemble", 30), ("factorise", 30), ("condense", 450),
           ("contact", 410))
_PROGRESS_TOTAL = sum(w for _, w in _STAGES)
#: back-substitution calls of the condensation (progress granularity: every call streams the
#: whole factor once more, ~1.3 s CPU each for the Visiflex helix)
_CHUNKS = 4
#: largest dense right-hand-side block of one back-substitution call, bytes: finer meshes take
#: more calls (4 calls of 0.74 GB on the default mesh, as before; a 192267-node mesh peaked at
#: 12.5 GB in 4 calls before this bound, the 248694-node one at 9.2 GB in 15 calls with it)
_RHS_BYTES = 1 << 30


def _at(stage: str, fraction: float = 0.0) -> tuple[int, int]:
    """(done, total) progress units at ``fraction`` of ``stage``."""
    done = 0
    for name, w in _STAGES:
        if name == stage:
            return int(done + fraction * w), _PROGRESS_TOTAL
        done += w
    raise KeyError(stage)


def fem_contact_stiffness(spring, edge_length: float | None = None, order: int = 2,
                          quality: str = "default", solver: str = "auto",
                          gaps: str = "as_built", stations_per_turn: int = 36,
                          contact_spacing_mm: float | None = None,
                          settings=None, mesh: TetMesh | None = None,
                          progress: Progress | None = None,
                          curved: bool = CURVED_DEFAULT) -> ContactFEM:
    """Solid FEM 6x6 of a closed-and-ground spring with contact (the reference of the chain).

    The helix is meshed as the part builds it (gmsh, TET10; dead turns ``DEAD_GAP d`` clear of
    the first active turn so the solid does not touch itself), the ground faces clamped to the
    base and rigid with the tip master (bonded, as ``ChainSettings(seat="bonded")``). Contact,
    unilateral and frictionless, along z between the top contact line of a turn and the bottom
    line one turn above (over each end's dead turn and ramp), and between the dead turns'
    bottom (top) line and the base (tip) seat plane where not bonded. Line contacts (default,
    ``contact_spacing_mm`` > 0; None: ``settings.contact_spacing_mm``, 0.1 mm as the chain):
    contact points every ``contact_spacing_mm`` of wire, independent of the mesh nodes, each
    point's u_z interpolated linearly (in turn count) between the two nodes of its contact
    line around it (the line: the node nearest the top / bottom of the wire per half tet
    edge); points whose line nodes are all held (ground faces) are dropped.
    ``contact_spacing_mm=0``: node contacts as before 2026-11-25, one node per station
    (``stations_per_turn``) paired node to node; their 10 N state depends on the station
    count (docs/flexure.md, "Solid FEM: contact discretisation").
    ``gaps="as_built"`` (default): the initial gap of each contact is the spring's as built at
    the same turn count (:func:`~designlab.sensors.flexure.chain_geometry.as_built`: dead pitch d,
    gap 0 at the wire end, the chain's geometry), the meshed clearance being what the mesher
    needs to keep the solid from touching itself; ``"meshed"``: the part's own gaps
    (dead turns ``DEAD_GAP d`` clear, pitch ramp from ``1 - RAMP / 2``: >= 0.4 mm for
    Visiflex). Penalty per contact ``k_n = E* h`` with ``h`` its length of wire (the point
    spacing, or the station spacing; the chain's rule; seat E* with the disc material of
    ``settings.seat_material``).

    The linear model is condensed exactly on the contact nodes' z displacements and the master
    (one factorisation, one back-substitution per kept dof); the active-set iteration of
    :class:`~designlab.sensors.flexure.active_set.ActiveSet` then runs on that small system:
    symmetric perturbations about the unloaded state and about ``settings.working_load_N``
    (force-controlled axial preload), like the chain. Geometrically linear. ``mesh``: a mesh
    of this part already made (the same call otherwise meshes it with :func:`helix_mesh`:
    ``edge_length`` None the default curvature-sized mesh, a number that edge, honoured;
    ``curved`` its wire surface's mid-edge nodes on the wire's surface, by projection,
    :data:`CURVED_DEFAULT`; ``curved=False`` straight-sided TET10, 6.5 % soft without contact).
    """
    import time

    import scipy.sparse as sp

    from designlab.fem.materials import get_material
    from designlab.fem.solvers import factorize
    from designlab.sensors.flexure.active_set import ActiveSet
    from designlab.sensors.flexure.chain_geometry import RAMP, ChainSettings, wire_contact_points

    cs = settings or ChainSettings()
    step = progress or (lambda text, done, total: None)
    t0 = time.perf_counter()
    if isinstance(spring, HelicalSpring):
        flexure, mat = flexure_from_spring(spring), spring_material(spring)
    else:
        flexure, mat = spring, get_material(spring.material)
    if flexure.ends != "closed_ground":
        raise ParameterError("ends", flexure.ends, "closed_ground for the contact FEM (plain "
                             "ends have no dead turn)")
    d, r = flexure.wire_diameter, flexure.wire_radius
    if gaps not in ("as_built", "meshed"):
        raise ParameterError("gaps", gaps, "as_built or meshed")
    spacing = cs.contact_spacing_mm if contact_spacing_mm is None else float(contact_spacing_mm)
    if not (np.isfinite(spacing) and spacing >= 0):
        raise ParameterError("contact_spacing_mm", spacing,
                             "a spacing >= 0 mm (0: one node contact per station)")
    L, N = float(flexure.length), flexure.total_coils
    timings = {}
    step("meshing the helix (gmsh)", *_at("mesh"))
    mesh_info = None
    if mesh is None:
        mesh, mesh_info = helix_mesh(flexure, edge_length, order=order, quality=quality,
                                     curved=curved)
    timings["mesh"] = time.perf_counter() - t0
    step("contact lines and assembly", *_at("assemble"))
    t1 = time.perf_counter()
    model = Model(mesh, materials={"spring": mat} if isinstance(spring, HelicalSpring) else None)
    model.fix("flexure_base")
    ref = model.rigid("tip_master", "flexure_tip", ref_point=(0.0, 0.0, L))
    system = model.build()
    base_nodes, tip_nodes = set(model.nodes("flexure_base")), set(model.nodes("flexure_tip"))
    if gaps == "as_built":
        from designlab.sensors.flexure.chain_geometry import as_built

        coil = as_built(HelicalSpring(wire_radius=r, mean_diameter=flexure.mean_diameter,
                                      coils=N, inactive_coils=2.0,
                                      pitch_angle=flexure.pitch_angle))

        def zc(u):
            """As-built centreline height above the base seat at turn count(s) u."""
            return np.asarray(coil.z_of_u(u), float) - coil.seat_lo
    else:
        z_lo = flexure._cut_planes()[0]

        def zc(u):
            """Meshed centreline height above the base seat at turn count(s) u."""
            return np.asarray(flexure.centerline_z(np.atleast_1d(u)), float).reshape(
                np.shape(u)) - z_lo

    h_turn = np.hypot(np.pi * flexure.mean_diameter, flexure.dead_pitch)
    # contacts: ({node: coefficient of its u_z}, tip seat point or None, initial gap mm,
    # length of wire mm (penalty E* x length), kind, contact line id, turn count)
    contacts = []
    line_nodes = n_line = 0
    if spacing > 0:
        # line contacts: points every ``spacing`` mm of wire, independent of the mesh nodes;
        # each point's u_z interpolated linearly in turn count between the two nodes of the
        # contact line (top / bottom of the wire, one node per half tet edge of the mesh made:
        # the median corner edge, gmsh's sweep is not always as fine as ``edge_length``)
        pc = mesh.points[mesh.cells[:, :4]]
        h_made = float(np.median(np.linalg.norm(pc[:, 1] - pc[:, 0], axis=1)))
        n_line = int(np.ceil(2 * h_turn / h_made))
        cand = contact_candidates(mesh, flexure, n_line)
        lines = {}
        for side in ("top", "bottom"):
            nd = cand[side][cand[side] >= 0]
            uu = cand["u"][nd]
            o = np.lexsort((nd, uu))
            lines[side] = (nd[o], uu[o])
            line_nodes += len(nd)

        def interp(side, us):
            """{node: weight} per turn count in ``us`` (None off the line's ends)."""
            nd, uu = lines[side]
            out = []
            for x in us:
                if len(uu) < 2 or x < uu[0] or x > uu[-1]:
                    out.append(None)
                    continue
                e = min(max(int(np.searchsorted(uu, x, side="right")) - 1, 0), len(uu) - 2)
                du = uu[e + 1] - uu[e]
                xi = 0.0 if du <= 0 else float((x - uu[e]) / du)
                w = {}
                for n, c in ((int(nd[e]), 1.0 - xi), (int(nd[e + 1]), xi)):
                    if c:
                        w[n] = w.get(n, 0.0) + c
                out.append(w)
            return out

        points, lo_spans = wire_contact_points(zc, flexure.mean_diameter / 2, N, spacing)
        lid = 0
        for lo, hi in lo_spans:
            us, w = points(lo, hi)
            g = np.maximum(zc(us + 1) - zc(us) - d, 0.0)
            for a_, b_, gk, wk, uk in zip(interp("top", us), interp("bottom", us + 1), g, w, us):
                if a_ is None or b_ is None:
                    continue
                coef = dict(b_)                               # upper wire bottom - lower top
                for n, c in a_.items():
                    coef[n] = coef.get(n, 0.0) - c
                contacts.append((coef, None, float(gk), float(wk), "coil", lid, float(uk)))
            lid += 1
        R = flexure.mean_diameter / 2
        for lo, hi, side in ((0.0, 1.0, 1), (N - 1.0, N, -1)):
            us, w = points(lo, hi)
            z = zc(us)
            if side > 0:                                      # wire bottom above the base
                for a_, gk, wk, uk in zip(interp("bottom", us), np.maximum(z - r, 0.0), w, us):
                    if a_ is not None:
                        contacts.append((a_, None, float(gk), float(wk), "seat", lid, float(uk)))
            else:                                             # tip seat above the wire top
                pts = np.column_stack([R * np.cos(2 * np.pi * us), R * np.sin(2 * np.pi * us),
                                       z + r])
                for a_, p_, gk, wk, uk in zip(interp("top", us), pts, np.maximum(L - z - r, 0.0), w,
                                               us):
                    if a_ is not None:
                        contacts.append(({n: -c for n, c in a_.items()}, p_, float(gk),
                                         float(wk), "seat", lid, float(uk)))
            lid += 1
    else:
        # node contacts (before 2026-11-25): one node per station, node to node along z
        cand = contact_candidates(mesh, flexure, stations_per_turn)
        h_st = h_turn / stations_per_turn
        top, bot, su = cand["top"], cand["bottom"], cand["station_u"]
        span = 1.0 + RAMP
        for k in range(len(su)):
            k_up = k + stations_per_turn
            if k_up >= len(su) or top[k] < 0 or bot[k_up] < 0:
                continue
            if not (su[k] <= span or su[k_up] >= N - span):
                continue
            i, j = int(top[k]), int(bot[k_up])
            # gap between the wire surfaces along z at the two nodes' stations (from the
            # centreline, as the chain: a node a few degrees off the top would add up to 0.27 mm)
            g = float(zc(cand["u"][j]) - zc(cand["u"][i]) - d)
            contacts.append(({j: 1.0, i: -1.0}, None, max(g, 0.0), h_st, "coil", 0,
                             float(cand["u"][i])))
        for k in range(len(su)):
            if su[k] <= 1.0 and bot[k] >= 0 and bot[k] not in base_nodes:
                n = int(bot[k])
                contacts.append(({n: 1.0}, None, max(float(zc(cand["u"][n])) - r, 0.0), h_st,
                                 "seat", 1, float(cand["u"][n])))
            if su[k] >= N - 1.0 and top[k] >= 0 and top[k] not in tip_nodes:
                n = int(top[k])
                contacts.append(({n: -1.0}, mesh.points[n].copy(),
                                 max(L - float(zc(cand["u"][n])) - r, 0.0), h_st, "seat", 2,
                                 float(cand["u"][n])))
    # kept dofs: u_z of every contact node (slaves of the master are expressed through it)
    nodes = sorted({n for c in contacts for n in c[0]})
    nodes = [n for n in nodes if n not in base_nodes and n not in tip_nodes]
    npts = mesh.n_points
    keep = [3 * n + 2 for n in nodes] + list(ref.dofs(npts))
    T = system.T.tocsr()
    Lmap = T[keep]                                 # (n_keep, n_free): q -> kept dofs
    K_full = system.K()
    Kr = system.reduce(K_full)
    timings["assemble"] = time.perf_counter() - t1
    step(f"factorising ({Kr.shape[0]} dofs)", *_at("factorise"))
    t1 = time.perf_counter()
    lin = factorize(Kr, solver, n_rhs=len(keep))
    timings["factorise"] = time.perf_counter() - t1
    # the condensation's back-substitutions in chunks, so the bar (and its ETA) moves
    t2 = time.perf_counter()
    C = np.empty((len(keep), len(keep)))
    n_calls = max(_CHUNKS, int(np.ceil(8.0 * Kr.shape[0] * len(keep) / _RHS_BYTES)))
    chunks = np.array_split(np.arange(len(keep)), min(n_calls, len(keep)))
    for c, cols in enumerate(chunks):
        step(f"condensing on {len(keep)} dofs ({cols[0]}/{len(keep)})",
             *_at("condense", c / len(chunks)))
        C[:, cols] = np.asarray(Lmap @ lin.solve(np.asarray(Lmap[cols].T.todense())))
    timings["back_substitution"] = time.perf_counter() - t2
    asym = float(np.abs(C - C.T).max() / np.abs(C).max())
    C = (C + C.T) / 2
    Kc = np.linalg.inv(C)
    Kc = (Kc + Kc.T) / 2
    timings["condense"] = time.perf_counter() - t1
    step("contact active sets", *_at("contact"))
    t1 = time.perf_counter()
    n_keep = len(keep)
    pos = {n: a for a, n in enumerate(nodes)}
    m = np.arange(n_keep - 6, n_keep)
    master = np.array([0.0, 0.0, L])

    def uz(n):
        """(n_keep,) u_z of node n: a kept dof, 0 on the base, rigid with the master on the tip."""
        row = np.zeros(n_keep)
        if n in pos:
            row[pos[n]] = 1.0
        elif n in tip_nodes:
            x = mesh.points[n] - master
            row[m] = [0.0, 0.0, 1.0, x[1], -x[0], 0.0]           # u_z = v_z + w_x y - w_y x
        return row

    nu = mat.E / (2 * mat.G) - 1 if hasattr(mat, "G") and mat.G else mat.nu
    E_ss = mat.E / (2 * (1 - nu ** 2))
    seat_m = get_material(cs.seat_material)
    E_seat = 1.0 / ((1 - nu ** 2) / mat.E + (1 - seat_m.nu ** 2) / seat_m.E)
    rows, kn, g0, kinds, runs, lens, us_c = [], [], [], [], [], [], []
    held = base_nodes | tip_nodes
    for coef, p_, g, w, kind, lid, uc in contacts:
        if all(n in held for n in coef):                        # the wire held there (bonded)
            continue
        row = np.zeros(n_keep)
        for n, c in coef.items():
            row += c * uz(n)
        if p_ is not None:                                      # the tip seat at p_
            x = p_ - master
            row[m] += [0.0, 0.0, 1.0, x[1], -x[0], 0.0]
        if not np.any(row):
            continue
        rows.append(row), g0.append(g), kinds.append(kind), runs.append(lid), lens.append(w)
        us_c.append(uc)
        kn.append((E_ss if kind == "coil" else E_seat) * w)

    class _Solid(ActiveSet):
        pass

    prob = _Solid()
    prob.Kq, prob.nq, prob.m, prob.s = sp.csr_matrix(Kc), n_keep, m, cs
    prob.N = sp.csr_matrix(np.array(rows).reshape(-1, n_keep))
    prob.kn, prob.g0 = np.array(kn), np.array(g0)
    if spacing > 0:
        prob.runs = np.array(runs)              # line contacts grow from their deepest point
    perm = np.array([3, 4, 5, 0, 1, 2])
    K_free = np.linalg.inv(C[np.ix_(m, m)])[np.ix_(perm, perm)]
    K_free = (K_free + K_free.T) / 2
    K, closed = prob.stiffness()
    K_loaded, info_l = None, None
    if cs.working_load_N > 0:
        pre = prob.solve(f_master=np.r_[0.0, 0.0, -cs.working_load_N, 0.0, 0.0, 0.0])
        K_loaded, closed_l = prob.stiffness(ref=pre)
        info_l = {"axial_deflection_mm": float(-pre["q"][m][2]),
                  "closed_contacts": int(np.count_nonzero(pre["closed"])),
                  "closed_length_mm": float(np.sum(np.array(lens)[pre["closed"]])),
                  "closed_turns": [[kinds[c], round(us_c[c], 4)] for c in np.nonzero(pre["closed"])[0]],
                  "closed_during_perturbations": [min(closed_l), max(closed_l)]}
    timings["contact"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    step("done", _PROGRESS_TOTAL, _PROGRESS_TOTAL)
    info = {"n_nodes": int(mesh.n_points), "n_cells": int(mesh.n_cells),
            "cell_nodes": int(mesh.cells.shape[1]), "dofs": int(Kr.shape[0]),
            "condensed_dofs": n_keep, "coil_pairs": kinds.count("coil"),
            "seat_contacts": kinds.count("seat"), "gaps": gaps,
            "closed_gaps_at_start": int(np.sum(np.array(g0) <= 0)),
            "stations_per_turn": None if spacing > 0 else stations_per_turn,
            "contact_spacing_mm": spacing, "line_nodes": line_nodes,
            "line_bins_per_turn": n_line if spacing > 0 else None, "asymmetry": asym,
            "closed_during_perturbations": [min(closed), max(closed)],
            "working_load": info_l, "solver": type(lin).__name__,
            "back_substitution_calls": len(chunks), "mesh": mesh_info, "timings_s": timings}
    return ContactFEM(K, K_loaded, K_free, master, np.array([0.0, 0.0, L / 2]), info, mesh)
