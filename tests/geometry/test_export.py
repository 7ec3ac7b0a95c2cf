"""Printable export: tessellation, 3MF (core + PrusaSlicer volumes), STL/STEP round trips,
printability checks, all-or-nothing writes, rendering, and the ``export``/``show`` commands.

Real-client checks use Debian's prusa-slicer (``--info``, ``--export-3mf`` round trip, slicing with
two extruders and reading the G-code's tool changes) and lib3mf for the 3MF core.
"""

from __future__ import annotations

import re
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from build123d import Align, Box, Cylinder, Pos, Sphere

from conftest import require_tool
from designlab.errors import MeshingError
from designlab.geometry.body import Body
from designlab.geometry.export import (export_bodies, parse_formats, prepare, threemf_of,
                                       write, write_png)
from designlab.geometry.printability import PrintabilityError, check_body, check_part
from designlab.geometry.tessellate import tessellate

LOW = (Align.CENTER, Align.CENTER, Align.MIN)
TRACE_Z = (0.6, 0.8)


def strap_bodies(trace_w: float = 0.8, trace_t: float = 0.2, overlap: bool = False) -> dict:
    """A 40x10x2 mm strap with an embedded trace (line + pad) on extruder 2, and a steel ball."""
    z0 = TRACE_Z[0]
    trace = (Pos(0, 0, z0) * Box(30, trace_w, trace_t, align=LOW)
             + Pos(-15, 0, z0) * Box(2, 4, trace_t, align=LOW))
    strap = Box(40, 10, 2, align=LOW)
    if not overlap:
        strap = strap - trace
    return {"strap": Body("strap", strap, "TPU", (0.2, 0.4, 0.8), 1),
            "trace": Body("trace", trace, "conductive TPU", (0.1, 0.1, 0.1), 2),
            "ball": Body("ball", Pos(25, 0, 3) * Sphere(3), "steel", (0.8, 0.8, 0.8), 1,
                         printed=False)}


# --- tessellation ----------------------------------------------------------------------------

def test_tessellate_volumes_and_closure():
    box = tessellate(Box(10, 4, 2))
    assert box.is_watertight and box.is_winding_consistent
    assert box.volume == pytest.approx(80.0, rel=1e-9)
    cyl = tessellate(Cylinder(5, 10), tolerance=0.01)
    assert cyl.is_watertight
    # chordal error 0.01 mm on r = 5: volume within 0.5 % (and below the true volume)
    assert cyl.volume == pytest.approx(np.pi * 25 * 10, rel=5e-3)
    assert cyl.volume < np.pi * 25 * 10
    ball = tessellate(Body("b", Sphere(3), "steel"))  # a Body works too
    assert ball.is_watertight and ball.volume == pytest.approx(4 / 3 * np.pi * 27, rel=5e-3)


def test_tessellate_list_of_disjoint_solids():
    """A list of solids (build123d's ShapeList after fusing disjoint parts) is one mesh."""
    parts = Box(2, 2, 2).fuse(Pos(5, 0, 0) * Box(2, 2, 2))
    m = tessellate(list(parts) if isinstance(parts, list) else [parts])
    assert m.is_watertight and m.volume == pytest.approx(16.0)
    assert len(m.split(only_watertight=True)) == 2


def test_tessellate_rejects_open_shell():
    face = Box(10, 4, 2).faces()[0]
    with pytest.raises(MeshingError):
        tessellate(face)
    assert not tessellate(face, check=False).is_watertight


# --- 3MF ------------------------------------------------------------------------------------

