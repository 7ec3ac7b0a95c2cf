"""Seed 002's goal pair against what no camera offset changes: the lateral/rocking ratio at the
elastic centre and the smallest diagonal error it allows with the couplings within 1.5x
(``report.bending_invariants``, ``report.diagonal_error_floor``; docs/validation/flexure.md)."""

import itertools

import numpy as np
import pytest

from designlab.sensors.flexure import beam_chain as bc
from designlab.sensors.flexure import chain_geometry as cg
from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG


@pytest.fixture(scope="module")
def paper():
    return fr.load_paper()


@pytest.fixture(scope="module")
def chain_loaded():
    return bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings()).K_loaded_centre_si


def _goal_terms(K, M):
    diag = 100.0 * np.mean([abs(K[i, i] / M[i, i] - 1.0) for i in range(6)])
    return diag, (K[1, 3] / M[1, 3], K[0, 4] / M[0, 4])


def test_invariants_do_not_move_with_the_frame(chain_loaded):
    ref = fr.bending_invariants(chain_loaded)
    for h in (0.0, 0.00545, 0.01109, 0.02):
        moved = fr.bending_invariants(fr.to_frame(chain_loaded, "camera", h))
        for key in ("rocking", "lateral", "lateral_over_rocking"):
            for a in ("x", "y"):
                assert moved[key][a] == pytest.approx(ref[key][a], rel=1e-9)


def test_the_floor_agrees_with_a_brute_force_search(paper):
    """Over a 10 N/m grid of both lateral stiffnesses the best feasible diagonal error is the
    floor (axial and torsion exact): the piecewise-linear minimum is found, not undercut."""
    M = np.asarray(paper["K_c_measured"], float)
    q, e = {"x": 7950.0, "y": 7950.0}, 0.01109
    floor = fr.diagonal_error_floor(M, q, e)["diagonal_floor_pct"]
    best = np.inf
    for kx, ky in itertools.product(np.arange(3000.0, 8000.0, 10.0), repeat=2):
        cx, cy = e * kx / abs(M[1, 3]), e * ky / abs(M[0, 4])
        if not all(1 / 1.5 <= c <= 1.5 for c in (cx, cy)):
            continue
        err = (abs((kx / q["x"] + e * e * kx) / M[1, 1] - 1) + abs(kx / M[3, 3] - 1)
               + abs((ky / q["y"] + e * e * ky) / M[0, 0] - 1) + abs(ky / M[4, 4] - 1))
        best = min(best, 100.0 * err / 6.0)
    assert floor <= best + 1e-9
    assert best - floor < 0.05


def test_the_measured_matrix_reaches_its_own_floor_near_zero(paper):
    M = np.asarray(paper["K_c_measured"], float)
    inv = fr.bending_invariants(M)
    assert fr.diagonal_error_floor(M, inv["lateral_over_rocking"])["diagonal_floor_pct"] < 0.5


def test_a_real_model_never_beats_its_floor(paper, chain_loaded):
    """The chain at 10 N moved to every offset 1-15 mm: wherever both couplings are within 1.5x
    its diagonal error is at least the floor its own lateral/rocking ratio sets there."""
    M = np.asarray(paper["K_c_measured"], float)
    q = fr.bending_invariants(chain_loaded)["lateral_over_rocking"]
    feasible = 0
    for e in np.linspace(0.001, 0.015, 57):
        diag, coup = _goal_terms(fr.to_frame(chain_loaded, "camera", e), M)
        if all(1 / 1.5 <= c <= 1.5 for c in coup):
            feasible += 1
            assert diag >= fr.diagonal_error_floor(M, q, e)["diagonal_floor_pct"] - 0.05
    assert feasible > 0


def test_symmetric_helix_models_cannot_meet_both_goals_at_the_paper_offset(paper):
    """`designlab flexure`: the models' ratios are 7949-12477 1/m^2
    against the measured 4652 / 5113; at the paper's 11.09 mm the floor is 17.1 % for the chain
    at 10 N (19.6 % Timoshenko), above the goal's 15 %, while the measured ratio allows 10.5 %."""
    r = fr.flexure_report(VISIFLEX_CATALOG, paper=paper,
                          K_chain_loaded_si=bc.chain_stiffness(VISIFLEX_CATALOG,
                                                               cg.ChainSettings()).K_loaded_centre_si)
    inv = r["offset_free"]
    assert inv["chain_loaded"]["goal_floor_paper_offset"]["diagonal_floor_pct"] == pytest.approx(17.1, abs=0.1)
    assert inv["closed_form_timoshenko"]["goal_floor_paper_offset"]["diagonal_floor_pct"] > 15.0
    assert inv["paper_measured"]["goal_floor_paper_offset"]["diagonal_floor_pct"] < 15.0
    assert all(v["goal_floor_paper_offset"]["diagonal_floor_pct"] > 15.0
               for k, v in inv.items() if not k.startswith(("paper_", "ratio_")))
    # the ratio above which no model meets the pair at the paper's offset: 6822 1/m^2, between
    # the measured ratio and every model's
    q = inv["ratio_limit_paper_offset"]["lateral_over_rocking"]
    assert q == pytest.approx(6822, abs=1)
    M = np.asarray(paper["K_c_measured"], float)
    h = fr.camera_offset(paper)
    at = fr.diagonal_error_floor(M, {"x": q, "y": q}, h)["diagonal_floor_pct"]
    assert at == pytest.approx(15.0, abs=1e-3)
    assert fr.diagonal_error_floor(M, {"x": 1.01 * q, "y": 1.01 * q}, h)["diagonal_floor_pct"] > 15.0
    assert max(inv["paper_measured"]["lateral_over_rocking"].values()) < q < min(
        inv["chain_loaded"]["lateral_over_rocking"].values())
    assert any("offset-free" in n for n in r["notes"])
