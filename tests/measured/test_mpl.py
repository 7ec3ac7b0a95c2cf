"""mPL model (seed 000): time updates against a plain loop, stability, parameter recovery."""

import numpy as np
import pytest

from designlab.measured import mpl
from designlab.errors import DataError, ModelError, ParameterError


def reference_states(u, P_T, P_S, dt, update, starts=None):
    """Straightforward per-sample loop of the cell equations (one cell)."""
    s = np.empty_like(u)
    s[0] = u[0]
    tau = P_T / (2 * P_S)
    for k in range(u.size - 1):
        x = u[k] - s[k]
        if update == "exact":
            s[k + 1] = u[k] - 2 * P_T * np.arctanh(np.tanh(x / (2 * P_T)) * np.exp(-dt / tau))
        else:
            s[k + 1] = s[k] + dt * P_S * (np.exp(x / P_T) - np.exp(-x / P_T))
        if starts is not None and starts[k + 1]:
            s[k + 1] = u[k + 1]
    return s


def drive(T=3000, dt=0.0133, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(T) * dt
    u = 0.5 + 0.3 * np.sin(0.7 * t) + 0.15 * np.sin(2.3 * t + 1) + 0.02 * rng.normal(size=T)
    idx = np.maximum.accumulate(np.where((t % 10) > 7, 0, np.arange(T)))
    return u[idx]                                   # holds: the last value over 7..10 s of each 10 s


def test_table_ii_defaults():
    p = mpl.MPLParams()
    assert (p.w0, p.w, p.V_b, p.P_T, p.P_S) == (1.0, (-0.1,), 0.1, (0.2,), (0.2,))
    assert p.g == (0.1,) * 6 and p.update == "exact"
    assert p.tau == (0.5,)                     # P_T / (2 P_S)
    assert p.n_parameters == 3 * 1 + 2 + 6
    assert mpl.DT_PAPER == 0.0133


@pytest.mark.parametrize("update", ["exact", "euler"])
@pytest.mark.parametrize("P_T,P_S", [(0.2, 0.2), (0.01, 0.004), (0.5, 0.002), (1e-3, 1e-4)])
def test_states_match_reference_loop(update, P_T, P_S):
    u, dt = drive(), 0.0133
    p = mpl.MPLParams(w=(0.3,), P_T=(P_T,), P_S=(P_S,), update=update)
    if update == "euler" and mpl.euler_stability(p, u, dt) >= 2:
        with pytest.raises(ModelError, match="unstable"):
            p.simulate(u, dt)
        return
    ref = reference_states(u, P_T, P_S, dt, update)
    assert np.all(np.isfinite(ref))
    np.testing.assert_allclose(p.states(u, dt)[0], ref, rtol=0, atol=1e-9 * (1 + np.abs(u).max()))


def test_many_cells_and_record_resets_match_loop():
    u, dt = drive(5000), 0.02
    starts = np.zeros(u.size, bool)
    starts[[0, 1700, 3900]] = True
    pt, ps = np.array([0.05, 0.1, 0.3]), np.array([0.01, 0.2, 0.003])
    s = mpl.cell_states(u, pt, ps, dt, starts=starts)
    for i in range(3):
        np.testing.assert_allclose(s[i], reference_states(u, pt[i], ps[i], dt, "exact", starts),
                                   atol=1e-10)


def test_simulate_output_stage():
    u, dt = drive(), 0.0133
    p = mpl.MPLParams(w0=0.8, w=(-0.2, 0.4), V_b=0.05, P_T=(0.1, 0.2), P_S=(0.1, 0.01),
                      g=(0.1, 2.0, -0.3))
    s = np.vstack([reference_states(u, pt, ps, dt, "exact") for pt, ps in zip(p.P_T, p.P_S)])
    z = 0.8 * u - 0.2 * s[0] + 0.4 * s[1] + 0.05
    np.testing.assert_allclose(p.simulate(u, dt), 0.1 + 2.0 * z - 0.3 * z ** 2, atol=1e-10)


def test_exact_never_overshoots_but_euler_does():
    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(-1, 1, 60), 20)            # big steps and holds
    dt = 0.5                                              # dt = 10 tau: far beyond Euler's limit
    p = mpl.MPLParams(P_T=(0.05,), P_S=(0.05 / (2 * 0.05),))
    s = p.states(u, dt)[0]
    step, gap = s[1:] - s[:-1], u[:-1] - s[:-1]
    assert np.all(step * gap >= -1e-15)                  # moves towards u_k ...
    assert np.all(np.abs(step) <= np.abs(gap) + 1e-15)   # ... and never past it
    assert mpl.euler_stability(p, u, dt) > 2
    with pytest.raises(ModelError, match="forward Euler is unstable"):
        mpl.with_update(p, "euler").simulate(u, dt)
    se = mpl.cell_states(u[:50], np.array(p.P_T), np.array(p.P_S), 0.15, "euler")[0]
    assert np.any(np.abs(se[1:] - se[:-1]) > np.abs(u[:49] - se[:-1]) + 1e-12)   # overshoot


def test_euler_converges_to_exact_for_small_dt():
    T_end = 20.0
    errs = []
    for dt in (0.01, 0.001):
        t = np.arange(0, T_end, dt)
        u = 0.4 * np.sin(0.9 * t) + 0.2 * np.sin(2.1 * t)
        p = mpl.MPLParams(P_T=(0.1,), P_S=(0.2,))
        assert mpl.euler_stability(p, u, dt) < 2
        ex, eu = p.simulate(u, dt), mpl.with_update(p, "euler").simulate(u, dt)
        errs.append(np.abs(ex - eu).max())
    assert errs[1] < 1e-3
    assert 5 < errs[0] / errs[1] < 20                     # first order in dt


