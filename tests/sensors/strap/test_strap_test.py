"""Virtual load test of the seed 000 strap: wrap geometry, physics premise, metrics, plots."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from designlab.sensors.strap import virtual as st

from designlab.sensors.strap import model as strap_model
from designlab.sensors.protocols import StrapLoadTest
from designlab.errors import ParameterError
from designlab.geometry.strap import ArchStrap

PART = ArchStrap()
COARSE = st.StrapModelSettings(edge_length=1.5)


def test_wrap_is_an_isometry_of_the_inner_face():
    """Arc length along the centreline and across the strap is kept; the centreline becomes a
    circle of the finger radius around the finger axis (y)."""
    R, (cx, cy) = PART.radius, PART.center
    phi = np.linspace(-PART.half_angle, PART.half_angle, 401)
    line = np.column_stack([cx + R * np.sin(phi), cy + R * np.cos(phi), np.zeros_like(phi)])
    w = strap_model.wrap_points(PART, line, 9.0)
    length = np.linalg.norm(np.diff(w, axis=0), axis=1).sum()
    assert length == pytest.approx(2 * PART.half_angle * R, rel=1e-4)
    assert np.hypot(w[:, 0], w[:, 2]) == pytest.approx(np.full(len(w), 9.0))
    assert np.ptp(w[:, 1]) < 1e-9
    across = np.array([[cx, cy + R - 5, 0.0], [cx, cy + R + 5, 0.0]])
    a = strap_model.wrap_points(PART, across, 9.0)
    assert np.linalg.norm(a[1] - a[0]) == pytest.approx(10.0, rel=1e-9)
    # thickness maps to the outward normal: 0.6 mm above the apex is 0.6 mm away
    apex = np.array([[0.0, PART.arch_height, 0.0], [0.0, PART.arch_height, 0.6]])
    b = strap_model.wrap_points(PART, apex, 9.0)
    assert np.linalg.norm(b[1] - b[0]) == pytest.approx(0.6)
    fr = st.pad_frame(PART, st.StrapModelSettings())
    assert (b[1] - b[0]) / 0.6 == pytest.approx(fr["n"])


def test_wrap_rejects_a_finger_wider_than_the_arch():
    with pytest.raises(ParameterError, match="finger_radius"):
        strap_model.wrap_points(PART, np.zeros((1, 3)), PART.radius + 1)


def test_staircase_reads_pick_the_end_of_each_hold():
    prot = StrapLoadTest(n_steps=2, step_hold_s=1.0, dt_s=0.1, cycles=1)
    t, fn, fx = prot.time_history()
    reads = strap_model.staircase_reads(prot, st.StrapModelSettings(read_fraction=0.2), len(t))
    assert len(reads) == 5
    assert [list(r) for r in reads[:2]] == [[8, 9], [18, 19]]
    assert [fn[r].mean() for r in reads] == pytest.approx([0, 2.5, 5, 2.5, 0])


def _synthetic(prot, M, lag=0.0):
    """Channels from a known 2x2 response (V per N), optional first-order lag (hysteresis)."""
    t, fn, fx = prot.time_history()
    dV = np.column_stack([fn, fx]) @ np.asarray(M).T
    if lag:
        a = np.exp(-prot.dt_s / lag)
        y = np.zeros_like(dV)
        for i in range(1, len(t)):
            y[i] = a * y[i - 1] + (1 - a) * dV[i]
        dV = y
    return t, fn, fx, dV


def test_evaluate_recovers_a_known_response():
    prot = StrapLoadTest()
    M = np.array([[0.02, 0.015], [0.02, -0.015]])        # V per N: Ch1, Ch2 x F_n, F_x
    t, fn, fx, dV = _synthetic(prot, M)
    r = st.evaluate(prot, st.StrapModelSettings(), t, fn, fx, dV, dV / 10)
    A = np.array(r["calibration_matrix"])
    assert A == pytest.approx(np.linalg.inv(M), rel=1e-9)
    assert r["condition_number"] == pytest.approx(np.linalg.cond(M), rel=1e-9)
    assert r["sensitivity"]["V_per_N"]["sum"]["F_n"] == pytest.approx(0.04)
    assert r["sensitivity"]["V_per_N"]["diff"]["F_x"] == pytest.approx(0.03)
    assert r["cross_talk_percent"]["F_x_in_sum_per_N_percent"] == pytest.approx(0, abs=1e-9)
    assert r["premise"]["normal_same_sign"] and r["premise"]["shear_opposite_sign"]
    assert r["hysteresis_percent"]["overall"] == pytest.approx(0, abs=1e-9)
    json.dumps(r)
    # a lagging sensor shows hysteresis on the staircase; one gauge leaking shear into the sum
    M2 = np.array([[0.02, 0.02], [0.02, -0.01]])
    t, fn, fx, dV = _synthetic(prot, M2, lag=2.0)
    r2 = st.evaluate(prot, st.StrapModelSettings(), t, fn, fx, dV, dV)
    assert r2["hysteresis_percent"]["overall"] > 1.0
    assert r2["cross_talk_percent"]["F_x_in_sum_per_N_percent"] > 10


def test_evaluate_needs_decorrelated_loads():
    prot = StrapLoadTest(cycles=0)
    t, fn, fx, dV = _synthetic(prot, np.eye(2))
    with pytest.raises(ParameterError, match="cycles"):
        st.evaluate(prot, st.StrapModelSettings(), t, fn, fx, dV, dV)


@pytest.fixture(scope="module")
def flat_mesh():
    return strap_model.mesh_strap(PART, COARSE)


def _elastic():
    """The library TPUs without their Prony stand-ins: the elastic strain per newton."""
    from designlab.fem.materials import get_material

    tpu = {"strap": "NinjaFlex", "trace_left": "PI-ETPU", "trace_right": "PI-ETPU"}
    return {body: dataclasses.replace(get_material(m), prony=None) for body, m in tpu.items()}


@pytest.fixture(scope="module")
def prediction(flat_mesh):
    return st.run(PART, StrapLoadTest(), COARSE, materials=_elastic(), mesh=flat_mesh)


def test_worn_strap_meets_the_seed_000_premise(prediction):
    """Both gauges stretch under F_n (the sum reads it); F_x stretches one and relaxes the
    other (the difference reads it), with the left/right responses matched by symmetry."""
    r = prediction.report
    e = r["strain_per_N"]
    assert e["Ch1"]["F_n"] > 0 and e["Ch2"]["F_n"] > 0
    assert e["Ch1"]["F_n"] == pytest.approx(e["Ch2"]["F_n"], rel=0.05)
    assert e["Ch1"]["F_x"] > 0 > e["Ch2"]["F_x"]
    assert -e["Ch2"]["F_x"] == pytest.approx(e["Ch1"]["F_x"], rel=0.1)
    assert r["premise"]["normal_same_sign"] and r["premise"]["shear_opposite_sign"]
    ct = r["cross_talk_percent"]
    assert ct["F_x_in_sum_per_N_percent"] < 5 and ct["F_n_in_diff_per_N_percent"] < 5
    # membrane estimate: each side carries ~F_n/2 over the strap's EA = 12 MPa * 15 * 0.6 mm^2
    assert 0.3 < e["Ch1"]["F_n"] / (0.5 / (12.0 * 15 * 0.6)) < 3


def test_report_contract(prediction, tmp_path):
    r = prediction.report
    json.dumps(r)
    for key in ("hysteresis_percent", "calibration_matrix", "condition_number", "sensitivity",
                "timings_s", "mesh"):
        assert key in r
    assert set(r["hysteresis_percent"]["by_location"]) == {"Ch1", "Ch2", "sum", "diff"}
    assert r["hysteresis_percent"]["overall"] == pytest.approx(0, abs=1e-6)   # elastic
    assert not r["viscoelastic"]
    assert set(r["timings_s"]) == {"mesh", "assemble", "solve", "metrics"}
    assert np.array(r["calibration_matrix"]).shape == (2, 2)
    assert 1 <= r["condition_number"] < 10
    # the fitted matrix reproduces the forces (divider nonlinearity only)
    assert r["calibration_fit"]["rms_residual_N"] < 0.02 * StrapLoadTest().normal_N
    assert 0 < r["linearity_percent_span"]["sum"] < 5
    # channels: divider change from the unloaded state; the readout saturates gently
    assert prediction.dV[0] == pytest.approx([0, 0], abs=1e-12)
    paths = st.plots(prediction, None, tmp_path)
    assert [p.name for p in paths] == ["strap_time_series.png", "strap_sum_diff.png",
                                       "strap_hysteresis.png"]
    assert all(p.stat().st_size > 1000 for p in paths)
    assert not list(tmp_path.glob("*.tmp*")) and len(list(tmp_path.iterdir())) == 3


def test_flat_strap_has_no_membrane_path_for_normal_force(flat_mesh, prediction):
    """Printed flat, the 0.6 mm strap only bends under F_n and the mid-plane gauges see a small
    fraction of the worn strap's membrane strain; in-plane F_x still reads."""
    flat = st.run(PART, StrapLoadTest(), dataclasses.replace(COARSE, configuration="flat",
                                                              tissue_stiffness=0.0),
                  materials=_elastic(), mesh=flat_mesh).report["strain_per_N"]
    worn = prediction.report["strain_per_N"]
    for ch in st.CHANNELS:
        assert abs(flat[ch]["F_n"]) < 0.25 * worn[ch]["F_n"]
    assert flat["Ch1"]["F_x"] > 0 > flat["Ch2"]["F_x"]


