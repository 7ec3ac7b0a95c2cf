"""The built-in three are sensor definitions like any other: the registry builds their records
from their definitions' plugged-in physics, and each declaration (bodies and materials,
supports, transducers, loads, protocol) states the same sensor as the physics runs: the same
materials, the same transducer constants, the same load points and loads, and faces that exist
on the part's B-rep."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import designlab as dl
from designlab.errors import ParameterError
from designlab.geometry.tessellate import triangulate
from designlab.sensors import definition as d
from designlab.sensors.generic.faces import pick
from designlab.sensors.generic.record import HOOKS, sensor_record
from designlab.sensors.generic.virtual import protocol_states
from designlab.sensors.registry import BUILT_IN_DEFINITIONS, SENSORS


@pytest.mark.parametrize("cls", BUILT_IN_DEFINITIONS, ids=lambda c: c.name)
def test_the_record_is_the_definitions_physics(cls):
    rec, ph = SENSORS[cls.name], cls.physics
    assert d.is_definition(cls) and isinstance(ph, d.Physics)
    assert (rec.run, rec.plots, rec.gains, rec.protocol, rec.settings) == (
        ph.run, ph.plots, ph.gains, ph.protocol, ph.settings)
    for k, v in ph.hooks.items():
        assert getattr(rec, k) is v
    assert rec.part is cls and dl.PARTS[cls.name] is cls


def test_a_physics_with_a_hook_the_record_lacks_is_one_line():
    ph = dataclasses.replace(BUILT_IN_DEFINITIONS[0].physics, hooks={"prefetch": None})
    cls = type("Odd", (BUILT_IN_DEFINITIONS[0],), {"physics": ph, "name": "odd"})
    with pytest.raises(ParameterError, match="hooks of the sensor record") as exc:
        sensor_record(cls)
    assert "prefetch" in str(exc.value) and "\n" not in str(exc.value)
    assert "finish" in HOOKS and "run" not in HOOKS


def test_a_design_is_the_same_made_as_its_cad_part_or_as_its_definition():
    from designlab.geometry.fingertip import CantileverFingertip as Cad

    assert dl.Fingertip(h=3) == Cad(h=3) and Cad(h=3) == dl.Fingertip(h=3)
    assert hash(dl.Fingertip(h=3)) == hash(Cad(h=3)) and dl.Fingertip(h=3) != Cad(h=2)
    assert dl.Fingertip.table_ii() == Cad.table_ii()


def _faces_exist(defn):
    """Every face a support, transducer or load names selects triangles of its body's B-rep."""
    bodies = defn.bodies()
    faces = [(f"supports.{i}", s.face) for i, s in enumerate(defn.supports())]
    for t in defn.transducers():
        for attr in ("face", "face_a", "face_b", "where"):
            f = getattr(t, attr, None)
            if isinstance(f, d.Face):
                faces.append((f"{t.name}.{attr}", f))
            elif isinstance(f, d.Region):
                assert f.body in bodies, t.name
    faces += [(lp.name, lp.face) for lp in defn.loads()]
    for what, f in faces:
        v, tri = triangulate(bodies[f.body].shape, tolerance=0.01)
        assert pick(v, tri, f, what).any(), what
    return len(faces)


@pytest.mark.slow
@pytest.mark.parametrize("cls, n_faces", [(dl.Fingertip, 1 + 6 + 12), (dl.Strap, 2 + 2 + 1),
                                          (dl.Flexure, 1 + 1)], ids=lambda c: getattr(c, "name", ""))
def test_every_declared_face_is_on_the_parts_brep(cls, n_faces):
    assert _faces_exist(cls()) == n_faces


