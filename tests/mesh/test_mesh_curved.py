"""Curved (isoparametric) TET10 from gmsh's second-order nodes: designlab.mesh.brep.curve_tet10."""

import numpy as np
import pytest

from designlab.errors import MeshingError
from designlab.mesh import brep
from designlab.mesh.tetmesh import TET10_EDGES, TRI6_EDGES, TetMesh

pytestmark = pytest.mark.skipif(not brep.available(), reason="gmsh not installed")

R, H, EDGE = 2.0, 3.0, 0.8


def _straight(shape, h):
    """Straight TET10 of one body as the mesher makes it (gmsh TET4, compact, quadratic)."""
    from designlab.mesh.meshing import compact

    p, c, r = brep.tetrahedralize([shape], ["b"], h)
    p, c = compact(p, c)
    return TetMesh(p, c, r, {0: "b"}, {"b": "ABS"}).quadratic()


@pytest.fixture(scope="module")
def cylinder():
    from build123d import Cylinder

    shape = Cylinder(R, H)                       # axis z, centred: caps at z = -H/2, +H/2
    straight = _straight(shape, EDGE)
    return shape, straight, brep.curve_tet10(straight, [shape], ["b"], EDGE)


def _surface_edges(mesh):
    """(corner pairs, mid-nodes, unit normal of the face) of the boundary triangles' edges."""
    tri = mesh.boundary_facets()
    p = mesh.points
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    pairs = tri[:, TRI6_EDGES]                                    # (k, 3, 2)
    # mid-node of each corner pair, from the cells
    n_pts = mesh.n_points
    key = np.sort(mesh.cells[:, TET10_EDGES].reshape(-1, 2), axis=1) @ np.array([n_pts, 1])
    mid = dict(zip(key.tolist(), mesh.cells[:, 4:].reshape(-1).tolist()))
    k2 = np.sort(pairs.reshape(-1, 2), axis=1) @ np.array([n_pts, 1])
    mids = np.array([mid[k] for k in k2.tolist()]).reshape(-1, 3)
    return pairs, mids, n


def test_curved_mid_nodes_lie_on_the_cylinder_straight_ones_do_not(cylinder):
    _, straight, curved = cylinder
    pairs, mids, n = _surface_edges(curved)
    lateral = np.abs(n[:, 2]) < 0.5                               # the round face's triangles
    m = mids[lateral].ravel()
    r_curved = np.hypot(curved.points[m, 0], curved.points[m, 1])
    r_straight = np.hypot(straight.points[m, 0], straight.points[m, 1])
    assert len(m) > 100
    assert np.abs(r_curved - R).max() < 1e-6
    assert np.abs(r_straight - R).max() > 1e-2                    # chords sag inside
    # the corners, cells and sets are the straight mesh's
    corners = np.unique(straight.cells[:, :4])
    assert np.array_equal(curved.points[corners], straight.points[corners])
    assert np.array_equal(curved.cells, straight.cells)


def test_flat_faces_and_interior_unchanged(cylinder):
    _, straight, curved = cylinder
    pairs, mids, n = _surface_edges(curved)
    cap = np.abs(n[:, 2]) > 0.999
    m = np.unique(mids[cap])
    # every cap mid-node stays on its plane; those not on the rim circle stay where they were
    # (to round-off: gmsh evaluates the plane at the parametric midpoint)
    assert np.abs(np.abs(curved.points[m, 2]) - H / 2).max() < 1e-9
    rim = np.abs(np.hypot(*curved.points[m, :2].T) - R) < 1e-9
    assert (~rim).sum() > 10
    assert np.abs(curved.points[m[~rim]] - straight.points[m[~rim]]).max() < 1e-9
    assert np.abs(curved.points[m[rim]] - straight.points[m[rim]]).max() > 1e-3
    on_surface = np.unique(mids)
    interior = np.setdiff1d(np.unique(curved.cells[:, 4:]), on_surface)
    assert len(interior) > 0
    assert np.array_equal(curved.points[interior], straight.points[interior])


def test_gmsh_tet10_order_is_mapped_to_c3d10_on_a_flat_body():
    """All-flat body: every curved mid-node is its edge's midpoint (a wrong local order would
    put it on another edge's midpoint)."""
    from build123d import Box

    box = Box(4.0, 3.0, 2.0)
    straight = _straight(box, EDGE)
    curved = brep.curve_tet10(straight, [box], ["b"], EDGE)
    p, c = curved.points, curved.cells
    mid = 0.5 * (p[c[:, TET10_EDGES[:, 0]]] + p[c[:, TET10_EDGES[:, 1]]])
    assert np.linalg.norm(p[c[:, 4:]] - mid, axis=2).max() < 1e-9
    # and the raw gmsh order-2 cells, mapped with GMSH_TET10_TO_C3D10, agree by themselves
    pts, cells, _ = brep._tetrahedralize([box], ["b"], EDGE, (), 0.5, None, 0, cell_order=2)
    mid = 0.5 * (pts[cells[:, TET10_EDGES[:, 0]]] + pts[cells[:, TET10_EDGES[:, 1]]])
    assert np.linalg.norm(pts[cells[:, 4:]] - mid, axis=2).max() < 1e-9
    swapped = cells[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]          # gmsh's own order
    mid = 0.5 * (pts[swapped[:, TET10_EDGES[:, 0]]] + pts[swapped[:, TET10_EDGES[:, 1]]])
    assert np.linalg.norm(pts[swapped[:, 4:]] - mid, axis=2).max() > 0.1


