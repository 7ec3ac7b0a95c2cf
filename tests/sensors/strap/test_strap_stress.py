"""The strap's stress check (every load case of the protocol, the wrap's prestress, the VTU
fields) and ``predict strap --measured`` (measured printed-material data in the FEM, the
readout and the stress). Cheap: a short protocol on a coarse TET4 mesh (about 2 s a solve)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.geometry.strap import ArchStrap
from designlab.sensors.strap import virtual as st
from designlab.sensors.strap import wrap_stress as strap_wrap
from designlab.sensors.protocols import StrapLoadTest

PART = ArchStrap()
SHORT = {"n_steps": 2, "step_hold_s": 1.0, "dt_s": 0.25, "cycles": 1, "cycle_period_s": 1.0}
CHEAP = {"edge_length": 2.0, "order": 1, "mesh_convergence": False}


def _records(tmp_path, **E):
    path = tmp_path / "measured.json"
    path.write_text(json.dumps({"measured": [
        {"material": m, "quantity": "E", "value": v, "source": "tensile test of a printed "
         "dog-bone (test data)", "date": "2026-11-25"} for m, v in E.items()]}))
    return path


def test_load_envelope_bounds_every_state_of_the_history():
    """The envelope's vertices reach the largest value of any convex function of the loads
    over the whole history (von Mises of a linear model is one); no shear: the two ends."""
    t, fn, fx = StrapLoadTest().time_history()
    env = st.load_envelope(fn, fx)
    V = np.array([(a, b) for a, b, _ in env])
    assert not np.any(np.all(V == 0, axis=1))            # the unloaded origin is no case
    rng = np.random.default_rng(0)
    for a, b, c in rng.normal(size=(50, 3)):
        f = lambda x, y: np.hypot(a * x + b * y, c * y)   # a seminorm of the loads
        assert f(V[:, 0], V[:, 1]).max() == pytest.approx(f(fn, fx).max(), rel=1e-12)
    for a, b, k in env:                                  # each vertex is a state of the history
        assert (fn[k], fx[k]) == pytest.approx((a, b), abs=1e-12)
    _, fn0, fx0 = StrapLoadTest(shear_N=0.0).time_history()
    assert [(a, b) for a, b, _ in st.load_envelope(fn0, fx0)] == [(5.0, 0.0)]


@pytest.fixture(scope="module")
def wrapped():
    """predict strap with the paper's medium slot (a prestrained wrap)."""
    from designlab.predict.run import predict

    return predict("strap", {}, protocol=SHORT, settings={**CHEAP, "slot": 2})


def test_every_load_case_has_its_stress_and_the_traces_say_why_none(wrapped):
    proto = StrapLoadTest(**SHORT)
    _, fn, fx = proto.time_history()
    s = wrapped.metrics["stress"]
    names = {f"F_n {a:.3g} N, F_x {b:+.3g} N" for a, b, _ in st.load_envelope(fn, fx)}
    assert set(s["load_cases"]) == names
    for case in s["load_cases"].values():
        assert set(case["bodies"]) == {"strap", "trace_left", "trace_right"}
        strap = case["bodies"]["strap"]
        assert strap["material"] == "NinjaFlex" and strap["strength_MPa"] == 4.0
        assert strap["safety_factor"] == pytest.approx(4.0 / strap["max_von_mises_MPa"])
        for tr in ("trace_left", "trace_right"):
            assert case["bodies"][tr]["safety_factor"] is None
            assert case["bodies"][tr]["max_von_mises_MPa"] > 0
    assert s["materials"]["PI-ETPU"]["strength_MPa"] is None
    assert any("PI-ETPU: no documented strength" in w for w in wrapped.warnings)
    # linear superposition of the unit cases: the same load twice as large, twice the stress
    U = wrapped.result.unit_displacement
    cs = st.load_cases(PART, proto, wrapped.settings, wrapped.result)
    for c in cs:
        F_n, F_x = (float(x) for x in c.name.replace("F_n", "").replace("F_x", "")
                    .replace("N", "").split(","))
        assert np.allclose(c.displacement, U @ [F_n, F_x])
    # below 2: warned, one line per body and case
    low = [(n, b) for n, c in s["load_cases"].items() for b, e in c["bodies"].items()
           if e["safety_factor"] is not None and e["safety_factor"] < 2]
    for n, b in low:
        assert any(f"in {b} (NinjaFlex) under {n}:" in w for w in wrapped.warnings)


