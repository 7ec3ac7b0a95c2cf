"""Wire stress and safety factor of the spring flexure (designlab.sensors.flexure.stress): the
closed form against Wahl/Shigley's textbook numbers, against the beam chain's section forces
(the independent check), and in the prediction (report, warnings)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.materials import get_material
from designlab.sensors.flexure import stress as fs
from designlab.sensors.flexure.beam_chain import Chain
from designlab.sensors.flexure.chain_geometry import ChainSettings, as_built
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG, HelicalSpring
from designlab.sensors.protocols import FlexureWrenchTest


@pytest.fixture(scope="module")
def catalogue_stress():
    return fs.wire_stress(VISIFLEX_CATALOG)


def test_wahl_factor_textbook_values():
    # Shigley 10th ed. Ex. 10-1 style numbers: C = 8 -> K_W = 31/28 + 0.615/8 = 1.1840
    k = fs.factors(8.0)
    assert k["K_W"] == pytest.approx(1.1840, abs=1e-4)
    assert k["K_s"] == pytest.approx(1.0625)
    assert k["K_c"] * k["K_s"] == pytest.approx(k["K_W"])
    # inner-fibre bending factor of a coiled wire (Shigley Sec. 10-12): C = 8 -> 1.1027
    assert k["K_i"] == pytest.approx((4 * 64 - 8 - 1) / (4 * 8 * 7), rel=1e-12)
    with pytest.raises(ParameterError, match="spring index"):
        fs.factors(1.0)


def test_axial_force_reproduces_wahl():
    """F along the axis of a (nearly) flat-pitch helix: tau = K_W 8 F D / (pi d^3), no
    bending, von Mises sqrt(3) tau, safety factor S_sy / tau (Shigley's n_s)."""
    s = dataclasses.replace(VISIFLEX_CATALOG, pitch_angle=1e-6)
    d, D, F = 2 * s.wire_radius, s.mean_diameter, 10.0
    sec = fs.closed_form_sections(s, [0, 0, 0, 0, 0, -F])
    st = fs.section_stress(sec["N"], sec["V"], sec["T"], sec["M"], d, D / d)
    tau = fs.factors(D / d)["K_W"] * 8 * F * D / (math.pi * d ** 3)
    assert st["tau"].max() == pytest.approx(tau, rel=1e-6)
    assert st["sigma"].max() < 1e-3 * tau
    assert st["von_mises"].max() == pytest.approx(math.sqrt(3) * tau, rel=1e-6)
    S_sy = fs.A313_SSY_OVER_SUT * fs.A313_A_MPA / d ** fs.A313_M
    assert fs.wire_strength("SS302", d)["strength_MPa"] / st["von_mises"].max() == \
        pytest.approx(S_sy / tau, rel=1e-6)


def test_strength_of_the_seed_002_wire_matches_the_material_table():
    """Shigley's S_ut(d) at d = 2.03 mm is the SS302 strength of designlab.fem.materials; a
    thinner wire is stronger; a wire outside the table's sizes says so; other materials use
    their table strength."""
    st = fs.wire_strength("SS302", 2.03)
    assert st["strength_MPa"] == pytest.approx(get_material("SS302").strength, rel=2e-3)
    assert fs.wire_strength("SS302", 1.0)["strength_MPa"] > st["strength_MPa"]
    assert "extrapolated" in fs.wire_strength("SS302", 4.06)["source"]
    assert "extrapolated" not in st["source"]
    assert fs.wire_strength("steel", 2.0)["strength_MPa"] == get_material("steel").strength


def test_chain_section_forces_are_the_statics_of_the_wrench():
    """Under an axial pull (no contact closes) every free section of the chain carries the
    torsion F R cos(a) and the shear F: the chain's element forces are statics."""
    ch = Chain(as_built(VISIFLEX_CATALOG), ChainSettings())
    F = 10.0
    r = ch.solve(f_master=np.r_[0.0, 0.0, F, 0.0, 0.0, 0.0])
    assert not r["closed"].any()
    sf = ch.section_forces(r["q"])
    free = sf["T"] > 1e-6 * F                    # elements between the bonded ends
    R = VISIFLEX_CATALOG.mean_radius
    active = free & (np.abs(sf["X"][:, 2] - ch.coil.length / 2) < 3.0)
    assert active.sum() > 20
    a = VISIFLEX_CATALOG.pitch_angle
    assert np.median(sf["T"][active]) == pytest.approx(F * R * math.cos(a), rel=0.01)
    assert sf["V"][active] == pytest.approx(F * np.ones(active.sum()), rel=0.02)
    # the bonded ends carry nothing inside themselves
    assert np.count_nonzero(~free) > 10


def test_force_solve_with_one_factorisation_equals_the_active_set_solve():
    """The stress cases' solver (one LU of the structure, contacts as a low-rank update) gives
    the chain's own active-set solution."""
    ch = Chain(as_built(VISIFLEX_CATALOG), ChainSettings())
    rs = np.random.default_rng(4)
    closed = 0
    for _ in range(4):
        f = np.r_[rs.uniform(-10, 10, 3), rs.uniform(-100, 100, 3)]
        a, b = ch.solve(f_master=f), ch.solve_force(f)
        assert np.array_equal(a["closed"], b["closed"])
        assert b["q"] == pytest.approx(a["q"], rel=1e-8, abs=1e-9 * np.abs(a["q"]).max())
        closed += int(a["closed"].sum())
    assert closed > 0                          # contact was part of it


def test_closed_form_agrees_with_the_beam_chain(catalogue_stress):
    """The independent check: the textbook helix (statics, Wahl factors) against the chain of
    the spring as built (bonded ground ends, dead-coil and seat contact), same stress formula.
    Without contact (pull, torsion) they agree to 2 %, with contact to 10 %."""
    cases = catalogue_stress["load_cases"]
    assert len(cases) == 13
    for name, c in cases.items():
        e = c["bodies"]["spring"]
        assert 0.9 <= e["chain_over_closed_form"] <= 1.1, name
        if e["chain_closed_contacts"] == 0:
            assert e["chain_over_closed_form"] == pytest.approx(1.0, abs=0.02), name
    assert cases["f_z +10 N"]["bodies"]["spring"]["chain_over_closed_form"] == \
        pytest.approx(1.0, abs=0.01)


def test_safety_factor_of_the_visiflex_spring(catalogue_stress):
    """Seed 002's spring at its 10 N working load: the lateral force is worst (the end coils
    carry F L0/2 and F R), SF ~4.6 against the wire's torsional yield, no warning. The worst
    direction is 86 deg from the axis; the chain of the spring as built is worst at one
    azimuth (where its wire ends sit), 3 % above the axisymmetric closed form."""
    r = catalogue_stress
    assert r["min_safety_factor"] == pytest.approx(4.62, abs=0.05)
    assert r["critical"]["load_case"] == "f 10 N worst direction"
    assert r["critical"]["governed_by"] == "chain"
    w = np.array(r["load_cases"]["f 10 N worst direction"]["wrench_at_centre"])
    assert np.linalg.norm(w[3:]) == pytest.approx(10.0)
    assert math.degrees(math.acos(w[5] / 10.0)) == pytest.approx(86.0, abs=1.0)
    ax = r["load_cases"]["f_z -10 N"]["bodies"]["spring"]
    assert ax["safety_factor"] == pytest.approx(6.30, abs=0.05)
    assert r["warnings"] == []
    # the worst direction is no better than any axis case
    worst = r["load_cases"]["f 10 N worst direction"]["bodies"]["spring"]["closed_form_MPa"]
    assert worst >= max(r["load_cases"][n]["bodies"]["spring"]["closed_form_MPa"]
                        for n in ("f_x +10 N", "f_y +10 N", "f_z +10 N")) - 1e-9


def test_stress_scales_with_load_and_warns_below_2():
    """Four times the force, a quarter of the safety factor; below 2 a one-line warning
    names the load case."""
    r = fs.wire_stress(VISIFLEX_CATALOG, FlexureWrenchTest(max_force_N=40.0), chain=False)
    r10 = fs.wire_stress(VISIFLEX_CATALOG, chain=False)
    f40 = r["load_cases"]["f_z -40 N"]["bodies"]["spring"]
    f10 = r10["load_cases"]["f_z -10 N"]["bodies"]["spring"]
    assert f40["safety_factor"] == pytest.approx(f10["safety_factor"] / 4, rel=1e-9)
    assert r["min_safety_factor"] < 2
    assert r["warnings"] and all("\n" not in w for w in r["warnings"])
    assert any("f 40 N worst direction" in w for w in r["warnings"])


def test_prediction_carries_the_stress_and_warns():
    from designlab.geometry.flexure import SpringFlexure
    from designlab.sensors.flexure.model import FlexureModelSettings, run

    part = SpringFlexure()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        p = run(part)
    st = p.report["stress"]
    assert st["min_safety_factor"] == pytest.approx(4.62, abs=0.05)
    assert st["critical"]["body"] == "spring" and st["critical"]["material"] == "SS302"
    assert not [w for w in caught if "safety factor" in str(w.message)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        p = run(part, FlexureWrenchTest(max_force_N=40.0),
                FlexureModelSettings(truth="timoshenko"))
    assert p.report["stress"]["min_safety_factor"] < 2
    assert "chain_MPa" not in p.report["stress"]["critical"]      # no chain in this model
    assert [w for w in caught if "safety factor" in str(w.message)]


def test_plain_ends_use_the_active_length():
    s = HelicalSpring(wire_radius=1.015, coils=1.75, inactive_coils=0.0)
    assert fs.end_height(s) == pytest.approx(s.active_length / 2)
    assert fs.end_height(VISIFLEX_CATALOG) == pytest.approx(
        VISIFLEX_CATALOG.free_length / 2 - VISIFLEX_CATALOG.wire_radius)
