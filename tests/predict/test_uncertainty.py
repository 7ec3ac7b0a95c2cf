"""Uncertainty: noise budgets, the Monte Carlo of a design, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from designlab.errors import ParameterError
from designlab.sensors.noise import FLEXURE_TABLE_I, POSE_NOISE_SIGMA_MM, sigma_from_mean_abs
from designlab.sensors.distributions import Distribution
from designlab.predict.uncertainty import draw, parse_uncertainty, run_batch, summarize


# ----------------------------------------------------------------------------- distributions

@pytest.mark.parametrize("table, name, text", [
    ({"bolt_preload_N": {"dist": "normal", "mean": 20.0, "std": -1.0}}, "std", ">= 0"),
    ({"bolt_preload_N": {"dist": "normal", "mean": 20.0, "std": 2.0, "lo": 21.0}}, "mean",
     "inside the bounds"),
    ({"bolt_preload_N": {"dist": "lognormal", "mean": 20.0, "std": 2.0, "hi": 10.0}}, "mean",
     "inside the bounds"),
    ({"bolt_preload": {"dist": "uniform", "lo": 1.0, "hi": 2.0}}, "uncertainty.bolt_preload",
     "bolt_preload_N"),
    ({"printed_modulus_scale": {"dist": "gauss", "mean": 1.0, "std": 0.1}}, "dist", "normal"),
    ({"printed_modulus_scale": {"dist": "uniform", "lo": 1.0, "hi": 0.5}}, "hi", "> lo"),
    ({"printed_modulus_scale": {"dist": "normal", "mean": 1.0, "sd": 0.1}}, "sd", "std"),
    ({"bolt_preload_N": {"dist": "normal", "mean": 20.0, "std": 1e308}}, "std",   # draws inf
     "|value| <= 1e+20"),
])
def test_bad_spec_is_one_line_naming_it(table, name, text):
    with pytest.raises(ParameterError) as e:
        parse_uncertainty("fingertip", table)
    msg = str(e.value)
    assert "\n" not in msg and name in msg and text in msg


@pytest.mark.parametrize("part, table, ok", [
    ("flexure", {"pose_noise_mm": {"dist": "normal", "mean": 0.03, "std": 1e10}}, False),
    ("flexure", {"pose_noise_mm": {"dist": "normal", "mean": 0.03, "std": 6.0}}, False),
    ("flexure", {"pose_noise_mm": {"dist": "fixed", "value": 11.0}}, False),
    ("flexure", {"pose_noise_mm": {"dist": "normal", "mean": 0.03, "std": 0.02}}, False),
    ("flexure", {"pose_noise_mm": {"dist": "normal", "mean": 0.03, "std": 0.005}}, True),
    ("flexure", {"pose_noise_mm": {"dist": "normal", "mean": 0.03, "std": 0.02, "lo": 0.0}},
     True),
    ("flexure", {"pose_noise_mm": {"dist": "uniform", "lo": 0.0, "hi": 10.0}}, True),
    ("strap", {"tpu_modulus_scale": {"dist": "normal", "mean": 1.0, "std": 0.6}}, False),
    ("strap", {"tpu_modulus_scale": {"dist": "normal", "mean": 1.0, "std": 0.1}}, True),
    ("fingertip", {"friction_coefficient": {"dist": "uniform", "lo": 0.1, "hi": 3.0}}, False),
])
def test_a_distribution_with_draws_outside_the_inputs_range_is_refused(part, table, ok):
    """A distribution whose 1st-99th percentiles leave the values a build accepts (a model
    setting's range, a positive scale) is refused before any build, in one line naming the
    input, the distribution and the range (a std of 1e10 mm failed every build)."""
    if ok:
        parse_uncertainty(part, table)
        return
    with pytest.raises(ParameterError) as e:
        parse_uncertainty(part, table)
    msg, (name,) = str(e.value), table
    assert "\n" not in msg and f"uncertainty.{name}=" in msg and "percentiles" in msg
    assert "range" in msg and "dist=" in msg


def test_every_default_distribution_is_inside_its_inputs_range():
    from designlab.predict.uncertainty import input_range, sensor_inputs

    for part in ("fingertip", "flexure", "strap"):
        spec = parse_uncertainty(part, None)
        for inp in sensor_inputs(part):
            meta = input_range(part, inp)
            if meta is not None:
                spec.inputs[inp.name].check_within(inp.name, meta, "default")


def test_a_monte_carlo_whose_every_build_fails_is_an_error(tmp_path, monkeypatch):
    """Every build fails: one-line error naming the first build's error, exit 2 from the CLI,
    no summary written (no empty table reported as a result)."""
    import dataclasses

    from designlab.errors import ModelError
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.montecarlo import monte_carlo
    from designlab.sensors import registry
    from designlab.sensors.distributions import Input, MonteCarloModel

    def build(ctx, values, seed):
        raise ValueError(f"gain={values['gain']:.3g} refused by this build")

    toy = MonteCarloModel((Input("gain", Distribution("uniform", lo=1.0, hi=2.0), "a gain"),),
                          ("twice_gain",), lambda part, settings, protocol, cache: {}, build)
    monkeypatch.setitem(registry.SENSORS, "strap",
                        dataclasses.replace(registry.SENSORS["strap"], uncertainty=toy))
    spec = parse_uncertainty("strap", {"samples": 4})
    with pytest.raises(ModelError) as e:
        monte_carlo("strap", spec, tmp_path, executor=LocalExecutor(1))
    msg = str(e.value)
    assert "\n" not in msg and "all 4 builds" in msg and "refused by this build" in msg
    assert not (tmp_path / "uncertainty.json").exists()


def test_numpy_numbers_are_numbers():
    d = Distribution("normal", mean=np.int64(20), std=np.float64(2.0)).check("bolt_preload_N")
    assert d.mean == 20


def test_unknown_name_lists_the_allowed_names():
    with pytest.raises(ParameterError) as e:
        parse_uncertainty("flexure", {"pulp_stiffness": {"dist": "fixed", "value": 1.0}})
    assert "hysteresis_percent" in str(e.value) and "pose_noise_mm" in str(e.value)


def test_draws_are_seeded_and_inside_their_bounds():
    t = {"samples": 500, "bolt_preload_N": {"dist": "normal", "mean": 20.0, "std": 10.0,
                                            "lo": 15.0, "hi": 22.0}}
    c1, v1 = draw(parse_uncertainty("fingertip", t))
    c2, v2 = draw(parse_uncertainty("fingertip", t))
    _, v3 = draw(parse_uncertainty("fingertip", {**t, "seed": 1}))
    assert c1 == c2 and np.array_equal(v1, v2) and not np.array_equal(v1, v3)
    j = c1.index("bolt_preload_N")
    assert v1[:, j].min() >= 15.0 and v1[:, j].max() <= 22.0
    # three independent FSS015 units
    k = [c1.index(f"fss015_sensitivity.{i}") for i in (1, 2, 3)]
    assert abs(np.corrcoef(v1[:, k].T)[0, 1]) < 0.15
    assert 2.2 <= v1[:, k].min() and v1[:, k].max() <= 2.6


def test_lognormal_has_the_asked_mean_and_std():
    d = Distribution("lognormal", mean=0.23, std=0.02).check("x")
    x = d.ppf((np.arange(20000) + 0.5) / 20000)
    assert x.mean() == pytest.approx(0.23, rel=2e-3) and x.std() == pytest.approx(0.02, rel=2e-2)


def test_pose_noise_sigma_from_the_papers_mean_abs():
    rs = np.random.default_rng(0).normal(0.0, POSE_NOISE_SIGMA_MM, 200000)
    assert np.abs(rs).mean() == pytest.approx(0.020, rel=1e-2)
    assert sigma_from_mean_abs(0.020) == pytest.approx(0.02507, rel=1e-3)


# ------------------------------------------------------------------------------ flexure

def _flexure():
    from designlab.geometry.parts import make_part
    from designlab.sensors.flexure.model import run

    p = run(make_part("flexure", {}))
    return p.K_true, p.K_design


@pytest.mark.slow
def test_flexure_force_error_within_1_5x_of_table_I_with_the_split():
    from designlab.sensors.flexure.force_error import run_force_test

    K, Kd = _flexure()
    r = run_force_test(K, Kd)
    for a in "xyz":
        ratio = r["per_axis"][a]["std"] / FLEXURE_TABLE_I[a]["std"]
        assert 1 / 1.5 <= ratio <= 1.5, (a, ratio)
        split = r["split_std"][a]
        assert split["hysteresis"] > 0 and split["pose_noise"] > 0
    assert r["within_1_5x_of_paper"]


@pytest.mark.slow
def test_flexure_mechanisms_alone():
    from designlab.sensors.flexure.force_error import FlexureForceTest, run_force_test

    K, Kd = _flexure()
    clean = run_force_test(K, Kd, FlexureForceTest(pose_noise_mm=0.0, hysteresis_percent=0.0))
    assert max(clean["per_axis"][a]["max_abs"] for a in "xyz") < 1e-9
    noise = run_force_test(K, Kd, FlexureForceTest(hysteresis_percent=0.0))
    for i, a in enumerate("xyz"):       # std of K n: the stiffness times the pose noise
        assert noise["per_axis"][a]["std"] == pytest.approx(K[3 + i, 3 + i] * POSE_NOISE_SIGMA_MM,
                                                            rel=0.1)
        assert noise["split_std"][a]["hysteresis"] < 1e-9
    hyst = run_force_test(K, Kd, FlexureForceTest(pose_noise_mm=0.0))
    assert all(hyst["split_std"][a]["pose_noise"] == 0 for a in "xyz")
    more = run_force_test(K, Kd, FlexureForceTest(pose_noise_mm=0.0, hysteresis_percent=5.0))
    assert all(more["per_axis"][a]["std"] > hyst["per_axis"][a]["std"] for a in "xyz")


def test_iwan_loop_deviates_by_the_asked_amplitude():
    from designlab.sensors.noise import IwanHysteresis

    h = IwanHysteresis(2.0, 0.7, 40)
    h.move(2.0)
    xs = np.linspace(2.0, -2.0, 201)
    down = np.array([h.move(x) for x in xs])
    up = np.array([h.move(x) for x in xs[::-1]])[::-1]
    assert np.max(np.abs(down - up)) / 2 == pytest.approx(0.7, rel=1e-6)


# ----------------------------------------------------------------------------- Monte Carlo

def _flexure_task(values, indices):
    from designlab.geometry.parts import make_part
    from designlab.params import as_dict

    return {"sensor": "flexure", "params": as_dict(make_part("flexure", {})), "settings": None,
            "protocol": None, "fem_cache": None, "seed": 3, "indices": indices,
            "values": values}


@pytest.mark.slow
def test_failed_build_is_recorded_and_counted():
    spec = parse_uncertainty("flexure", {"samples": 3})
    good = {"hysteresis_percent": 3.0, "pose_noise_mm": 0.025}
    bad = {"hysteresis_percent": -1.0, "pose_noise_mm": 0.025}
    res = run_batch(_flexure_task([good, bad, good], [0, 1, 2]))
    status = [r["status"] for r in res["rows"]]
    assert status == ["ok", "failed", "ok"]
    assert "hysteresis_percent" in res["rows"][1]["error"]
    cols = spec.columns()
    s = summarize(spec, cols, np.array([[3.0, 0.025], [-1.0, 0.025], [3.0, 0.025]]), res["rows"])
    assert s["ok"] == 2 and s["failed"] == 1 and s["failed_indices"] == [1]
    assert sum(s["failed_errors"].values()) == 1


@pytest.mark.slow
def test_build_noise_depends_on_its_index_not_its_batch():
    v = {"hysteresis_percent": 3.0, "pose_noise_mm": 0.025}
    a = run_batch(_flexure_task([v, v], [4, 5]))["rows"]
    b = run_batch(_flexure_task([v], [5]))["rows"]
    assert a[1]["metrics"] == b[0]["metrics"] and a[0]["metrics"] != a[1]["metrics"]


@pytest.mark.slow
def test_monte_carlo_resumes_and_summarises(tmp_path):
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.montecarlo import monte_carlo

    spec = parse_uncertainty("flexure", {"samples": 12, "batch": 4})
    s1 = monte_carlo("flexure", spec, tmp_path, executor=LocalExecutor(1))
    assert s1["ok"] == 12 and s1["failed"] == 0 and s1["reused_builds"] == 0
    m = s1["metrics"]["force_error_std.x"]
    assert m["p5"] <= m["p50"] <= m["p95"] and m["std"] > 0
    # the hysteresis drives its own share of the error, not the pose noise
    d = s1["metrics"]["split_std.hysteresis.x"]["drivers"]
    assert next(iter(d)) == "hysteresis_percent" and d["hysteresis_percent"] > 0.8
    s2 = monte_carlo("flexure", spec, tmp_path, executor=LocalExecutor(1))
    assert s2["reused_builds"] == 12 and s2["metrics"] == s1["metrics"]
    assert json.loads((tmp_path / "uncertainty.json").read_text())["ok"] == 12


def test_sobol_indices_with_salib():
    # 64 base samples: the Sobol estimate of a linear y is within a few % of its ST = 1 with
    # any number of sampled inputs (8 left it at 0.55 once the wire diameter was sampled too)
    spec = parse_uncertainty("flexure", {"samples": 64, "sensitivity": "sobol"})
    cols, V = draw(spec)
    assert len(V) == 64 * (2 * len(cols) + 2)
    rows = [{"index": i, "status": "ok", "metrics": {"y": float(3 * v[0] + 0.01 * v[1])}}
            for i, v in enumerate(V)]
    s = summarize(spec, cols, V, rows)
    d = s["metrics"]["y"]["drivers"]
    assert next(iter(d)) == "hysteresis_percent" and d["hysteresis_percent"]["ST"] > 0.9


# ---------------------------------------------------------------------------- fingertip (FEM)

@pytest.fixture(scope="module")
def fingertip_fem():
    from designlab.geometry.parts import make_part
    from designlab.sensors.fingertip.model import FingertipModelSettings
    from designlab.sensors.fingertip.calibration import structure
    from designlab.sensors.protocols import HangingWeightTest

    part = make_part("fingertip", {})
    sett = FingertipModelSettings()
    proto = HangingWeightTest.preset("optimized")
    return part, structure(part, sett, proto), sett, proto


@pytest.mark.slow
def test_condensed_structure_equals_the_linear_fem(fingertip_fem):
    from designlab.sensors.fingertip.virtual import run
    from designlab.sensors.fingertip.calibration import FingertipBuild, unit_responses

    part, fem, sett, proto = fingertip_fem
    H = run(part, proto, sett).unit_readings[-1]
    G = unit_responses(part, fem, sett, FingertipBuild(contact=False))["normal"]
    assert np.abs(G - H).max() < 1e-3 * np.abs(H).max()


@pytest.mark.slow
def test_printed_modulus_scale_is_exact_without_resolving(fingertip_fem):
    from designlab.fem.materials import MATERIALS, Material
    from designlab.sensors.fingertip.calibration import (FingertipBuild, condense_structure,
                                                         unit_responses)

    part, fem, sett, proto = fingertip_fem
    m = MATERIALS["ABS"]
    soft = dict(MATERIALS)
    soft["ABS"] = Material("ABS", E=0.8 * m.E, nu=m.nu, density=m.density, prony=m.prony,
                           source="test")
    import designlab.fem.materials as mats
    old = dict(mats.MATERIALS)
    mats.MATERIALS.clear()
    mats.MATERIALS.update(soft)
    try:
        fem_soft = condense_structure(part, sett)
    finally:
        mats.MATERIALS.clear()
        mats.MATERIALS.update(old)
    b = FingertipBuild(contact=False)
    scaled = unit_responses(part, fem, sett, FingertipBuild(contact=False,
                                                            printed_modulus_scale=0.8))
    direct = unit_responses(part, fem_soft, sett, b)
    assert np.abs(scaled["normal"] - direct["normal"]).max() < 1e-8


@pytest.mark.slow
def test_fingertip_Pz_worst_as_fig9(fingertip_fem):
    from designlab.sensors.fingertip.calibration import (fingertip_calibration_budget,
                                                         nominal_build)

    part, fem, sett, proto = fingertip_fem
    r = fingertip_calibration_budget(part, sett, proto)
    # 1.07 with the repeatability as Honeywell defines it (1.5 with the band on one reading)
    assert r["worst_axis"] == "z" and r["Pz_error_over_xy"] > 1.0
    assert r["split_std"]["z"]["readout_noise"] > r["split_std"]["z"]["model_error"]
    # no readout noise: the remaining error is the 3-sensor model's alone
    import dataclasses
    clean = fingertip_calibration_budget(part, sett, proto, dataclasses.replace(
        nominal_build(), repeatability_percent_fs=0.0, daq_bits=32))
    assert clean["split_std"]["z"]["readout_noise"] < 1e-3


# ------------------------------------------------------------------------------------ CLI

@pytest.mark.slow     # each case a new process importing the CLI: about 3 s
@pytest.mark.parametrize("toml, text", [
    ("[uncertainty]\nbolt_preload_N = { dist = 'normal', mean = 20.0, std = -2.0 }\n", ">= 0"),
    ("[uncertainty]\nwire_modulus = { dist = 'fixed', value = 1.0 }\n", "hysteresis_percent"),
    ("[uncertainty]\nsamples = 4\npose_noise_mm = { dist = 'normal', mean = 0.03, std = 1e10 }\n",
     "percentiles"),
])
def test_cli_bad_uncertainty_exit_2_one_line(tmp_path, toml, text):
    import subprocess
    import sys

    f = tmp_path / "u.toml"
    f.write_text(toml)
    part = "fingertip" if "bolt" in toml else "flexure"
    r = subprocess.run([sys.executable, "-c", "from designlab.cli import main; main()", "predict",
                        part, "--uncertainty", str(f), "--samples", "4", "--out",
                        str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and text in lines[0] and str(f) in lines[0]
    assert not (tmp_path / "o" / "uncertainty.json").exists()


# ------------------------------------------------------------------------------ robust design

@pytest.mark.slow
def test_robust_sweep_minimises_a_quantile(tmp_path):
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.robust import load_robust_config, robust_optimize

    res, bands = robust_optimize("examples/uncertainty_sweep_flexure.toml", tmp_path,
                                 method="pareto", executor=LocalExecutor(1))
    name = "mc.force_error_std.z.p95"
    ok = [r for r in res.sweep.rows if r["status"] == "ok"]
    assert ok and all(r[name] is not None for r in ok)
    assert all(r["error"] for r in res.sweep.rows if r["status"] != "ok")   # recorded
    assert res.chosen[name] == min(r[name] for r in ok)
    lo, mid, hi = bands[res.chosen["key"]]["mc.force_error_std.z"]
    assert lo <= mid <= hi and hi == res.chosen[name]
    # the quantile is not the nominal: designs differ in their spread, not only their centre
    assert any(r[name] > r["mc.force_error_std.z.mean"] for r in ok)
    cfg, _ = load_robust_config("examples/uncertainty_sweep_flexure.toml")
    assert name in cfg.objectives


def test_robust_config_refuses_an_unknown_mc_metric():
    from designlab.optimize.robust import robust_config

    with pytest.raises(ParameterError) as e:
        robust_config({"part": "flexure", "parameters": {"wire_radius": [0.8, 1.3]},
                       "uncertainty": {}, "objectives": {"mc.force_error.z.p95": "min"}})
    assert "force_error_std.z" in str(e.value) and "\n" not in str(e.value)


def test_a_robust_sweeps_rows_are_keyed_apart_from_the_nominal_and_other_specs():
    """A robust row carries mc.* columns: its key holds the [uncertainty] spec, so a nominal
    row (or another spec's) left in the same store is never reused for it."""
    import dataclasses

    from designlab.optimize.robust import RobustEvaluator, load_robust_config
    from designlab.optimize.sweep import tasks_of

    cfg, spec = load_robust_config("examples/uncertainty_sweep_flexure.toml")
    nominal = [t["key"] for t in tasks_of(cfg)]
    robust = [t["key"] for t in tasks_of(cfg, RobustEvaluator(spec))]
    other = [t["key"] for t in tasks_of(cfg, RobustEvaluator(
        dataclasses.replace(spec, seed=spec.seed + 1)))]
    assert len(set(nominal)) == len(nominal) == len(robust)
    assert not set(nominal) & set(robust) and not set(robust) & set(other)
    assert robust == [t["key"] for t in tasks_of(cfg, RobustEvaluator(spec))]


# ------------------------------------------------------- the Monte Carlo model in the record

def test_a_sensor_brings_its_own_monte_carlo_model(monkeypatch):
    """The Monte Carlo reads the sensor's record only: a toy model given to the strap runs
    through parse/draw/run_batch/summarize without any change in uncertainty.py."""
    import dataclasses

    from designlab.sensors import registry
    from designlab.sensors.distributions import Input, MonteCarloModel
    from designlab.predict.uncertainty import build_values, mc_metrics, sensor_inputs

    # a sensor without a model: one line listing those that have one
    monkeypatch.setitem(registry.SENSORS, "strap",
                        dataclasses.replace(registry.SENSORS["strap"], uncertainty=None))
    with pytest.raises(ParameterError) as e:
        parse_uncertainty("strap", None)
    assert "fingertip, flexure" in str(e.value)
    toy = MonteCarloModel(
        (Input("gain", Distribution("uniform", lo=1.0, hi=2.0), "a gain"),),
        ("twice_gain",), lambda part, settings, protocol, cache: {"k": 2.0},
        lambda ctx, values, seed: {"twice_gain": ctx["k"] * values["gain"]},
        paper={"twice_gain": 3.0})
    monkeypatch.setitem(registry.SENSORS, "strap",
                        dataclasses.replace(registry.SENSORS["strap"], uncertainty=toy))
    assert [i.name for i in sensor_inputs("strap")] == ["gain"]
    assert mc_metrics("strap") == ("twice_gain",)
    spec = parse_uncertainty("strap", {"samples": 5})
    cols, V = draw(spec)
    from designlab.geometry.parts import make_part
    from designlab.params import as_dict

    res = run_batch({"sensor": "strap", "params": as_dict(make_part("strap", {})),
                     "settings": None, "protocol": None, "fem_cache": None, "seed": 0,
                     "indices": list(range(5)),
                     "values": [build_values(spec, cols, v) for v in V]})
    got = [r["metrics"]["twice_gain"] for r in res["rows"]]
    assert got == pytest.approx(2.0 * V[:, 0])
    s = summarize(spec, cols, V, res["rows"])
    assert s["paper"] == {"twice_gain": 3.0} and s["metrics"]["twice_gain"]["drivers"]["gain"] > 0.99


@pytest.mark.slow
def test_flexure_monte_carlo_summary_carries_the_papers_table_I(tmp_path):
    spec = parse_uncertainty("flexure", {"samples": 3})
    cols, V = draw(spec)
    from designlab.predict.uncertainty import build_values

    res = run_batch(_flexure_task([build_values(spec, cols, v) for v in V], [0, 1, 2]))
    s = summarize(spec, cols, V, res["rows"])
    for a in "xyz":
        assert s["paper"][f"force_error_std.{a}"] == FLEXURE_TABLE_I[a]["std"]
        assert s["paper"][f"force_error_mean.{a}"] == FLEXURE_TABLE_I[a]["mean"]


def test_wire_modulus_scale_scales_the_error_exactly():
    """Part-to-part wire modulus: the built stiffness times s; with hysteresis and pose noise
    both scaling with K (hysteresis as a share of the range, noise through K_c), the force
    error scales by s."""
    from designlab.sensors.flexure.montecarlo import MONTE_CARLO

    K, Kd = _flexure()
    v = {"hysteresis_percent": 3.0, "pose_noise_mm": 0.025}
    a = MONTE_CARLO.build({"K_true": K, "K_design": Kd}, {**v, "wire_modulus_scale": 1.0}, 7)
    b = MONTE_CARLO.build({"K_true": K, "K_design": Kd}, {**v, "wire_modulus_scale": 1.02}, 7)
    for ax in "xyz":
        assert b[f"split_std.pose_noise.{ax}"] == pytest.approx(
            1.02 * a[f"split_std.pose_noise.{ax}"], rel=1e-3)
    spec = parse_uncertainty("flexure", {"wire_modulus_scale": {"dist": "uniform", "lo": 0.983,
                                                                "hi": 1.017}})
    assert "wire_modulus_scale" in spec.columns()
    assert "wire_modulus_scale" not in parse_uncertainty("flexure", None).columns()


@pytest.mark.slow
def test_monte_carlo_identical_on_local_processes_and_dask(tmp_path):
    """8 flexure builds on 2 local processes and on a Dask LocalCluster: the same numbers."""
    from distributed import LocalCluster

    from designlab.optimize.executors import DaskExecutor, LocalExecutor
    from designlab.optimize.montecarlo import monte_carlo

    spec = parse_uncertainty("flexure", {"samples": 8, "batch": 4, "seed": 5})
    local = monte_carlo("flexure", spec, tmp_path / "a", executor=LocalExecutor(2))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        dask = monte_carlo("flexure", spec, tmp_path / "b",
                           executor=DaskExecutor(cluster.scheduler_address))
    assert local["ok"] == dask["ok"] == 8
    assert local["metrics"] == dask["metrics"]
    assert local["metrics"]["force_error_std.z"]["std"] > 0


# ----------------------------------------------------------------------------------- strap

def _strap_report(sens, johnson=1e-6, adc=2e-6):
    return {"sensitivity": {"V_per_N": {"Ch1": {"F_n": sens[0][0], "F_x": sens[0][1]},
                                        "Ch2": {"F_n": sens[1][0], "F_x": sens[1][1]}}},
            "electrical": {"noise": {"johnson_V_rms": johnson, "adc_quantisation_V_rms": adc,
                                     "bandwidth_hz": 10.0},
                           "divider": {"R_fixed_ohm": 2200.0, "supply_V": 5.0}}}


def test_strap_budget_noise_matches_the_resolution_and_splits_exactly():
    from designlab.sensors.strap.noise import StrapForceTest, run_strap_force_test

    # symmetric gauges: the sum sees F_n only, the difference F_x only
    rep = _strap_report([[2e-3, 1e-3], [2e-3, -1e-3]], johnson=3e-5, adc=4e-5)
    r = run_strap_force_test(rep, StrapForceTest(model_points=2000, test_points=20000))
    for a, g in (("F_n", 1 / 4e-3), ("F_x", 1 / 2e-3)):
        want = g * np.sqrt(2) * 5e-5                    # |g| sqrt(2) hypot(3e-5, 4e-5)
        assert r["per_axis"][a]["std"] == pytest.approx(want, rel=0.03)
        # the fitted slope is diluted by the noise (F_x: 1.5 % at this signal-to-noise)
        assert r["fit"][a]["noise_std_predicted_N"] == pytest.approx(want, rel=0.03)
        sp = r["split_std"][a]
        assert sp["adc"] / sp["johnson"] == pytest.approx(4 / 3, rel=0.05)
        # no cross-talk: the model term is only the slope the noisy fit dilutes
        assert sp["model_error"] < 0.2 * r["per_axis"][a]["std"]
    # noise-free: the error is the model error, here the sum's cross-talk from F_x
    skew = _strap_report([[2e-3, 1e-3], [2e-3, -0.5e-3]])
    clean = run_strap_force_test(skew, StrapForceTest(noise_scale=0.0))
    assert clean["split_std"]["F_n"]["johnson"] == 0 and clean["per_axis"]["F_n"]["std"] > 0.01
    assert clean["per_axis"]["F_n"]["std"] == pytest.approx(
        clean["split_std"]["F_n"]["model_error"])
    # same seed, same numbers
    assert run_strap_force_test(rep) == run_strap_force_test(rep)


def test_strap_budget_bad_input_is_one_line():
    from designlab.sensors.strap.noise import StrapForceTest, run_strap_force_test

    with pytest.raises(ParameterError) as e:
        run_strap_force_test({"sensitivity": {}})
    assert "sensitivity.V_per_N" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ParameterError):
        StrapForceTest(noise_scale=-1.0)


def test_flexure_prediction_carries_the_force_error_test_beside_table_I():
    from designlab.predict.run import predict

    m = predict("flexure").metrics
    ft = m["force_error_test"]
    for a in "xyz":
        assert ft["paper_table_I"][a]["std"] == FLEXURE_TABLE_I[a]["std"]
        assert 1 / 1.5 <= ft["std_over_paper"][a] <= 1.5
        assert set(ft["split_std"][a]) == {"pose_noise", "hysteresis", "model_error"}
    assert "model error only" in m["wrench_error"]["table_I_forces_N_note"]


def _cli(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-c", "from designlab.cli import main; main()", *args],
                          capture_output=True, text=True)


_ROBUST_TOML = """part = "flexure"
[parameters]
wire_radius = {{ range = [0.9, 1.2], levels = 2 }}
[uncertainty]
samples = 3
{extra}
[objectives]
"mc.force_error_std.z.p95" = "min"
"""


@pytest.mark.parametrize("cmd", ["sweep", "optimize"])
@pytest.mark.slow
def test_cli_sweep_and_optimize_refuse_a_bad_uncertainty_table(tmp_path, cmd):
    f = tmp_path / "s.toml"
    f.write_text(_ROBUST_TOML.format(extra="pulp = { dist = 'fixed', value = 1.0 }"))
    r = _cli(cmd, str(f), "--out", str(tmp_path / "o"))
    assert r.returncode == 2
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "uncertainty.pulp" in lines[0] and "hysteresis_percent" in lines[0]
    assert not (tmp_path / "o" / "results.parquet").exists()


@pytest.mark.slow
def test_cli_robust_sweep_prints_the_bands(tmp_path):
    import pyarrow.parquet as pq

    f = tmp_path / "s.toml"
    f.write_text(_ROBUST_TOML.format(extra=""))
    r = _cli("sweep", str(f), "--out", str(tmp_path / "o"), "--workers", "1")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("Monte Carlo band") == 2 and "mc.force_error_std.z" in r.stdout
    rows = pq.read_table(tmp_path / "o" / "results.parquet").to_pylist()
    assert len(rows) == 2
    for row in rows:
        assert row["mc.force_error_std.z.p5"] <= row["mc.force_error_std.z.p95"]
        assert row["mc.failed"] == 0
