"""Objectives and constraints name metrics a sweep row has: a metric whose setting is not given
(K_f_target_error without K_f_target_N_per_m), a made-up member of a checked family
(hysteresis_percent.nonexistent, electrical.nonsense) is refused before any design runs, in one
line naming the config file, the key, the name and the names allowed."""

from __future__ import annotations

import pytest

from conftest import ROOT
from designlab.errors import ParameterError

STRAP = (ROOT / "examples" / "sweep_strap.toml").read_text()


@pytest.mark.parametrize("name, text", [
    ("K_f_target_error", "[settings] K_f_target_N_per_m"),
    ("hysteresis_percent.nonexistent", "hysteresis_percent.overall"),
    ("electrical.nonsense", "electrical.noise.channel_V_rms"),
    ("condition_numbr", "did you mean 'condition_number'"),
])
def test_an_objective_the_part_never_has_is_refused_naming_the_file(name, text, tmp_path):
    from designlab.optimize.robust import load_sweep

    cfg = tmp_path / "s_badobj.toml"
    cfg.write_text(STRAP.replace('"hysteresis_percent.overall" = "min"', f'"{name}" = "min"'))
    with pytest.raises(ParameterError) as e:
        load_sweep(cfg)
    msg = str(e.value)
    assert "\n" not in msg and str(cfg) in msg and f"objectives.{name}=" in msg and text in msg


def test_the_members_rows_have_are_accepted():
    from designlab.optimize.metrics import check_metric_names

    names = ["hysteresis_percent.by_location.Ch1", "hysteresis_percent.by_group.G1",
             "hysteresis_percent.overall_noise_free", "electrical.resolution_mN.F_n",
             "sensitivity.V_per_N.sum.F_n", "linearity_percent_span.diff", "timings_s.total",
             "mesh_convergence.condition_number.coarse", "k_z_N_per_m"]
    check_metric_names({}, {"objectives": names, "constraints": names})


def test_a_metric_of_a_setting_needs_the_setting():
    from designlab.optimize.metrics import check_metric_names

    with pytest.raises(ParameterError, match="K_f_target_N_per_m"):
        check_metric_names({}, {"objectives": ["K_f_target_error"]})
    check_metric_names({"K_f_target_N_per_m": 4000.0}, {"objectives": ["K_f_target_error"]})


def test_a_constraint_the_part_never_has_is_refused():
    from designlab.optimize.space import sweep_config

    with pytest.raises(ParameterError) as e:
        sweep_config({"part": "strap", "parameters": {"thickness": [0.5, 1.0]},
                      "objectives": {"condition_number": "min"},
                      "constraints": {"electrical.noise.nonsense_V": {"max": 1.0}}})
    assert "constraints.electrical.noise.nonsense_V" in str(e.value)