@pytest.mark.slow
def test_viscoelastic_materials_give_hysteresis(flat_mesh):
    """With a Prony series in both TPUs the history is marched and the staircase loop opens."""
    from designlab.fem.materials import get_material
    from designlab.fem.prony import Prony

    pr = Prony(g=(0.3,), tau=(2.0,))
    mats = {"strap": dataclasses.replace(get_material("NinjaFlex"), prony=pr),
            "trace_left": dataclasses.replace(get_material("PI-ETPU"), prony=pr),
            "trace_right": dataclasses.replace(get_material("PI-ETPU"), prony=pr)}
    prot = StrapLoadTest(n_steps=2, step_hold_s=1.0, dt_s=0.25, cycles=1, cycle_period_s=1.0)
    p = st.run(PART, prot, COARSE, materials=mats, mesh=flat_mesh)
    r = p.report
    assert r["viscoelastic"]
    h = r["hysteresis_percent"]
    assert h["overall"] > 0.5
    assert h["by_location"]["sum"] > 0.5
    assert r["premise"]["normal_same_sign"] and r["premise"]["shear_opposite_sign"]


def test_report_has_the_derived_electrical_design_and_the_paper_slots(prediction):
    """The paper's geometry reads 1.8 kOhm by construction; resolution = noise / sensitivity;
    the three slots on the 9 mm finger give increasing initial strain, falling sensitivity."""
    r = prediction.report
    el = r["electrical"]
    assert el["resistance_ohm"]["total"] == pytest.approx(1800.0)
    assert el["resolution_mN"]["F_n"] == pytest.approx(
        1e3 * el["noise"]["sum_or_diff_V_rms"] / r["sensitivity"]["V_per_N"]["sum"]["F_n"])
    rows = r["slots"]["slots"]
    assert [x["initial_strain"] for x in rows] == sorted(x["initial_strain"] for x in rows)
    assert rows[0]["sum_F_n_V_per_N"] > rows[1]["sum_F_n_V_per_N"] > rows[2]["sum_F_n_V_per_N"]
    assert r["prestrain"] is None
    assert any("PI-ETPU: gauge_factor" in n for n in r["material_stand_ins"])


