import numpy as np

from designlab.calibration.metrics import ncc, rmse, wilcoxon
from designlab.fem.prony import Prony


def test_rmse_and_ncc():
    t = np.linspace(0, 1, 200)
    y = np.sin(6 * t)
    assert rmse(y, y + 0.5) == 0.5
    assert ncc(y, 3 * y + 1) == 1.0 or abs(ncc(y, 3 * y + 1) - 1) < 1e-12
    assert abs(ncc(y, -y) + 1) < 1e-12


def test_wilcoxon_detects_shift():
    rng = np.random.default_rng(0)
    a = rng.normal(1, 0.1, 30)
    assert wilcoxon(a, a - 0.5)["p_value"] < 1e-4


def test_prony_relaxation_limits():
    p = Prony(g=(0.3, 0.2), tau=(1.0, 10.0))
    assert abs(p.relaxation(0.0) - 1.0) < 1e-12
    assert abs(p.relaxation(1e6) - 0.5) < 1e-12