def test_uniform_strain_gives_E_eps_on_the_strap_mesh(wrapped):
    """Closed form on the strap's own mesh and materials: a uniaxial uniform strain eps along
    x (lateral contraction -nu eps) has von Mises stress E eps in every cell of each body
    (long-time modulus: the stress module's convention)."""
    from designlab.fem.materials import get_material
    from designlab.fem.stress import case_stresses, relaxed

    mesh, eps = wrapped.result.mesh, 0.01
    for body, name in (("strap", "NinjaFlex"), ("trace_left", "PI-ETPU")):
        m = relaxed(get_material(name))
        x = mesh.points
        u = eps * np.column_stack([x[:, 0], -m.nu * x[:, 1], -m.nu * x[:, 2]])
        vm = case_stresses(mesh, {"uniaxial": ("", u)})[0].cell[mesh.region == mesh.region_id(body)]
        assert np.allclose(vm, m.E * eps, rtol=1e-9)


def test_the_wrap_stress_is_the_closed_form_and_warns(wrapped):
    from designlab.sensors.strap.prestrain import neo_hooke

    pre = wrapped.metrics["prestrain"]
    ws = pre["stress"]
    eps0 = pre["initial_strain"]
    assert ws["initial_strain"] == eps0 > 0
    e = ws["bodies"]["strap"]
    assert e["linear_E_eps0_MPa"] == pytest.approx(12.0 * eps0)
    assert e["max_von_mises_MPa"] == pytest.approx(
        12.0 * (1 + eps0 - (1 + eps0) ** -2) / 3.0, rel=1e-12)
    assert e["safety_factor"] == pytest.approx(4.0 / e["max_von_mises_MPa"])
    assert ws["bodies"]["trace_left"]["safety_factor"] is None
    # small strain: E eps
    tiny = strap_wrap.wrap_stress({0: _mat("NinjaFlex")}, wrapped.result.mesh, 1e-4)
    assert next(iter(tiny["bodies"].values()))["max_von_mises_MPa"] == pytest.approx(
        12.0e-4, rel=2e-4)
    assert neo_hooke(0.5)["stress_over_linear"] * 12 * 0.5 > 2.0          # 4.2 MPa
    big = strap_wrap.wrap_stress({0: _mat("NinjaFlex")}, wrapped.result.mesh, 0.5)
    (w,) = strap_wrap.wrap_stress_warnings(big)
    assert "from the wrap alone" in w and "initial strain 0.5" in w


def _mat(name):
    from designlab.fem.materials import get_material

    return get_material(name)


@pytest.mark.slow
def test_the_vtu_has_a_von_mises_field_per_load_case_and_the_region_names(wrapped, tmp_path):
    import pyvista as pv

    wrapped.save(tmp_path / "out")
    doc = json.loads((tmp_path / "out" / "prediction.json").read_text())
    assert set(doc["stress"]["load_cases"]) == {c.name for c in wrapped.load_cases}
    assert doc["prestrain"]["stress"]["bodies"]["strap"]["safety_factor"] > 0
    grid = pv.read(tmp_path / "out" / "deformed.vtu")
    shown = [c for c in wrapped.load_cases if c.vtu]
    assert len(shown) >= 2
    vm = sorted(k for k in grid.point_data if k.startswith("von Mises"))
    assert vm == sorted(f"von Mises {c.name} (MPa)" for c in shown)
    for c, st_ in zip(wrapped.load_cases, wrapped.stresses):
        if c.vtu:
            assert np.allclose(grid.point_data[f"von Mises {c.name} (MPa)"], st_.node)
    assert list(grid.field_data["region_names"]) == ["strap", "trace_left", "trace_right"]


