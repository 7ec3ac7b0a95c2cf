"""Verification cases of the FEM (the same functions `designlab verify` runs) must pass."""

import json

import numpy as np
import pytest

from conftest import require_tool
from designlab.cli import main
from designlab.fem import verify


def _assert_passed(cases):
    assert cases, "no cases returned"
    for c in cases:
        assert set(c) == {"name", "quantity", "value", "reference", "rel_error", "tolerance", "passed"}
        assert c["passed"], f"{c['name']}: {c['quantity']} = {c['value']:.6g} vs {c['reference']:.6g} " \
                            f"(error {c['rel_error']:.2e} > {c['tolerance']:.0e})"


def test_patch_test_exact_on_distorted_mesh():
    cases = verify.patch_test()
    _assert_passed(cases)
    assert len(cases) == 4
    mesh = verify.distorted_box(3, 3, 3, order=2, seed=1)
    assert mesh.order == 2 and mesh.corner_volumes.min() > 0
    regular = verify.box_tet_mesh(2.0, 1.0, 1.5, 3, 3, 3)
    assert not np.allclose(mesh.points[:regular.n_points], regular.points)  # really distorted


def test_symmetry_and_rigid_body_modes():
    _assert_passed(verify.stiffness_symmetry())
    _assert_passed(verify.rigid_body_modes())


def test_cantilever_within_one_percent_of_timoshenko():
    (c,) = verify.cantilever()
    _assert_passed([c])
    # the closed form itself: Euler-Bernoulli part dominates, shear part as expected
    eb = 5.0 * 100 ** 3 / (3 * 2000.0 * 10 * 10 ** 3 / 12)
    assert verify.timoshenko_tip_deflection(5.0, 100, 10, 10, 2000.0, 0.0) == pytest.approx(
        eb + 5.0 * 100 / (5 / 6 * 1000.0 * 100))


@pytest.mark.slow
def test_convergence_orders():
    cases = verify.convergence_rates()
    _assert_passed(cases)
    assert [round(c["reference"]) for c in cases] == [2, 3]


def test_viscoelastic_creep_and_relaxation_match_exact_responses():
    cases = verify.viscoelastic_cases()
    _assert_passed(cases)
    # far inside the 1 % contract: the recursion is exact for piecewise-linear strain and
    # O(dt^2) otherwise
    assert cases[0]["rel_error"] < 1e-9
    assert all(c["rel_error"] < 1e-3 for c in cases)


def test_calculix_node_by_node():
    require_tool("ccx")
    cases = verify.calculix_cases(threads=1)
    _assert_passed(cases)
    assert len(cases) == 4


def test_case_failure_detection_and_report(tmp_path):
    bad = verify.case("x", "q", 1.02, 1.0, 0.01)
    assert not bad["passed"] and bad["rel_error"] == pytest.approx(0.02)
    nan = verify.case("x", "q", float("nan"), 1.0, 0.01)
    assert not nan["passed"]
    path = verify.write_report([bad, nan], tmp_path / "out" / "verify.json")
    data = json.loads(path.read_text())
    assert data["passed"] is False and data["cases"][1]["value"] is None
    assert not list(path.parent.glob(".verify-*"))  # no temp file left


def _run(argv):
    try:
        main(argv)
    except SystemExit as exc:
        return exc.code or 0
    return 0


def test_cli_verify_exit_codes(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(verify, "default_cases",
                        lambda reference=None, threads=1: [("symmetry", verify.stiffness_symmetry)])
    assert _run(["verify", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "verify.json").read_text())
    assert data["passed"] and len(data["cases"]) == 2
    monkeypatch.setattr(verify, "default_cases", lambda reference=None, threads=1: [
        ("failing", lambda: [verify.case("broken", "q", 2.0, 1.0, 0.01)])])
    assert _run(["verify", "--out", str(tmp_path / "f")]) == 1
    assert json.loads((tmp_path / "f" / "verify.json").read_text())["passed"] is False
    assert _run(["verify", "--reference", "abaqus", "--out", str(tmp_path / "g")]) == 2
    assert "calculix" in capsys.readouterr().err
    assert not (tmp_path / "g").exists()


def test_cli_reference_calculix_without_ccx_is_one_line_error(tmp_path, monkeypatch, capsys):
    from designlab.fem import calculix

    monkeypatch.setattr(calculix.shutil, "which", lambda name: None)
    assert _run(["verify", "--reference", "calculix", "--out", str(tmp_path / "h")]) == 2
    err = capsys.readouterr().err.strip()
    assert "ccx" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "h").exists()