def test_3mf_core_is_one_object_with_per_triangle_materials(tmp_path):
    import lib3mf

    bodies = strap_bodies()
    p = prepare("strap", bodies)
    path = tmp_path / "strap.3mf"
    path.write_bytes(threemf_of(p))
    names = zipfile.ZipFile(path).namelist()
    for member in ("[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model",
                   "Metadata/Slic3r_PE_model.config", "Metadata/model_settings.config"):
        assert member in names
    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    reader = model.QueryReader("3mf")
    reader.SetStrictModeActive(True)
    reader.ReadFromFile(str(path))
    objs = model.GetMeshObjects()
    found = []
    while objs.MoveNext():
        found.append(objs.GetCurrentMeshObject())
    assert len(found) == 1
    obj = found[0]
    n_strap, n_trace = len(p.meshes["strap"].faces), len(p.meshes["trace"].faces)
    assert obj.GetTriangleCount() == n_strap + n_trace
    assert obj.IsManifoldAndOriented()
    props = [t.PropertyIDs[0] for t in obj.GetAllTriangleProperties()]
    groups = model.GetBaseMaterialGroups()
    assert groups.MoveNext()
    group = groups.GetCurrentBaseMaterialGroup()
    material = {pid: group.GetName(pid) for pid in group.GetAllPropertyIDs()}
    used = [material[k] for k in props]
    assert used.count("TPU") == n_strap and used.count("conductive TPU") == n_trace
    # the printed volume of the object is strap + trace, the bought ball is not in it
    assert p.meshes["strap"].volume + p.meshes["trace"].volume == pytest.approx(800.0, rel=1e-6)


def _prusa(*args, cwd=None) -> str:
    exe = require_tool("prusa-slicer")
    res = subprocess.run([exe, "--loglevel", "1", *map(str, args)], capture_output=True,
                         text=True, timeout=300, cwd=cwd)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    return res.stdout


def prusa_info(path) -> list[dict]:
    """One dict per object PrusaSlicer loads from ``path`` (``--info``)."""
    out, cur = [], None
    for line in _prusa("--info", path).splitlines():
        if line.startswith("[") and line.rstrip().endswith("]"):
            cur = {}
            out.append(cur)
        elif cur is not None and "=" in line:
            k, v = (s.strip() for s in line.split("=", 1))
            cur[k] = v
    return out


TWO_EXTRUDERS = ["--nozzle-diameter", "0.4,0.4", "--filament-diameter", "1.75,1.75",
                 "--temperature", "225,225", "--first-layer-temperature", "225,225",
                 "--extruder-offset", "0x0,0x0", "--retract-length", "1,1",
                 "--retract-length-toolchange", "2,2"]


def slice_gcode(path, out, layer: float, extra=()) -> Path:
    _prusa("--export-gcode", "-o", out, "--layer-height", layer, "--first-layer-height", layer,
           *TWO_EXTRUDERS, *extra, path)
    return Path(out)


def gcode_extrusions(path) -> dict[int, np.ndarray]:
    """Extruding moves per tool: ``{tool: (k, 3) array of (x, y, z)}`` (absolute E, G92 resets)."""
    tool, z, e_last, x, y = 0, 0.0, 0.0, 0.0, 0.0
    relative = False
    out: dict[int, list] = {}
    word = re.compile(r"([XYZEF])(-?\d*\.?\d+)")
    for line in Path(path).read_text().splitlines():
        line = line.split(";", 1)[0].strip()
        if not line:
            continue
        if re.fullmatch(r"T\d+", line):
            tool = int(line[1:])
            continue
        if line.startswith("M83"):
            relative = True
        elif line.startswith("M82"):
            relative = False
        if line.startswith("G92"):
            w = dict((k, float(v)) for k, v in word.findall(line))
            e_last = w.get("E", e_last)
            continue
        if not (line.startswith("G1 ") or line.startswith("G0 ")):
            continue
        w = dict((k, float(v)) for k, v in word.findall(line))
        x, y, z = w.get("X", x), w.get("Y", y), w.get("Z", z)
        if "E" in w:
            de = w["E"] if relative else w["E"] - e_last
            e_last = e_last + w["E"] if relative else w["E"]
            if de > 0 and ("X" in w or "Y" in w):
                out.setdefault(tool, []).append((x, y, z))
    return {k: np.array(v) for k, v in out.items()}


