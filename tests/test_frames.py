"""SE(3) helpers: exp/log round trips, adjoint identities, and seed 002 eq. 3 on the paper's K_f."""

import json

import numpy as np
import pytest
from scipy.linalg import expm

from designlab import frames as fr


def _random_twist(rng, scale=1.0):
    return rng.normal(size=6) * scale


def _se3_matrix(X):
    M = np.zeros((4, 4))
    M[:3, :3] = fr.skew(X[:3])
    M[:3, 3] = X[3:]
    return M


def test_exp_matches_scipy_expm_and_log_inverts():
    rng = np.random.default_rng(0)
    for _ in range(20):
        X = _random_twist(rng)
        X[:3] *= 2.5 / max(np.linalg.norm(X[:3]), 1e-9) * rng.uniform(0, 1)  # |w| < pi
        T = fr.exp_se3(X)
        np.testing.assert_allclose(T, expm(_se3_matrix(X)), atol=1e-12)
        np.testing.assert_allclose(fr.log_se3(T), X, atol=1e-10)


def test_log_near_pi_and_identity():
    w = np.array([0.0, 0.0, np.pi - 1e-9])
    np.testing.assert_allclose(np.abs(fr.log_so3(fr.exp_so3(w))), np.abs(w), atol=1e-6)
    np.testing.assert_allclose(fr.log_se3(np.eye(4)), np.zeros(6), atol=0)
    with pytest.raises(ValueError):
        fr.rotation_about((0, 0, 0), 1.0)


def test_adjoint_conjugation_and_inverse():
    rng = np.random.default_rng(1)
    T = fr.exp_se3(_random_twist(rng))
    X = _random_twist(rng)
    # [Ad_T X] = T [X] T^-1
    lhs = _se3_matrix(fr.adjoint(T) @ X)
    rhs = T @ _se3_matrix(X) @ fr.inverse(T)
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)
    np.testing.assert_allclose(fr.adjoint(fr.inverse(T)), np.linalg.inv(fr.adjoint(T)), atol=1e-12)
    np.testing.assert_allclose(fr.inverse(T) @ T, np.eye(4), atol=1e-12)


def test_stiffness_transform_preserves_power_and_round_trips():
    """Power F.X is frame-independent; moving K there and back returns K; compliance rule agrees."""
    rng = np.random.default_rng(2)
    A = rng.normal(size=(6, 6))
    K_f = A @ A.T + 6 * np.eye(6)
    T_af = fr.exp_se3(_random_twist(rng))
    K_a = fr.transform_stiffness(K_f, T_af)
    X_f = _random_twist(rng)
    X_a = fr.transform_twist(X_f, T_af)
    F_a = fr.transform_wrench(K_f @ X_f, T_af)
    np.testing.assert_allclose(K_a @ X_a, F_a, atol=1e-9)
    assert F_a @ X_a == pytest.approx((K_f @ X_f) @ X_f)
    np.testing.assert_allclose(fr.transform_stiffness(K_a, fr.inverse(T_af)), K_f, atol=1e-9)
    np.testing.assert_allclose(np.linalg.inv(K_a),
                               fr.transform_compliance(np.linalg.inv(K_f), T_af), atol=1e-9)


def test_force_at_offset_makes_the_lever_moment():
    """A force f_x applied at {f} = (0, 0, h) in {a} is m_y = h f_x about {a}."""
    h = 11.0
    F_a = fr.transform_wrench([0, 0, 0, 2.0, 0, 0], fr.transform(translation=(0, 0, h)))
    np.testing.assert_allclose(F_a, [0, h * 2.0, 0, 2.0, 0, 0])


def test_paper_K_f_to_camera_frame_offset(shared):
    """Seed 002: moving the paper's K_f by h = +11.09 mm along z gives its K_c (+-121, 2.22)."""
    P = json.loads((shared / "data/papers/visiflex_flexure.json").read_text())
    K_f = np.array(P["K_f_theory_at_spring_centre"])
    K_c = np.array(P["K_c_theory_camera_frame"])
    est = fr.offset_along_z(K_f, K_c)
    h = est["from_coupling_x"]
    assert h == pytest.approx(0.01109, abs=5e-5)  # m
    assert est["from_coupling_y"] == pytest.approx(h)
    assert est["from_rotational_gain"] == pytest.approx(h, rel=0.01)
    K = fr.transform_stiffness(K_f, fr.transform(translation=(0, 0, h)))
    assert K[0, 4] == pytest.approx(-121, abs=0.5) and K[1, 3] == pytest.approx(121, abs=0.5)
    assert K[0, 0] == pytest.approx(2.22, abs=0.005) and K[1, 1] == pytest.approx(2.22, abs=0.005)
    # the wrong sign of the offset flips the couplings
    K_wrong = fr.transform_stiffness(K_f, fr.transform(translation=(0, 0, -h)))
    assert K_wrong[0, 4] == pytest.approx(121, abs=0.5)
    # every entry the paper prints except k_wz (1.06 in K_f, 1.0 in K_c: an offset cannot change it)
    mask = np.ones((6, 6), bool)
    mask[2, 2] = False
    np.testing.assert_allclose(K[mask], K_c[mask], atol=0.5)
    assert K[2, 2] == K_f[2, 2]


def test_pose_twist_is_zero_at_rest_and_recovers_displacement():
    T_cr = fr.transform(fr.rotation_about((1, 2, 3), 0.3), (1.0, -2.0, 30.0))
    np.testing.assert_allclose(fr.pose_twist(T_cr, T_cr), np.zeros(6), atol=1e-12)
    X = np.array([0.01, -0.02, 0.005, 0.3, -0.1, 0.2])
    T_cd = fr.exp_se3(X) @ T_cr
    np.testing.assert_allclose(fr.pose_twist(T_cd, T_cr), X, atol=1e-12)
