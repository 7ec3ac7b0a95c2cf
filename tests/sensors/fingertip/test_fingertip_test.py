"""Seed 001 virtual test: the metrics on exact lumped cases, Boltzmann superposition against a
full history, and the predict command on the real part (slow)."""

import json

import numpy as np
import pytest

from designlab.sensors.fingertip.model import WRENCH, FingertipModelSettings
from designlab.sensors.fingertip.virtual import evaluate, step_responses, superpose_steps
from designlab.sensors.protocols import HangingWeightTest
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.prony import Prony
from designlab.fem.history import History
from designlab.fem.viscoelastic import solve_history
from designlab.geometry.fingertip import CantileverFingertip
from designlab.mesh.tetmesh import box_tet_mesh


def _ball_on_sensors(part, prony=None):
    """A ball held only by the three FSS springs (to ground) with its rotations fixed: the
    ideal frictionless hard-finger model of seed 001 eqs. 2-8."""
    mesh = box_tet_mesh(2, 2, 2, 1, 1, 1, origin=(20, 20, 20))
    model = Model(mesh, {"block": Material("m", 1000.0, 0.3, prony=prony)})
    model.fix(np.arange(mesh.n_points))
    ball = model.free_body("ball", (0.0, 0.0, 0.0))
    model.fix(ball, "rx")
    model.fix(ball, "ry")
    model.fix(ball, "rz")
    axes, contacts = part.sensor_axes()
    for k in range(3):
        model.spring(f"sensor_{k + 1}", a=(ball, contacts[k]), k=500.0, axis=-axes[k])
    for i, name in enumerate(WRENCH):
        model.force(ball, force=np.eye(6)[i, :3], moment=np.eye(6)[i, 3:], case=name)
    return model


def test_ideal_rigid_geometry_gives_eq8_condition_number():
    part = CantileverFingertip()
    model = _ball_on_sensors(part)
    res = solve_static(model)
    per = np.array([[res.spring_force(f"sensor_{k + 1}", c) for k in range(3)] for c in WRENCH])
    protocol = HangingWeightTest.preset("optimized")
    t, load, step = protocol.time_history()
    unit = np.broadcast_to(per, (len(t), 6, 3)).copy()
    settings = FingertipModelSettings(rotations_deg=(0.0, 120.0))
    rep = evaluate(part, protocol, settings, t, load, step, unit)
    assert abs(rep["condition_number"] - np.sqrt(2)) < 1e-9
    assert abs(rep["geometric_condition_number"] - 1.41421356) < 1e-6
    # A is the geometric matrix (eq. 8) up to the sensor output scale and sign convention
    A = np.array(rep["calibration_matrix"])
    G = np.array(rep["geometric_matrix"])
    np.testing.assert_allclose(A / A[0, 1], G / G[0, 1], atol=1e-9)
    assert rep["hysteresis_percent"]["overall"] < 1e-9          # elastic: no hysteresis


def test_superposition_of_step_responses_equals_full_history():
    part = CantileverFingertip()
    prony = Prony(g=(0.3,), tau=(2.0,))
    mesh = box_tet_mesh(10, 4, 4, 4, 2, 2, origin=(-5, -2, -12))
    model = Model(mesh, {"block": Material("m", 50.0, 0.3, prony=prony)})
    model.fix("zmin")
    ball = model.rigid("ball", "zmax", ref_point=(0.0, 0.0, 0.0))
    axes, contacts = part.sensor_axes()
    for k in range(3):
        model.spring(f"sensor_{k + 1}", a=(ball, contacts[k]), k=20.0, axis=-axes[k])
    for i, name in enumerate(WRENCH):
        model.force(ball, force=np.eye(6)[i, :3], moment=np.eye(6)[i, 3:], case=name)
    protocol = HangingWeightTest(weights_g=(0.0, 50.0, 150.0), hold_s=4.0, read_window_s=1.0,
                                 dt_s=0.5)
    t, load, _ = protocol.time_history()
    sensors = [f"sensor_{k + 1}" for k in range(3)]
    H, _ = step_responses(model, sensors, 2.0, protocol.dt_s, t[-1])
    fast = superpose_steps(H, protocol.dt_s, t, load)
    # the full history with true jumps (a repeated time is a jump) at every weight change
    jumps = np.flatnonzero(np.diff(load)) + 1
    t2 = np.insert(t, jumps, t[jumps])
    load2 = np.insert(load, jumps, load[jumps - 1])
    keep = np.delete(np.arange(len(t2)), jumps + np.arange(len(jumps)))
    full = solve_history(model, History(t2, {c: load2 for c in WRENCH}), batch=True)
    ref = np.moveaxis(np.stack([full.spring_force(s) for s in sensors], -1), 0, 1)[keep]
    ref = ref / np.where(load > 0, load, 1.0)[:, None, None]
    # exact up to the truncation of the step response after 7 tau (exp(-7) of the relaxing part)
    assert np.abs(fast - ref).max() <= 2e-3 * np.abs(ref).max()
    assert np.abs(fast - ref)[t < 14.0].max() <= 1e-9 * np.abs(ref).max()