def synthetic(truth, T=4000, dt=0.05, seed=1):
    u = drive(T, dt, seed)
    return u, truth.simulate(u, dt), dt


def test_fit_recovers_one_cell_truth_in_physical_units():
    # sensor-like units: u in ohm around 2 kohm, y in N
    truth = mpl.MPLParams(w0=1.0, w=(-0.4,), V_b=0.0, P_T=(30.0,), P_S=(30.0 / (2 * 1.5),),
                          g=(0.5, 2e-3, 1e-7))
    u, dt = 2000 + 1000 * drive(4000, 0.05), 0.05
    y = truth.simulate(u, dt)
    p, rep = mpl.fit(u, y, dt, cells=1, order=2)
    assert p.tau[0] == pytest.approx(1.5, rel=1e-4)
    assert p.P_T[0] == pytest.approx(30.0, rel=1e-4)
    assert p.w[0] == pytest.approx(-0.4, rel=1e-4)
    assert rep.rmse < 1e-8 * np.ptp(y)
    assert rep.starts >= 1 and rep.iterations > 0 and rep.time_s > 0
    np.testing.assert_allclose(p.simulate(u, dt), y, atol=1e-7 * np.ptp(y))


@pytest.mark.slow
def test_fit_adds_cells_while_validation_improves():
    truth = mpl.MPLParams(w0=1.0, w=(-0.3, 0.2), V_b=0.0, P_T=(0.05, 0.1),
                          P_S=(0.05 / (2 * 0.5), 0.1 / (2 * 20.0)), g=(0.1, 2.0, -0.5, 0.3))
    u, y, dt = synthetic(truth, T=6000, dt=0.05)
    p, rep = mpl.fit(u, y, dt, order=3, max_cells=3)
    assert p.n_cells == 2
    assert rep.history[0][2] > 100 * rep.history[1][2]     # 1 cell clearly worse on held-out
    assert sorted(p.tau) == pytest.approx([0.5, 20.0], rel=1e-3)
    assert rep.rmse < 1e-6


def test_fit_as_compensator_and_forward_model():
    # forward: force -> sensor (hysteretic); compensator: sensor -> force (the inverse)
    truth = mpl.MPLParams(w0=1.0, w=(-0.3,), V_b=0.0, P_T=(0.05,), P_S=(0.05 / (2 * 2.0),),
                          g=(0.0, 1.0, 0.3))
    force, sensor, dt = synthetic(truth, T=4000, dt=0.05)
    fwd, _ = mpl.fit(force, sensor, dt, cells=1, order=2)
    assert np.sqrt(np.mean((fwd.simulate(force, dt) - sensor) ** 2)) < 1e-6 * np.ptp(sensor)
    comp, rep = mpl.fit(sensor, force, dt, cells=1, order=5)
    lin = np.polyval(np.polyfit(sensor, force, 1), sensor)
    rmse_lin = np.sqrt(np.mean((lin - force) ** 2))
    assert rep.rmse < 0.2 * rmse_lin


def test_fit_on_several_records_and_validation_data():
    truth = mpl.MPLParams(w0=1.0, w=(-0.3,), V_b=0.0, P_T=(0.05,), P_S=(0.05,),
                          g=(0.0, 1.0, 0.3))
    u1, y1, dt = synthetic(truth, T=2000, dt=0.05, seed=1)
    u2, y2, _ = synthetic(truth, T=1500, dt=0.05, seed=2)
    u3, y3, _ = synthetic(truth, T=1500, dt=0.05, seed=3)
    p, rep = mpl.fit([u1, u2], [y1, y2], dt, u_val=u3, y_val=y3, order=2, max_cells=2)
    assert p.tau[0] == pytest.approx(0.5, rel=1e-3)
    assert rep.val_rmse < 1e-6


def test_bad_input_is_one_line():
    u = np.linspace(0, 1, 200)
    cases = [
        (lambda: mpl.fit(u, u[:-1], 0.01), DataError, "lengths differ"),
        (lambda: mpl.fit(np.r_[u[:-1], np.nan], u, 0.01), DataError, "NaN"),
        (lambda: mpl.fit(u[:10], u[:10], 0.01), DataError, "at least"),
        (lambda: mpl.fit(u, u, 0.0), ParameterError, "dt"),
        (lambda: mpl.fit(u, u, 0.01, cells=0), ParameterError, "cells"),
        (lambda: mpl.fit(u, u, 0.01, update="rk4"), ParameterError, "update"),
        (lambda: mpl.MPLParams(P_T=(-1.0,)), ParameterError, "P_T"),
        (lambda: mpl.MPLParams(w=(1.0, 2.0)), ParameterError, "one weight per cell"),
        (lambda: mpl.MPLParams(update="rk4"), ParameterError, "update"),
        (lambda: mpl.MPLParams().simulate(np.ones((3, 3)), 0.01), DataError, "1-D"),
        (lambda: mpl.MPLParams().simulate(u, -1.0), ParameterError, "dt"),
    ]
    for call, exc, text in cases:
        with pytest.raises(exc, match=text) as info:
            call()
        assert "\n" not in str(info.value)
