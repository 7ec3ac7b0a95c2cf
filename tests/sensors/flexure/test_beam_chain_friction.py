"""Coulomb friction inside the beam chain's contact solve: the return map with a
tangential penalty, solved incrementally; checks against the frictionless solve, the stuck
bound and the textbook loop of a single contact."""

import numpy as np
import pytest
import scipy.sparse as sp

from designlab.errors import ParameterError
from designlab.sensors.flexure import active_set as act
from designlab.sensors.flexure import beam_chain as bc
from designlab.sensors.flexure import chain_friction as cf
from designlab.sensors.flexure import chain_geometry as cg
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG


def _rel(A, B):
    return float(np.linalg.norm(A - B) / np.linalg.norm(B))


@pytest.fixture(scope="module")
def frictionless():
    return bc.chain_stiffness(VISIFLEX_CATALOG)


@pytest.mark.slow
def test_zero_mu_is_the_frictionless_chain(frictionless):
    """mu = 0: the incremental frictional solve (10 force increments to the 10 N working load,
    then the perturbations from that state) gives the frictionless 6x6, unloaded and loaded:
    to 1e-9 (relative Frobenius norm) with node contacts, to 1e-7 with the line contacts
    (measured 3e-8: beams of 0.25 mm and 2887 stiff penalties leave more round-off)."""
    r = cf.friction_stiffness(VISIFLEX_CATALOG, mu=0.0)
    assert _rel(r.K, frictionless.K) < 1e-9
    assert _rel(r.K_loaded, frictionless.K_loaded) < 1e-7
    nodes = cg.ChainSettings(contact_spacing_mm=0.0)
    a = cf.friction_stiffness(VISIFLEX_CATALOG, nodes, mu=0.0)
    assert _rel(a.K_loaded, bc.chain_stiffness(VISIFLEX_CATALOG, nodes).K_loaded) < 1e-9
    wl = r.info["working_load"]
    assert wl["axial_deflection_mm"] == pytest.approx(
        frictionless.info["working_load"]["axial_deflection_mm"], rel=1e-9)


def test_large_mu_is_the_stuck_bound():
    """mu = 1e4: every closed contact sticks through the preload and the perturbations, and the
    6x6 at the working load is the stuck bound (fixed-set condensation with Mindlin's
    tangential penalty) to 1e-6. Node contacts (``contact_spacing_mm=0``): with line contacts
    the preload at mu = 1e4 does not converge (a zone's edge point closes with a vanishing
    normal force and slides with a traction slope mu k_n; the increment halving gives up)."""
    nodes = cg.ChainSettings(contact_spacing_mm=0.0)
    b = cf.friction_bounds(VISIFLEX_CATALOG, nodes, mu=0.3)
    big = cf.friction_stiffness(VISIFLEX_CATALOG, nodes, mu=1e4)
    wl = big.info["working_load"]
    assert wl["stuck_contacts"] == wl["closed_contacts"] > 0
    assert _rel(big.at(big.centre, loaded=True), b["K_stick_centre"]) < 1e-6


@pytest.mark.slow
def test_friction_lies_between_slip_and_stick():
    """At the working load the frictional secant (0.02 mm / 2 mrad) lies between the
    frictionless (slip) tangent and the stuck bound on the diagonal (within 1 %), its lateral
    and axial terms grow with mu, and mu = 0.3 is not stuck. 15-25 s on the shared machine."""
    b = cf.friction_bounds(VISIFLEX_CATALOG, mu=0.3)
    slip, stick = np.diag(b["K_slip_centre"]), np.diag(b["K_stick_centre"])
    diag = {}
    for mu in (0.1, 0.3):
        r = cf.friction_stiffness(VISIFLEX_CATALOG, mu=mu)
        diag[mu] = np.diag(r.at(r.centre, loaded=True))
        # a secant of two sliding paths, not a tangent: an entry may sit slightly below the
        # frictionless one (k_wy at mu 0.3: -0.15 %); the bounds hold the working load's
        # closed set, and the line contacts' zone edges open and close under the
        # perturbations, so the secant may exceed the stuck bound slightly (k_wx +0.4 %)
        assert np.all(diag[mu] >= slip * 0.99) and np.all(diag[mu] <= stick * 1.01)
        assert r.info["working_load"]["closed_contacts"] > 0
    assert np.all(diag[0.3][[2, 3, 4, 5]] > diag[0.1][[2, 3, 4, 5]])
    assert diag[0.3][3] < 0.999 * stick[3]          # mu = 0.3 is not stuck