def test_unknown_load_point_is_an_error():
    from designlab.sensors.fingertip.model import check_locations
    from designlab.errors import ParameterError

    part = CantileverFingertip()                       # Table III: h1..h6, r1..r6
    check_locations(part, HangingWeightTest.preset("optimized"))
    with pytest.raises(ParameterError, match="g1_locations='h7'.*h1, h2"):
        check_locations(part, HangingWeightTest())     # Table II names h7..h9


def test_predict_bad_input_is_one_line_exit_2(tmp_path, capsys):
    from designlab.cli import main

    proto = tmp_path.parent / f"{tmp_path.name}-p.toml"
    proto.write_text('preset = "optimized"\ng2_locations = ["r1", "r9"]\n')
    for argv, needle in ((["predict", "wing", "--out", str(tmp_path / "a")], "part"),
                         (["predict", "fingertip", "--setting", "edge_length=-1", "--out",
                           str(tmp_path / "b")], "settings.edge_length"),
                         (["predict", "fingertip", "--set", "r=12", "--out",
                           str(tmp_path / "c")], "r=12"),
                         (["predict", "fingertip", "--protocol", str(proto),
                           "--out", str(tmp_path / "d")], "g2_locations='r9'")):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert needle in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_predict_fingertip_end_to_end(tmp_path):
    from designlab.cli import main

    main(["predict", "fingertip", "--setting", "edge_length=3.0", "--out", str(tmp_path)])
    pred = json.loads((tmp_path / "prediction.json").read_text())
    for key in ("design", "hysteresis_percent", "calibration_matrix", "condition_number",
                "geometric_condition_number", "sensitivity", "timings_s"):
        assert key in pred
    assert set(pred["hysteresis_percent"]["by_location"]) == {
        *(f"h{i}" for i in range(1, 7)), *(f"r{i}" for i in range(1, 7))}
    # the bolt and cap carry most of P_z: the axial sensitivity is far below the radial one
    share = pred["load_paths"]["share_through_sensors"]
    assert share["z"] < 0.5 * min(share["x"], share["y"])
    assert 1.5 < pred["condition_number"] < 200
    assert abs(pred["geometric_condition_number"] - 1.41421) < 1e-4
    for f in ("hysteresis_loops.png", "applied_vs_estimated.png", "deformed.vtu"):
        assert (tmp_path / f).stat().st_size > 1000
    # the paper comparison is designlab validate's (tests/predict/test_validate.py)
    assert "paper_comparison" not in pred and not (tmp_path / "paper_comparison.png").exists()
    # the contact model (default): both eq. 1 definitions, preload, the paper's two designs
    hp = pred["hysteresis_percent"]
    assert hp["overall"] > hp["overall_noise_free"] > 0         # readout errors add to friction
    assert {"paper_eq1_all_sensors", "robust_eq1_span10", "robust_eq1_span10_noise_free"} <= \
        set(pred["hysteresis_definitions"])
    assert abs(pred["preload"]["bolt_tension_N"] - 20.0) < 1e-6
    assert "hysteresis_percent.overall_noise_free" in pred["mesh_convergence"]
    from designlab.loop.model import load_model

    model = load_model(tmp_path / "model.json")        # the loop's starting point
    assert model.outputs == ["sensor_1", "sensor_2", "sensor_3"]


def test_default_protocol_keeps_the_load_points_a_design_has():
    from designlab.predict.run import protocol_from

    short = CantileverFingertip(h=0.0, r=6.0)          # top at 6 mm: no h1..h3 of Table III
    p = protocol_from("fingertip", design=short)
    assert p.g1_locations == ("h4", "h5", "h6") and len(p.g2_locations) == 6
    from designlab.sensors.fingertip.model import check_locations
    from designlab.errors import ParameterError

    explicit = protocol_from("fingertip", values={"g1_locations": ["h1"]}, design=short)
    with pytest.raises(ParameterError, match="g1_locations='h1'"):
        check_locations(short, explicit)               # asked for explicitly: an error


