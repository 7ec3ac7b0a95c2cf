"""FEM 6x6 of a flexure: a clamped prism against beam theory, then the meshed Visiflex helix."""

import numpy as np
import pytest

from designlab.fem.materials import get_material
from designlab.sensors.flexure.helix_fem import stiffness_6x6
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import box_tet_mesh


@pytest.fixture(scope="module")
def bar():
    a, L = 10.0, 100.0
    mesh = box_tet_mesh(a, a, L, 3, 3, 20, origin=(-a / 2, -a / 2, 0), material="steel").quadratic()
    return a, L, mesh, stiffness_6x6(mesh, "zmin", "zmax")


def test_prism_6x6_matches_beam_theory(bar):
    """Square steel bar 10 x 10 x 100 mm clamped at z=0, rigid tip: K at the bar centre."""
    a, L, mesh, fem = bar
    mat = get_material("steel")
    E, G = mat.E, mat.G
    I, A, J = a**4 / 12, a * a, 0.1406 * a**4          # J of a square section (Roark)
    k_lat = 1 / (L**3 / (12 * E * I) + L / (5 / 6 * G * A))  # Timoshenko, guided ends
    K = fem.K_centre
    assert K[0, 0] == pytest.approx(E * I / L, rel=0.03)
    assert K[1, 1] == pytest.approx(E * I / L, rel=0.03)
    assert K[2, 2] == pytest.approx(G * J / L, rel=0.03)
    assert K[3, 3] == pytest.approx(k_lat, rel=0.03)
    assert K[5, 5] == pytest.approx(E * A / L, rel=0.03)   # clamped ends stiffen by < 1 %
    # at the centre the couplings vanish (to 1 % of the geometric mean of the diagonal terms)
    scale = np.sqrt(np.outer(np.diag(K), np.diag(K)))
    off = np.abs(K - np.diag(np.diag(K))) / scale
    assert off.max() < 0.01
    assert fem.asymmetry < 1e-9
    np.testing.assert_allclose(fem.centre, [0, 0, L / 2], atol=1e-9)


def test_tip_frame_couplings_follow_the_adjoint(bar):
    a, L, mesh, fem = bar
    K_tip = fem.K
    np.testing.assert_allclose(fem.master, [0, 0, L], atol=1e-9)
    K_from_centre = transform_stiffness(fem.K_centre, transform(translation=(0, 0, -L / 2)))
    np.testing.assert_allclose(K_tip, K_from_centre, rtol=1e-9, atol=1e-6 * np.abs(K_tip).max())
    # Euler-Bernoulli tip: k_wy_vx = -L/2 * k_vx(centre) ... sign: m_y from v_x at the tip
    assert K_tip[1, 3] == pytest.approx(-L / 2 * fem.K_centre[3, 3], rel=0.02)


def test_missing_sets_raise_model_error(bar):
    from designlab.errors import ModelError

    a, L, mesh, fem = bar
    with pytest.raises(ModelError, match="does not exist"):
        stiffness_6x6(mesh, "flexure_base", "zmax")


def test_report_shows_which_model_is_closer_to_the_measurement(shared):
    """Entry by entry: an FEM matrix equal to the measurement wins every non-zero entry."""
    from designlab.sensors.flexure import report as fr
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    paper = fr.load_paper(shared / "data/papers/visiflex_flexure.json")
    h = fr.camera_offset(paper)
    K_meas_centre = transform_stiffness(paper["K_c_measured"], transform(translation=(0, 0, -h)))
    rep = fr.flexure_report(VISIFLEX_CATALOG, "camera", K_fem_spring_si=K_meas_centre, paper=paper)
    assert all(r["closer_to_measured"] == "fem" for r in rep["rows"])
    assert all(abs(r["fem_vs_measured_pct"]) < 1e-6 for r in rep["rows"])
    # an FEM twice the closed form loses wherever the closed form is already above the measurement
    K_cf = np.asarray(rep["closed_form"])
    rep2 = fr.flexure_report(VISIFLEX_CATALOG, "spring", paper=paper,
                             K_fem_spring_si=2 * np.asarray(fr.flexure_report(
                                 VISIFLEX_CATALOG, "spring", paper=paper)["closed_form"]))
    row = {r["entry"]: r for r in rep2["rows"]}
    assert row["k_vx"]["closer_to_measured"] == "closed_form"      # 10979 vs 5830 measured
    assert rep2["condition_numbers"]["fem"] == pytest.approx(rep2["condition_numbers"]["closed_form"])
    assert K_cf.shape == (6, 6)