def test_3mf_in_prusaslicer_is_one_object_two_volumes_in_place(tmp_path):
    require_tool("prusa-slicer")
    bodies = strap_bodies()
    p = prepare("strap", bodies)
    path = tmp_path / "strap.3mf"
    path.write_bytes(threemf_of(p))

    info = prusa_info(path)
    assert len(info) == 1, info  # one object, not one per body
    assert info[0]["manifold"] == "yes"
    n = len(p.meshes["strap"].faces) + len(p.meshes["trace"].faces)
    assert int(info[0]["number_of_facets"]) == n
    assert float(info[0]["volume"]) == pytest.approx(800.0, rel=1e-4)
    assert float(info[0]["size_x"]) == pytest.approx(40.0, abs=1e-4)

    # PrusaSlicer's own project export keeps the two volumes, their names and extruders
    rt = tmp_path / "roundtrip.3mf"
    _prusa("--export-3mf", "-o", rt, path)
    cfg = zipfile.ZipFile(rt).read("Metadata/Slic3r_PE_model.config").decode()
    assert cfg.count("<object ") == 1 and cfg.count("<volume ") == 2
    assert re.search(r'key="name" value="trace".*?key="extruder" value="2"', cfg, re.S)
    assert re.search(r'key="name" value="strap".*?key="extruder" value="1"', cfg, re.S)

    # sliced with 0.1 mm layers, the trace is printed by the second tool, inside the strap's
    # footprint and only on the two layers of its 0.2 mm thickness
    g = gcode_extrusions(slice_gcode(path, tmp_path / "strap.gcode", 0.1))
    assert set(g) == {0, 1}
    t0, t1 = g[0], g[1]
    assert np.all(t1[:, :2].min(0) >= t0[:, :2].min(0)) and np.all(
        t1[:, :2].max(0) <= t0[:, :2].max(0))
    assert sorted(set(np.round(t1[:, 2], 3))) == [0.7, 0.8]
    span = t1[:, :2].max(0) - t1[:, :2].min(0)
    assert span[0] == pytest.approx(30.0, abs=1.0)  # the 30 mm trace line, not moved


# --- STL / STEP round trips -------------------------------------------------------------------

def test_files_round_trip(tmp_path):
    from build123d import import_step

    bodies = strap_bodies()
    files = export_bodies("strap", bodies, tmp_path, formats="stl,3mf,step,gltf", png=False)
    names = sorted(f.name for f in files)
    assert names == ["strap-strap.stl", "strap-trace.stl", "strap.3mf", "strap.glb",
                     "strap.step"]
    for body in ("strap", "trace"):
        stl = tmp_path / "strap" / f"strap-{body}.stl"
        assert stl.read_bytes()[:5] != b"solid"  # binary STL
        m = trimesh.load(stl)
        assert m.is_watertight
        assert m.volume == pytest.approx(bodies[body].shape.volume, rel=1e-5)
    step = import_step(tmp_path / "strap" / "strap.step")
    total = sum(b.shape.volume for b in bodies.values())
    assert step.volume == pytest.approx(total, rel=1e-6)
    glb = trimesh.load(tmp_path / "strap" / "strap.glb")
    assert {re.sub(r"_\d+$", "", k) for k in glb.geometry} == {"strap", "trace", "ball"}
    assert sorted(glb.extents) == pytest.approx(sorted([40 / 2 + 25 + 3, 10, 6]), abs=0.05)
    # all writes are atomic: no temp files are left behind
    assert not [f for f in (tmp_path / "strap").iterdir() if f.name.startswith(".")]


# --- printability -------------------------------------------------------------------------

def test_good_part_passes_with_measured_feature_sizes():
    reports = {r.body: r for r in check_part("strap", strap_bodies())}
    assert reports["strap"].ok and reports["trace"].ok, reports
    tr = reports["trace"]
    assert tr.watertight and tr.manifold and tr.valid_brep
    assert tr.min_wall_mm == pytest.approx(0.8, abs=1e-3)   # trace width vs 2 nozzles
    assert tr.min_skin_mm == pytest.approx(0.2, abs=1e-3)   # trace thickness vs layer
    assert reports["strap"].min_skin_mm == pytest.approx(0.6, abs=1e-3)  # under the trace
    assert not reports["ball"].printed


def test_thin_trace_is_reported():
    thin = {r.body: r for r in check_part("strap", strap_bodies(trace_w=0.3, trace_t=0.05))}
    assert not thin["trace"].ok
    text = " ".join(thin["trace"].problems)
    assert "wall thinner" in text and "(thinnest 0.3 mm)" in text
    assert "skin thinner" in text and "(thinnest 0.05 mm)" in text
    # an embedded second-extruder line 0.6 mm wide fails (PrusaSlicer drops it, see the slicing
    # test), a 0.6 mm wall of the host material would pass
    r6 = {r.body: r for r in check_part("strap", strap_bodies(trace_w=0.6))}
    assert not r6["trace"].ok and "2 nozzle widths" in r6["trace"].problems[0]
    assert thin["strap"].ok  # the strap around the thin pocket is still printable


