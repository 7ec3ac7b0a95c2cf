"""NARX network of seed 000: lagged features, open vs closed loop, beats linear on hysteresis."""

import numpy as np
import pytest

from designlab.measured import linear_fit
from designlab.measured import mpl
from designlab.measured import narx
from designlab.errors import DataError, ParameterError


def test_lagged_matches_explicit_loop():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 3))
    for first, last, start in [(0, 5, 5), (1, 4, 6), (0, 0, 0), (1, 1, 1)]:
        got = narx.lagged(x, first, last, start)
        want = np.array([np.concatenate([x[k - last:k - first + 1, c] for c in range(3)])
                         for k in range(start, 40)])
        np.testing.assert_array_equal(got, want)


def hysteretic(T=6000, dt=0.05, seed=0):
    """Force -> two gauges through an mPL cell (hysteresis + creep); returns u (T,2), y (T,2)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * dt
    fn = 2 + np.sin(0.31 * t) + 0.5 * np.sin(1.13 * t + 1) + 0.05 * rng.normal(size=T)
    fx = 0.3 * np.sin(0.53 * t + 2)
    gauge = mpl.MPLParams(w0=1.0, w=(-0.5,), V_b=0.0, P_T=(0.1,), P_S=(0.1 / (2 * 1.0),),
                          g=(0.0, 1.0, 0.05))
    u = np.column_stack([gauge.simulate(fn + fx, dt), gauge.simulate(fn - fx, dt)])
    return u, np.column_stack([fn, fx]), dt


@pytest.mark.slow
def test_narx_beats_linear_on_hysteretic_data():
    u, y, dt = hysteretic()
    tr, va = slice(0, 4000), slice(4000, None)
    lin = linear_fit.fit_linear(u[tr], y[tr])
    e_lin = np.sqrt(np.mean((lin.predict(u[va]) - y[va]) ** 2, axis=0))
    # seed 000's input-output network (no output feedback): 10 neurons, 50 delays
    net, rep = narx.fit(u[tr], y[tr], narx.NARXParams(max_iter=200))
    assert rep.rows == 4000 - 50 and rep.features == 2 * 51
    e_net = np.sqrt(np.mean((net.predict(u[va]) - y[va]) ** 2, axis=0))
    assert np.all(e_net < 0.5 * e_lin)
    # NARX with fed-back outputs: trained series-parallel it beats linear one step ahead
    fb, rep = narx.fit(u[tr], y[tr], narx.NARXParams(output_delays=2, max_iter=200))
    assert rep.features == 2 * 51 + 2 * 2
    e_ol = np.sqrt(np.mean((fb.predict_open_loop(u[va], y[va]) - y[va]) ** 2, axis=0))
    assert np.all(e_ol < 0.5 * e_lin)
    assert np.all(np.isfinite(fb.predict(u[va])))          # closed loop runs (accuracy varies)


@pytest.mark.slow
def test_open_and_closed_loop():
    u, y, dt = hysteretic(T=3000)
    net0, _ = narx.fit(u, y, narx.NARXParams(input_delays=20, output_delays=0, max_iter=50))
    np.testing.assert_allclose(net0.predict(u), net0.predict_open_loop(u, y))
    net, rep = narx.fit(u, y, narx.NARXParams(input_delays=20, output_delays=5, max_iter=100))
    ol = net.predict_open_loop(u, y)
    # the open-loop (series-parallel) estimate is what the network was trained on
    e_ol = np.sqrt(np.mean((ol[20:] - y[20:]) ** 2, axis=0))
    np.testing.assert_allclose(e_ol, rep.open_loop_rmse, rtol=1e-6)
    # closed loop feeds back its own estimates: differs from the open loop
    assert not np.allclose(net.predict(u), ol)


def test_records_and_bad_input():
    u, y, dt = hysteretic(T=1200)
    net, rep = narx.fit([u[:600], u[600:]], [y[:600], y[600:]],
                        narx.NARXParams(max_iter=20))
    assert rep.rows == 2 * (600 - 50)
    cases = [
        (lambda: narx.fit(u[:40], y[:40]), DataError, "needs more than 51"),
        (lambda: narx.fit(u, y[:-1]), DataError, "lengths differ"),
        (lambda: narx.fit(np.where(np.arange(1200)[:, None] == 7, np.nan, u), y), DataError, "NaN"),
        (lambda: narx.fit(u, np.ones_like(y)), DataError, "constant"),
        (lambda: narx.fit(u * 1e-300, y), DataError,
         r"channel\(s\) 0, 1 vary by .* only; allowed: a spread >= 1e-60: a smaller one is below "
         r"the precision a fit needs"),
        (lambda: narx.NARXParams(hidden=0), ParameterError, "hidden"),
        (lambda: narx.NARXParams(output_delays=-1), ParameterError, "output_delays"),
        (lambda: net.predict(u[:, :1]), DataError, "channels"),
    ]
    for call, exc, text in cases:
        with pytest.raises(exc, match=text) as info:
            call()
        assert "\n" not in str(info.value)


def test_the_scaling_names_the_channels_it_cannot_use():
    a = np.column_stack([np.ones(50), np.sin(np.arange(50)) * 1e-300, np.arange(50.0)])
    with pytest.raises(DataError, match=r"^channel\(s\) 'p' are constant: nothing to learn"):
        narx._std(a, ["p", "sensor_1", "r"])
    with pytest.raises(DataError, match=r"^channel\(s\) 'sensor_1' vary by 2e-300 only"):
        narx._std(a[:, 1:], ["sensor_1", "r"])