def test_flexure_geometry_from_spring():
    pytest.importorskip("build123d")
    from designlab.errors import ParameterError
    from designlab.sensors.flexure.helix_fem import flexure_from_spring, spring_material
    from designlab.sensors.flexure.spring import VISIFLEX_AS_PRINTED, VISIFLEX_CATALOG, HelicalSpring

    f = flexure_from_spring(VISIFLEX_CATALOG)
    assert f.ends == "closed_ground" and f.active_coils == 1.75 and f.wire_radius == 1.015
    assert f.length == pytest.approx(VISIFLEX_CATALOG.free_length, abs=0.05)
    assert flexure_from_spring(VISIFLEX_AS_PRINTED).ends == "plain"
    with pytest.raises(ParameterError, match="inactive_coils"):
        flexure_from_spring(HelicalSpring(inactive_coils=1.0))
    m = spring_material(VISIFLEX_CATALOG)
    assert m.G == pytest.approx(69000.0) and m.E == 193000.0


@pytest.mark.slow
def test_small_pitch_helix_axial_stiffness_matches_closed_form():
    """Meshed helix (5 plain coils, pitch angle 0.08 rad, spring index 5) vs the zero-pitch
    closed form: axial stiffness within 10 % (the flat end footprints clamped on the discs
    shorten the free wire by ~0.35 turn, so the curved FEM is ~8 % stiffer;
    benchmarks/bench_flexure_small_pitch.py); ~30 s."""
    from designlab.sensors.flexure.helix_fem import fem_stiffness
    from designlab.sensors.flexure.spring import HelicalSpring, stiffness_zero_pitch

    s = HelicalSpring(wire_radius=2.0, mean_diameter=20.0, coils=5.0, pitch_angle=0.08)
    fem = fem_stiffness(s, edge_length=2.0, quality="coarse")
    K = stiffness_zero_pitch(s)
    assert fem.K_centre[5, 5] == pytest.approx(K[5, 5], rel=0.10)
    assert fem.K_centre[2, 2] == pytest.approx(K[2, 2], rel=0.15)
    assert fem.asymmetry < 1e-6
    assert np.all(np.linalg.eigvalsh(fem.K) > 0)


@pytest.mark.slow
def test_solid_fem_with_contact_condenses_exactly_and_contact_stiffens():
    """The Visiflex helix (gmsh TET10) condensed on its contact nodes and the tip master:
    with every contact open it is the plain solid FEM (the 6x6 recorded in test_beam_chain from
    `fem_stiffness(VISIFLEX_CATALOG)` on the straight mesh, `curved=False` now: 538.07, 538.16,
    647.77 N*mm/rad, 4.5588, 4.5577, 2.4125 N/mm) within 0.5 %; line contacts (the default): with the meshed gaps (>= 0.4 mm) kept no contact
    closes under the 0.02 mm / 2 mrad perturbations; at the 10 N working load contact stiffens
    the axial and lateral terms. Minutes on a shared machine (one factorisation per call)."""
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.contact_fem import fem_contact_stiffness
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    solid = np.array([538.07, 538.16, 647.77, 4.5588, 4.5577, 2.4125])
    res = fem_contact_stiffness(VISIFLEX_CATALOG, curved=False)
    free = np.diag(res.at(res.centre, "free"))
    assert free == pytest.approx(solid, rel=5e-3)
    assert res.info["asymmetry"] < 1e-5 and res.info["coil_pairs"] > 50
    loaded = np.diag(res.at(res.centre, "loaded"))
    assert loaded[5] > 1.1 * free[5] and loaded[3] > 1.05 * free[3]
    assert res.info["working_load"]["closed_contacts"] > 0
    # the chain stiffens like the solid at 10 N (the fast model checked against the
    # reference): loaded / no contact, axial and lateral, chain against solid
    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import with_settings

    ch = chain_stiffness(VISIFLEX_CATALOG)
    ch0 = chain_stiffness(VISIFLEX_CATALOG, with_settings(contact=False, working_load_N=0.0))
    gain_solid = loaded / free
    gain_chain = np.diag(ch.at(ch.centre, loaded=True)) / np.diag(ch0.K_centre)
    assert gain_chain[5] == pytest.approx(gain_solid[5], rel=0.05)             # axial, ~1.3
    # lateral: chain +24 %, solid +14 % (both with k_n = E* x spacing in mm; the solid with
    # node contacts); solid with line contacts (the default) +18 %
    assert gain_chain[3:5].mean() == pytest.approx(gain_solid[3:5].mean(), rel=0.10)
    assert np.all(gain_chain[:5] > 1.0) and np.all(gain_solid[[0, 1, 3, 4, 5]] > 1.0)
    kept = fem_contact_stiffness(VISIFLEX_CATALOG, gaps="meshed", mesh=res.mesh,
                                 settings=ChainSettings(working_load_N=0.0))
    assert kept.info["closed_during_perturbations"] == [0, 0]
    np.testing.assert_allclose(kept.K, kept.K_free, rtol=1e-9, atol=1e-9 * np.abs(kept.K).max())