def test_load_only_parameters_leave_the_meshed_bodies_unchanged(tmp_path):
    """The FEM key ignores LOAD_ONLY_PARAMS: the meshed bodies' exact B-rep must not change
    with them (else two designs would share a FEM they do not have). Compared by volume, area
    and every vertex (a BREP file also carries a triangulation when the shape was tessellated
    earlier in the process)."""
    from designlab.sensors.fingertip.model import LOAD_ONLY_PARAMS

    a = CantileverFingertip()
    b = CantileverFingertip(h=12.0, r=7.0, fingertip_radius=10.0, load_table="II",
                            load_patch_radius=2.0, skin_thickness=1.0)
    assert {f for f in LOAD_ONLY_PARAMS} <= set(vars(a))

    def signature(shape):
        v = np.array(sorted(tuple(round(c, 9) for c in tuple(x)) for x in shape.vertices()))
        return round(shape.volume, 9), round(shape.area, 9), len(shape.faces()), v

    for name in ("base", "cap"):
        sa, sb = signature(a.build()[name].shape), signature(b.build()[name].shape)
        assert sa[:3] == sb[:3], name
        assert np.array_equal(sa[3], sb[3]), name


@pytest.mark.parametrize("contact", [True, False], ids=["contact", "linear"])
@pytest.mark.slow
def test_designs_that_share_the_fem_solve_it_once(tmp_path, contact):
    """Two (h, r) designs: the second reuses the first one's FEM from the cache folder and its
    numbers equal an uncached run's exactly; a base parameter changes the key. Both models:
    the contact model (its condensed structure is part of the cached FEM stage) and the
    linear one (contact=False)."""
    from designlab.fem.cache import FEMCache, clear_memory
    from designlab.sensors.fingertip.model import fem_key
    from designlab.sensors.fingertip.virtual import run
    from designlab.sensors.protocols import HangingWeightTest

    settings = FingertipModelSettings(edge_length=4.0, order=1, contact=contact)
    prot = HangingWeightTest(g1_locations=("h4", "h5"), g2_locations=("r1", "r4"))
    a, b = CantileverFingertip(h=0.0, r=9.0), CantileverFingertip(h=6.0, r=8.0)
    assert fem_key(a, prot, settings) == fem_key(b, prot, settings)
    assert fem_key(a, prot, settings) != fem_key(CantileverFingertip(base_radius=10.0), prot,
                                                 settings)
    clear_memory()
    cache = FEMCache(tmp_path / "fem")
    ra = run(a, prot, settings, cache=cache)
    clear_memory()                                     # the second design reads the folder
    rb = run(b, prot, settings, cache=cache)
    assert (cache.misses, cache.hits) == (1, 1)
    assert not ra.report["fem_reused"] and rb.report["fem_reused"]
    assert len(list((tmp_path / "fem").glob("*.npz"))) == 1
    clear_memory()
    fresh = run(b, prot, settings)                     # no cache: solved again
    assert fresh.report["condition_number"] == rb.report["condition_number"]
    assert fresh.report["hysteresis_percent"] == rb.report["hysteresis_percent"]
    if contact:
        # the cached condensed structure is the one condense_fingertip builds on the mesh
        from designlab.sensors.fingertip.model import contact_settings, mesh_fingertip
        from designlab.sensors.fingertip.contact import condense_fingertip, run_contact_test

        cf = condense_fingertip(b, mesh_fingertip(b, settings), settings)
        direct = run_contact_test(b, prot, contact_settings(settings), cf,
                                  rotations_deg=settings.rotations_deg)
        assert direct["hysteresis_percent"] == rb.report["hysteresis_percent"]
        assert rb.report["model"].startswith("contact")
        assert rb.report["hysteresis_percent"]["by_location"]["h4"] > 0
    else:
        assert rb.report["viscoelastic"] and rb.report["model"].startswith("linear")
        assert "hysteresis_definitions" not in rb.report