def test_curved_cells_valid_volume_closer_and_deterministic(cylinder):
    from designlab.fem import elements
    from designlab.fem.elements import tet_element

    shape, straight, curved = cylinder
    xi = np.vstack([elements.TET10_NODES_XI, tet_element(10).quadrature.points])
    det = elements.tet10_jacobians(curved.points, curved.cells, xi)
    assert det.min() > 0
    exact = np.pi * R ** 2 * H
    v_s = elements.tet10_volume(straight.points, straight.cells)
    v_c = elements.tet10_volume(curved.points, curved.cells)
    assert abs(v_s / exact - 1) > 0.01                            # faceted: -1.9 %
    assert abs(v_c / exact - 1) < 1e-3                            # curved: -3e-5
    again = brep.curve_tet10(straight, [shape], ["b"], EDGE)
    assert np.array_equal(again.points, curved.points)
    assert np.array_equal(again.cells, curved.cells)


def test_other_arguments_than_the_straight_mesh_are_an_error(cylinder):
    shape, straight, _ = cylinder
    with pytest.raises(MeshingError, match="not the straight mesh"):
        brep.curve_tet10(straight, [shape], ["b"], 0.6)
    tet4 = TetMesh(straight.points, straight.cells[:, :4], straight.region)
    with pytest.raises(MeshingError, match="TET10"):
        brep.curve_tet10(tet4, [shape], ["b"], EDGE)


# ------------------------------------------------------------------ by projection (mesh.curve)

def _cylinder_tube(radius=R):
    """The cylinder's round face as a :class:`~designlab.mesh.curve.Tube` (axis z)."""
    from designlab.mesh.curve import Tube

    def centre(u):
        u = np.asarray(u, float)
        return np.column_stack([0 * u, 0 * u, u])

    def d_centre(u):
        u = np.asarray(u, float)
        return np.column_stack([0 * u, 0 * u, 1 + 0 * u])

    def dd_centre(u):
        return np.zeros((len(np.asarray(u)), 3))

    return Tube(centre, d_centre, dd_centre, radius, -H / 2, H / 2, seeds=64)


@pytest.fixture(scope="module")
def projected(cylinder):
    from designlab.mesh.curve import curve_boundary

    shape, straight, _ = cylinder
    planes = brep.planar_faces(shape)
    points, info = curve_boundary(straight, _cylinder_tube(), planes)
    return planes, points, info


def test_planar_faces_of_the_cylinder_are_its_caps(projected):
    planes, _, _ = projected
    assert len(planes) == 2
    for o, n in planes:
        assert abs(abs(n[2]) - 1) < 1e-12 and abs(abs(o[2]) - H / 2) < 1e-12


def test_projected_mid_nodes_on_the_cylinder_caps_and_rims(cylinder, projected):
    """Round-face mid-nodes on the radius within 1e-6 mm; cap mid-nodes stay on their plane
    (off the rim: unchanged); rim mid-nodes on both the circle and the cap's plane; the interior,
    the corners and the cells unchanged; gmsh's second-order nodes (curve_tet10) are the same
    points here (parametric and nearest-point midpoints coincide on a cylinder)."""
    _, straight, curved = cylinder
    _, points, info = projected
    pairs, mids, n = _surface_edges(straight)
    lateral = np.unique(mids[np.abs(n[:, 2]) < 0.5])
    assert len(lateral) > 100
    assert np.abs(np.hypot(*points[lateral, :2].T) - R).max() < 1e-6
    cap = np.unique(mids[np.abs(n[:, 2]) > 0.999])
    assert np.abs(np.abs(points[cap, 2]) - H / 2).max() < 1e-12          # on the plane
    rim = np.abs(np.hypot(*points[cap, :2].T) - R) < 1e-6
    assert rim.sum() > 10 and (~rim).sum() > 10
    assert np.array_equal(points[cap[~rim]], straight.points[cap[~rim]])
    assert np.abs(np.hypot(*straight.points[cap[rim], :2].T) - R).min() > 1e-3  # the chord's
    assert info["rim_mid_nodes"] == rim.sum() and info["rim_not_converged"] == 0
    assert info["surface_mid_nodes"] == len(np.setdiff1d(lateral, cap))
    interior = np.setdiff1d(np.unique(straight.cells[:, 4:]), np.unique(mids))
    corners = np.unique(straight.cells[:, :4])
    assert np.array_equal(points[interior], straight.points[interior])
    assert np.array_equal(points[corners], straight.points[corners])
    assert np.abs(points - curved.points).max() < 1e-9