@pytest.mark.slow
def test_prestrained_run_matches_the_slot_table(flat_mesh, prediction):
    """slot=2: the worn strap at the medium slot's initial strain; its sensitivity equals the
    stress-free run's slot-table entry (same FEM, operating point and tangent applied)."""
    p = st.run(PART, StrapLoadTest(), dataclasses.replace(COARSE, slot=2),
               materials=_elastic(), mesh=flat_mesh).report
    assert p["prestrain"]["initial_strain"] == pytest.approx(0.1729, abs=2e-4)
    row = prediction.report["slots"]["slots"][1]
    assert p["sensitivity"]["V_per_N"]["sum"]["F_n"] == pytest.approx(row["sum_F_n_V_per_N"],
                                                                      rel=0.02)
    assert p["electrical"]["resistance_at_rest_ohm"] > 1800.0
    with pytest.raises(ParameterError, match="slot"):
        st.StrapModelSettings(slot=2, configuration="flat")


# ------------------------------------------------------------------------- the FEM stage cache

#: a short viscoelastic protocol on a coarse TET4 mesh: the cache tests stay cheap
SHORT = StrapLoadTest(n_steps=2, step_hold_s=1.0, dt_s=0.25, cycles=1, cycle_period_s=1.0)
CHEAP = st.StrapModelSettings(edge_length=2.0, order=1)


