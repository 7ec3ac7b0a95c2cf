"""Per-end conditions of the beam chain (seat_base / seat_tip): the symmetric default unchanged,
the zero-coupling point moving towards the rotationally compliant end, the offset-independent
rocking stiffness, and seed 002's goals over every end combination (docs/validation/flexure.md)."""

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.sensors.flexure import beam_chain as bc
from designlab.sensors.flexure import chain_geometry as cg
from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG, to_si

UNLOADED = dict(working_load_N=0.0)


@pytest.fixture(scope="module")
def paper():
    return fr.load_paper()


@pytest.fixture(scope="module")
def table(paper):
    return fr.end_condition_table(VISIFLEX_CATALOG, paper)


def _row(table, base, tip, state):
    (r,) = [r for r in table if (r["base"], r["tip"], r["state"]) == (base, tip, state)]
    return r


@pytest.mark.parametrize("seat", fr.END_SEATS)
@pytest.mark.slow
def test_same_condition_at_both_ends_is_the_symmetric_setting_bit_for_bit(seat):
    a = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat=seat))
    b = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat_base=seat, seat_tip=seat))
    assert np.array_equal(a.K, b.K) and np.array_equal(a.K_loaded, b.K_loaded)
    assert a.info["seats"] == {"base": seat, "tip": seat}


@pytest.mark.slow
def test_one_end_overrides_the_common_setting_only_at_that_end():
    s = cg.ChainSettings(seat="potted", seat_base="contact")
    assert s.end_seats == ("contact", "potted")
    assert cg.ChainSettings().end_seats == ("bonded", "bonded")
    a = bc.chain_stiffness(VISIFLEX_CATALOG, cg.with_settings(s, **UNLOADED))
    b = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat_base="contact",
                                                              seat_tip="potted", **UNLOADED))
    assert np.array_equal(a.K, b.K)
    # the bonded node sets follow the ends: one node at the contact base, the whole dead turn
    # at the potted tip
    assert len(a.chain.base_bond) == 1 and len(a.chain.tip_bond) > 30


@pytest.mark.slow
def test_zero_coupling_point_moves_towards_the_rotationally_compliant_end():
    """Seated (contact) base and potted tip: the elastic centre moves towards the base; the
    mirrored assembly moves it as far towards the tip; symmetric ends keep it at the centre."""
    zc = {}
    for base, tip in (("contact", "potted"), ("potted", "contact"), ("bonded", "potted"),
                      ("bonded", "bonded"), ("contact", "contact"), ("potted", "potted")):
        r = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat_base=base, seat_tip=tip,
                                                                  **UNLOADED))
        zc[base, tip] = r.zero_coupling()["mean_mm"]
    assert zc["contact", "potted"] < -2.0          # -2.46 mm with the line contacts
    assert zc["potted", "contact"] > 2.0
    assert zc["contact", "potted"] == pytest.approx(-zc["potted", "contact"], abs=0.05)
    assert zc["bonded", "potted"] < -1.0           # bonded is softer than potted: -1.26 mm
    for s in ("bonded", "contact", "potted"):
        assert abs(zc[s, s]) < 0.15, s


def test_zero_coupling_point_agrees_with_the_camera_frame_definition(paper):
    r = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat_base="contact",
                                                              seat_tip="potted", **UNLOADED))
    h = fr.camera_offset(paper)
    Kc = fr.to_frame(r.K_centre_si, "camera", h)
    assert 1e3 * fr.zero_coupling_point(Kc) == pytest.approx(1e3 * h + r.zero_coupling()["mean_mm"],
                                                             abs=1e-6)


def test_rocking_at_the_elastic_centre_does_not_depend_on_the_offset(paper):
    M = paper["K_c_measured"]
    K = to_si(bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(**UNLOADED)).K_centre)
    for A in (M, K):
        ref = fr.rocking_at_elastic_centre(A)
        for h in (-0.02, 0.005, 0.011):
            moved = fr.to_frame(A, "camera", h)
            assert fr.rocking_at_elastic_centre(moved) == pytest.approx(ref, rel=1e-9)
            assert moved[3, 3] == pytest.approx(A[3, 3], rel=1e-12)


def test_no_end_combination_meets_both_goals_at_the_paper_offset(table, paper):
    """benchmarks/bench_flexure_end_seats.py (line contacts): 0 of 18 rows
    meet both goals; the default (bonded/bonded at 10 N) is 12.7 %, 1.75 / 2.03x; the measured
    rocking stiffness at its elastic centre (1.25-1.29 N*m/rad) is above every end
    combination's (0.50-0.88)."""
    assert len(table) == 18
    assert not any(fr.meets_goals(r) for r in table)
    d = _row(table, "bonded", "bonded", "loaded")
    assert d["diagonal_mean_abs_error_pct"] == pytest.approx(12.7, abs=0.1)
    c = d["coupling_model_over_measured"]
    assert (c["k_wx_vy"], c["k_wy_vx"]) == pytest.approx((1.75, 2.03), abs=0.01)
    kb_meas = min(fr.rocking_at_elastic_centre(paper["K_c_measured"]))
    kb_model = max(max(r["rocking_at_elastic_centre_si"]) for r in table)
    assert kb_model < 0.75 * kb_meas
    # the couplings-only choice fails the diagonal it did not see, and the reverse
    best_c = min(table, key=fr.coupling_misfit)
    best_d = min(table, key=lambda r: r["diagonal_mean_abs_error_pct"])
    assert best_c["diagonal_mean_abs_error_pct"] > 30.0
    assert min(best_d["coupling_model_over_measured"].values()) > 1.5
    # a goal checker that can say yes
    ok = dict(d, diagonal_mean_abs_error_pct=10.0,
              coupling_model_over_measured={"k_wx_vy": 1.4, "k_wy_vx": 0.7})
    assert fr.meets_goals(ok)


@pytest.mark.parametrize("name", ["seat_base", "seat_tip"])
def test_bad_end_condition_names_the_parameter(name):
    with pytest.raises(ParameterError, match=name):
        cg.ChainSettings(**{name: "glued"})