def test_projected_cylinder_valid_closer_volume_and_deterministic(cylinder, projected):
    from designlab.fem import elements
    from designlab.fem.elements import tet_element
    from designlab.mesh.curve import curve_boundary

    shape, straight, _ = cylinder
    planes, points, _ = projected
    xi = np.vstack([elements.TET10_NODES_XI, tet_element(10).quadrature.points])
    assert elements.tet10_jacobians(points, straight.cells, xi).min() > 0
    v = elements.tet10_volume(points, straight.cells)
    assert abs(v / (np.pi * R ** 2 * H) - 1) < 1e-3
    again, _ = curve_boundary(straight, _cylinder_tube(), planes)
    assert np.array_equal(again, points)


def test_projector_not_the_mesh_surface_is_an_error(cylinder):
    from designlab.mesh.curve import curve_boundary

    shape, straight, _ = cylinder
    with pytest.raises(MeshingError, match="off the surface"):
        curve_boundary(straight, _cylinder_tube(1.1 * R), brep.planar_faces(shape))
    tet4 = TetMesh(straight.points, straight.cells[:, :4], straight.region)
    with pytest.raises(MeshingError, match="TET10"):
        curve_boundary(tet4, _cylinder_tube(), brep.planar_faces(shape))


def test_bent_tube_projection_newton_on_a_curved_centreline():
    """Three quarters of a torus (a tube along a circular arc, cut by two planes): every
    mid-node of the round face at the minor radius from the centre circle within 1e-6 mm
    (nearest point by Newton from a KD-tree seed), the rims' also on their end plane, the end
    faces' others unchanged; the volume within 0.1 % of 3/4 2 pi^2 R r^2 (straight: -1 % or
    worse); gmsh's second-order nodes (curve_tet10) are the same points (4e-15 mm apart when
    written)."""
    from build123d import Axis, Circle, Plane, Pos, revolve

    from designlab.fem import elements
    from designlab.mesh.curve import Tube, curve_boundary

    Rm, rm, h = 4.0, 1.2, 0.7
    shape = revolve(Plane.XZ * Pos(Rm, 0) * Circle(rm), Axis.Z, 270)
    straight = _straight(shape, h)

    def centre(u):
        u = np.asarray(u, float)
        return np.column_stack([Rm * np.cos(u), Rm * np.sin(u), 0 * u])

    def d_centre(u):
        u = np.asarray(u, float)
        return np.column_stack([-Rm * np.sin(u), Rm * np.cos(u), 0 * u])

    def dd_centre(u):
        u = np.asarray(u, float)
        return np.column_stack([-Rm * np.cos(u), -Rm * np.sin(u), 0 * u])

    tube = Tube(centre, d_centre, dd_centre, rm, 0.0, 1.5 * np.pi, seeds=300)
    planes = brep.planar_faces(shape)
    assert len(planes) == 2
    points, info = curve_boundary(straight, tube, planes)
    _, mids, n = _surface_edges(straight)
    on_plane = [np.abs((straight.points[mids] - o) @ nrm).max(axis=1) < 1e-9 for o, nrm in planes]
    m = np.unique(mids[~(on_plane[0] | on_plane[1])])           # round-face triangles' mid-nodes
    rho = np.hypot(np.hypot(*points[m, :2].T) - Rm, points[m, 2])
    assert np.abs(rho - rm).max() < 1e-6
    for (o, nrm), sel in zip(planes, on_plane):
        cap = np.unique(mids[sel])
        assert np.abs((points[cap] - o) @ nrm).max() < 1e-9
        rim = np.isin(cap, m)
        assert rim.sum() > 5 and (~rim).sum() > 0
        assert np.array_equal(points[cap[~rim]], straight.points[cap[~rim]])
    assert info["rim_mid_nodes"] > 10 and info["rim_not_converged"] == 0
    exact = 0.75 * 2 * np.pi ** 2 * Rm * rm ** 2
    assert elements.tet10_volume(straight.points, straight.cells) / exact - 1 < -0.01
    assert abs(elements.tet10_volume(points, straight.cells) / exact - 1) < 1e-3
    gm = brep.curve_tet10(straight, [shape], ["b"], h)
    assert np.linalg.norm(points - gm.points, axis=1).max() < 1e-9
