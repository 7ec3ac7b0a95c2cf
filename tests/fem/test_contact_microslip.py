"""Mindlin's partial slip as an Iwan model (designlab.fem.contact): closed-form checks."""

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.contact import (ContactLaw, ContactProblem, ContactState, LawArrays, commit,
                                   contact_forces, iwan_elements,
                                   mindlin_loop_energy, mindlin_tangential_force)

K_N, K_T, N0, MU = 1000.0, 400.0, 5.0, 0.3


def _drive(law, gt_path, N=N0):
    """Tangential displacement path (along t1) at a constant normal force N: forces T1."""
    la = LawArrays([law])
    st = ContactState.zero(1, 1)
    if la.n_el:
        st.Te = np.zeros((1, 1, 2, la.n_el))
    out = []
    for x in gt_path:
        g = np.array([[[-N / K_N, x, 0.0]]])
        p, _, Te = contact_forces(la, g, st, elements=True)
        st = commit(g, p, Te)
        out.append(p[0, 0, 1])
    return np.array(out)


def test_iwan_elements_sum_to_the_contact():
    for n in (1, 2, 7, 40):
        w, c = iwan_elements(n)
        assert w.sum() == pytest.approx(1.0) and c.sum() == pytest.approx(1.0)
        assert np.all(np.diff(c) > 0) or n == 1
    with pytest.raises(ParameterError, match="microslip_elements"):
        ContactLaw(0.3, None, K_N, K_T, microslip=-1)


def test_backbone_is_cattaneo_mindlin():
    """Monotonic loading at constant N follows T = mu N (1 - (1 - d/d_s)^(3/2))."""
    d_s = 1.5 * MU * N0 / K_T
    d = np.linspace(0.0, 1.3 * d_s, 400)
    law = ContactLaw(MU, None, K_N, K_T, microslip=64)
    T = -_drive(law, d)                       # T is the force B exerts on A: against the motion
    ref = mindlin_tangential_force(d, MU * N0, K_T)
    assert np.abs(T - ref).max() < 0.01 * MU * N0
    assert T[-1] == pytest.approx(MU * N0, rel=1e-12)
    # initial stiffness: Mindlin's k_t
    assert T[1] / d[1] == pytest.approx(K_T, rel=1e-12)


@pytest.mark.parametrize("q", [0.1, 0.3, 0.7, 0.95])
def test_loop_energy_is_mindlin_deresiewicz(q):
    """A cycle +-T_amp (Masing unloading) dissipates Johnson's eq. 7.53; the elastic-perfectly-
    plastic law dissipates nothing below sliding."""
    n = 200
    law = ContactLaw(MU, None, K_N, K_T, microslip=n)
    muN = MU * N0
    d_amp = 1.5 * muN / K_T * (1 - (1 - q) ** (2 / 3))        # backbone at T = q mu N
    s = np.linspace(0, 1, 801)
    path = np.concatenate([d_amp * s, d_amp * (1 - 2 * s[1:]), d_amp * (-1 + 2 * s[1:]),
                           d_amp * (1 - 2 * s[1:])])
    T = -_drive(law, path)
    cycle = slice(len(s) - 1, 3 * (len(s) - 1) + 1)     # +d_amp -> -d_amp -> +d_amp
    assert T[cycle][0] == pytest.approx(q * muN, rel=0.02)
    W = abs(np.trapezoid(T[cycle], path[cycle]))
    assert W == pytest.approx(mindlin_loop_energy(q * muN, muN, K_T), rel=0.03)
    T_epp = -_drive(ContactLaw(MU, None, K_N, K_T), path)
    if K_T * d_amp < muN:                     # the whole contact would not slide yet
            assert abs(np.trapezoid(T_epp[cycle], path[cycle])) < 1e-12 * muN * d_amp


def test_one_element_is_the_elastic_perfectly_plastic_law():
    rng = np.random.default_rng(3)
    path = np.cumsum(rng.normal(0, 0.002, 300))
    a = _drive(ContactLaw(MU, None, K_N, K_T), path)
    b = _drive(ContactLaw(MU, None, K_N, K_T, microslip=1), path)
    assert np.abs(a - b).max() < 1e-12


def test_tangent_matches_finite_differences():
    """dp/dg of the partial-slip law (with a Hertz contact: k_t and the slip forces vary with
    N) against central differences, in a state with some elements slipping."""
    from designlab.fem.contact import HertzContact
    hz = HertzContact(4.7, 0.8, 210e3, 0.3, 193e3, 0.3)
    law = ContactLaw(0.25, hz, 500.0, microslip=16)
    la = LawArrays([law])
    st = ContactState.zero(1, 1)
    st.Te = np.zeros((1, 1, 2, 16))
    g1 = np.array([[[-0.012, 0.0004, -0.0002]]])
    p, _, Te = contact_forces(la, g1, st, elements=True)
    st = commit(g1, p, Te)
    g = np.array([[[-0.0118, 0.0009, 0.0001]]])
    p, D = contact_forces(la, g, st)
    Dn = np.zeros((3, 3))
    h = 1e-9
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        Dn[:, j] = (contact_forces(la, g + e, st)[0][0, 0]
                    - contact_forces(la, g - e, st)[0][0, 0]) / (2 * h)
    assert np.abs(D[0, 0] - Dn).max() < 1e-5 * np.abs(Dn).max()


def test_problem_path_with_partial_slip_has_a_loop_below_sliding():
    """On a structure (two springs), a tangential load cycle below mu N gives a loop with partial
    slip and none with the elastic-perfectly-plastic law; the first loading is the same."""
    C = np.diag([1 / 50.0, 1 / 80.0, 1 / 80.0])       # master dofs: the contact's n, t1, t2
    L = np.eye(3)[None]
    f_n = -N0
    pts = np.array([[f_n, 0, 0], [f_n, 0.5 * MU * N0, 0], [f_n, 0, 0], [f_n, -0.5 * MU * N0, 0],
                    [f_n, 0, 0]])[None]
    out = {}
    for n in (0, 24):
        prob = ContactProblem(C, L, [ContactLaw(MU, None, K_N, K_T, microslip=n)])
        res = prob.solve_path(pts, ContactState.zero(1, 1), n_sub=20)
        out[n] = res.g[0, :, 0, 1]
    assert abs(out[0][2]) < 1e-12                    # back to zero: no loop
    assert abs(out[24][2]) > 1e-5                    # a residual displacement: a loop
    assert out[24][1] > out[0][1]                    # softer on the way up
