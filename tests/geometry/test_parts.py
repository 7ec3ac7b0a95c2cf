"""Parametric parts: valid closed solids, closed-form volumes, no overlaps, named facet sets,
one-line parameter errors, paper load points and sensor axes, assemblies."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from designlab.errors import ParameterError
from designlab.geometry.body import Body
from designlab.geometry.fingertip import (TABLE_II_HEIGHTS, TABLE_II_RADII, TABLE_III_HEIGHTS,
                                          TABLE_III_RADII, CantileverFingertip)
from designlab.geometry.flexure import SpringFlexure
from designlab.geometry.parts import PARTS, make_part, part_name
from designlab.geometry.solids import volume
from designlab.geometry.strap import ArchStrap

SETTINGS = settings(max_examples=5, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ------------------------------------------------------------------------------- helpers
def tri_mesh(shape, tol: float = 0.05) -> trimesh.Trimesh:
    """Tessellation of a build123d shape as a cleaned trimesh (pole slivers removed)."""
    v, f = shape.tessellate(tol, 0.3)
    m = trimesh.Trimesh(np.round(np.array([tuple(x) for x in v]), 7), np.array(f))
    m.update_faces(m.nondegenerate_faces())
    m.merge_vertices()
    return m


def check_bodies(part, tol: float = 0.05, overlaps: bool = True) -> dict[str, Body]:
    """Every body: a valid closed Solid with a watertight, outward tessellation; no overlaps
    (pairwise boolean intersection volume ~ 0, unless ``overlaps=False``)."""
    bodies = part.build()
    assert set(part.mesh_bodies()) <= set(bodies)
    for name, b in bodies.items():
        assert b.name == name
        assert type(b.shape).__name__ == "Solid" and b.shape.is_valid, name
        m = tri_mesh(b.shape, tol)
        assert m.is_watertight and m.is_winding_consistent, name
        assert m.volume > 0 and m.volume == pytest.approx(b.shape.volume, rel=0.05), name
    names = list(bodies) if overlaps else []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            sa, sb = bodies[a].shape, bodies[b].shape
            inter = sa & sb
            vol = 0.0 if inter is None else abs(inter.volume)
            assert vol < 1e-4 * min(sa.volume, sb.volume), (a, b, vol)
    return bodies


def facets(bodies, names, samples: int = 0):
    """(centroids, normals, areas) of the tessellated boundary of ``names``; with ``samples``,
    uniform random surface points instead (each carrying an equal share of the area), which
    resolves small regions on big planar faces that the tessellation covers with big triangles."""
    ms = [tri_mesh(bodies[n].shape, 0.02) for n in names]
    m = trimesh.util.concatenate(ms)
    if not samples:
        return m.triangles_center, m.face_normals, m.area_faces
    pts, idx = trimesh.sample.sample_surface(m, samples, seed=1)
    return pts, m.face_normals[idx], np.full(samples, m.area / samples)


def one_line_error(make, name):
    with pytest.raises(ParameterError) as exc:
        make()
    assert exc.value.name == name
    assert "\n" not in str(exc.value) and str(exc.value).startswith(f"{name}=")
    return str(exc.value)


# ------------------------------------------------------------------------------- strategies
@st.composite
def straps(draw):
    w = draw(st.floats(0.8, 1.2))  # embedded traces: at least two nozzle lines
    g = draw(st.floats(0.4, 0.9))
    base = ArchStrap(arch_width=draw(st.floats(36, 60)), arch_height=draw(st.floats(5, 12)),
                     legs=draw(st.sampled_from([4, 6])), trace_width=w, trace_gap=g,
                     lead_length=w + g + 0.2, pad_width=draw(st.floats(1.0, 1.6)),
                     gauge_length=draw(st.floats(4, 8)), gauge_offset=8.0,
                     trace_cover=draw(st.sampled_from([0.1, 0.2])))
    lo, hi = base.gauge_offset_range()
    return dataclasses.replace(base, gauge_offset=lo + draw(st.floats(0, 1)) * (hi - lo))


@st.composite
def fingertips(draw):
    h = draw(st.floats(0, 25))
    rf = draw(st.floats(7, 11))
    r = draw(st.floats(max(0.0, 5.7 - h), min(9.0, rf)))
    return CantileverFingertip(h=h, r=r, fingertip_radius=rf,
                               load_table="II" if h + r > 22.76 else "III",
                               skin_thickness=draw(st.sampled_from([0.0, 0.0, 1.5])))


@st.composite
def flexures(draw):
    rw = draw(st.floats(0.6, 1.4))
    D = draw(st.floats(16, 34))
    a_min = math.atan(2.2 * rw / (math.pi * D))
    return SpringFlexure(wire_radius=rw, mean_diameter=D,
                         pitch_angle=draw(st.floats(1.3 * a_min, 0.15)),
                         active_coils=draw(st.floats(1.0, 3.0)),
                         ends=draw(st.sampled_from(["plain", "closed_ground"])),
                         disc_radius=D / 2 + rw + 1, disc_bore=D / 2 - rw - 1)


# ------------------------------------------------------------------------------- strap
@SETTINGS
@given(straps())
@pytest.mark.slow
def test_strap_builds_and_fills_the_slotted_outline(p):
    bodies = check_bodies(p)
    filled = sum(bodies[n].shape.volume for n in ("strap", "trace_left", "trace_right"))
    assert filled == pytest.approx(p.outline_area() * p.thickness, rel=1e-6)
    # the traces are embedded: inside the strap's thickness, under >= one layer of cover
    for n in ("trace_left", "trace_right"):
        bb = bodies[n].shape.bounding_box()
        assert bb.min.Z == pytest.approx(p.trace_cover)
        assert bb.max.Z == pytest.approx(p.thickness)  # the pads reach the top surface
        assert bodies[n].extruder == 2 and bodies[n].material == "PI-ETPU"
    assert bodies["strap"].extruder == 1 and bodies["strap"].material == "NinjaFlex"


def test_strap_defaults_are_the_paper():
    p = ArchStrap()
    paper = {"strap_width": 15, "thickness": 0.6, "trace_thickness": 0.2, "layer_height": 0.1,
             "slot_count": 3}
    for k, v in paper.items():
        assert getattr(p, k) == v
    assert p.trace_width >= 0.8  # at least two nozzle lines (embedded second extruder)
    assert p.thickness - p.trace_cover - p.trace_thickness >= p.layer_height


def test_strap_trace_volume_closed_form():
    p = ArchStrap()
    b = p.build()
    R, w, t = p.radius, p.trace_width, p.trace_thickness
    a = p.gauge_angles()
    legs = sum((a["b"] - a["a"]) * (R + y) * w for y in p.leg_offsets)
    turns = sum(a["turn"] / 2 * ((R + p.leg_offsets[i + 1] + w / 2) ** 2
                                 - (R + p.leg_offsets[i] - w / 2) ** 2)
                for i in range(p.legs - 1))
    leads = sum((a["p0"] - a["b"]) * (R + y) * w for y in (p.leg_offsets[0], p.leg_offsets[-1]))
    pads = sum((a["p1"] - a["p0"]) * (R + y) * p.pad_width
               for y in (p.leg_offsets[0], p.leg_offsets[-1]))
    expect = (legs + turns + leads) * t + pads * (p.thickness - p.trace_cover)
    for n in ("trace_left", "trace_right"):
        assert b[n].shape.volume == pytest.approx(expect, rel=1e-9)


def test_strap_facet_sets():
    p = ArchStrap()
    b = p.build()
    c, n, area = facets(b, p.mesh_bodies())
    sets = {k: f(c, n) for k, f in p.facet_sets().items()}
    assert set(sets) >= {"nail_plate", "finger_contact", "pad_left", "pad_right"}
    a = p.gauge_angles()
    R = p.radius
    pad_area = 2 * (a["p1"] - a["p0"]) * R * p.pad_width  # two pads, mean radius R +- y
    assert area[sets["pad_left"]].sum() == pytest.approx(pad_area, rel=1e-3)
    assert area[sets["pad_right"]].sum() == pytest.approx(pad_area, rel=1e-3)
    assert c[sets["pad_left"], 0].max() < 0 < c[sets["pad_right"], 0].min()
    assert area[sets["finger_contact"]].sum() == pytest.approx(p.contact_length * p.strap_width,
                                                               rel=2e-2)
    slot = math.pi * p.slot_width ** 2 / 4 + (p.slot_length - p.slot_width) * p.slot_width
    tabs = 2 * (p.tab_length * p.strap_width - p.slot_count * slot)
    # big planar triangles straddle the arch foot (and the tessellation depends on what else
    # meshed the cached shape before): measure the tab area with uniform surface samples
    cs, ns, a_s = facets(b, p.mesh_bodies(), samples=100_000)
    tab = p.facet_sets()["nail_plate"](cs, ns) & (ns[:, 2] < -0.9)
    assert a_s[tab].sum() == pytest.approx(tabs, rel=0.03)
    assert not (sets["nail_plate"] & sets["finger_contact"]).any()
    for center, radius, edge in p.refinement():
        assert center.shape == (3,) and radius > 0 and 0 < edge <= p.trace_thickness * 1.5


@pytest.mark.parametrize("kw, name", [
    ({"trace_width": 3.0}, "trace_width"),
    ({"trace_width": 0.3}, "trace_width"),  # below one nozzle line
    ({"legs": 5}, "legs"),
    ({"arch_height": 25.0}, "arch_height"),
    ({"gauge_offset": 1.0}, "gauge_offset"),
    ({"gauge_offset": 30.0}, "gauge_offset"),
    ({"trace_thickness": 0.35}, "trace_thickness"),
    ({"tab_length": 6.0}, "tab_length"),
    ({"thickness": float("nan")}, "thickness"),
    ({"legs": 4.5}, "legs"),
    ({"slot_count": "3"}, "slot_count"),
])
def test_strap_rejects(kw, name):
    msg = one_line_error(lambda: ArchStrap(**kw), name)
    if name == "trace_width" and kw[name] > 1:
        assert "<=" in msg and "legs" in msg


# ------------------------------------------------------------------------------- fingertip
def _outline_volume(R: float, h: float, r: float) -> float:
    """Cylinder R x h plus the top rounded with edge radius r (Pappus on the quarter disc)."""
    top = math.pi * ((R - r) ** 2 * r + 2 * (R - r) * math.pi * r ** 2 / 4 + 2 * r ** 3 / 3)
    return math.pi * R ** 2 * h + top


@SETTINGS
@given(fingertips())
@pytest.mark.slow
def test_fingertip_builds(p):
    b = check_bodies(p)
    R, h, r, rb, t = p.fingertip_radius, p.h, p.r, p.ball_radius, p.skin_thickness
    # OCC's adaptive volume integration is good to ~1e-5 on these analytic faces
    assert volume(b["fingertip"].shape) == pytest.approx(
        _outline_volume(R, h, r) - 2 / 3 * math.pi * rb ** 3, rel=1e-4)
    assert ("skin" in b) == (t > 0) and ("skin" in p.mesh_bodies()) == (t > 0)
    if t:
        assert volume(b["skin"].shape) == pytest.approx(
            _outline_volume(R + t, h, r + t) - _outline_volume(R, h, r), rel=1e-4)
        assert b["skin"].material == "silicone" and not b["skin"].printed
    rb, rbolt = p.ball_radius, p.bolt_diameter / 2
    zt = p.bolt_top_z
    hole = math.pi * rbolt ** 2 * (zt + math.sqrt(rb ** 2 - rbolt ** 2))
    z1 = math.sqrt(rb ** 2 - rbolt ** 2)  # spherical cap below the hole's flat start
    hole += math.pi * ((rb - z1) * rb ** 2 - (rb ** 3 - z1 ** 3) / 3)
    assert b["ball"].shape.volume == pytest.approx(4 / 3 * math.pi * rb ** 3 - hole, rel=1e-6)
    s = p.sensor_size ** 2 * p.sensor_thickness + 2 / 3 * math.pi * p.button_radius ** 3
    assert b["sensor_1"].shape.volume == pytest.approx(s, rel=1e-6)
    assert b["cap"].shape.volume == pytest.approx(
        math.pi * (p.base_radius ** 2 - (rbolt + 0.2) ** 2) * p.cap_thickness, rel=1e-6)
    assert {n for n, x in b.items() if x.printed} == {"fingertip", "base", "cap"}
    assert all(b[n].material == "ABS" for n in ("fingertip", "base", "cap"))
    assert all(b[n].material == "steel" for n in ("ball", "bolt"))
    outer = b["skin" if t else "fingertip"].shape
    for name, (pt, d) in p.load_points().items():  # load points lie on the outer surface
        assert outer.distance_to(tuple(pt)) < 1e-6, name
        assert np.linalg.norm(d) == pytest.approx(1.0)


def test_fingertip_defaults_reproduce_tables(shared):
    paper = json.loads((shared / "data/papers/fingertip_xu2014.json").read_text())
    t2, t3 = paper["tested_sensor_table_II"], paper["optimized_sensor_table_III"]
    opt, tested = CantileverFingertip(), CantileverFingertip.tested()
    assert (opt.h, opt.r) == (t3["optimized_h_mm"], t3["optimized_r_mm"])
    assert opt.total_height == pytest.approx(t3["total_height_mm"])
    assert tested.total_height == pytest.approx(t2["total_height_mm"])
    for p in (opt, tested):
        assert 2 * p.fingertip_radius == pytest.approx(t3["total_diameter_mm"])
        assert p.ball_diameter == paper["hardware"]["central_steel_ball_diameter_mm"]
    assert TABLE_III_HEIGHTS == tuple(t3["heights_mm_h1_h6"])
    assert TABLE_III_RADII == tuple(t3["radii_mm_r1_r6"])
    assert TABLE_II_HEIGHTS == tuple(t2["heights_mm_h1_h9"])
    assert TABLE_II_RADII == tuple(t2["radii_mm_r1_r5"])
    for p, heights, radii in ((opt, TABLE_III_HEIGHTS, TABLE_III_RADII),
                              (tested, TABLE_II_HEIGHTS, TABLE_II_RADII)):
        lp = p.load_points()
        assert [lp[f"h{i + 1}"][0][2] for i in range(len(heights))] == list(heights)
        assert np.allclose([np.hypot(*lp[f"r{i + 1}"][0][:2]) for i in range(len(radii))],
                           radii, atol=1e-12)
        assert all(np.allclose(lp[f"r{i + 1}"][1], [0, 0, -1]) for i in range(len(radii)))
        for i in range(len(heights)):
            pt, d = lp[f"h{i + 1}"]
            assert d[2] == 0 and np.dot(d, pt[:2].tolist() + [0]) < 0  # lateral, inwards
        locs = p.load_locations()
        assert np.allclose(tuple(locs["h1"].position), lp["h1"][0])
    # on the optimised dome the two tables are a mirrored set of points (same datum)
    lp = opt.load_points()
    for i in range(6):
        assert np.hypot(*lp[f"h{i + 1}"][0][:2]) == pytest.approx(
            math.sqrt(81 - TABLE_III_HEIGHTS[i] ** 2))


def test_sensor_axes(shared):
    paper = json.loads((shared / "data/papers/fingertip_xu2014.json").read_text())
    p = CantileverFingertip()
    axes, contacts = p.sensor_axes()
    assert np.allclose(np.linalg.norm(axes, axis=1), 1)
    assert np.allclose(np.degrees(np.arccos(axes[:, 2])), 45)  # 45 deg from vertical
    az = np.degrees(np.arctan2(axes[:, 1], axes[:, 0])) % 360
    assert np.allclose(az, [270, 30, 150])
    # columns of the paper's eq. 8 geometry matrix are the sensor axes (4 decimals)
    assert np.allclose(np.array(paper["geometry_matrix_eq_8_unit_k"]), axes.T, atol=6e-5)
    b = p.build()
    for k in range(3):  # each button touches the ball at its contact point
        assert np.linalg.norm(contacts[k]) == pytest.approx(p.ball_radius)
        assert b[f"sensor_{k + 1}"].shape.distance_to(tuple(contacts[k])) < 1e-6
        assert b["ball"].shape.distance_to(tuple(contacts[k])) < 1e-6


def test_fingertip_facet_sets():
    p = CantileverFingertip()
    b = p.build()
    c, n, area = facets(b, p.mesh_bodies(), samples=400_000)
    sets = {k: f(c, n) for k, f in p.facet_sets().items()}
    assert {"ball_seat", "sensor_well_1", "sensor_well_2", "sensor_well_3", "bolt_head",
            "load_h1", "load_r6"} <= set(sets)
    # sampled areas: ~1-3 % statistical error
    assert area[sets["ball_seat"]].sum() == pytest.approx(2 * math.pi * p.ball_radius ** 2,
                                                          rel=0.05)
    wells = [area[sets[f"sensor_well_{k}"]].sum() for k in (1, 2, 3)]
    side = p.sensor_size + 2 * p.well_clearance
    assert np.allclose(wells, wells[0], rtol=0.1)
    assert side ** 2 * 0.75 < wells[0] <= side ** 2 * 1.05  # minus the wire channel's bite
    rh, rc = p.bolt_diameter / 2 + 0.2, p.head_diameter / 2
    assert area[sets["bolt_head"]].sum() == pytest.approx(math.pi * (rc ** 2 - rh ** 2), rel=0.12)
    mount = math.pi * (p.base_radius ** 2 - (rc + 0.5) ** 2)
    assert area[sets["cap_mount"]].sum() == pytest.approx(mount, rel=0.05)
    assert not (sets["cap_mount"] & sets["bolt_head"]).any()
    for k in list(p.load_points()):
        assert sets[f"load_{k}"].any(), k
    for center, radius, edge in p.refinement():
        assert center.shape == (3,) and radius > 0 and edge > 0


def test_fingertip_silicone_skin():
    p = CantileverFingertip(skin_thickness=1.0)
    b = p.build()
    assert p.total_height == pytest.approx(21.0) and p.outer_radius == 10.0
    assert p.mesh_bodies() == ("fingertip", "skin", "base", "cap")
    pt, d = p.load_points()["h1"]
    assert np.hypot(*pt[:2]) == pytest.approx(math.sqrt(10 ** 2 - 8.41 ** 2))
    assert b["skin"].shape.distance_to(tuple(pt)) < 1e-6
    inter = b["skin"].shape & b["fingertip"].shape
    assert inter is None or abs(inter.volume) < 1e-6


@pytest.mark.parametrize("kw, name", [
    ({"r": 10.0}, "r"),
    ({"r": 9.0, "fingertip_radius": 8.0}, "r"),
    ({"h": 0.0, "r": 3.0}, "r"),
    ({"base_height": 5.0}, "base_height"),
    ({"bolt_length": 4.0}, "bolt_length"),
    ({"load_table": "IV"}, "load_table"),
])
def test_fingertip_rejects(kw, name):
    one_line_error(lambda: CantileverFingertip(**kw), name)


@pytest.mark.parametrize("kw", [{}, {"ball_diameter": 10.0, "base_height": 9.0,
                                     "base_radius": 10.0}, {"sensor_size": 4.0, "gap": 0.8}])
def test_well_top_skin_is_the_cad_skin_over_the_well_corner(kw):
    """:func:`well_top_skin` against the built base: vertical rays through the base's top face
    over the first sensor's well (a 0.01 mm grid); the least material between the top face
    and the next face below is the predicted skin."""
    from designlab.geometry.fingertip import well_top_skin
    from designlab.geometry.tessellate import tessellate

    p = CantileverFingertip(**kw)
    s2 = p.sensor_size / 2 + p.well_clearance
    mesh = tessellate(p.build()["base"].shape, 0.002, 0.05, check=False)
    axes, _ = p.sensor_axes()
    e = -axes[0, :2] / np.linalg.norm(axes[0, :2])      # outward, towards the first sensor
    w = np.array([-e[1], e[0]])
    radial, tangential = np.meshgrid(np.arange(2.0, p.ball_radius + 3, 0.01),
                                     np.linspace(-s2 + 0.005, s2 - 0.005, 9))
    xy = radial.reshape(-1, 1) * e + tangential.reshape(-1, 1) * w
    starts = np.column_stack([xy, np.full(len(xy), 5.0)])
    hits, ray, _ = mesh.ray.intersects_location(starts, np.tile([0.0, 0.0, -1.0], (len(xy), 1)))
    skins = []
    for k in np.unique(ray):
        z = np.sort(hits[ray == k, 2])[::-1]
        if len(z) > 1 and abs(z[0] + p.gap) < 1e-6:       # through the top face
            skins.append(z[0] - z[1])
    assert min(skins) == pytest.approx(well_top_skin(p.ball_radius, s2, p.gap), abs=0.015)


def test_the_documented_ball_diameter_end_is_refused_with_the_printable_bound(tmp_path,
                                                                             capsys):
    """ball_diameter=6 (the range's lower end) passed the range check, then its 5 mm sensor
    wells cut through the base's top face and printability failed: refused at once, one line
    naming the bound, exit 2, nothing written; a 6 mm ball with 2 mm sensors builds."""
    from designlab.cli import main

    with pytest.raises(SystemExit) as e:
        main(["export", "fingertip", "--set", "ball_diameter=6", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("error:") == 1
    assert "ball_diameter=6.0 is not allowed: >= 9.182 mm" in err
    assert not (tmp_path / "x").exists()
    one_line_error(lambda: CantileverFingertip(gap=1.0), "ball_diameter")
    CantileverFingertip(ball_diameter=6.0, sensor_size=2.0)


# ------------------------------------------------------------------------------- flexure
@SETTINGS
@given(flexures())
@pytest.mark.slow
def test_flexure_builds(p):
    # the discs are the slabs z < 0 and z > length: the spring must stay between them (checked on
    # its vertices and tessellation instead of slow B-spline booleans)
    b = check_bodies(p, tol=0.03, overlaps=False)   # the catalogue wire: r = 1.015 mm
    assert volume(b["spring"].shape) == pytest.approx(p.wire_volume(), rel=1e-4)
    z = np.array([tuple(v) for v in b["spring"].shape.vertices()])[:, 2]
    assert z.min() == pytest.approx(0, abs=1e-6) and z.max() == pytest.approx(p.length, abs=1e-6)
    zt = tri_mesh(b["spring"].shape, 0.1).vertices[:, 2]
    assert zt.min() > -1e-6 and zt.max() < p.length + 1e-6
    for name, (z0, z1) in {"base_disc": (-p.disc_thickness, 0), "tip_disc": (
            p.length, p.length + p.disc_thickness)}.items():
        zd = np.array([tuple(v) for v in b[name].shape.vertices()])[:, 2]
        assert zd.min() == pytest.approx(z0) and zd.max() == pytest.approx(z1)
    c, n, area = facets(b, ["spring"])
    sets = {k: f(c, n) for k, f in p.facet_sets().items()}
    assert sets["flexure_base"].any() and sets["flexure_tip"].any()
    assert area[sets["flexure_base"]].sum() == pytest.approx(area[sets["flexure_tip"]].sum(),
                                                             rel=0.05)


def test_flexure_visiflex_defaults(shared):
    paper = json.loads((shared / "data/papers/visiflex_flexure.json").read_text())["spring"]
    p = SpringFlexure()
    assert p.mean_diameter == paper["mean_diameter_mm"]
    assert p.pitch_angle == paper["pitch_angle_rad"]
    assert p.total_coils == paper["coils"]
    assert p.wire_diameter == paper["wire_radius_mm"]  # see the flexure module docstring
    assert p.length == pytest.approx(paper["rest_length_mm"], abs=0.01)
    # handbook axial stiffness with SS302 (G = 69 GPa) matches the paper's K_f[5][5] = 3911 N/m
    k_z = 69e3 * p.wire_diameter ** 4 / (8 * p.mean_diameter ** 3 * p.active_coils) * 1e3
    assert k_z == pytest.approx(3911, rel=0.02)
    # plain ends: the wire is exactly n_a turns of the helix
    q = SpringFlexure(ends="plain")
    assert q.wire_length() == pytest.approx(
        q.active_coils * math.hypot(math.pi * q.mean_diameter, q.pitch), rel=1e-12)
    b = q.build()
    assert volume(b["spring"].shape) == pytest.approx(q.wire_volume(), rel=1e-4)
    assert volume(p.build()["spring"].shape) == pytest.approx(p.wire_volume(), rel=1e-4)
    assert b["spring"].material == "SS302" and not b["spring"].printed
    assert b["base_disc"].material == "PLA" and b["tip_disc"].printed


def test_flexure_rejects_touching_coils():
    rw, D = 1.015, 27.73
    a_min = math.atan(2.2 * rw / (math.pi * D))
    msg = one_line_error(lambda: SpringFlexure(pitch_angle=0.9 * a_min), "pitch_angle")
    printed = float(msg.split(">= ")[1].split()[0])  # rounded up: the bound typed back works
    assert a_min <= printed <= a_min * (1 + 1e-4)
    assert SpringFlexure(pitch_angle=printed).pitch_angle == printed
    one_line_error(lambda: SpringFlexure(mean_diameter=5.0), "mean_diameter")
    one_line_error(lambda: SpringFlexure(ends="ground"), "ends")
    one_line_error(lambda: SpringFlexure(disc_radius=10.0), "disc_radius")


@pytest.mark.parametrize("ends", ["closed_ground", "plain"])
def test_flexure_from_free_length(ends):
    p = SpringFlexure.with_free_length(19.8, ends=ends)
    assert p.length == pytest.approx(19.8, abs=1e-3)
    if ends == "closed_ground":
        assert p.pitch_angle == pytest.approx(0.1029, abs=2e-4)  # the paper's angle back
    one_line_error(lambda: SpringFlexure.with_free_length(3.0), "free_length")


# ------------------------------------------------------------------------------- bad values
def _ranged_fields(cls):
    return [f for f in dataclasses.fields(cls) if f.metadata and f.metadata.get("lo") is not None
            and f.metadata.get("hi") is not None]


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.data())
def test_out_of_range_values_name_the_parameter(data):
    cls = data.draw(st.sampled_from([ArchStrap, CantileverFingertip, SpringFlexure]))
    f = data.draw(st.sampled_from(_ranged_fields(cls)))
    lo, hi = f.metadata["lo"], f.metadata["hi"]
    bad = data.draw(st.sampled_from([lo - 0.5 * (hi - lo) - 1, hi + 0.5 * (hi - lo) + 1,
                                     float("inf"), "abc"]))
    if isinstance(f.default, int) and not isinstance(bad, str) and math.isfinite(bad):
        bad = int(bad)
    with pytest.raises(ParameterError) as exc:
        make_part(part_name(cls()), {f.name: bad})
    assert exc.value.name == f.name and "\n" not in str(exc.value)


# ------------------------------------------------------------------------------- registry
def test_make_part():
    assert set(PARTS) == {"strap", "fingertip", "flexure"}
    p = make_part("fingertip", {"h": "3", "r": "8"})
    assert (p.h, p.r) == (3.0, 8.0) and part_name(p) == "fingertip"
    p = make_part("fingertip", None, {"fingertip": {"h": 2.0}, "strap": {"legs": 6}})
    assert p.h == 2.0
    assert make_part("strap", {"legs": "6"}, {"legs": 4, "sweep": {"x": 1}}).legs == 6
    one_line_error(lambda: make_part("gripper"), "part")
    one_line_error(lambda: make_part("strap", {"nope": "1"}), "nope")
    one_line_error(lambda: make_part("flexure", {"pitch_angle": "0.01"}), "pitch_angle")
    assert make_part("strap", None, {"legs": 6.0, "slot_count": 2.0}).slot_count == 2
    p1 = make_part("strap")
    assert p1.build()["strap"].shape is p1.build()["strap"].shape  # cached


# ------------------------------------------------------------------------------- assemblies
def test_assemblies_step_and_gltf(tmp_path, monkeypatch):
    import cadquery as cq

    from designlab.geometry import assembly as asm

    assert asm.assembly(ArchStrap(), name="strap").name == "strap_assembly"
    p = CantileverFingertip()
    a = asm.assembly(p)
    assert sorted(c.name for c in a.children) == sorted(p.build())
    step = asm.save_assembly_step(a, tmp_path / "fingertip.step")
    glb = asm.save_assembly_gltf(a, tmp_path / "fingertip.glb")
    back = cq.importers.importStep(str(step))
    assert len(back.solids().vals()) == len(p.build())
    scene = trimesh.load(glb)  # cadquery writes one coloured mesh per CAD face, named by body
    names = set(p.build())
    assert names <= set(scene.geometry)
    tip = scene.geometry["fingertip"].visual.material.baseColorFactor[:3] / 255
    assert np.allclose(tip, np.array(p.build()["fingertip"].color) ** 2.2, atol=0.02)  # linear
    text = step.read_text(errors="ignore")
    assert "COLOUR_RGB" in text and "sensor_1" in text

    def boom(*args, **kw):
        raise OSError("disk full")

    import cadquery.occ_impl.exporters.assembly as ex
    monkeypatch.setattr(ex, "exportAssembly", boom)
    with pytest.raises(OSError):
        asm.save_assembly_step(a, tmp_path / "bad.step")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["fingertip.glb", "fingertip.step"]


def test_no_lead_is_a_two_leg_strap_and_the_refusal_says_so():
    """lead_length = 0 ("none") needs legs = 2 (the pads then lie at the meander's ends); with
    more legs the message names that way out."""
    from designlab.errors import ParameterError
    from designlab.geometry.strap import ArchStrap

    assert ArchStrap(lead_length=0, legs=2, pad_width=0.8).lead_length == 0
    with pytest.raises(ParameterError, match=r"lead_length=0 is not allowed: .*with legs = 4.*"
                                             r"\(0, no lead, takes legs = 2\)"):
        ArchStrap(lead_length=0)
