"""The fingertip's streamlined contact solve gives the numbers of the generic one, bit for bit."""

import dataclasses

import numpy as np
import pytest

from designlab.fem.contact import ContactProblem, ContactState
from designlab.geometry.fingertip import CantileverFingertip
from designlab.sensors.fingertip.model import ContactSettings
from designlab.sensors.fingertip.contact import _FastProblem, contact_laws


def _problem_data(seed=3, n=12):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    C = A @ A.T / n * 1e-3 + np.eye(n) * 2e-4             # SPD flexibility, mm/N
    L = rng.standard_normal((3, 3, n)) * 0.5
    return C, L, rng


def _path(C, L, rng, batch=5, npt=14):
    n = C.shape[0]
    f_pre = np.zeros(n)
    f_pre[:3] = -40.0 * np.linalg.lstsq(L[:, 0].T, np.ones(n), rcond=None)[0][:3]
    loads = np.concatenate([np.linspace(0, 1, npt // 2), np.linspace(1, 0, npt - npt // 2)])
    W = rng.standard_normal((batch, n)) * 8.0
    return f_pre[None, None] + loads[None, :, None] * W[:, None], f_pre


@pytest.mark.parametrize("kt_series,microslip", [(None, 0), (None, 24), (400.0, 24)])
def test_fast_problem_is_bit_identical_to_the_generic_solve(kt_series, microslip):
    C, L, rng = _problem_data()
    settings = dataclasses.replace(ContactSettings(), sensor_lateral_stiffness=kt_series or 0.0,
                                   microslip_elements=microslip)
    laws = contact_laws(CantileverFingertip(h=3.0, r=6.0), settings, 500.0)
    ref = ContactProblem(C, L, laws)
    fast = _FastProblem(C, L, laws)
    assert fast._fast == (kt_series is None)              # a tangential spring: generic path
    f_points, f_pre = _path(C, L, rng)
    f_points = np.concatenate([f_points, f_points[:, ::-1] * 1.3], axis=1)
    st = ContactState.zero(f_points.shape[0], 3)
    a = ref.solve_path(f_points, st, 3)
    b = fast.solve_path(f_points, st, 3)
    for x, y in ((a.p, b.p), (a.g, b.g), (a.state.T, b.state.T), (a.state.gt, b.state.gt),
                 (a.state.N, b.state.N)):
        assert np.array_equal(x, y)
    assert (a.state.Te is None) == (microslip == 0)
    if microslip:
        assert np.array_equal(a.state.Te, b.state.Te)
        # the committed elements add up to the committed tangential force, bit for bit
        assert np.array_equal(b.state.T, b.state.Te.sum(axis=-1))
    assert a.iterations == b.iterations and a.lift_off == b.lift_off
    # the path exercises what the streamlined code resolves: slip and open contacts
    N = a.p[..., 0]
    assert (N == 0).any() and (N > 0).any()
    T = np.linalg.norm(a.p[..., 1:], axis=-1)
    mu = laws[0].mu
    assert np.isclose(T[N > 0], mu * N[N > 0], rtol=1e-9).any()        # slipping
    assert (T[N > 0] < mu * N[N > 0] * (1 - 1e-6)).any()                # sticking
