"""Wire-diameter scatter in the flexure's Monte Carlo (designlab.sensors.flexure.montecarlo):
the built 6x6 follows the wire (d^4 for the closed form), the force error and the wire stress
with it, the drivers analysis names it, and a bad spread is a one-line error."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.geometry.parts import make_part
from designlab.sensors.flexure.montecarlo import (MONTE_CARLO, WIRE_DIAMETER_TOLERANCE_MM,
                                                  stiffness_at_diameter)
from designlab.predict.uncertainty import parse_uncertainty

NOISE = {"hysteresis_percent": 3.5, "pose_noise_mm": 0.025}


@pytest.fixture(scope="module")
def ctx_timoshenko():
    return MONTE_CARLO.fem_stage(make_part("flexure", {}), {"truth": "timoshenko"}, None, None)


@pytest.fixture(scope="module")
def ctx_chain():
    return MONTE_CARLO.fem_stage(make_part("flexure", {}), None, None, None)


def test_default_distribution_is_the_catalogue_tolerance():
    spec = parse_uncertainty("flexure", None)
    d = spec.inputs["wire_diameter_offset_mm"]
    assert (d.dist, d.lo, d.hi) == ("uniform", -WIRE_DIAMETER_TOLERANCE_MM,
                                    WIRE_DIAMETER_TOLERANCE_MM) == ("uniform", -0.015, 0.015)
    assert "0.015 mm" in d.source and "wire_diameter_offset_mm" in spec.columns()


def test_closed_form_stiffness_scales_as_d4(ctx_timoshenko):
    """A build with only wire-diameter scatter: the Timoshenko column's every entry is E d^4 or
    G d^4 over geometry that does not depend on d, so K(d) = K0 (d/d0)^4 exactly, and the
    metrics carry it."""
    d0 = ctx_timoshenko["d0_mm"]
    K0 = ctx_timoshenko["K_true"]
    for dd in (-0.015, 0.007, 0.2):
        K = stiffness_at_diameter(ctx_timoshenko, d0 + dd)
        assert K == pytest.approx(K0 * ((d0 + dd) / d0) ** 4, rel=1e-9, abs=1e-12)
    a = MONTE_CARLO.build(ctx_timoshenko, NOISE, 3)
    b = MONTE_CARLO.build(ctx_timoshenko, {**NOISE, "wire_diameter_offset_mm": 0.015}, 3)
    for ax in ("w_x", "w_z", "v_x", "v_z"):
        assert b[f"K_f_diag.{ax}"] / a[f"K_f_diag.{ax}"] == pytest.approx(
            ((d0 + 0.015) / d0) ** 4, rel=1e-9)
    # the designer keeps the nominal wire: its closed form now misses the built z stiffness
    assert a["closed_form_error_std.z"] == pytest.approx(0.0, abs=1e-9)
    assert b["closed_form_error_std.z"] > 0.1
    # the wire stress falls with a thicker wire (~d^-3): the safety factor rises
    assert b["min_safety_factor"] > a["min_safety_factor"] * 1.02


def test_beam_chain_stiffness_follows_the_wire(ctx_chain):
    """The chain of the spring as built: close to d^4 (wire shear, contact and the ground ends
    bend it a little), every diagonal entry stiffer with a thicker wire. The working-load
    state's few closed contact nodes move with the wire (k_wy: exponent 3.44 since the contact
    penalty is E* times the node spacing in mm)."""
    d0 = ctx_chain["d0_mm"]
    K0, K1 = ctx_chain["K_true"], stiffness_at_diameter(ctx_chain, d0 + 0.015)
    p = np.log(np.diag(K1) / np.diag(K0)) / np.log((d0 + 0.015) / d0)
    assert np.all((p > 3.0) & (p < 4.5)), p
    assert K1 == pytest.approx(K1.T)


@pytest.mark.slow
def test_drivers_name_the_wire_diameter(tmp_path):
    """Monte Carlo with the default inputs: the built stiffness is driven by the wire
    diameter alone; the calibrated force error is not (the paper's calibration absorbs it)."""
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.montecarlo import monte_carlo

    spec = parse_uncertainty("flexure", {"samples": 8, "batch": 8, "seed": 2})
    s = monte_carlo("flexure", spec, tmp_path, executor=LocalExecutor(1))
    assert s["ok"] == 8
    for ax in ("v_x", "v_z", "w_z"):
        m = s["metrics"][f"K_f_diag.{ax}"]
        assert next(iter(m["drivers"])) == "wire_diameter_offset_mm"
        assert m["drivers"]["wire_diameter_offset_mm"] == pytest.approx(1.0)
        # +-0.015 mm of 2.03 mm: about +-3 % of stiffness
        assert 0.005 < (m["p95"] - m["p5"]) / m["mean"] < 0.07
    sf = s["metrics"]["min_safety_factor"]
    assert sf["drivers"]["wire_diameter_offset_mm"] == pytest.approx(1.0)
    assert 4.4 < sf["p5"] < sf["p95"] < 4.9


def test_bad_spread_is_a_one_line_error():
    with pytest.raises(ParameterError) as e:
        parse_uncertainty("flexure", {"wire_diameter_offset_mm": {"dist": "normal", "mean": 0.0,
                                                                  "std": -0.01}})
    msg = str(e.value)
    assert "uncertainty.wire_diameter_offset_mm.std" in msg and "\n" not in msg
    with pytest.raises(ParameterError, match="wire_diameter_offset_mm.hi"):
        parse_uncertainty("flexure", {"wire_diameter_offset_mm": {"dist": "uniform", "lo": 0.02,
                                                                  "hi": -0.02}})


def test_a_wire_that_cannot_exist_fails_its_build(ctx_timoshenko):
    """An offset that leaves no wire (or a wire as thick as the coil) fails that build with a
    one-line error naming the input (the Monte Carlo records and counts it)."""
    d0 = ctx_timoshenko["d0_mm"]
    with pytest.raises(ParameterError) as e:
        MONTE_CARLO.build(ctx_timoshenko, {**NOISE, "wire_diameter_offset_mm": -d0}, 1)
    assert "wire_diameter_offset_mm" in str(e.value) and "\n" not in str(e.value)


def test_cli_bad_spread_exits_2(tmp_path, capsys):
    from designlab.cli import main

    toml = tmp_path / "u.toml"
    toml.write_text("[uncertainty]\nwire_diameter_offset_mm = { dist = \"normal\", mean = 0.0, "
                    "std = -0.005 }\n")
    with pytest.raises(SystemExit) as e:
        main(["predict", "flexure", "--samples", "2", "--uncertainty", str(toml),
              "--out", str(tmp_path / "mc")])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "wire_diameter_offset_mm.std" in err and len(err.splitlines()) == 1
