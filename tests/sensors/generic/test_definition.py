"""The public sensor definition: registration, bad definitions (one line naming the item), the
transducers' read-out against closed forms, and every command on a fresh ``designlab new``
file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import designlab as dl
from designlab.errors import ParameterError
from designlab.sensors.definition import check_bodies

ROOT = Path(__file__).resolve().parents[3]
LOAD_CELL = ROOT / "examples" / "sensors" / "load_cell.py"


def _cell(**kw):
    from designlab.geometry.parts import make_part
    from designlab.sensors.registry import resolve

    return make_part(resolve(str(LOAD_CELL)), kw)


def _run(part, edge=3.0, **sett):
    from designlab.sensors.generic.virtual import run, settings_class

    return run(part, settings=settings_class(type(part))(edge_length=edge, **sett))


@pytest.fixture(scope="module", autouse=True)
def _cad_library():
    """build123d imported once for the module (its import is not what these tests measure)."""
    import build123d  # noqa: F401


def test_registered_from_a_file_and_from_module_class():
    from designlab.sensors.registry import SENSORS, resolve

    name = resolve(str(LOAD_CELL))
    assert name == "load_cell" and SENSORS[name].paper
    assert resolve(f"{LOAD_CELL}:LoadCell") == name
    with pytest.raises(ParameterError, match="NoSuch"):
        resolve(f"{LOAD_CELL}:NoSuch")
    with pytest.raises(ParameterError, match="existing Python file"):
        resolve("no/such/file.py")


def test_a_definition_cannot_take_a_built_in_name():
    from designlab.sensors.registry import register

    class Strap(dl.SensorDefinition):
        name = "strap"

    with pytest.raises(ParameterError, match="not a built-in"):
        register(Strap)


def test_parameters_are_checked_like_the_built_in_parts():
    with pytest.raises(ParameterError, match="thickness"):
        _cell(thickness=0.1)


def test_a_body_without_a_library_material_is_named():
    from build123d import Box

    with pytest.raises(ParameterError, match=r"bodies\.b\.material"):
        check_bodies({"b": dl.Solid(Box(1, 1, 1), "wood")})


def test_overlapping_bodies_are_named():
    from build123d import Box, Pos

    bodies = {"a": dl.Solid(Box(4, 4, 4), "PLA"), "b": dl.Solid(Pos(2, 0, 0) * Box(4, 4, 4), "PLA")}
    with pytest.raises(ParameterError, match="overlaps b by 32"):
        check_bodies(bodies)
    touching = {"a": bodies["a"], "b": dl.Solid(Pos(4, 0, 0) * Box(4, 4, 4), "PLA")}
    check_bodies(touching)      # bodies that touch are bonded, not an error
    # a swept wire standing on a disc: their intersection is no solid at all (None)
    check_bodies(dl.Flexure().bodies())


def test_staircase_loops_pair_each_weight_up_and_down():
    st = dl.Staircase("tip", weights_g=(10, 20, 30), cycles=2)
    states = st.states()
    assert len(states) == 2 * 6
    for loads_up, up, loads_down, down in st.loops():
        fz = lambda i: 0.0 if i < 0 else -states[i].force_N[2] / 9.81e-3   # back to grams
        assert np.allclose([fz(i) for i in up], loads_up)
        assert np.allclose([fz(i) for i in down], loads_down)


def test_wrenches_from_masses_take_moments_about_the_point():
    w = dl.Wrenches.from_masses("jig", [1.0], [(0.0, 0.0, 100.0)], [(1, 0, 0)])
    F, M = np.array(w.wrenches[0][:3]), np.array(w.wrenches[0][3:])
    assert np.allclose(F, (9.81, 0, 0)) and np.allclose(M, (0, 981.0, 0))   # r x F, N mm


def test_dipole_field_on_its_axis_matches_the_closed_form():
    from designlab.sensors.generic.fem import dipole_field_uT, dipole_jacobian

    m = np.array([0.0, 0.0, 0.1])                         # A m^2
    B = dipole_field_uT(np.zeros(3), m, np.array([0.0, 0.0, 20.0]))
    assert B[2] == pytest.approx(1e-7 * 2 * 0.1 / 0.02 ** 3 * 1e6, rel=1e-12)   # 2500 uT
    J = dipole_jacobian(np.zeros(3), m, np.array([0.0, 0.0, 20.0]))
    # moving the magnet 1 mm towards the sensor: dB/dz = 3 B / r
    assert J[2, 2] == pytest.approx(3 * B[2] / 20.0, rel=1e-6)


@pytest.mark.parametrize("edit, item", [
    (("top = dl.Face(\"beam\", normal=(0, 0, 1))", "top = dl.Face(\"bam\", normal=(0, 0, 1))"),
     r"transducers\[0\] \(gauge\)\.face\.body"),
    (("at=(x, 0, t))]", "at=(x, 0, 50.0))]"),
     r"loads\[0\] \(tip\)\.at"),
    (('return [dl.Clamped(dl.Face("beam", normal=(-1, 0, 0)))]', "return []"), "supports"),
])
def test_bad_definitions_name_the_item(tmp_path, edit, item):
    from designlab.sensors.registry import load_class

    text = LOAD_CELL.read_text()
    assert edit[0] in text
    f = tmp_path / "bad.py"
    f.write_text(text.replace(*edit))
    part = load_class(str(f))()
    with pytest.raises(ParameterError, match=item):
        _run(part, edge=4.0)


def test_load_only_parameters_share_the_fem():
    """A parameter that only moves the load point reuses the FEM, and the reading is exactly
    linear in where the load acts (the same face, a shifted point)."""
    class Moving(dl.SensorDefinition):
        name = "moving_load"
        at_x: float = dl.param(40.0, 10, 70, unit="mm", moves_load=True)

        def bodies(self):
            from build123d import Box, Pos

            return {"beam": dl.Solid(Pos(40, 0, 2) * Box(80, 12, 4), "PLA")}

        def supports(self):
            return [dl.Clamped(dl.Face("beam", normal=(-1, 0, 0)))]

        def transducers(self):
            return [dl.StrainGauge("gauge", dl.Face("beam", normal=(0, 0, 1)), (12, 0, 4),
                                   (1, 0, 0), 3.0, 1.6)]

        def loads(self):
            return [dl.LoadPoint("top", dl.Face("beam", normal=(0, 0, 1)), at=(self.at_x, 0, 4))]

        def protocol(self):
            return dl.Staircase("top", weights_g=(10, 20, 30))

    r = [_run(Moving(at_x=x), edge=4.0, viscoelastic=False) for x in (20.0, 40.0, 60.0)]
    assert not r[0].report["mesh"]["fem_reused"]
    assert r[1].report["mesh"]["fem_reused"] and r[2].report["mesh"]["fem_reused"]
    k = [x.report["sensitivity"]["gauge"]["top_Fz"] for x in r]
    assert k[2] - k[1] == pytest.approx(k[1] - k[0], rel=1e-9)
    assert abs(k[2]) > abs(k[0])


@pytest.mark.slow
def test_every_command_runs_on_a_fresh_new_file(tmp_path, monkeypatch):
    from designlab.cli import main

    monkeypatch.chdir(tmp_path)
    main(["new", "my_beam"])
    f = str(tmp_path / "my_beam.py")
    for args in (["params", f], ["show", f, "--out", "s.png"], ["mesh", f, "--out", "m"],
                 ["export", f, "--out", "e"], ["predict", f, "--out", "p"]):
        main(args)
    pred = json.loads((tmp_path / "p" / "prediction.json").read_text())
    assert pred["sensitivity"]["gauge"]["tip_Fz"] < 0 and pred["mesh_convergence"]
    assert (tmp_path / "s.png").stat().st_size and list((tmp_path / "e").rglob("*.3mf"))
    with pytest.raises(SystemExit) as exc:
        main(["new", "my_beam"])
    assert exc.value.code == 2


def _drift_model(path, beta):
    from designlab.loop.effects.base import Fitted
    from designlab.loop.effects.drift import Drift
    from designlab.sensors.sensor import linear_sensor_model

    m = linear_sensor_model({"gauge": {"tip_Fz": -0.28}}, {"gauge": "mV/V"}, {"source": "test"})
    m.effects["gauge"] = [Fitted(Drift(), {"variant": "polynomial", "order": 1,
                                           "duration_s": 120.0}, (beta,), (), ())]
    m.save(path)
    return path


@pytest.mark.slow
def test_a_learned_model_is_applied_back_to_a_definition(tmp_path):
    """loop -> predict: a drift of zero changes nothing; a drift adds hysteresis (the readings
    going down come later than going up)."""
    from designlab.sensors.generic.loop import apply_model
    from designlab.sensors.generic.virtual import DefinitionProtocol

    part = _cell()
    res = _run(part, edge=4.0)
    proto = DefinitionProtocol()
    zero = apply_model(res.report, res, _drift_model(tmp_path / "z.json", 0.0), proto, None, part)
    assert zero["condition_number"] == pytest.approx(res.report["condition_number"], rel=1e-9)
    assert zero["hysteresis_percent"]["overall"] == pytest.approx(
        res.report["hysteresis_percent"]["overall"], rel=1e-9)
    drift = apply_model(res.report, res, _drift_model(tmp_path / "d.json", 0.01), proto, None,
                        part)
    assert drift["learned_effects"] == {"gauge": ["drift"]}
    assert drift["hysteresis_percent"]["overall"] > 10 * res.report["hysteresis_percent"]["overall"]
    with pytest.raises(ParameterError, match="--model"):
        bad = _drift_model(tmp_path / "b.json", 0.01)
        text = bad.read_text().replace('"gauge"', '"other"')
        bad.write_text(text)
        apply_model(res.report, res, bad, proto, None, part)


@pytest.mark.slow
def test_the_superposed_march_equals_marching_the_protocol():
    """The readings at the end of each hold: one step-response march superposed over the load
    changes equals the protocol marched as it is (held loads, jumps between them)."""
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history
    from designlab.sensors.generic import virtual as g

    part = _cell()
    res = _run(part, edge=4.0)
    st = res.stage
    W, _, _ = g._unit_wrenches(part, st, part.protocol().states())
    hold, n = 10.0, len(W)
    sub = g._steps_per_hold(st["model"], hold)
    assert sub > 1                  # the march steps within a hold
    # each hold: the jump at its start, then its steps; read at its end
    t = np.concatenate([k * hold + hold * np.arange(sub + 1) / sub for k in range(n)])
    amp = np.repeat(W, sub + 1, axis=0)
    hist = History(t, {c: amp[:, j] for j, c in enumerate(st["cases"])})
    U = np.asarray(solve_history(st["model"], hist, forces=False).U)[:, sub::sub + 1]
    direct = np.asarray(st["read"] @ U).T
    assert np.allclose(res.readings, direct, rtol=1e-9, atol=1e-12 * np.abs(direct).max())
    assert res.report["hysteresis_percent"]["overall"] > 0


def test_a_definitions_settings_travel_to_another_process():
    """predict's forked side process (the coarse mesh of the error bar) and workers receive a
    definition's settings, whose class is made at run time: pickled, they come back equal and
    of the same class."""
    import pickle

    from designlab.sensors.generic import virtual as g

    cls = type(_cell())
    settings = g.settings_class(cls)(edge_length=3.0, viscoelastic=False)
    back = pickle.loads(pickle.dumps(settings))
    assert back == settings and type(back) is g.settings_class(cls) is type(settings)


def test_the_settled_march_gives_the_long_time_displacements():
    """Once every Prony term has decayed, the unit steps' last response is the relaxed one: the
    stress cases taken from it equal a solve with the relaxed moduli."""
    from designlab.fem.viscoelastic import long_time_displacements
    from designlab.sensors.generic import virtual as g

    part = _cell()
    res = _run(part, edge=4.0)
    st = res.stage
    assert g._settled_holds(st["model"], part.protocol().hold_s) < len(res.loads)
    ref = long_time_displacements(st["model"])
    assert np.abs(st["U_long"] - ref).max() <= 1e-8 * np.abs(ref).max()


def test_a_clamped_rigid_body_holds_what_is_bonded_to_it():
    """A support on a rigid body's face holds the body's reference point (its nodes follow
    it; fixing them too was a model error): a rigid block clamped at the beam's root reads as
    the beam clamped at its root face."""
    from build123d import Box, Pos

    base = _cell()
    cls = type(base)

    class Blocked(cls):
        name = "blocked_cell"

        def bodies(self):
            block = Pos(-2.5, 0, self.thickness / 2) * Box(5.0, self.width, self.thickness)
            return {**super().bodies(), "block": dl.Solid(block, "PLA", rigid=True)}

        def supports(self):
            return [dl.Clamped(dl.Face("block", normal=(-1, 0, 0)))]

    a = _run(base, edge=3.0, viscoelastic=False, mesh_convergence=False).report
    b = _run(Blocked(), edge=3.0, viscoelastic=False, mesh_convergence=False).report
    ga, gb = a["sensitivity"]["gauge"]["tip_Fz"], b["sensitivity"]["gauge"]["tip_Fz"]
    assert gb == pytest.approx(ga, rel=0.03)
