import json

import numpy as np
import pytest

from designlab.calibration.calibration_matrix import (condition_number, cross_talk_percent,
                                                      fit_calibration_matrix, geometric_matrix,
                                                      linearity_percent)
from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps
from designlab.errors import ParameterError


def test_geometric_matrix_matches_paper_eq8(shared):
    paper = json.loads((shared / "data/papers/fingertip_xu2014.json").read_text())
    A = geometric_matrix()
    np.testing.assert_allclose(A, paper["geometry_matrix_eq_8_unit_k"], atol=1e-4)
    assert abs(condition_number(A) - np.sqrt(2)) < 1e-12
    assert abs(condition_number(A) - paper["geometry_matrix_condition_number_computed"]) < 1e-3


def test_paper_A_opt_condition_number(shared):
    paper = json.loads((shared / "data/papers/fingertip_xu2014.json").read_text())
    A = np.array(paper["calibration"]["A_opt_eq_9"])
    assert abs(condition_number(A) - paper["calibration"]["condition_number"]) < 0.05


def test_fit_recovers_matrix_from_noisy_load_sets():
    rng = np.random.default_rng(1)
    A = geometric_matrix(k=(2.0, 1.5, 0.7))
    P = rng.normal(size=(72, 3))
    S = np.linalg.solve(A, P.T).T + rng.normal(scale=1e-4, size=(72, 3))
    A_fit, rep = fit_calibration_matrix(S, P)
    np.testing.assert_allclose(A_fit, A, atol=2e-3)
    assert rep["rms_residual_N"] < 1e-3
    assert cross_talk_percent(P, S @ A_fit.T).max() < 0.5


def test_hysteresis_eq1_by_hand():
    w = [0, 5, 15, 35, 55, 105, 132, 232, 132, 105, 55, 35, 15, 5, 0]
    # loading readings linear; unloading higher by 0.1 at every interior point
    s = np.array(w, float) / 232.0
    s[8:14] += 0.1
    lu, su, ld, sd = loop_from_steps(w, s)
    # mid-load 116 lies between 105 and 132 on both branches: difference 0.1, span 1
    assert abs(hysteresis_percent(lu, su, ld, sd) - 10.0) < 1e-9


def test_hysteresis_multi_channel_and_zero_loop():
    w = np.array([0.0, 1, 2, 3])
    s = np.column_stack([w, -2 * w])
    h = hysteresis_percent(w, s, w[::-1], s[::-1])
    np.testing.assert_allclose(h, [0, 0], atol=1e-12)


def test_hysteresis_rejects_non_increasing_loads():
    with pytest.raises(ParameterError, match="load_up"):
        hysteresis_percent([0, 2, 1], [0, 1, 2], [1, 2, 0], [2, 1, 0])


def test_linearity():
    x = np.linspace(0, 1, 11)
    assert linearity_percent(x, 3 * x + 1) < 1e-9
    assert linearity_percent(x, x ** 2) > 5
