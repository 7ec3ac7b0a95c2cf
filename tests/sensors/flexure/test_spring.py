"""Closed-form helical spring 6x6 (seed 002): textbook limits, paper ratios, the common factor."""

import json
import math

import numpy as np
import pytest

from designlab.sensors.flexure import report as fr
from designlab.errors import DataError, ParameterError
from designlab.sensors.flexure import spring as sp
from designlab.frames import transform, transform_stiffness


@pytest.fixture(scope="module")
def paper(shared):
    return fr.load_paper(shared / "data/papers/visiflex_flexure.json")


def test_axial_and_torsion_match_textbook_spring_formulas():
    s = sp.HelicalSpring(wire_radius=1.0, mean_diameter=20.0, coils=10.0, E=200e3, G=80e3)
    d, D, n = 2.0, 20.0, 10.0
    K = sp.stiffness_zero_pitch(s)
    assert K[5, 5] == pytest.approx(80e3 * d**4 / (8 * D**3 * n))          # G d^4 / (8 D^3 n)
    assert K[2, 2] == pytest.approx(200e3 * d**4 / (64 * D * n))           # E d^4 / (64 D n)
    assert K[3, 3] / K[5, 5] == pytest.approx(200e3 / 80e3)                # k_x / k_z = E / G
    nu = 200e3 / (2 * 80e3) - 1
    assert K[0, 0] / K[2, 2] == pytest.approx(2 / (2 + nu))                # k_bx / k_tz
    np.testing.assert_array_equal(K, np.diag(np.diag(K)))


def test_si_conversion_round_trip():
    K = sp.stiffness_timoshenko(sp.VISIFLEX_CATALOG, frame="tip")
    Ksi = sp.to_si(K)
    assert Ksi[5, 5] == pytest.approx(K[5, 5] * 1e3)      # N/mm -> N/m
    assert Ksi[0, 0] == pytest.approx(K[0, 0] * 1e-3)     # N*mm/rad -> N*m/rad
    assert Ksi[0, 4] == pytest.approx(K[0, 4])            # N -> N
    np.testing.assert_allclose(sp.from_si(Ksi), K)


def test_ratios_match_the_paper_within_2_percent(paper):
    """k_x/k_z, k_tz/k_z and k_bx/k_tz of the stated spring agree with the paper's K_f."""
    ours = sp.stiffness_ratios(sp.to_si(sp.stiffness_zero_pitch(sp.VISIFLEX_AS_PRINTED)))
    theirs = sp.stiffness_ratios(paper["K_f_theory"])
    for k in ours:
        assert ours[k] == pytest.approx(theirs[k], rel=0.02), k


def test_stated_parameters_give_one_common_factor_and_the_tool_explains_it(paper):
    rep = fr.flexure_report(sp.VISIFLEX_AS_PRINTED, frame="spring", paper=paper)
    cf = rep["common_factor"]
    assert cf["is_common"] and cf["spread"] < 0.02
    assert 7.3 < cf["factor"] < 7.6
    ex = rep["explanation"]
    assert ex["predicted_factor"] == pytest.approx(16 * 1.75 / 3.75)
    assert cf["factor"] == pytest.approx(ex["predicted_factor"], rel=0.01)
    assert ex["max_deviation_from_paper_K_f"] < 0.01
    assert ex["free_length_mm"] == pytest.approx(19.8, abs=0.05)
    assert any("7.48x" in n for n in rep["notes"])


def test_catalogue_reading_reproduces_the_paper_K_f(paper):
    K = sp.to_si(sp.stiffness_zero_pitch(sp.VISIFLEX_CATALOG))
    np.testing.assert_allclose(np.diag(K), np.diag(paper["K_f_theory"]), rtol=0.01)
    assert sp.VISIFLEX_CATALOG.free_length == pytest.approx(19.8, abs=0.05)
    rep = fr.flexure_report(sp.VISIFLEX_CATALOG, frame="spring", paper=paper)
    assert rep["explanation"] is None and abs(rep["common_factor"]["factor"] - 1) < 0.01


def test_camera_frame_structure_and_values(paper):
    """Our K_f moved by the recovered offset reproduces the paper's K_c: +-121 and 2.22."""
    h = fr.camera_offset(paper)
    assert h == pytest.approx(0.01109, abs=5e-5)
    K_c = fr.to_frame(sp.to_si(sp.stiffness_zero_pitch(sp.VISIFLEX_CATALOG)), "camera", h)
    P = paper["K_c_theory"]
    assert K_c[0, 4] == pytest.approx(P[0, 4], rel=0.01) and K_c[1, 3] == pytest.approx(P[1, 3], rel=0.01)
    assert K_c[3, 1] == pytest.approx(P[3, 1], rel=0.01) and K_c[4, 0] == pytest.approx(P[4, 0], rel=0.01)
    assert K_c[0, 0] == pytest.approx(2.22, rel=0.01) and K_c[1, 1] == pytest.approx(2.22, rel=0.01)
    np.testing.assert_array_equal(np.abs(K_c) > 1e-9, np.abs(P) > 0)      # same sparsity
    # as printed, the same structure scaled by the common factor
    K_c2 = fr.to_frame(sp.to_si(sp.stiffness_zero_pitch(sp.VISIFLEX_AS_PRINTED)), "camera", h)
    np.testing.assert_allclose(K_c2[0, 4] / P[0, 4], 7.5, rtol=0.02)