def test_contact_spacing_is_checked_before_meshing():
    from designlab.errors import ParameterError
    from designlab.sensors.flexure.contact_fem import fem_contact_stiffness
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    pytest.importorskip("build123d")
    for bad in (-0.1, float("nan")):
        with pytest.raises(ParameterError, match="contact_spacing_mm"):
            fem_contact_stiffness(VISIFLEX_CATALOG, contact_spacing_mm=bad)


@pytest.mark.slow
def test_solid_line_contacts_remove_the_node_contacts_scatter():
    """docs/models/flexure_contact_fem.md: at the 10 N working load the node
    contacts (one node per station, 36 per turn, the earlier scheme) rock the tip 21 %
    stiffer about y than about x (606 / 734 N*mm/rad) and their 10 N diagonal error scatters
    14.8-22.0 % over 18-144 stations; line contacts (points every 0.5 mm of wire interpolated
    between the contact line's nodes) are x/y symmetric within 3 % (718 / 703) and close more
    contact points than stations. Same mesh for both, straight TET10, which these numbers are
    for (minutes on a shared machine)."""
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.contact_fem import fem_contact_stiffness
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    cs = ChainSettings(seat="bonded")
    node = fem_contact_stiffness(VISIFLEX_CATALOG, contact_spacing_mm=0.0, settings=cs,
                                 curved=False)
    line = fem_contact_stiffness(VISIFLEX_CATALOG, contact_spacing_mm=0.5, settings=cs,
                                 mesh=node.mesh)
    kn, kl = (np.diag(s.at(s.centre, "loaded")) for s in (node, line))
    assert kn[1] / kn[0] > 1.15                       # node contacts: x/y asymmetry 21 %
    assert abs(kl[1] / kl[0] - 1) < 0.05              # line contacts: 2 %
    assert abs(kl[4] / kl[3] - 1) < 0.05
    assert line.info["contact_spacing_mm"] == 0.5 and line.info["stations_per_turn"] is None
    assert line.info["coil_pairs"] > 4 * node.info["coil_pairs"]
    wl = line.info["working_load"]
    assert wl["closed_contacts"] > node.info["working_load"]["closed_contacts"]
    assert 1.0 < wl["closed_length_mm"] < 20.0
    # with every contact open both are the same plain solid (condensed exactly)
    np.testing.assert_allclose(line.K_free, node.K_free, rtol=1e-6)
    # contact stiffens: axial +32 %, lateral +16 % at 10 N
    free = np.diag(line.at(line.centre, "free"))
    assert kl[5] > 1.2 * free[5] and kl[3] > 1.1 * free[3]


@pytest.mark.slow
def test_helix_mesh_honours_the_edge_asked():
    """The edge length asked is the mesh's, not that of a fallback sized by the wire's
    curvature (which gave one mesh, 67851 TET10 nodes, for every edge from 0.7 mm up, where the
    first try facets the wire section beyond the 5 % volume check); an edge too coarse for the
    section is a ParameterError, not that mesh."""
    pytest.importorskip("gmsh")
    from designlab.errors import ParameterError
    from designlab.sensors.flexure.helix_fem import flexure_from_spring, helix_mesh
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    flex = flexure_from_spring(VISIFLEX_CATALOG)
    coarse, ci = helix_mesh(flex, 0.65, order=1)
    fine, fi = helix_mesh(flex, 0.5, order=1)
    # corner edges follow the size asked (gmsh's median edge is 1.0-1.2x it)
    assert 1.0 < ci["median_edge_mm"] / 0.65 < 1.2 and 1.0 < fi["median_edge_mm"] / 0.5 < 1.2
    # (0.65 / 0.5)^3 = 2.2 more cells, 1.8x the corner nodes (6766 -> 12416)
    assert 1.8 < fine.n_cells / coarse.n_cells < 2.6
    assert 1.5 < fine.n_points / coarse.n_points < 2.2
    assert ci["sized_by"].endswith("curvature 0: ok, %d cells" % coarse.n_cells)
    # the faceted section: volume -3 % at 0.5 mm, more at 0.65 mm, both within 5 %
    assert -0.05 < ci["volume_error"] < fi["volume_error"] < 0
    with pytest.raises(ParameterError, match="edge_length.*within 5 % of its volume"):
        helix_mesh(flex, 1.0, order=1)