@pytest.mark.slow
def test_measured_moduli_change_the_prediction_as_the_scaling_law_says(tmp_path):
    """Both TPUs measured twice as stiff and the finger's support doubled: the whole model is
    twice as stiff, so every gauge strain halves exactly, the stress (load control) stays, and
    the record is in prediction.json; the measured E left the stand-ins."""
    from designlab.predict.run import predict

    path = _records(tmp_path, **{"NinjaFlex": 24.0, "PI-ETPU": 24.0})
    a = predict("strap", {}, protocol=SHORT, settings=CHEAP)
    b = predict("strap", {}, protocol=SHORT, settings={**CHEAP, "tissue_stiffness": 0.04},
                measured=path)
    assert np.allclose(2 * b.result.strain, a.result.strain, rtol=1e-9,
                       atol=1e-12 * np.abs(a.result.strain).max())
    assert b.metrics["stress"]["max_von_mises_MPa"] == pytest.approx(
        a.metrics["stress"]["max_von_mises_MPa"], rel=1e-9)
    assert [r["material"] for r in b.metrics["measured_materials"]] == ["NinjaFlex", "PI-ETPU"]
    sa = a.metrics["sensitivity"]["V_per_N"]["sum"]["F_n"]
    sb = b.metrics["sensitivity"]["V_per_N"]["sum"]["F_n"]
    # the voltage follows the strain through the divider, which is not linear at the
    # paper-sized strains (1.5 % off half here): the exact law is the strain's, above
    assert sb == pytest.approx(sa / 2, rel=0.03)
    # only the trace stiffer: the band carries less, the gauges' strain falls, but not by half
    c = predict("strap", {}, protocol=SHORT, settings=CHEAP,
                measured=_records(tmp_path, **{"PI-ETPU": 24.0}))
    ratio = np.abs(c.result.strain).max() / np.abs(a.result.strain).max()
    assert 0.5 < ratio < 1.0


def test_a_bad_measured_file_is_one_line_and_exit_2(tmp_path, capsys):
    from designlab.cli import main

    bad = tmp_path / "bad.json"
    bad.write_text('{"measured": [')
    other = _records(tmp_path, **{"ABS": 2000.0})
    for f, says in ((bad, "JSON"), (other, "a material of this part: NinjaFlex, PI-ETPU"),
                    (tmp_path / "none.json", "an existing JSON file")):
        out = tmp_path / f"out_{f.stem}"
        with pytest.raises(SystemExit) as exc:
            main(["predict", "strap", "--measured", str(f), "--out", str(out),
                  "--setting", "edge_length=2.0", "--setting", "order=1"])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and says in err, err
        assert not out.exists()
    with pytest.raises(ParameterError, match="a material of this part"):
        from designlab.predict.run import measured_materials

        measured_materials(PART, other)


@pytest.mark.slow
def test_a_tight_wrap_warns_once():
    """A custom wrap at 50 % initial strain: 4.2 MPa in the band (neo-Hookean stand-in) against
    its 4 MPa, one warning line although the error bar's coarse run repeats the run."""
    import math

    from designlab.sensors.strap import fit as sf
    from designlab.predict.run import predict

    L = sf.wrap_path(PART, 2 * math.pi * 9.0) / 1.5
    p = predict("strap", {}, protocol=SHORT, settings={**CHEAP, "mesh_convergence": True,
                                                        "wrap_length": round(L, 6)})
    ws = p.metrics["prestrain"]["stress"]
    assert ws["initial_strain"] == pytest.approx(0.5, rel=1e-5)
    assert ws["min_safety_factor"] == pytest.approx(4.0 / (12 * (1.5 - 1.5 ** -2) / 3), rel=1e-4)
    wrap = [w for w in p.warnings if "from the wrap alone" in w]
    # the band (NinjaFlex) only: the traces have no documented strength
    assert len(wrap) == 1 and "in strap (NinjaFlex)" in wrap[0]
    assert len(set(p.warnings)) == len(p.warnings)
