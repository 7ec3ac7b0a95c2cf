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


@pytest.mark.parametrize("cls, kw", [
    (HangingWeightTest, {}),
    (StrapLoadTest, {}),
    (StrapLoadTest, {"cycles": 1000, "cycle_period_s": 600.0, "n_steps": 100,
                     "step_hold_s": 600.0}),                  # the longest test: dt_s >= 3.6 s
    (HangingWeightTest, {"hold_s": 3600.0}),
])
def test_time_steps_are_capped_and_the_printed_dt_works(cls, kw):
    """dt_s = 1e-6 s would be 1.5e8 samples (over 2 GB): a one-line error naming dt_s with the
    smallest allowed step; that step typed back is accepted and stays under the cap."""
    import re

    from designlab.sensors.protocols import MAX_TIME_STEPS

    with pytest.raises(ParameterError) as exc:
        cls(dt_s=1e-6, **kw)
    msg = str(exc.value)
    assert exc.value.name == "dt_s" and "\n" not in msg and f"{MAX_TIME_STEPS} time steps" in msg
    bound = float(re.search(r">= ([0-9.e+-]+) s", msg).group(1))
    n = len(cls(dt_s=bound, **kw).time_history()[0])
    assert MAX_TIME_STEPS * 0.99 < n <= MAX_TIME_STEPS


def test_too_many_weights_is_named():
    with pytest.raises(ParameterError) as exc:
        HangingWeightTest(weights_g=tuple(float(i) for i in range(20_000)))
    assert exc.value.name == "weights_g" and "at most 10000 masses" in str(exc.value)


@pytest.mark.parametrize("weights", [("a", "b", "c"), ("0", "5", "10"), (0, 5, True),
                                     (0, float("nan"), 10), (0, 5, float("inf"))])
def test_weights_that_are_not_finite_numbers_are_named(weights):
    with pytest.raises(ParameterError, match="weights_g=.*at least 3 finite"):
        HangingWeightTest(weights_g=weights)


def test_a_protocol_file_without_preset_starts_from_the_designs_defaults(tmp_path):
    """A file holding only hold_s keeps what the design chose (Table III, its load points)."""
    from designlab.sensors.protocols import protocol_for

    class Design:
        load_table = "III"

        def load_points(self, _):
            return ("h1", "h2", "r1")

    def design_protocol(proto, design, overrides):
        from dataclasses import replace
        proto = type(proto).preset("optimized")
        return replace(proto, g1_locations=("h1", "h2"), g2_locations=("r1",))

    f = tmp_path / "p.toml"
    f.write_text("hold_s = 5.0\n")
    p = protocol_for(HangingWeightTest, f, None, Design(), design_protocol)
    assert p.hold_s == 5.0 and p.g1_locations == ("h1", "h2")
    assert p.weights_g == HangingWeightTest.preset("optimized").weights_g
    f.write_text('weights_g = ["a", "b", "c"]\n')
    with pytest.raises(ParameterError, match="weights_g"):
        protocol_for(HangingWeightTest, f, None, Design(), design_protocol)