@pytest.mark.slow
def test_helix_mesh_curved_by_projection_default_mesh():
    """docs/models/flexure_contact_fem.md: the default mesh curved by
    projection (the default): the same corners and cells as straight, every
    moved mid-node on the wire surface (1e-6 mm) or, on the ground faces, on its plane; the
    wire volume within 0.5 % (straight: -3.4 %), no inverted cell, the same points twice."""
    pytest.importorskip("gmsh")
    from designlab.sensors.flexure.helix_fem import (CURVED_DEFAULT, _curve, flexure_from_spring,
                                                     helix_mesh, wire_surface)
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    assert CURVED_DEFAULT is True
    flex = flexure_from_spring(VISIFLEX_CATALOG)
    straight, si = helix_mesh(flex, curved=False)
    curved, ci = helix_mesh(flex)
    assert ci["curved"] and ci["curve_by"] == "projection" and not si["curved"]
    assert np.array_equal(straight.cells, curved.cells)
    corners = np.unique(straight.cells[:, :4])
    assert np.array_equal(straight.points[corners], curved.points[corners])
    assert si["volume_error"] < -0.03 and abs(ci["volume_error"]) < 0.005
    assert ci["min_jacobian_ratio"] > 0 and ci["straightened_cells"] == 0
    c = ci["curving"]
    assert c["kept_far"] == 0 and c["rim_not_converged"] == 0 and c["rim_mid_nodes"] > 100
    assert c["corner_distance_mm"] < 0.005                  # the part's spline vs centerline_z
    moved = np.nonzero(np.linalg.norm(curved.points - straight.points, axis=1) > 1e-12)[0]
    assert len(moved) == c["surface_mid_nodes"] + c["rim_mid_nodes"]
    q, _ = wire_surface(flex).closest(curved.points[moved])
    assert np.linalg.norm(q - curved.points[moved], axis=1).max() < 1e-6
    L = flex.length
    for name, z in (("flexure_base", 0.0), ("flexure_tip", L)):
        # the set's triangles on the ground plane (it also takes a few tube triangles within
        # 0.02 mm of the disc where the wire leaves it: those are curved like the tube)
        tri = curved.facet_sets[name]
        flat = np.abs(straight.points[tri[:, :3], 2] - z).max(axis=1) < 1e-9
        assert flat.sum() > 0.9 * len(tri)
        mids = np.unique(tri[flat, 3:])
        assert np.abs(curved.points[mids, 2] - z).max() < 1e-9   # on the ground plane
        rim = np.isin(mids, moved)
        assert 0 < rim.sum() < len(mids)                       # the rim's moved within it
        assert np.array_equal(curved.points[mids[~rim]], straight.points[mids[~rim]])
    again, n_again, _ = _curve(flex, straight, None)
    assert n_again == 0 and np.array_equal(again.points, curved.points)


@pytest.mark.slow
def test_helix_mesh_curved_by_projection_matches_gmsh():
    """docs/models/flexure_contact_fem.md: ``curve_by="gmsh"`` (gmsh's
    second-order nodes on the B-rep, a second gmsh run) and the projection (the default) move
    the same mid-nodes, to within 0.01 mm (the part's spline centreline against the closed
    form one), and nothing else; both close the faceting volume loss (-4.6 % at 0.65 mm),
    every cell has a positive Jacobian at its nodes and quadrature points (the few a curved
    face inverts put back straight). ~2 min (the gmsh run)."""
    pytest.importorskip("gmsh")
    from designlab.sensors.flexure.helix_fem import flexure_from_spring, helix_mesh
    from designlab.sensors.flexure.spring import VISIFLEX_CATALOG

    flex = flexure_from_spring(VISIFLEX_CATALOG)
    straight, si = helix_mesh(flex, 0.65, curved=False)
    curved, ci = helix_mesh(flex, 0.65, curved=True, curve_by="gmsh")
    proj, pi = helix_mesh(flex, 0.65)
    assert not si["curved"] and ci["curved"] and ci["curve_by"] == "gmsh"
    assert np.array_equal(straight.cells, curved.cells)
    corners = np.unique(straight.cells[:, :4])
    assert np.array_equal(straight.points[corners], curved.points[corners])
    # straight: the TET10 volume is the corner tetrahedra's (to round-off), -4.6 %
    assert abs(si["volume_error"] - si["volume_error_corners"]) < 1e-9
    assert si["volume_error_corners"] < -0.04
    assert ci["volume_error_corners"] == si["volume_error_corners"]
    for info in (ci, pi):
        assert abs(info["volume_error"]) < 0.005
        assert info["min_jacobian_ratio"] > 0                    # after straightening
        assert info["straightened_cells"] < 0.001 * curved.n_cells
    moved = np.linalg.norm(curved.points - straight.points, axis=1) > 1e-9
    assert 0 < moved.sum() < curved.n_points - len(corners)       # the surface's, not all
    moved_p = np.linalg.norm(proj.points - straight.points, axis=1) > 1e-9
    both = moved & moved_p
    # the same nodes, but for those of cells one of them straightened (6 mid-nodes each)
    assert (moved ^ moved_p).sum() <= 6 * (ci["straightened_cells"] + pi["straightened_cells"])
    d = np.linalg.norm(proj.points[both] - curved.points[both], axis=1)
    assert d.max() < 0.01 and np.median(d) < 1e-3
