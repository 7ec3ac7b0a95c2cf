"""Prony fitting from relaxation/creep data and the exact uniaxial viscoelastic responses."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from designlab.errors import DataError, ParameterError
from designlab.fem import prony_fit as pf
from designlab.fem.prony import Prony

E0 = 120.0
TRUE = Prony(g=(0.35, 0.2), tau=(0.4, 25.0))
T = np.logspace(-2, 3, 80)


def test_creep_compliance_limits_and_expm_reference():
    J = pf.creep_compliance(E0, TRUE, [0.0, 1e9])
    assert J[0] == pytest.approx(1 / E0, rel=1e-12)
    assert J[1] == pytest.approx(1 / (E0 * TRUE.g_inf), rel=1e-10)
    # independent reference: integrate the Maxwell-branch ODEs under constant stress numerically
    g, tau = np.array(TRUE.g), np.array(TRUE.tau)

    def rhs(_, a):
        eps = 1.0 / E0 + g @ a  # sigma = 1 = E0 (eps - g.a)
        return (eps - a) / tau

    sol = solve_ivp(rhs, (0, T[-1]), np.zeros(2), t_eval=T, rtol=1e-10, atol=1e-14, method="LSODA")
    ref = 1.0 / E0 + g @ sol.y
    assert np.max(np.abs(pf.creep_compliance(E0, TRUE, T) / ref - 1)) < 1e-6
    # retardation spectrum reproduces J(t)
    J_inf, j, lam = pf.retardation_spectrum(E0, TRUE)
    assert np.all(j > 0) and np.all(lam > np.array(TRUE.tau))  # retardation slower than relaxation
    assert np.allclose(J_inf - np.exp(-np.outer(T, 1 / lam)) @ j, pf.creep_compliance(E0, TRUE, T))


def test_uniaxial_3d_bar_matches_rod_when_bulk_relaxes_alike():
    same = Prony(g=TRUE.g, tau=TRUE.tau, k=TRUE.g, k_tau=TRUE.tau)
    for nu in (0.0, 0.3, 0.45):
        assert np.allclose(pf.relaxation_modulus(E0, same, T, nu=nu), pf.relaxation_modulus(E0, TRUE, T))
        assert np.allclose(pf.creep_compliance(E0, same, T, nu=nu), pf.creep_compliance(E0, TRUE, T))
    # shear-only relaxation with elastic bulk: E_inf = 9 K G_inf / (3 K + G_inf)
    nu = 0.4
    G, K = E0 / (2 * (1 + nu)), E0 / (3 * (1 - 2 * nu))
    Ginf = G * TRUE.g_inf
    E_inf = 9 * K * Ginf / (3 * K + Ginf)
    assert pf.relaxation_modulus(E0, TRUE, [1e9], nu=nu)[0] == pytest.approx(E_inf, rel=1e-9)
    assert pf.creep_compliance(E0, TRUE, [1e9], nu=nu)[0] == pytest.approx(1 / E_inf, rel=1e-9)
    assert pf.relaxation_modulus(E0, TRUE, [0.0], nu=nu)[0] == pytest.approx(E0, rel=1e-12)


def test_piecewise_linear_histories_are_exact():
    # ramp to eps0 over tr then hold: closed form of the Maxwell branches
    eps0, tr = 0.02, 1.5
    t = np.array([0.0, 0.5, 1.0, tr, 3.0, 10.0, 60.0])
    eps = np.minimum(t / tr, 1.0) * eps0
    sig = pf.stress_response(E0, TRUE, t, eps)
    rate = eps0 / tr
    g, tau = np.array(TRUE.g), np.array(TRUE.tau)

    def closed(tt):
        if tt <= tr:
            return E0 * rate * (TRUE.g_inf * tt + np.sum(g * tau * (1 - np.exp(-tt / tau))))
        br = g * tau * (1 - np.exp(-tr / tau)) * np.exp(-(tt - tr) / tau)
        return E0 * rate * (TRUE.g_inf * tr + np.sum(br))

    assert np.allclose(sig, [closed(x) for x in t], rtol=1e-10, atol=1e-12)
    # stress-controlled step history -> creep compliance; stress then removed -> recovery
    t2 = np.array([0.0, 5.0, 5.0, 50.0])
    s2 = np.array([1.0, 1.0, 0.0, 0.0])
    e2 = pf.strain_response(E0, TRUE, t2, s2)
    J = lambda x: pf.creep_compliance(E0, TRUE, [x])[0]  # noqa: E731
    assert e2[1] == pytest.approx(J(5.0), rel=1e-10)
    assert e2[3] == pytest.approx(J(50.0) - J(45.0), rel=1e-8)  # Boltzmann superposition


@pytest.mark.parametrize("nu", [None, 0.35])
def test_fit_relaxation_recovers_terms_from_noisy_data(nu):
    rng = np.random.default_rng(3)
    y = pf.relaxation_modulus(E0, TRUE, T, nu=nu) * (1 + 0.005 * rng.standard_normal(len(T)))
    E0_fit, prony, rep = pf.fit_prony_relaxation(T, y, 2, nu=nu)
    assert E0_fit == pytest.approx(E0, rel=0.01)
    assert np.allclose(prony.g, TRUE.g, rtol=0.03)
    assert np.allclose(prony.tau, TRUE.tau, rtol=0.06)
    assert rep["rms_rel_error"] < 0.008 and rep["n_terms"] == 2
    # stress data under a step strain gives the same material
    E0_s, prony_s, _ = pf.fit_prony_relaxation(T, y * 0.01, 2, strain0=0.01, nu=nu)
    assert E0_s == pytest.approx(E0_fit, rel=1e-6)


@pytest.mark.parametrize("nu", [None, 0.35])
def test_fit_creep_recovers_terms_from_noisy_data(nu):
    rng = np.random.default_rng(4)
    J = pf.creep_compliance(E0, TRUE, T, nu=nu) * (1 + 0.005 * rng.standard_normal(len(T)))
    E0_fit, prony, rep = pf.fit_prony_creep(T, J * 2.0, 2, stress0=2.0, nu=nu)
    assert E0_fit == pytest.approx(E0, rel=0.01)
    assert np.allclose(prony.g, TRUE.g, rtol=0.04)
    assert np.allclose(prony.tau, TRUE.tau, rtol=0.08)
    assert rep["rms_rel_error"] < 0.008


def test_fit_terms_stay_positive_with_too_many_terms():
    rng = np.random.default_rng(5)
    y = pf.relaxation_modulus(E0, TRUE, T) * (1 + 0.01 * rng.standard_normal(len(T)))
    E0_fit, prony, rep = pf.fit_prony_relaxation(T, y, 5)
    assert all(g > 0 for g in prony.g) and sum(prony.g) < 1 and all(x > 0 for x in prony.tau)
    assert rep["n_terms"] + rep["dropped_terms"] == 5
    assert rep["rms_rel_error"] < 0.012
    assert np.max(np.abs(pf.relaxation_modulus(E0_fit, prony, T) / pf.relaxation_modulus(E0, TRUE, T) - 1)) < 0.02


@pytest.mark.parametrize("t, y, n, exc, word", [
    (np.linspace(-1, 10, 20), np.ones(20), 2, DataError, "negative"),
    (np.array([0, 1, 2, 1.5, 3, 4, 5.0]), np.ones(7), 1, DataError, "increasing"),
    (np.linspace(0, 10, 5), np.ones(5), 2, DataError, "too few"),
    (np.linspace(0, 10, 20), np.r_[np.ones(19), np.nan], 2, DataError, "finite"),
    (np.linspace(0, 10, 20), -np.ones(20), 2, DataError, "> 0"),
    (np.linspace(0, 10, 20), np.ones(20), 0, ParameterError, "n_terms"),
    (np.linspace(0, 10, 20), np.ones(19), 2, DataError, "lengths"),
])
def test_bad_input_is_one_line_error(t, y, n, exc, word):
    for fit in (pf.fit_prony_relaxation, pf.fit_prony_creep):
        with pytest.raises(exc) as info:
            fit(t, y, n)
        assert word in str(info.value) and "\n" not in str(info.value)


def test_bad_material_and_history():
    with pytest.raises(ParameterError):
        pf.relaxation_modulus(-1.0, TRUE, T)
    with pytest.raises(ParameterError):
        pf.creep_compliance(E0, TRUE, T, nu=0.5)
    with pytest.raises(DataError):
        pf.stress_response(E0, TRUE, [0.0, 2.0, 1.0], [0.0, 1.0, 1.0])


@pytest.mark.parametrize("nu_fit", [None, 0.4])
def test_fitted_material_reproduces_creep_data_in_the_fem(nu_fit):
    """Creep data -> fit -> Material -> FEM bar in uniaxial stress (history solver) -> the data."""
    from dataclasses import replace

    from designlab.fem.materials import Material
    from designlab.fem.model import Model
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history
    from designlab.mesh.tetmesh import box_tet_mesh

    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 60.0, 121)
    J = pf.creep_compliance(E0, TRUE, t, nu=0.4) * (1 + 0.003 * rng.standard_normal(len(t)))
    E0_fit, prony, _ = pf.fit_prony_creep(t, J, 2, nu=nu_fit)
    mat = replace(Material("tpu", E=1.0, nu=0.4), E=E0_fit, prony=prony)
    model = Model(box_tet_mesh(10.0, 2.0, 2.0, 4, 1, 1), materials={"block": mat})
    model.fix("xmin", "x")
    model.fix("ymin", "y")
    model.fix("zmin", "z")
    model.traction("xmax", (0.3, 0.0, 0.0), case="load")
    res = solve_history(model, History(t, {"load": np.ones_like(t)}))
    eps = res.U[3 * model.nodes("xmax")].mean(axis=0) / 10.0
    assert np.max(np.abs(eps / (0.3 * J) - 1)) < 0.015


@pytest.mark.parametrize("nu, start", [(None, "rest"), (0.4, "relaxed")])
def test_fit_history_recovers_terms_from_ramps_and_holds(nu, start):
    """A real-world test: finite-rate ramps, holds and unloading, jittered clock, prestrain."""
    dt = 0.1
    t = np.arange(0.0, 120.0, dt)
    eps = np.interp(t, [0, 2, 40, 42, 80, 81, 120], [0.05, 0.15, 0.15, 0.10, 0.10, 0.2, 0.2])
    model = pf._model(E0, TRUE, nu, "strain")
    # reference stress from the expm recursion (independent of the modal filter used to fit)
    if start == "rest":
        sig = model.response(t, eps)
    else:
        # equilibrium at the prestrain: long-term modulus, plus the response to the increments
        sig = model.response(t, eps - eps[0]) + pf.relaxation_modulus(E0, TRUE, [1e12], nu=nu)[0] * eps[0]
    rng = np.random.default_rng(7)
    tj = t + np.r_[0.0, rng.uniform(-0.02, 0.02, len(t) - 1)]
    noisy = sig + 0.004 * np.abs(sig).max() * rng.standard_normal(len(t))
    E0_fit, prony, rep = pf.fit_prony_history(tj, eps, noisy, 2, nu=nu, start=start)
    assert E0_fit == pytest.approx(E0, rel=0.02)
    assert np.allclose(prony.g, TRUE.g, rtol=0.05)
    assert np.allclose(prony.tau, TRUE.tau, rtol=0.06)
    assert rep["rms_rel_error"] < 0.006 and rep["dt"] == pytest.approx(dt, rel=0.01)


def test_fit_history_bad_input():
    t = np.linspace(0, 10, 50)
    with pytest.raises(ParameterError, match="start"):
        pf.fit_prony_history(t, t, t, 2, start="hot")
    with pytest.raises(DataError, match="vary"):
        pf.fit_prony_history(t, np.ones(50), t, 2)
    with pytest.raises(DataError, match="increasing"):
        pf.fit_prony_history(t[::-1], t, t, 2)
    with pytest.raises(DataError, match="lengths"):
        pf.fit_prony_history(t, t[:-1], t, 2)