def test_load_only_parameters_leave_the_meshed_bodies_unchanged():
    """The FEM key ignores LOAD_ONLY_PARAMS (the nail plate): the meshed bodies' exact B-rep must
    not change with them, else two designs would share a FEM they do not have."""
    a = ArchStrap()
    b = ArchStrap(nail_plate_length=20.0, nail_plate_width=14.0, nail_plate_thickness=2.0)
    assert set(strap_model.LOAD_ONLY_PARAMS) <= set(vars(a))

    def signature(shape):
        v = np.array(sorted(tuple(round(c, 9) for c in tuple(x)) for x in shape.vertices()))
        return round(shape.volume, 9), round(shape.area, 9), len(shape.faces()), v

    for name in a.mesh_bodies():
        sa, sb = signature(a.build()[name].shape), signature(b.build()[name].shape)
        assert sa[:3] == sb[:3], name
        assert np.array_equal(sa[3], sb[3]), name
    assert a.build()["nail_plate"].shape.volume != b.build()["nail_plate"].shape.volume


def test_fem_key_holds_what_the_fem_depends_on():
    """Readout settings, the wrap's slot and the nail plate leave the key; the mesh, the model,
    the materials and (a relaxing material) the protocol change it."""
    key = strap_model.fem_key(PART, SHORT, CHEAP)
    same = [strap_model.fem_key(PART, SHORT, dataclasses.replace(CHEAP, **kw)) for kw in (
        {"divider_ohm": 4700.0}, {"supply_V": 3.3}, {"adc_bits": 12}, {"bandwidth_hz": 50.0},
        {"contact_ohm": 20.0}, {"read_fraction": 0.5}, {"slot": 2}, {"wrap_length": 60.0},
        {"mesh_convergence": False})]
    same.append(strap_model.fem_key(ArchStrap(nail_plate_width=14.0), SHORT, CHEAP))
    assert set(same) == {key}
    other = [strap_model.fem_key(PART, SHORT, dataclasses.replace(CHEAP, **kw)) for kw in (
        {"edge_length": 2.5}, {"order": 2}, {"tissue_stiffness": 0.05}, {"finger_radius": 8.0},
        {"load": "traction"}, {"solver": "amg"}, {"mesher": "tetwild"})]
    other.append(strap_model.fem_key(ArchStrap(thickness=0.8), SHORT, CHEAP))
    other.append(strap_model.fem_key(PART, dataclasses.replace(SHORT, normal_N=4.0), CHEAP))
    assert len(set(other)) == len(other) and key not in other
    # elastic materials: one static solve of the unit loads, whatever the protocol
    el = _elastic()
    assert strap_model.fem_key(PART, SHORT, CHEAP, el) != key
    assert strap_model.fem_key(PART, SHORT, CHEAP, el) == strap_model.fem_key(
        PART, dataclasses.replace(SHORT, normal_N=4.0, cycles=2), CHEAP, el)


@pytest.mark.slow
def test_designs_that_share_the_fem_solve_it_once(tmp_path):
    """Two designs that differ in readout settings only (divider, supply, ADC, bandwidth, the
    wrap's slot): the second reuses the first one's FEM from the cache folder and its numbers
    equal an uncached run's exactly; the report says which mesher and solver ran."""
    from designlab.fem.cache import FEMCache, clear_memory

    a = CHEAP
    b = dataclasses.replace(CHEAP, divider_ohm=4700.0, supply_V=3.3, adc_bits=12,
                            bandwidth_hz=50.0, slot=2)
    clear_memory()
    cache = FEMCache(tmp_path / "fem")
    ra = st.run(PART, SHORT, a, cache=cache)
    clear_memory()                                       # the second design reads the folder
    rb = st.run(PART, SHORT, b, cache=cache)
    assert (cache.misses, cache.hits) == (1, 1)
    assert not ra.report["fem_reused"] and rb.report["fem_reused"]
    assert ra.report["fem_key"] == rb.report["fem_key"]
    assert rb.report["timings_s"]["solve"] == 0.0 and rb.report["timings_s"]["fem_cache"] > 0
    assert len(list((tmp_path / "fem").glob("*.npz"))) == 1
    clear_memory()
    fresh = st.run(PART, SHORT, b)                       # no cache folder: solved again
    assert not fresh.report["fem_reused"]
    for k in ("condition_number", "hysteresis_percent", "sensitivity", "electrical",
              "prestrain", "calibration_matrix", "series"):
        assert fresh.report[k] == rb.report[k], k
    assert np.array_equal(fresh.dV, rb.dV) and np.array_equal(fresh.displacement, rb.displacement)
    assert rb.report["viscoelastic"] and rb.report["hysteresis_percent"]["overall"] > 0
    # the readout did change: another divider and supply, another sensitivity
    assert rb.report["sensitivity"]["V_per_N"]["sum"]["F_n"] != \
        ra.report["sensitivity"]["V_per_N"]["sum"]["F_n"]
    assert "4.7 kOhm divider at 3.3 V" in rb.report["model"]["readout"]
    m = rb.report["mesh"]
    assert m["mesher"] == "gmsh" and m["solver"] == "direct" and m["attempts"]
    assert m == ra.report["mesh"]