def test_overlapping_bodies_are_reported():
    rep = {r.body: r for r in check_part("strap", strap_bodies(overlap=True))}
    assert any("overlaps trace" in p for p in rep["strap"].problems)
    assert any("overlaps strap" in p for p in rep["trace"].problems)


def test_open_mesh_is_not_watertight_nor_manifold():
    body = strap_bodies()["trace"]
    m = tessellate(body.shape)
    broken = trimesh.Trimesh(m.vertices, m.faces[1:], process=False)
    r = check_body("strap", body, mesh=broken)
    assert not r.ok and not r.watertight and not r.manifold
    assert "mesh not watertight" in r.problems


def test_failed_check_writes_nothing(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(PrintabilityError) as exc:
        export_bodies("strap", strap_bodies(trace_w=0.3), out)
    assert "strap/trace" in str(exc.value) and "\n" not in str(exc.value)
    assert not out.exists()


def test_writer_failure_leaves_nothing(tmp_path, monkeypatch):
    import designlab.geometry.export as ex

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(ex, "_save_step", boom)
    p = prepare("strap", strap_bodies())
    with pytest.raises(OSError):
        write(p, tmp_path, formats="stl,3mf,step", png=False)
    assert not (tmp_path / "strap").exists()
    # an existing directory keeps its old files and gets no temp files
    (tmp_path / "strap").mkdir()
    (tmp_path / "strap" / "strap.3mf").write_bytes(b"old")
    with pytest.raises(OSError):
        write(p, tmp_path, formats="stl,3mf,step", png=False)
    assert [f.name for f in (tmp_path / "strap").iterdir()] == ["strap.3mf"]
    assert (tmp_path / "strap" / "strap.3mf").read_bytes() == b"old"


def test_multi_part_write_is_all_or_nothing(tmp_path, monkeypatch):
    """The second part's STEP fails: the first part's finished files are not left behind."""
    import designlab.geometry.export as ex

    real = ex._save_step
    calls = []

    def second_fails(assy, path):
        calls.append(path)
        if len(calls) == 2:
            raise OSError("disk full")
        real(assy, path)

    monkeypatch.setattr(ex, "_save_step", second_fails)
    a, b = prepare("a", strap_bodies()), prepare("b", strap_bodies())
    out = tmp_path / "deep" / "out"
    with pytest.raises(OSError):
        ex.write_all([a, b], out, formats="stl,step", png=False)
    assert len(calls) == 2 and not (tmp_path / "deep").exists()
    files = ex.write_all([a, b], out, formats="stl,3mf", png=False)
    assert sorted(f.relative_to(out).as_posix() for f in files) == [
        "a/a-strap.stl", "a/a-trace.stl", "a/a.3mf", "b/b-strap.stl", "b/b-trace.stl", "b/b.3mf"]


def test_parse_formats():
    assert parse_formats("STL, 3mf,stp") == ("stl", "3mf", "step")
    with pytest.raises(Exception, match="--format"):
        parse_formats("stl,obj")


# --- rendering ------------------------------------------------------------------------------

def _colour_fraction(png: Path, rgb, tol=60) -> float:
    import matplotlib.image as mpimg

    img = mpimg.imread(png)[..., :3] * 255
    return float((np.abs(img - np.asarray(rgb) * 255).max(-1) < tol).mean())


@pytest.mark.parametrize("backend", ["pyvista", "matplotlib"])
def test_render_shows_bodies(tmp_path, backend):
    from designlab.geometry.render import ensure_display, render_bodies

    if backend == "pyvista" and not ensure_display():
        require_tool("Xvfb")
    png = tmp_path / f"{backend}.png"
    used = render_bodies(strap_bodies(), png, size=(400, 300), backend=backend)
    assert used == backend
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert _colour_fraction(png, (1, 1, 1), tol=8) > 0.3  # white background
    assert _colour_fraction(png, (0.2, 0.4, 0.8), tol=90) > 0.01  # the blue strap is seen


def test_write_png_is_atomic_and_checks_suffix(tmp_path):
    with pytest.raises(Exception, match=r"\.png"):
        write_png(strap_bodies(), tmp_path / "x.jpg")
    path = write_png(strap_bodies(), tmp_path / "x.png", size=(300, 200))
    assert path.exists() and [f.name for f in tmp_path.iterdir()] == ["x.png"]


def test_separate_pieces_are_separate_objects_laid_out(tmp_path):
    """A second host-material piece (a clip printed beside the strap) is its own 3MF object,
    placed beside the strap on the plate; the trace stays a volume of the strap object."""
    import lib3mf

    bodies = strap_bodies()
    bodies["clip"] = Body("clip", Pos(0, 0, 5) * Box(8, 6, 1.5, align=LOW), "TPU",
                          (0.3, 0.5, 0.9), 1)
    p = prepare("strap", bodies)
    path = tmp_path / "two.3mf"
    path.write_bytes(threemf_of(p))
    model = lib3mf.get_wrapper().CreateModel()
    model.QueryReader("3mf").ReadFromFile(str(path))
    items = model.GetBuildItems()
    boxes = []
    while items.MoveNext():
        item = items.GetCurrent()
        obj = item.GetObjectResource()
        mesh = model.GetMeshObjectByID(obj.GetResourceID())
        t = item.GetObjectTransform().Fields
        shift = np.array([t[3][0], t[3][1], t[3][2]])
        v = np.array([[x.Coordinates[0], x.Coordinates[1], x.Coordinates[2]]
                      for x in mesh.GetVertices()]) + shift
        boxes.append((mesh.GetName(), v.min(0), v.max(0)))
    names = [b[0] for b in boxes]
    assert names == ["strap-strap", "strap-clip"]
    (_, lo0, hi0), (_, lo1, hi1) = boxes
    assert lo0[2] == pytest.approx(0) and lo1[2] == pytest.approx(0)  # both on the plate
    assert hi0[0] + 4.99 <= lo1[0]  # side by side, 5 mm apart
    if require_tool("prusa-slicer"):
        assert len(prusa_info(path)) == 2


# --- the default parts -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def default_parts():
    from designlab.geometry.parts import PARTS, make_part

    return {name: make_part(name, None, None) for name in PARTS}


@pytest.fixture(scope="module")
def prepared_parts(default_parts):
    return {name: prepare(name, part.build()) for name, part in default_parts.items()}


@pytest.mark.parametrize("name", ["strap", "flexure", "fingertip"])
def test_default_parts_are_printable(prepared_parts, name):
    p = prepared_parts[name]
    for r in p.reports:
        if r.printed:
            assert r.watertight and r.manifold and r.valid_brep and r.volume_mm3 > 0
    assert p.ok, [r for r in p.reports if not r.ok]


def test_thin_area_is_measured_over_the_area():
    """A 0.2 mm fin 4 mm long and 3 mm tall on a 2 mm plate: its two sides (2 x 4 x 3 =
    24 mm^2) are thinner than the nozzle, whatever the tessellation (two big triangles each);
    the plate's 90 deg edges are corners, not thin walls."""
    from designlab.geometry.printability import feature_sizes

    body = Box(10, 10, 2, align=LOW) + Pos(0, 0, 2) * Box(0.2, 4, 3, align=LOW)
    fs = feature_sizes(tessellate(body))
    assert fs.thin_wall_area == pytest.approx(24.0, rel=0.05)
    assert fs.min_wall == pytest.approx(0.2, abs=1e-3)
    assert fs.thin_skin_area == 0.0
    plate = feature_sizes(tessellate(Box(10, 10, 2, align=LOW)))
    assert plate.thin_wall_area == 0.0 and plate.thin_skin_area == 0.0
    # a 0.05 mm fin (an eighth of the nozzle) is a sliver the slicer leaves out: not a weak wall
    sliver = feature_sizes(tessellate(Box(10, 10, 2, align=LOW)
                                      + Pos(0, 0, 2) * Box(0.05, 4, 3, align=LOW)))
    assert sliver.min_wall == pytest.approx(0.05, abs=1e-3) and sliver.thin_wall_area == 0.0


@pytest.mark.slow
def test_default_parts_slice(prepared_parts, default_parts, tmp_path):
    """Every default part slices; the strap (0.1 mm layers, two extruders) prints its traces with
    the second tool, in the trace layers, whole (their full extent) and inside the strap."""
    from designlab.geometry.export import print_objects

    require_tool("prusa-slicer")
    for name, p in prepared_parts.items():
        path = tmp_path / f"{name}.3mf"
        path.write_bytes(threemf_of(p))
        info = prusa_info(path)
        assert len(info) == len(print_objects(p))
        assert all(o["manifold"] == "yes" for o in info)
        layer = 0.1 if name == "strap" else 0.3
        g = gcode_extrusions(slice_gcode(path, tmp_path / f"{name}.gcode", layer))
        if name != "strap":
            assert set(g) == {0} and len(g[0]) > 100
            continue
        strap = default_parts["strap"]
        assert set(g) == {0, 1}
        t1 = g[1]
        z_layers = sorted(set(np.round(t1[:, 2], 3)))
        lo, hi = strap.trace_z
        n_trace_layers = round((hi - lo) / strap.layer_height)
        assert z_layers[0] == pytest.approx(lo + strap.layer_height)
        assert len([z for z in z_layers if z <= hi + 1e-6]) == n_trace_layers
        assert max(z_layers) <= strap.thickness + 1e-6  # pads rise to the top, not above
        traces = np.vstack([p.meshes[k].vertices for k in ("trace_left", "trace_right")])
        extent = traces[:, :2].max(0) - traces[:, :2].min(0)
        assert t1[:, :2].max(0) - t1[:, :2].min(0) == pytest.approx(extent, abs=1.0)
        t0 = g[0][np.isin(np.round(g[0][:, 2], 3), z_layers)]
        assert np.all(t1[:, :2].min(0) >= t0[:, :2].min(0))
        assert np.all(t1[:, :2].max(0) <= t0[:, :2].max(0))


# --- command line --------------------------------------------------------------------------------

def _run(argv, capsys):
    from designlab.cli import main

    try:
        main(argv)
        code = 0
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("argv, needle", [
    (["export", "wing"], "part='wing'"),
    (["export", "strap", "--set", "strap_width"], "--set"),
    (["export", "strap", "--set", "no_such=1"], "no_such"),
    (["export", "strap", "--set", "strap_width=abc"], "strap_width"),
    (["export", "strap", "--set", "strap_width=1000"], "strap_width"),
    (["export", "all", "--set", "strap_width=12"], "PART.NAME=VALUE"),
    (["export", "strap", "--format", "stl,obj"], "--format"),
    (["export", "strap", "--nozzle", "0"], "--nozzle"),
    (["export", "strap", "--config", "MISSING.toml"], "--config"),
    (["export", "strap", "--config", "BAD.toml"], "--config"),
])
def test_export_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys, argv, needle):
    out = tmp_path / "out"
    (tmp_path / "BAD.toml").write_text("strap_width = [unclosed\n")
    argv = [a.replace("MISSING.toml", str(tmp_path / "missing.toml"))
            .replace("BAD.toml", str(tmp_path / "BAD.toml")) for a in argv]
    code, _, err = _run(argv + ["--out", str(out)], capsys)
    assert code == 2
    assert needle in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_show_bad_input(tmp_path, capsys):
    for argv, needle in ((["show", "all", "--out", str(tmp_path / "a.png")], "part='all'"),
                         (["show", "strap", "--out", str(tmp_path / "a.jpg")], ".png"),
                         (["show", "wing", "--out", str(tmp_path / "a.png")], "wing")):
        code, _, err = _run(argv, capsys)
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_cli_export_and_show(tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, _ = _run(["export", "strap", "--out", str(out), "--set", "strap_width=14"],
                           capsys)
    assert code == 0
    files = sorted(f.name for f in (out / "strap").iterdir())
    assert files == ["strap-nail_plate.stl", "strap-strap.stl", "strap-trace_left.stl",
                     "strap-trace_right.stl", "strap.3mf", "strap.glb", "strap.png", "strap.step"]
    assert "printability" in stdout and "wrote" in stdout
    code, _, _ = _run(["export", "all", "--out", str(out), "--format", "3mf", "--no-png",
                       "--set", "flexure.disc_thickness=3.5"], capsys)
    assert code == 0
    for part in ("fingertip", "flexure"):
        assert [f.name for f in (out / part).iterdir()] == [f"{part}.3mf"]
    png = tmp_path / "pics" / "fingertip.png"
    code, _, _ = _run(["show", "fingertip", "--out", str(png), "--width", "400", "--height",
                       "300"], capsys)
    assert code == 0 and png.read_bytes()[:4] == b"\x89PNG"


def test_cli_export_refuses_unprintable_part(tmp_path, capsys, monkeypatch):
    import designlab.geometry.printability as pr

    monkeypatch.setattr(pr, "MM_WALL_FACTOR", 5.0)  # traces now "too thin": 0.8 < 2.0 mm
    out = tmp_path / "out"
    code, _, err = _run(["export", "strap", "--out", str(out), "--no-png"], capsys)
    assert code == 2
    assert "trace_left" in err and "nothing written" in err
    assert not out.exists()


def test_self_intersecting_solid_is_reported():
    """Two overlapping boxes' faces sewn into one shell: a self-intersecting solid."""
    from build123d import Solid
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeSolid
    from OCP.TopoDS import TopoDS_Shell

    from designlab.geometry.printability import brep_problems

    a, b = Box(2, 2, 2), Pos(1, 1, 1) * Box(2, 2, 2)
    builder, shell = BRep_Builder(), TopoDS_Shell()
    builder.MakeShell(shell)
    for f in a.faces() + b.faces():
        builder.Add(shell, f.wrapped)
    bad = Solid(BRepBuilderAPI_MakeSolid(shell).Solid())
    assert any("self-intersecting" in p for p in brep_problems(bad))
    assert brep_problems(a) == []
    r = check_body("x", Body("x", bad, "PLA"))
    assert not r.ok and not r.valid_brep


def test_a_folder_by_a_targets_name_is_one_line_and_leaves_no_temp(tmp_path):
    from designlab.errors import OutputError
    from designlab.geometry.export import _Staging

    (tmp_path / "a.png").mkdir()
    staging = _Staging()
    staging.run(tmp_path, [("a.png", lambda p: p.write_bytes(b"x"))])
    with pytest.raises(OutputError, match="a.png: it is a directory"):
        staging.commit()
    assert [p.name for p in tmp_path.iterdir()] == ["a.png"]


def test_show_refuses_a_folder_as_its_png_before_any_work(tmp_path, capsys):
    from designlab.cli import main

    (tmp_path / "d.png").mkdir()
    with pytest.raises(SystemExit) as e:
        main(["show", "fingertip", "--out", str(tmp_path / "d.png")])
    assert e.value.code == 2 and "(it is a folder)" in capsys.readouterr().err


def test_a_failed_glb_leaves_no_buffer_file(tmp_path, monkeypatch):
    """On a full disk the glTF writer fails after opening its buffer file beside the target
    (``<temp>.bin.tmp``): nothing of it stays."""
    from cadquery.occ_impl.exporters import assembly as cq_assembly

    from designlab.errors import OutputError
    from designlab.geometry.assembly import save_assembly_gltf

    def full_disk(assy, path, **kw):
        Path(path).with_suffix(".bin.tmp").write_bytes(b"partial")
        return False

    monkeypatch.setattr(cq_assembly, "exportGLTF", full_disk)
    with pytest.raises(OutputError, match="glTF export"):
        save_assembly_gltf(None, tmp_path / "part.glb")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_render_that_cannot_fit_the_address_space_limit_is_refused(tmp_path):
    """Under ``ulimit -v`` (6 GB) an 8000 x 8000 render aborted the interpreter (the renderer
    cannot fail an allocation): refused in one line naming a size that fits, which renders."""
    import resource
    import sys

    script = ("import designlab as dl\nfrom designlab.errors import ParameterError\n"
              "try:\n    dl.Strap().render('big.png', size=(8000, 8000))\n"
              "except ParameterError as e:\n    print(e)\n")

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (6_000_000_000, 6_000_000_000))

    res = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                         text=True, preexec_fn=limit, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    m = re.search(r"size=\(8000, 8000\) is not allowed: .* about (\d+) x \1 px", res.stdout)
    assert m and not (tmp_path / "big.png").exists(), res.stdout
    side = int(m.group(1))
    ok = subprocess.run([sys.executable, "-c", f"import designlab as dl\n"
                         f"dl.Strap().render('fits.png', size=({side}, {side}))\n"],
                        cwd=tmp_path, capture_output=True, text=True, preexec_fn=limit,
                        timeout=600)
    assert ok.returncode == 0 and (tmp_path / "fits.png").stat().st_size > 0, ok.stderr[-2000:]