def test_contact_settings_are_model_settings_and_leave_the_fem_key():
    """Every ContactSettings field is a --setting of the fingertip (type-checked, one-line
    error naming it); the settings that act after the condensation do not change the FEM key,
    ``contact`` and (with contact) ``structure_moduli`` do."""
    from designlab.errors import ParameterError
    from designlab.sensors.fingertip.model import CONTACT_ONLY_SETTINGS, fem_key
    from designlab.predict.run import model_settings

    s = model_settings("fingertip", {"friction_coefficient": "0.1", "bolt_preload_N": 12,
                                     "seed": "7"})
    assert (s.friction_coefficient, s.bolt_preload_N, s.seed, s.contact) == (0.1, 12.0, 7, True)
    assert model_settings("fingertip", {"contact": "false"}).contact is False
    with pytest.raises(ParameterError, match="settings.friction_coefficient") as e:
        model_settings("fingertip", {"friction_coefficient": "3"})
    assert "\n" not in str(e.value)
    part, prot = CantileverFingertip(), HangingWeightTest()
    base = FingertipModelSettings()
    key = fem_key(part, prot, base)
    import dataclasses
    changed = {"friction_coefficient": 0.5, "bolt_preload_N": 10.0, "hertz": False,
               "sensor_lateral_stiffness": 100.0, "seed": 3, "repeatability_percent_fs": 0.0,
               "increments_per_step": 8, "daq_bits": 12}
    assert set(changed) <= set(CONTACT_ONLY_SETTINGS)
    for k, v in changed.items():
        assert fem_key(part, prot, dataclasses.replace(base, **{k: v})) == key, k
    assert fem_key(part, prot, dataclasses.replace(base, contact=False)) != key
    inst = dataclasses.replace(base, structure_moduli="instantaneous")
    assert fem_key(part, prot, inst) != key
    lin = dataclasses.replace(base, contact=False)
    assert fem_key(part, prot, dataclasses.replace(lin, structure_moduli="instantaneous")) == \
        fem_key(part, prot, lin)


@pytest.mark.slow
def test_prediction_json_settings_are_the_model_settings_predict_used():
    """``settings`` of prediction.json (``Prediction.to_json``) holds every model setting the
    contact model ran with, the FEMSettings fields included; the contact model's own
    settings are reported beside them as ``contact_settings`` and do not replace them."""
    import dataclasses

    from designlab.fem.settings import FEMSettings
    from designlab.sensors.fingertip.model import ContactSettings
    from designlab.predict.run import predict

    pred = predict("fingertip", {}, protocol={"g1_locations": ["h4", "h5"],
                                              "g2_locations": ["r1", "r4"]},
                   settings={"edge_length": 4.0, "order": 1, "mesh_convergence": False,
                             "friction_coefficient": 0.3})
    doc = json.loads(json.dumps(pred.to_json()))
    st = doc["settings"]
    assert st["edge_length"] == 4.0 and st["order"] == 1 and st["contact"] is True
    assert {f.name for f in dataclasses.fields(FEMSettings)} <= set(st)
    assert (st["solver"], st["mesher"]) == ("auto", "auto")
    assert st == json.loads(json.dumps(dataclasses.asdict(pred.settings)))
    cs = doc["contact_settings"]
    assert set(cs) == {f.name for f in dataclasses.fields(ContactSettings)}
    assert cs["friction_coefficient"] == st["friction_coefficient"] == 0.3
    # the typed fields a sweep reads
    assert pred.geometric_condition_number == pytest.approx(2 ** 0.5, abs=1e-4)
    assert pred.stress is not None and pred.min_safety_factor == \
        doc["stress"]["min_safety_factor"] > 0
    assert pred.mesh_convergence is None and pred.fem_key == doc["fem_key"]
    assert pred.hysteresis == doc["hysteresis_percent"]


@pytest.mark.slow
def test_predict_twice_gives_identical_numbers_and_a_mesh_error_bar(tmp_path):
    """Deterministic meshing: two predicts of one design agree to the last bit, and the
    prediction carries its discretisation estimate."""
    from designlab.fem.cache import clear_memory
    from designlab.predict.run import predict

    clear_memory()
    p1 = predict("fingertip", {}, settings={"edge_length": 4.0}).to_json()
    clear_memory()
    p2 = predict("fingertip", {}, settings={"edge_length": 4.0}).to_json()
    for k in ("condition_number", "hysteresis_percent", "calibration_matrix",
              "mesh_convergence"):
        assert p1[k] == p2[k], k
    mc = p1["mesh_convergence"]
    assert mc["coarse_edge_length_mm"] == pytest.approx(6.0)
    assert mc["condition_number"]["value"] == p1["condition_number"]
    assert mc["hysteresis_percent.overall"]["value"] == p1["hysteresis_percent"]["overall"]
    for k in ("condition_number", "hysteresis_percent.overall"):
        assert mc[k]["coarse"] != mc[k]["value"]          # a different mesh was solved
        assert mc[k]["rel_change"] is not None and mc[k]["rel_change"] >= 0
