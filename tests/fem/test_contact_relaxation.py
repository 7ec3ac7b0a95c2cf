"""A relaxing structure under the contact problem (designlab.fem.contact.RelaxingContactProblem):
closed forms and the quasi-static limit."""

import math

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.fem.contact import ContactLaw, ContactProblem, ContactState, RelaxingContactProblem

K_INF, DK, TAU, K_S = 300.0, 60.0, 2.0, 500.0


def _one_dof(dK=DK, mu=0.0):
    """One master dof pressed onto a linear contact spring (normal along the dof)."""
    L = np.array([[[1.0], [0.0], [0.0]]])
    law = ContactLaw(mu, None, k_series=K_S, kt_series=1e6)
    return RelaxingContactProblem(np.array([[K_INF]]), np.array([[dK]]), TAU, L, [law])


def test_creep_of_a_standard_linear_solid():
    """A step load on the structure in parallel with the contact spring: the standard linear
    solid's creep, q(t) = f/k_e - (f/k_e - f/(k_e + dK)) exp(-t/tau_r), k_e = K_inf + k_s,
    tau_r = tau (k_e + dK) / k_e; the first step is the instantaneous stiffness."""
    prob = _one_dof()
    f = -2.0
    dt = 0.01
    n = 800
    fp = np.full((1, n + 1, 1), f)
    dts = np.r_[0.0, np.full(n, dt)]
    res, q, h = prob.solve_history(fp, dts, ContactState.zero(1, 1), np.zeros((1, 1)),
                                   np.zeros((1, 1)))
    k_e = K_INF + K_S
    tau_r = TAU * (k_e + DK) / k_e
    t = np.arange(n + 1) * dt
    q_ref = f / k_e - (f / k_e - f / (k_e + DK)) * np.exp(-t / tau_r)
    N = res.p[0, :, 0, 0]
    q_num = -N / K_S                              # the spring's approach is -q
    assert q_num[0] == pytest.approx(f / (k_e + DK), rel=1e-12)
    assert np.abs(q_num - q_ref).max() < 2e-5 * abs(f / k_e)
    # the relaxing branch carries what the springs do not: h = f - k_e q
    assert h[0, 0] == pytest.approx(f - k_e * q_num[-1], abs=1e-9 * abs(f))


def test_no_relaxation_is_the_quasi_static_path():
    """dK = 0: holds change nothing and the load changes are the ContactProblem's path (to
    round-off: a hold is one more Newton solve at a converged point), with friction and a
    tangential load, so the history matters."""
    rng = np.random.default_rng(2)
    n = 6
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    L = rng.standard_normal((2, 3, n)) * 0.3
    laws = [ContactLaw(0.3, None, k_series=400.0, kt_series=300.0, microslip=8)] * 2
    base = ContactProblem(np.linalg.inv(K), L, laws)
    relax = RelaxingContactProblem(K, np.zeros((n, n)), TAU, L, laws)
    # equal inverses: the same C in both
    relax._steps[0.0] = (base, 1.0, 1.0)
    relax._steps[1.0] = (base, 1.0, math.exp(-1.0 / TAU))
    L0 = L[:, 0]                                  # normal rows: press both contacts shut
    f_pre = K @ L0.T @ np.linalg.solve(L0 @ L0.T, -0.05 * np.ones(2))
    W = rng.standard_normal(n) * 4.0
    loads = np.array([0.0, 0.5, 1.0, 0.5, 0.0])
    f_pts = f_pre[None, None] + loads[None, :, None] * W[None, None]
    a = base.solve_path(f_pts, ContactState.zero(1, 2), 3)
    # each load change (dt = 0, 3 increments) followed by a 1 s hold
    f_hist = np.repeat(f_pts, 2, axis=1)
    dts = np.tile([0.0, 1.0], len(loads))
    b, q, h = relax.solve_history(f_hist, dts, ContactState.zero(1, 2), np.zeros((1, n)),
                                  np.zeros((1, n)), n_sub=3)
    scale = np.abs(a.p).max()
    assert np.abs(a.p - b.p[:, ::2]).max() < 1e-11 * scale
    assert np.abs(b.p[:, ::2] - b.p[:, 1::2]).max() < 1e-11 * scale
    assert (a.p[0, :, :, 0] == 0).any()           # a contact opens and closes on the way
    assert np.abs(h).max() == 0.0


def test_bad_relaxation_time():
    with pytest.raises(ParameterError, match="tau"):
        RelaxingContactProblem(np.eye(1), np.eye(1), 0.0, np.zeros((1, 3, 1)),
                               [ContactLaw(0.0, None, k_series=1.0)])


def test_a_problem_loaded_by_its_interference_alone_converges():
    """Zero loads, an initial interference: the contact closes on the structure (the
    tolerance scales with the interference, not only with the free motion)."""
    C = np.diag([1 / 200.0, 1 / 100.0, 1 / 100.0])
    prob = ContactProblem(C, np.eye(3)[None], [ContactLaw(0.3, None, k_series=K_S,
                                                          kt_series=300.0)],
                          gap0=np.array([0.05]))
    res = prob.solve_path(np.zeros((1, 1, 3)), ContactState.zero(1, 1))
    # springs in series: N = 0.05 / (1/k_s + 1/200)
    assert res.p[0, 0, 0, 0] == pytest.approx(0.05 / (1 / K_S + 1 / 200.0), rel=1e-9)
