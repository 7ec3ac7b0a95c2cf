import numpy as np
import pytest

from designlab.sensors.protocols import (FlexureWrenchTest, HangingWeightTest, StrapLoadTest,
                                             load_protocol)
from designlab.errors import ParameterError


def test_table_ii_defaults_and_max_force(shared):
    import json
    paper = json.loads((shared / "data/papers/fingertip_xu2014.json").read_text())
    p = HangingWeightTest()
    assert list(p.weights_g) == paper["tested_sensor_table_II"]["hanging_weights_g"]
    assert len(p.g1_locations) == 9 and len(p.g2_locations) == 5
    # the paper's 2.27 N maximum is the 232 g weight (tray zeroed out)
    assert abs((p.max_load_N - p.loads_N[0]) - paper["hysteresis_results"]["max_force_N"]) < 0.01
    o = HangingWeightTest.preset("optimized")
    assert list(o.weights_g) == paper["optimized_sensor_table_III"]["hanging_weights_g"]


def test_time_history_and_read_windows():
    p = HangingWeightTest(hold_s=5, read_window_s=3, dt_s=0.5)
    t, load, step = p.time_history()
    masks = p.read_masks(t, step)
    assert len(masks) == 2 * len(p.weights_g) - 1
    for k, m in enumerate(masks):
        assert np.all(load[m] == p.loads_N[k])
        assert 6 <= m.sum() <= 8  # 3 s at 0.5 s


@pytest.mark.parametrize("kw, name", [({"weights_g": (0, 10, 5)}, "weights_g"),
                                      ({"weights_g": (0, 5)}, "weights_g"),
                                      ({"hold_s": 2, "read_window_s": 3}, "read_window_s"),
                                      ({"g1_locations": ("h1", "h1")}, "g1_locations"),
                                      ({"hold_s": -1}, "hold_s")])
def test_bad_protocols(kw, name):
    with pytest.raises(ParameterError) as e:
        HangingWeightTest(**kw)
    assert e.value.name == name


def test_range_check_warns_then_errors():
    p = HangingWeightTest()
    with pytest.warns(UserWarning, match="sensing range"):
        p.check_sensor_range(20.0)
    with pytest.raises(ParameterError, match="overforce"):
        p.check_sensor_range(50.0)


def test_toml_protocol(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[protocol]\npreset = "optimized"\nhold_s = 20.0\n')
    p = load_protocol(HangingWeightTest, f)
    assert p.hold_s == 20 and len(p.g2_locations) == 6
    f.write_text('weights_g = [0, 50, 20]\n')
    with pytest.raises(ParameterError, match="weights_g"):
        load_protocol(HangingWeightTest, f)
    f.write_text('bogus = 1\n')
    with pytest.raises(ParameterError, match="bogus"):
        load_protocol(StrapLoadTest, f)


def test_strap_and_flexure_histories():
    t, fn, fx = StrapLoadTest().time_history()
    assert fn.max() == pytest.approx(5.0) and np.abs(fx).max() == pytest.approx(0.5)
    assert fn[0] == 0 and fn[-1] == 0
    w = FlexureWrenchTest(steps=2).wrenches()
    assert w.shape == (24, 6) and np.abs(w[:, 3:]).max() == 10