def test_the_fingertip_declares_what_its_contact_physics_runs():
    from designlab.sensors.fingertip.model import FingertipModelSettings, FSS015_V_PER_N
    from designlab.sensors.fingertip.readout import repeatability_sigma_V
    from designlab.sensors.protocols import HangingWeightTest

    f = dl.Fingertip()
    built = f.build()
    assert {n: s.material for n, s in f.bodies().items()} == {
        n: built[n].material for n in ("fingertip", "base", "cap", "ball", "bolt")}
    assert [n for n, s in f.bodies().items() if s.rigid] == ["ball"]
    axes, _ = f.sensor_axes()
    settings = FingertipModelSettings()
    for k, t in enumerate(f.transducers()):
        assert t.stiffness_N_per_mm == settings.sensor_stiffness
        assert t.sensitivity_V_per_N == FSS015_V_PER_N
        assert t.noise_V == repeatability_sigma_V(settings.repeatability_percent_fs)
        assert np.allclose(t.axis, -axes[k])
    pts = f.load_points(0.0)
    assert {lp.name: (lp.at, lp.direction) for lp in f.loads()} == {
        n: (tuple(p), tuple(v)) for n, (p, v) in pts.items()}
    test = HangingWeightTest.preset("optimized")
    states = protocol_states(f)
    per = len(states) // len(pts)
    for k, name in enumerate(test.g1_locations + test.g2_locations):
        seq = states[k * per:(k + 1) * per]
        assert {s.load for s in seq} == {name}
        size = [np.linalg.norm(s.force_N) for s in seq]
        assert np.allclose(size[:-1], test.loads_N, rtol=1e-12)       # the tray hangs between
        assert np.allclose(np.asarray(seq[0].force_N) / size[0], pts[name][1])


def test_the_strap_declares_what_its_worn_physics_runs():
    from designlab.fem.materials import get_material
    from designlab.sensors.protocols import StrapLoadTest
    from designlab.sensors.strap.electrical import electrical_report, gauge_resistance

    s = dl.Strap()
    assert {n: b.material for n, b in s.bodies().items()} == {
        n: b.material for n, b in s.build().items()}
    trace = get_material("PI-ETPU")
    R0 = gauge_resistance(s, 0.0, trace)["total"]
    noise = electrical_report(s, trace, 1.0, 1.0)["noise"]["channel_V_rms"]
    for g in s.transducers():
        assert (g.kind, g.gauge_factor, g.R0_ohm) == ("printed", trace.gauge_factor, R0)
        assert g.noise == pytest.approx(noise, rel=1e-12)
    test = StrapLoadTest()
    _, fn, fx = test.time_history()
    stair = (2 * test.n_steps + 1) * round(test.step_hold_s / test.dt_s)  # then grasp cycles
    levels = np.unique(np.round(fn[:stair], 12))
    rows = np.array(s.protocol().wrenches)
    assert np.allclose(np.unique(np.round(rows[:, 2], 12)), levels)
    assert np.allclose(rows[:, 0], rows[:, 2] * test.shear_N / test.normal_N)


def test_the_flexure_declares_what_its_beam_chain_runs():
    from designlab.sensors.flexure.force_error import FlexureForceTest
    from designlab.sensors.protocols import FlexureWrenchTest

    f = dl.Flexure()
    assert f.bodies()["spring"].material == f.material and not f.bodies()["spring"].printed
    assert [n for n, s in f.bodies().items() if s.rigid] == ["base_disc", "tip_disc"]
    W = FlexureWrenchTest().wrenches()
    assert np.allclose(np.array(f.protocol().wrenches), np.c_[W[:, 3:], W[:, :3]])
    probes = f.transducers()
    assert [p.noise for p in probes[:3]] == [FlexureForceTest().pose_noise_mm] * 3
    assert [p.noise for p in probes[3:]] == [FlexureForceTest().pose_noise_rad] * 3


def test_a_designer_subclasses_a_built_in_and_keeps_its_physics():
    class Wide(dl.Fingertip):
        name = "wide_fingertip"

    assert Wide.physics is dl.Fingertip.physics
    assert Wide(base_radius=12).transducers()[0].name == "sensor_1"


@pytest.mark.slow
def test_predict_runs_a_subclass_of_a_built_in_with_its_physics(tmp_path, run_cli):
    import json

    src = tmp_path / "wide_finger.py"
    src.write_text("import designlab as dl\n\n\nclass WideFingertip(dl.Fingertip):\n"
                   "    name = 'wide_fingertip'\n"
                   "    base_radius: float = dl.param(12.0, 6, 20, unit='mm', doc='wider')\n")
    rc, out, err = run_cli(["predict", src, "--out", tmp_path / "run", "--setting",
                            "mesh_convergence=false", "--setting", "contact=false"])
    assert rc == 0, err
    assert "designlab validate fingertip" in " ".join(out.split())
    pred = json.loads((tmp_path / "run" / "prediction.json").read_text())
    assert pred["design"]["params"]["base_radius"] == 12.0
    assert pred["model"].startswith("linear") and pred["condition_number"] > 1