def test_timoshenko_column_limits_and_cantilever_compliance():
    s = sp.VISIFLEX_CATALOG
    np.testing.assert_allclose(sp.stiffness_timoshenko(s, length=0.0), sp.stiffness_zero_pitch(s))
    L = s.active_length
    assert L == pytest.approx(1.75 * 2 * math.pi * 13.865 * math.tan(0.1029))
    t = sp.centre_terms(s)
    B, S = t["k_bx"] * L, t["k_x"] * L
    C_tip = np.linalg.inv(sp.stiffness_timoshenko(s, frame="tip"))
    # tip of a cantilever: deflection L^3/3B + L/S, rotation L/B, coupling L^2/2B
    assert C_tip[3, 3] == pytest.approx(L**3 / (3 * B) + L / S)
    assert C_tip[1, 1] == pytest.approx(L / B)
    assert abs(C_tip[1, 3]) == pytest.approx(L**2 / (2 * B))
    # a force +x at the tip of a base-clamped column tilts it about +y
    assert C_tip[1, 3] > 0
    K_base = sp.stiffness_timoshenko(s, frame="base")
    np.testing.assert_allclose(K_base, transform_stiffness(
        sp.stiffness_timoshenko(s), transform(translation=(0, 0, L / 2))))


def test_bad_parameters_raise_one_line_errors():
    with pytest.raises(ParameterError, match="wire_radius"):
        sp.HelicalSpring(wire_radius=-1)
    with pytest.raises(ParameterError, match="inactive_coils"):
        sp.HelicalSpring(coils=1.0, inactive_coils=1.0)
    with pytest.raises(ParameterError, match=r"coils=2\.0 .*>= 2\.5 turns for closed and ground"):
        sp.HelicalSpring(coils=2.0, inactive_coils=2.0)
    with pytest.raises(ParameterError, match="wire_radius"):
        sp.HelicalSpring(wire_radius=15.0, mean_diameter=20.0)
    with pytest.raises(ParameterError, match="--preset"):
        sp.preset("nope")
    with pytest.raises(ParameterError, match="frame"):
        sp.stiffness_timoshenko(sp.VISIFLEX_CATALOG, frame="middle")


def test_missing_or_bad_paper_json_is_a_data_error(tmp_path):
    with pytest.raises(DataError, match="not found"):
        fr.load_paper(tmp_path / "nope.json")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"K_f_theory_at_spring_centre": [[1]]}))
    with pytest.raises(DataError, match="seed 002"):
        fr.load_paper(bad)


def test_report_json_is_written_atomically(tmp_path, paper):
    rep = fr.flexure_report(sp.VISIFLEX_AS_PRINTED, frame="camera", paper=paper)
    out = fr.write_json(tmp_path / "k.json", rep)
    data = json.loads(out.read_text())
    assert {"closed_form", "fem", "frame", "paper_theory", "paper_measured", "ratios",
            "units"} <= set(data)
    assert data["units"] == "SI: N*m/rad, N/m, N/rad" and data["fem"] is None
    assert np.array(data["closed_form"]).shape == (6, 6)
    assert list(tmp_path.iterdir()) == [out]
    with pytest.raises(ParameterError, match="--json"):
        fr.write_json(tmp_path / "no" / "dir.json", rep)


@pytest.mark.slow
def test_cli_flexure_no_fem(tmp_path, shared):
    from designlab.cli import main

    out = tmp_path / "flex.json"
    main(["flexure", "--no-fem", "--json", str(out), "--frame", "spring"])
    data = json.loads(out.read_text())
    assert data["frame"] == "spring" and data["common_factor"]["is_common"]
    # the default is the catalogue reading, the spring `predict flexure` builds: its chain at
    # the working load is the virtual test's default truth
    from designlab.geometry.flexure import SpringFlexure
    from designlab.sensors.flexure import virtual

    assert data["spring"]["wire_radius"] == 1.015 and data["explanation"] is None
    truth = virtual.run(SpringFlexure()).report["K_f"]
    assert np.array(data["chain_loaded"]) == pytest.approx(np.array(truth), rel=1e-9)
    main(["flexure", "--no-fem", "--preset", "visiflex", "--json", str(out)])
    assert json.loads(out.read_text())["common_factor"]["factor"] == pytest.approx(7.47, rel=0.01)
    with pytest.raises(SystemExit) as exc:
        main(["flexure", "--no-fem", "--paper-json", str(tmp_path / "missing.json")])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["flexure", "--no-fem", "--set", "wire_radius=abc"])
    assert exc.value.code == 2
