"""Tetrahedral meshing: regions, conforming interfaces, facet sets, TET10, quality, VTU, errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from build123d import Box, Pos
from scipy.spatial import cKDTree

from designlab.errors import MeshingError, ParameterError
from designlab.mesh import meshing
from designlab.geometry.body import Body
from designlab.mesh.tetmesh import TET10_EDGES, TRI6_EDGES, box_tet_mesh
from designlab.mesh.facets import cell_faces, interface_facets
from designlab.mesh.io import read_vtu, write_vtu
from designlab.mesh.quality import dihedral_angles, mesh_quality, radius_ratios
from designlab.mesh.meshing import (MeshResult, _solid_angle_sum, mesh_bodies,
                                        mesh_bodies_detailed, save_mesh, winding_number)

# a 16 x 6 x 0.6 mm strap with a 0.2 mm thick meander trace embedded at mid-thickness
L, W, T, TT = 16.0, 6.0, 0.6, 0.2


def _trace():
    legs = [Pos(0, y, T / 2) * Box(8.0, 0.6, TT) for y in (-1.2, 0.0, 1.2)]
    links = [Pos(3.7, -0.6, T / 2) * Box(0.6, 1.8, TT), Pos(-3.7, 0.6, T / 2) * Box(0.6, 1.8, TT)]
    shape = legs[0]
    for s in legs[1:] + links:
        shape = shape + s
    return shape


def _bodies():
    trace = _trace()
    strap = Pos(0, 0, T / 2) * Box(L, W, T) - trace
    return {"strap": Body("strap", strap, "NinjaFlex"), "trace": Body("trace", trace, "PI-ETPU")}


SELECTORS = {
    "top": lambda c, n: n[:, 2] > 0.9,
    "xmin": lambda c, n: c[:, 0] < -L / 2 + 1e-6,
}


@pytest.fixture(scope="module")
def strap_result() -> MeshResult:
    return mesh_bodies_detailed(_bodies(), SELECTORS, edge_length=0.6, order=1)


@pytest.fixture(scope="module")
def strap_mesh(strap_result):
    return strap_result.mesh


# ------------------------------------------------------------------ regions and interfaces

def test_every_cell_has_a_named_region(strap_mesh):
    m = strap_mesh
    assert set(m.region_names.values()) == {"strap", "trace"}
    assert m.materials == {"strap": "NinjaFlex", "trace": "PI-ETPU"}
    assert len(m.region) == m.n_cells
    assert set(np.unique(m.region)) == set(m.region_names)


def test_region_volumes_match_bodies(strap_result):
    got = strap_result.region_volumes()
    trace_volume = _bodies()["trace"].shape.volume
    assert got["trace"] == pytest.approx(trace_volume, rel=0.02)
    assert got["strap"] == pytest.approx(L * W * T - trace_volume, rel=0.02)
    assert strap_result.mesh.volume == pytest.approx(L * W * T, rel=0.01)


def test_interface_is_conforming(strap_mesh):
    m = strap_mesh
    tri = m.facet_sets["interface:strap|trace"]
    assert len(tri) > 0
    faces = np.sort(cell_faces(m.cells), axis=1)
    owner_cell = np.repeat(np.arange(m.n_cells), 4)
    keys, inverse, counts = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
    lookup = {tuple(k): i for i, k in enumerate(keys)}
    ids = np.array([lookup[tuple(k)] for k in np.sort(tri, axis=1)])
    assert (counts[ids] == 2).all(), "an interface triangle is not shared by exactly two cells"
    sid, tid = m.region_id("strap"), m.region_id("trace")
    for i in ids[:200]:
        cells = owner_cell[inverse.ravel() == i]
        assert sorted(m.region[cells].tolist()) == sorted([sid, tid])
    # no duplicated nodes anywhere (so none at the interface either)
    assert not cKDTree(m.points).query_pairs(1e-9)
    # every node is used
    assert len(np.unique(m.cells)) == m.n_points


def test_trace_surface_is_fully_interface(strap_mesh):
    """The embedded trace touches no outer boundary: its whole surface is the interface."""
    m = strap_mesh
    tri = m.facet_sets["interface:strap|trace"]
    p = m.points[tri]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert area == pytest.approx(_bodies()["trace"].shape.area, rel=0.02)


def test_positive_orientation_both_orders(strap_mesh):
    assert (strap_mesh.corner_volumes > 0).all()
    assert (strap_mesh.quadratic().corner_volumes > 0).all()


# ------------------------------------------------------------------ facet sets

def test_facet_sets_selected_on_the_boundary(strap_result):
    m, eps = strap_result.mesh, strap_result.epsilon
    top, xmin = m.facet_sets["top"], m.facet_sets["xmin"]
    assert len(top) and len(xmin)
    # fTetWild keeps the surface within its envelope epsilon of the input
    assert np.abs(m.points[top][:, :, 2] - T).max() <= eps
    assert np.abs(m.points[xmin][:, :, 0] + L / 2).max() <= eps
    p = m.points[top]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert area == pytest.approx(L * W, rel=1e-3)
    # outward: normals of the top set point +z
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (n[:, 2] > 0).all()


@pytest.mark.slow
def test_empty_facet_set_names_it():
    with pytest.raises(MeshingError, match="'nowhere'"):
        mesh_bodies([_bodies()["trace"]], {"nowhere": lambda c, n: c[:, 0] > 1e3},
                    edge_length=0.5, order=1)


# ------------------------------------------------------------------ TET10

def test_tet10_mid_nodes_on_straight_edges(strap_mesh):
    q = strap_mesh.quadratic()
    assert q.order == 2 and q.cells.shape[1] == 10
    p = q.points
    mid = 0.5 * (p[q.cells[:, TET10_EDGES[:, 0]]] + p[q.cells[:, TET10_EDGES[:, 1]]])
    assert np.allclose(p[q.cells[:, 4:]], mid, atol=1e-12)
    for tri in q.facet_sets.values():
        assert tri.shape[1] == 6
        fm = 0.5 * (p[tri[:, TRI6_EDGES[:, 0]]] + p[tri[:, TRI6_EDGES[:, 1]]])
        assert np.allclose(p[tri[:, 3:]], fm, atol=1e-12)
    assert not cKDTree(p).query_pairs(1e-9)


def test_order_two_is_the_default():
    m = mesh_bodies([_bodies()["trace"]], edge_length=0.5)
    assert m.order == 2 and (m.corner_volumes > 0).all()


# ------------------------------------------------------------------ refinement

def test_refinement_sphere_gives_finer_cells():
    block = Body("block", Pos(0, 0, 2) * Box(20, 6, 4), "ABS")
    centre = np.array([-5.0, 0.0, 2.0])
    res = mesh_bodies_detailed([block], edge_length=1.5, refinement=[(centre, 2.5, 0.5)],
                               order=1)
    m = res.mesh
    cen = m.points[m.cells].mean(axis=1)
    p = m.points[m.cells]
    edge = np.linalg.norm(p[:, [0, 1, 2, 0, 1, 2]] - p[:, [1, 2, 0, 3, 3, 3]], axis=2).mean(1)
    inside = np.linalg.norm(cen - centre, axis=1) < 2.0
    mirror = np.linalg.norm(cen - centre * [-1, 1, 1], axis=1) < 2.0
    assert edge[inside].mean() < 0.75
    assert edge[mirror].mean() > 1.5 * edge[inside].mean()
    assert m.volume == pytest.approx(480.0, rel=1e-3)


def test_bad_refinement_and_options():
    bodies = _bodies()
    with pytest.raises(ParameterError, match="refinement"):
        mesh_bodies(bodies, refinement=[((0, 0), 1.0, 0.2)])
    with pytest.raises(ParameterError, match="order"):
        mesh_bodies(bodies, order=3)
    with pytest.raises(ParameterError, match="quality"):
        mesh_bodies(bodies, quality="ultra")
    with pytest.raises(ParameterError, match="edge_length"):
        mesh_bodies(bodies, edge_length=-1.0)


# ------------------------------------------------------------------ failures

def test_fTetWild_failure_retries_then_one_line_error(monkeypatch):
    calls = []

    def broken(*args, **kw):
        calls.append(args[2:5])  # edge, epsilon, stop energy
        raise RuntimeError("simulated fTetWild crash")

    monkeypatch.setattr(meshing, "_tetwild", broken)
    with pytest.raises(MeshingError) as err:
        mesh_bodies(_bodies(), edge_length=0.6, mesher="tetwild")
    msg = str(err.value)
    assert "\n" not in msg and "strap, trace" in msg and "simulated fTetWild crash" in msg
    assert len(calls) == 3
    (h0, e0, s0), (h1, e1, _), (h2, _, s2) = calls
    assert e1 < e0 and h2 < h0 and s2 != s0  # tighter envelope, then finer / other energy


@pytest.mark.slow
def test_lost_thin_body_is_detected(monkeypatch):
    """A mesh in which the trace has vanished (here: no cell tagged) fails the volume check."""
    monkeypatch.setattr(meshing, "_attempts", lambda h, eps, e: [(h, eps, e)])
    monkeypatch.setattr(meshing, "tag_regions",
                        lambda points, cells, surfaces, host, pad: np.full(len(cells), host))
    with pytest.raises(MeshingError, match="'trace' meshed to 0 mm\\^3 instead of"):
        mesh_bodies(_bodies(), edge_length=1.0, order=1, mesher="tetwild")


def _abort(*args):
    """Stands for a C++ abort inside fTetWild (module level: the child process imports it)."""
    import os

    os.abort()


@pytest.mark.slow
def test_fTetWild_abort_is_contained(monkeypatch):
    """fTetWild runs in a forked child: a C++ abort there is a MeshingError here."""

    monkeypatch.setattr(meshing, "_attempts", lambda h, eps, e: [(h, eps, e)])
    monkeypatch.setattr(meshing, "_tetwild_call", _abort)
    with pytest.raises(MeshingError, match="crashed"):
        mesh_bodies(_bodies(), edge_length=1.0, order=1, mesher="tetwild")


def test_not_a_solid_and_overlaps_are_refused():
    from build123d import Rectangle

    with pytest.raises(MeshingError, match="flat"):
        mesh_bodies([Body("flat", Rectangle(2, 2), "ABS")])
    a = Body("a", Box(2, 2, 2), "ABS")
    b = Body("b", Pos(1, 0, 0) * Box(2, 2, 2), "ABS")
    with pytest.raises(MeshingError, match="overlap"):
        mesh_bodies([a, b])
    with pytest.raises(MeshingError, match="unique"):
        mesh_bodies([a, Body("a", Pos(5, 0, 0) * Box(1, 1, 1), "ABS")])
    with pytest.raises(MeshingError, match="no bodies"):
        mesh_bodies([])


# ------------------------------------------------------------------ helpers

@pytest.mark.slow
def test_winding_number_fast_matches_exact():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=2.0)
    cyl = trimesh.creation.cylinder(radius=0.5, height=6.0, sections=64)
    rng = np.random.default_rng(1)
    for s in (sphere, cyl):
        q = rng.uniform(-3.5, 3.5, (3000, 3))
        fast = winding_number(q, s.vertices, s.faces)
        exact = _solid_angle_sum(q, s.vertices[s.faces])
        assert np.abs(fast - exact).max() < 0.05
        assert ((fast > 0.5) == (exact > 0.5)).mean() > 0.999
        assert np.abs(exact[np.abs(q).max(axis=1) < 0.3] - 1).max() < 1e-9  # inside both


def test_interface_facets_of_a_split_box():
    m = box_tet_mesh(2.0, 1.0, 1.0, 4, 2, 3)
    cen = m.points[m.cells].mean(axis=1)
    region = (cen[:, 0] > 1.0).astype(int)
    sets = interface_facets(m.cells, region, {0: "left", 1: "right"})
    tri = sets["interface:left|right"]
    assert len(tri) == 2 * 2 * 3  # two triangles per quad of the x = 1 plane
    assert np.allclose(m.points[tri][:, :, 0], 1.0)
    n = np.cross(m.points[tri[:, 1]] - m.points[tri[:, 0]], m.points[tri[:, 2]] - m.points[tri[:, 0]])
    assert (n[:, 0] > 0).all()  # outward of "left"


def test_quality_measures_on_known_tetrahedra():
    regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]])
    corner = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 1e-6]])
    c = np.array([[0, 1, 2, 3]])
    assert np.allclose(dihedral_angles(regular, c), np.degrees(np.arccos(1 / 3)))
    assert radius_ratios(regular, c)[0] == pytest.approx(1.0)
    assert sorted(dihedral_angles(corner, c)[0]) == pytest.approx([54.7356] * 3 + [90] * 3,
                                                                  abs=1e-3)
    assert radius_ratios(corner, c)[0] == pytest.approx(np.sqrt(3) - 1)
    assert radius_ratios(flat, c)[0] < 1e-4


def test_quality_report(strap_result):
    q = mesh_quality(strap_result.mesh)
    d = q.as_dict()
    assert d["n_cells"] == strap_result.mesh.n_cells == sum(d["radius_ratio_hist"])
    assert 0 < q.radius_ratio_min <= q.radius_ratio_mean <= 1
    assert 0 < q.min_dihedral_deg < 70.6 < q.max_dihedral_deg < 180
    assert q.n_poor < 0.01 * q.n_cells
    json.dumps(d)
    rep = strap_result.report()
    assert rep["regions"]["trace"]["cells"] > 0
    assert abs(rep["regions"]["trace"]["volume_error_percent"]) < 2
    json.dumps(rep)


# ------------------------------------------------------------------ I/O

@pytest.mark.parametrize("order", [1, 2])
def test_vtu_round_trip(strap_mesh, tmp_path, order):
    m = strap_mesh if order == 1 else strap_mesh.quadratic()
    path = write_vtu(m, tmp_path / "m.vtu")
    r = read_vtu(path)
    assert r.order == order
    assert np.array_equal(r.points, m.points) and np.array_equal(r.cells, m.cells)
    assert np.array_equal(r.region, m.region)
    assert r.region_names == m.region_names and r.materials == m.materials
    assert set(r.facet_sets) == set(m.facet_sets)
    for k in m.facet_sets:
        assert np.array_equal(r.facet_sets[k], m.facet_sets[k])
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]  # no temp file left behind


def test_vtu_readable_by_meshio(strap_mesh, tmp_path):
    import meshio

    write_vtu(strap_mesh.quadratic(), tmp_path / "m.vtu")
    mm = meshio.read(tmp_path / "m.vtu")
    assert len(mm.cells_dict["tetra10"]) == strap_mesh.n_cells


def test_save_mesh_writes_vtu_and_json(strap_result, tmp_path):
    vtu, js = save_mesh(strap_result, tmp_path / "out")
    rep = json.loads(js.read_text())
    assert rep["n_cells"] == strap_result.mesh.n_cells
    assert set(rep["facet_sets"]) == set(strap_result.mesh.facet_sets)
    assert read_vtu(vtu).n_cells == strap_result.mesh.n_cells


@pytest.mark.slow
def test_cli_rejects_unknown_part(tmp_path):
    out = subprocess.run([sys.executable, "-m", "designlab.cli", "mesh", "teapot", "--out",
                          str(tmp_path / "x")], capture_output=True, text=True)
    assert out.returncode == 2 and "part" in out.stderr
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------ the real parts

@pytest.mark.slow
@pytest.mark.parametrize("name", ["strap", "fingertip", "flexure"])
def test_default_parts_mesh(name):
    from designlab.mesh.meshing import mesh_part_detailed
    from designlab.geometry.parts import make_part

    part = make_part(name)
    res = mesh_part_detailed(part, quality="coarse", order=2, refine=False)
    m = res.mesh
    assert set(m.region_names.values()) == set(part.mesh_bodies())
    # against the exact B-rep volume; the thin helix loses most to its faceted surface
    rtol = 0.05 if name == "flexure" else 0.02
    for body, vol in res.body_volumes.items():
        assert res.region_volumes()[body] == pytest.approx(vol, rel=rtol), body
    for k in part.facet_sets():
        assert len(m.facet_sets[k]) > 0, k
    assert (m.corner_volumes > 0).all()
    assert not cKDTree(m.points).query_pairs(1e-9)


@pytest.mark.slow
def test_cli_mesh_strap(tmp_path):
    out = subprocess.run([sys.executable, "-m", "designlab.cli", "mesh", "strap", "--quality",
                          "coarse", "--no-refine", "--order", "1", "--out", str(tmp_path)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    rep = json.loads((tmp_path / "mesh.json").read_text())
    assert rep["order"] == 1 and set(rep["regions"]) == {"strap", "trace_left", "trace_right"}
    assert read_vtu(tmp_path / "mesh.vtu").n_cells == rep["n_cells"]


# ------------------------------------------------------------------ gmsh from the B-rep

def test_gmsh_is_the_default_and_deterministic():
    """Same input -> the same mesh, bit for bit (gmsh on one thread with a fixed seed)."""
    a = mesh_bodies_detailed(_bodies(), SELECTORS, edge_length=0.6, order=2)
    b = mesh_bodies_detailed(_bodies(), SELECTORS, edge_length=0.6, order=2)
    assert a.mesher == b.mesher == "gmsh"
    for x, y in ((a.mesh.points, b.mesh.points), (a.mesh.cells, b.mesh.cells),
                 (a.mesh.region, b.mesh.region)):
        assert x.shape == y.shape and np.array_equal(x, y)
    assert {k: v.tolist() for k, v in a.mesh.facet_sets.items()} == \
        {k: v.tolist() for k, v in b.mesh.facet_sets.items()}


@pytest.mark.slow
def test_gmsh_failure_falls_back_to_fTetWild(monkeypatch, tmp_path):
    """gmsh fails on every attempt -> fTetWild meshes it, the result says so, and nothing is
    written into the working directory."""
    from designlab.mesh import brep

    def broken(*a, **kw):
        raise MeshingError("simulated gmsh failure")

    monkeypatch.setattr(brep, "tetrahedralize", broken)
    monkeypatch.chdir(tmp_path)
    res = mesh_bodies_detailed(_bodies(), SELECTORS, edge_length=0.6, order=1)
    assert res.mesher == "tetwild" and res.mesh.n_cells > 0
    assert sum("simulated gmsh failure" in a for a in res.attempts) == 3
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(MeshingError, match="with gmsh failed"):
        mesh_bodies(_bodies(), edge_length=0.6, mesher="gmsh")


def test_stl_soup_is_meshed_with_fTetWild_and_open_stl_refused(tmp_path):
    import trimesh

    from designlab.mesh.meshing import mesh_stl

    box = trimesh.creation.box((10.0, 4.0, 2.0))
    box.export(tmp_path / "box.stl")
    res = mesh_stl(tmp_path / "box.stl", edge_length=1.0, order=1)
    assert res.mesher == "tetwild"
    assert res.mesh.volume == pytest.approx(80.0, rel=0.01)
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    open_box.export(tmp_path / "open.stl")
    with pytest.raises(MeshingError, match="not closed: 3 open edges"):
        mesh_stl(tmp_path / "open.stl", edge_length=1.0)


# ------------------------------------------------------------------ failures name the body, temp dirs

def _tetwild_dirs() -> set:
    import tempfile
    from pathlib import Path

    return set(Path(tempfile.gettempdir()).glob("designlab-tetwild-*"))


@pytest.mark.parametrize("isolate", [True, False], ids=["child", "in-process"])
@pytest.mark.slow
def test_fTetWild_leaves_nothing_behind(tmp_path, monkeypatch, isolate):
    """fTetWild writes __tracked_surface.stl into its working directory: in a child process or
    in this one, that is a temporary directory that is gone afterwards, and the caller's working
    directory is where it was, empty."""
    import os

    import trimesh

    box = trimesh.creation.box((4.0, 3.0, 2.0))
    monkeypatch.chdir(tmp_path)
    before = _tetwild_dirs()
    points, cells = meshing._tetwild(np.asarray(box.vertices, float), np.asarray(box.faces),
                                     1.0, 0.004, 10.0, None, 1, isolate)
    assert len(cells) > 0 and os.getcwd() == str(tmp_path)
    assert list(tmp_path.iterdir()) == []
    assert _tetwild_dirs() - before == set()


def test_all_meshers_failing_name_the_body_in_one_line(monkeypatch):
    """gmsh fails whenever body 'b' is in the call (a multi-line message), fTetWild fails too:
    one line that names 'b' (found by meshing each body alone), counts the attempts, and does
    not paste the whole logs."""
    from designlab.mesh import brep

    real = brep.tetrahedralize

    def picky(shapes, names, *a, **kw):
        if "b" in names:
            raise MeshingError("gmsh failed on surface 7\n" + "Invalid boundary mesh\n" * 40)
        return real(shapes, names, *a, **kw)

    def crash(*a, **kw):
        raise RuntimeError("simulated fTetWild crash\n" + "trace line\n" * 40)

    monkeypatch.setattr(brep, "tetrahedralize", picky)
    monkeypatch.setattr(meshing, "_tetwild", crash)
    bodies = [Body(n, Pos(3.0 * k, 0, 0) * Box(1, 1, 1), "ABS") for k, n in enumerate("abc")]
    with pytest.raises(MeshingError) as err:
        mesh_bodies(bodies, edge_length=0.5, order=1)
    msg = str(err.value)
    assert "\n" not in msg and len(msg) < 600
    assert "body 'b' fails on its own (gmsh failed on surface 7" in msg
    assert "3 gmsh attempts, 3 fTetWild attempts" in msg and "simulated fTetWild crash" in msg
    with pytest.raises(MeshingError) as err:
        mesh_bodies(bodies, edge_length=0.5, order=1, mesher="gmsh")
    assert "with gmsh failed: body 'b'" in str(err.value) and "fTetWild" not in str(err.value)
    monkeypatch.setattr(brep, "tetrahedralize", lambda *a, **kw: (_ for _ in ()).throw(
        MeshingError("interface trouble")) if len(a[1]) > 1 else real(*a, **kw))
    with pytest.raises(MeshingError, match="each body meshes on its own, not together"):
        mesh_bodies(bodies, edge_length=0.5, order=1, mesher="gmsh")


def test_gmsh_in_threads_gives_the_serial_mesh():
    """gmsh's state is global: threads (Dask's threaded workers) mesh one at a time and each
    gets exactly the mesh a serial call gives."""
    from concurrent.futures import ThreadPoolExecutor

    from designlab.mesh import brep

    shapes = [Box(2, 1, 1), Pos(0, 0, 1) * Box(2, 1, 1)]
    serial = brep.tetrahedralize(shapes, ["lo", "hi"], 0.4)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: brep.tetrahedralize(shapes, ["lo", "hi"], 0.4),
                                range(4)))
    for r in results:
        assert all(np.array_equal(x, y) for x, y in zip(r, serial))