class _Block(act.ActiveSet):
    """One contact: a block (x, y, z) on the plane z = 0, tied to the master (u_x, u_y, u_z) by
    springs ``k_s``; the master's rotations carry nothing (always prescribed here)."""

    def __init__(self, k_s=100.0, k_n=1e4):
        K = np.zeros((9, 9))
        for a in range(3):
            K[np.ix_([a, 3 + a], [a, 3 + a])] += k_s * np.array([[1, -1], [-1, 1]])
        self.Kq, self.nq, self.m, self.s = sp.csr_matrix(K), 9, np.arange(3, 9), cg.ChainSettings()
        self.N = sp.csr_matrix(np.eye(9)[[2]])            # gap opening = block z
        self.Rt = sp.csr_matrix(np.eye(9)[[0, 1]])        # slip = block x, y
        self.kn, self.g0 = np.array([k_n]), np.array([0.0])


@pytest.mark.parametrize("mu", [0.2, 0.6])
def test_single_contact_cyclic_tangential_load_gives_the_loop_width_2_mu_N(mu):
    """Pressed with N by the master (z held), pulled along x through +-1 mm: the two branches of
    the loop differ by 2 mu N at the same displacement (the textbook Coulomb loop), the force
    never exceeds k_s x and mu N, and mu = 0 has no loop."""
    blk = _Block()
    kt = 0.75 * blk.kn
    pre = blk.solve_friction(mu, kt, q_master=np.r_[0, 0, -0.1, 0, 0, 0])
    N = -pre["reaction"][2]
    assert N == pytest.approx(0.1 / (1 / 100.0 + 1 / 1e4), rel=1e-9)
    st, path = pre, np.r_[np.linspace(0, 1, 5)[1:], np.linspace(1, -1, 9)[1:],
                          np.linspace(-1, 1, 9)[1:]]
    F = {}
    for x in path:
        st = blk.solve_friction(mu, kt, q_master=np.r_[x, 0, -0.1, 0, 0, 0], ref=st)
        F.setdefault(round(float(x), 9), []).append(st["reaction"][0])
        assert abs(st["reaction"][0]) <= mu * N * (1 + 1e-9)
    down, up = F[0.0][-2], F[0.0][-1]                   # x = 0 descending, then ascending
    assert up - down == pytest.approx(2 * mu * N, rel=1e-9)      # sliding back, then forth
    assert F[1.0][-1] == pytest.approx(mu * N, rel=1e-9)
    blk0 = _Block()
    st = blk0.solve_friction(0.0, kt, q_master=np.r_[0.5, 0, -0.1, 0, 0, 0])
    assert st["reaction"][0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.slow
def test_loops_about_the_relaxed_spring_fit_like_the_paper():
    """Seed 002's fit (loops about the relaxed configuration, F = K X by least squares): with
    mu = 0 the loops have no width; with mu = 0.3 they do (the closed dead-turn contacts
    slide), and the fitted diagonal moves by less than 5 %: the loop's band averages out."""
    L0 = cf.loop_stiffness(VISIFLEX_CATALOG, mu=0.0, points=2)
    L3 = cf.loop_stiffness(VISIFLEX_CATALOG, mu=0.3, points=2)
    # N, N mm: the active set's +-tol band (2e-8 mm of gap at each of the line contacts'
    # points, measured 1.6e-4 N mm of a 100 N mm loop; 1e-5 with node contacts)
    assert max(L0["half_width"].values()) < 1e-3
    assert L3["half_width"]["u_x"] > 0.01 and L3["half_width"]["th_x"] > 0.01
    d0, d3 = np.diag(L0["K"]), np.diag(L3["K"])
    assert np.all(np.abs(d3 / d0 - 1) < 0.05)
    assert np.all(np.linalg.eigvalsh(L3["K"]) > 0)


def test_friction_bad_input():
    with pytest.raises(ParameterError) as e:
        cf.friction_stiffness(VISIFLEX_CATALOG, mu=-0.1)
    assert "mu" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ParameterError):
        cg.ChainSettings(mu=-1.0)
    with pytest.raises(ParameterError, match="contact"):
        cf.loop_stiffness(VISIFLEX_CATALOG, cg.with_settings(contact=False))
    with pytest.raises(ParameterError, match="amplitude"):
        cf.loop_stiffness(VISIFLEX_CATALOG, amplitude_mm=0.0)


@pytest.mark.slow
def test_friction_same_input_same_output():
    """The frictional path (10 N preload in 10 increments, then a perturbation) is bit-identical
    run to run."""
    settings, mu, chain, kt = cf._friction_setup(VISIFLEX_CATALOG, None, 0.3)
    runs = []
    for _ in range(2):
        pre = chain.solve_friction(mu, kt, f_master=np.r_[0, 0, -10.0, 0, 0, 0], steps=10)
        q = pre["q"][chain.m] + np.r_[0.02, 0, 0, 0, 0, 0]
        runs.append(chain.solve_friction(mu, kt, q_master=q, ref=pre))
    np.testing.assert_array_equal(runs[0]["reaction"], runs[1]["reaction"])
    np.testing.assert_array_equal(runs[0]["t"], runs[1]["t"])