@pytest.mark.slow
def test_a_mesher_fallback_is_recorded(monkeypatch):
    """Whichever mesher made the mesh (fTetWild when gmsh failed: tests/mesh/test_meshing.py
    ::test_gmsh_failure_falls_back_to_fTetWild) and its attempts reach the report; a given mesh
    says so."""
    from designlab.fem.cache import FEMCache, clear_memory
    from designlab.mesh import meshing

    clear_memory()                       # no FEM stage of an earlier test in this process
    real = meshing.mesh_bodies_detailed

    def fell_back(*a, **kw):
        res = real(*a, **kw)
        return dataclasses.replace(res, mesher="tetwild",
                                   attempts=["gmsh: edge 2 mm, curvature 0: simulated failure",
                                             *res.attempts])

    monkeypatch.setattr(meshing, "mesh_bodies_detailed", fell_back)
    el = _elastic()
    r = st.run(PART, SHORT, CHEAP, materials=el, cache=FEMCache()).report["mesh"]
    assert r["mesher"] == "tetwild" and "simulated failure" in r["attempts"][0]
    assert r["solver"] == "direct"
    given = st.run(PART, SHORT, CHEAP, materials=el,
                   mesh=strap_model.mesh_strap(PART, CHEAP)).report["mesh"]
    assert given["mesher"] == "given" and given["attempts"] == []


@pytest.mark.slow
def test_a_wrap_that_inverts_a_cell_remeshes_finer(monkeypatch):
    """A flat sliver cell that the wrap turns inside out: the strap is meshed again with shorter
    edges (recorded in the attempts and the report's edge length); a given mesh is not."""
    import designlab.sensors.strap.model as strap_model
    from designlab.errors import ModelError
    from designlab.fem.cache import FEMCache, clear_memory

    real, calls = strap_model.build_model, []

    def inverts_first(part, flat, settings, materials=None):
        calls.append(flat.n_cells)
        if len(calls) == 1:
            raise ModelError("1 inverted or degenerate elements (non-positive Jacobian), first "
                             "element id 7")
        return real(part, flat, settings, materials)

    monkeypatch.setattr(strap_model, "build_model", inverts_first)   # solve_fem looks it up there
    clear_memory()
    r = st.run(PART, SHORT, CHEAP, materials=_elastic(), cache=FEMCache()).report["mesh"]
    assert len(calls) >= 2 and calls[1] > calls[0]          # finer
    assert r["edge_length_mm"] == pytest.approx(CHEAP.edge_length
                                                * strap_model.WRAP_REFINE ** (len(calls) - 1))
    assert any("wrapped onto the finger: 1 inverted" in a for a in r["attempts"])
    calls.clear()
    with pytest.raises(ModelError, match="inverted"):
        st.run(PART, SHORT, CHEAP, materials=_elastic(), mesh=strap_model.mesh_strap(PART, CHEAP))


def test_prediction_carries_the_force_error_test_at_the_protocols_loads():
    """predict strap runs seed 000's calibration with its electrical noise on the designed
    strap (finish hook): loads at the protocol's amplitudes, the error split exactly, the
    noise part equal to the resolution the electrical budget predicts."""
    from designlab.predict.run import predict

    proto = {k: getattr(SHORT, k) for k in ("n_steps", "step_hold_s", "dt_s", "cycles",
                                             "cycle_period_s")}
    pred = predict("strap", {}, protocol=proto,
                   settings={"edge_length": 2.0, "order": 1, "mesh_convergence": False})
    r = pred.metrics["force_error_test"]
    assert r["budget"]["loads"] == {"normal_N": SHORT.normal_N, "shear_N": SHORT.shear_N}
    for a in ("F_n", "F_x"):
        sp = r["split_std"][a]
        assert r["per_axis"][a]["std"] > 0 and set(sp) == {"johnson", "adc", "model_error"}
        noise = np.hypot(sp["johnson"], sp["adc"])
        assert noise == pytest.approx(r["fit"][a]["noise_std_predicted_N"], rel=0.15)
    # the sensitivities the test used are the prediction's own
    s = pred.metrics["sensitivity"]["V_per_N"]
    assert r["budget"]["sensitivity_V_per_N"]["Ch1"]["F_n"] == s["Ch1"]["F_n"]
