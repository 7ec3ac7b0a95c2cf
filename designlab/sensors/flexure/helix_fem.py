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
from designlab.fem.static import solve_static
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import TetMesh
from designlab.sensors.flexure.spring import HelicalSpring, to_si

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
#: projected onto the swept circle (docs/validation/flexure.md, the solid FEM)
CURVED_DEFAULT = True


def fem_stiffness(spring, edge_length: float | None = None, order: int = 2,
                  quality: str = "default", solver: str = "direct",
                  progress: Progress | None = None,
                  curved: bool = CURVED_DEFAULT) -> FlexureFEM:
    """FEM 6x6 of a spring flexure: mesh the helix, clamp ``flexure_base``, rigid ``flexure_tip``.

    spring:      a :class:`~designlab.sensors.flexure.spring.HelicalSpring` (its E, G are used for the wire)
                 or a ``SpringFlexure`` (its material name is used).
    edge_length: tet edge length, mm (default: the wire radius).
    solver:      "direct" by default: a slender wire has little fill-in while AMG-CG converges
                 slowly on it.
    curved:      TET10 (``order`` 2) with the wire surface's mid-edge nodes on the swept circle
                 (:func:`helix_mesh` ``curved``, by projection; cells it inverts straightened):
                 the round section not faceted, 6.9 % stiffer in k_wx than straight on the
                 Visiflex default mesh (docs/validation/flexure.md, the solid FEM).
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
    asked from 0.7 mm up; docs/validation/flexure.md, the solid FEM). ``edge_length``
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
    (:func:`designlab.mesh.curve.curve_boundary`; on the default mesh within 3.7e-3 mm of gmsh's nodes, the no-contact 6x6 diagonal within 1e-5
    of gmsh's); ``"gmsh"``: gmsh's second-order nodes on the B-rep
    (:func:`designlab.mesh.brep.curve_tet10`, a second gmsh run). A cell that curving inverts (Jacobian <= 0 at a node or quadrature point) gets its
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
#: (docs/validation/flexure.md, the solid FEM)
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