@pytest.mark.parametrize("base", [dl.Fingertip, dl.Strap, dl.Flexure])
def test_a_subclass_may_not_change_what_its_physics_does_not_read(base, tmp_path, run_cli):
    """A built-in's subclass that changes its transducers (a stiffer force sensor, another
    gauge) would run the built-in's physics, which takes them from its own settings: refused
    in one line naming the declaration; the same override returning the built-in's
    declaration, or new defaults alone, are accepted."""
    def noisier(self):
        return [dataclasses.replace(t, noise_V=2 * t.noise_V) if hasattr(t, "noise_V") else
                dataclasses.replace(t, noise=2 * t.noise) for t in base.transducers(self)]

    changed = type("Changed", (base,), {"name": "changed_" + base.name, "transducers": noisier})
    with pytest.raises(ParameterError) as exc:
        sensor_record(changed)
    assert exc.value.name == "Changed.transducers()" and "does not read" not in str(exc.value)
    assert "without reading transducers()" in str(exc.value)
    same = type("Same", (base,), {"name": "same_" + base.name,
                                  "transducers": lambda self: base.transducers(self)})
    assert sensor_record(same).run is sensor_record(base).run
    if base is dl.Fingertip:   # and through the CLI: one line, exit 2, nothing written
        src = tmp_path / "stiff.py"
        src.write_text("import dataclasses\nimport designlab as dl\n\n\n"
                       "class StiffTip(dl.Fingertip):\n    name = 'stiff_tip'\n\n"
                       "    def transducers(self):\n        return [dataclasses.replace("
                       "t, stiffness_N_per_mm=2000.0) for t in super().transducers()]\n")
        rc, _, err = run_cli(["predict", src, "--out", tmp_path / "run"])
        assert rc == 2 and err.count("error:") == 1 and "StiffTip.transducers()" in err, err
        assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_the_generic_test_on_the_flexures_declaration_meets_its_own_fem():
    """Two code paths, one sensor: the generic virtual test of the flexure's declaration (the
    spring bonded to its two discs, taken rigid as the flexure's FEM takes its ends; the pose
    probes on the fingertip disc; loads at the fingertip) against the flexure's own FEM of the
    spring (K_f_fem at the spring centre, moved to the same load point and probe). Diagonal
    within 3 %, the rotations per moment (a rigid body's, whatever point reads them) within
    5 %. The translations' off-diagonal terms depend on where the probe reads (a Region reads
    the mean of its mesh nodes, pulled towards the refined wire ends) and are not compared."""
    from designlab.sensors.generic import virtual as g
    from designlab.sensors.registry import SENSORS

    class Declared(dl.Flexure):
        name = "flexure_declared"
        physics = None

        def mesh_bodies(self):
            return tuple(self.solids())

    part = Declared()
    rep = g.run(part, settings=g.settings_class(Declared)(viscoelastic=False,
                                                          mesh_convergence=False)).report
    chans = [c["name"] for c in rep["channels"]]
    loads = [x["name"] for x in rep["loads"]]
    C_gen = np.array([[rep["sensitivity"][c][x] for x in loads] for c in chans])

    flex = SENSORS["flexure"]
    res = flex.run(dl.Flexure(), flex.protocol(),
                   flex.settings(truth="fem", mesh_convergence=False))
    K = np.array(res.report["K_f_fem"])        # SI, rows (m, f), columns (w, v), spring centre
    K_mm = np.diag([1e3] * 3 + [1] * 3) @ K @ np.diag([1] * 3 + [1e-3] * 3)
    p = np.asarray(part.spring_center, float)
    a = np.array(part.loads()[0].at)
    c = np.array([0.0, 0.0, part.length + part.disc_thickness / 2])

    def skew(r):
        return np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])

    loads_to_wrench = np.block([[skew(a - p), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])
    twist_to_reading = np.block([[-skew(c - p), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])
    C_fem = twist_to_reading @ np.linalg.inv(K_mm) @ loads_to_wrench
    assert np.allclose(np.diag(C_gen), np.diag(C_fem), rtol=0.03)
    rot_gen, rot_fem = C_gen[3:, 3:], C_fem[3:, 3:]
    assert np.linalg.norm(rot_gen - rot_fem) <= 0.05 * np.linalg.norm(rot_fem)
