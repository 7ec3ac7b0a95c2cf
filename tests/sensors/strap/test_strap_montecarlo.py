"""The strap's Monte Carlo model: the FEM stage on the support-stiffness grid, what
is exact (a common modulus scale of both TPUs with the support), the interpolation's error, the
build's readout against the virtual test's, and ``designlab predict strap --samples N``.
Cheap: a short protocol on a coarse TET4 mesh."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from designlab.fem.cache import FEMCache
from designlab.geometry.strap import ArchStrap
from designlab.sensors.strap import montecarlo as mc
from designlab.sensors.strap import virtual as st
from designlab.sensors.protocols import StrapLoadTest

PART = ArchStrap()
SHORT = {"n_steps": 2, "step_hold_s": 1.0, "dt_s": 0.25, "cycles": 1, "cycle_period_s": 1.0}
CHEAP = {"edge_length": 2.0, "order": 1}
NOMINAL = {i.name: i.default.center for i in mc.INPUTS} | {"tissue_stiffness": 0.02}


@pytest.fixture(scope="module")
def ctx():
    return mc.fem_stage(PART, CHEAP, SHORT, FEMCache())


def _elastic_run(scale: float, k: float):
    """The strap with both TPUs' moduli x ``scale`` and support ``k``: a FEM of its own."""
    mats = {b: dataclasses.replace(m, E=m.E * scale) for b, m in mc.elastic_materials(PART).items()}
    sett = st.StrapModelSettings(**CHEAP, tissue_stiffness=k)
    r = st.run(PART, StrapLoadTest(**SHORT), sett, materials=mats).report["strain_per_N"]
    return np.array([[r[c]["F_n"], r[c]["F_x"]] for c in ("Ch1", "Ch2")])


def test_the_defaults_are_checked_distributions_with_sources():
    for i in mc.INPUTS:
        i.default.check(i.name)
        assert i.default.source and i.doc
    lo = next(i for i in mc.INPUTS if i.name == "tissue_stiffness").default
    s = next(i for i in mc.INPUTS if i.name == "tpu_modulus_scale").default
    # the default support over the default modulus scale stays inside the FEM grid
    assert mc.TISSUE_GRID[0] <= lo.lo / s.hi and lo.hi / s.lo <= mc.TISSUE_GRID[-1]


def test_a_common_modulus_scale_is_exact_and_the_interpolation_is_close(ctx):
    """unit(k / s) / s is the strain per newton of the model with both TPUs x s and support k:
    exact at a grid stiffness (checked against its own FEM); between grid points the PCHIP
    in log k is within 0.5 % of a FEM at that stiffness."""
    s, k = 1.15, 0.02 * 1.15
    want = _elastic_run(s, k)
    got = mc.unit_at(ctx, k / s) / s
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())
    k = 0.03                                     # between 0.02 and 0.04
    want = _elastic_run(1.0, k)
    got = mc.unit_at(ctx, k)
    assert np.abs(got - want).max() <= 0.005 * np.abs(want).max()
    with pytest.raises(ValueError, match="outside the FEM grid"):
        mc.unit_at(ctx, 0.2)


def test_the_nominal_build_reads_as_the_virtual_test(ctx):
    """All inputs nominal: the build's sum/difference sensitivities are the elastic virtual
    test's (same strains, divider and fit), the resistance the paper's 1.8 kOhm."""
    rep = st.run(PART, StrapLoadTest(**SHORT), st.StrapModelSettings(**CHEAP),
                 materials=mc.elastic_materials(PART)).report
    out = mc.build(ctx, NOMINAL, seed=1)
    assert set(out) == set(mc.METRICS)
    V = rep["sensitivity"]["V_per_N"]
    assert out["sensitivity.sum_F_n"] == pytest.approx(V["sum"]["F_n"], rel=1e-9)
    assert out["sensitivity.diff_F_x"] == pytest.approx(V["diff"]["F_x"], rel=1e-9)
    assert out["resistance_ohm"] == pytest.approx(1800.0, rel=1e-9)
    assert out["initial_strain"] == 0.0
    assert out["resolution_mN.F_n"] == pytest.approx(rep["electrical"]["resolution_mN"]["F_n"],
                                                     rel=1e-9)
    assert mc.build(ctx, NOMINAL, seed=1) == out                  # same input, same output
    assert mc.build(ctx, NOMINAL, seed=2)["force_error_std.F_n"] != out["force_error_std.F_n"]


@pytest.mark.slow
def test_inputs_move_what_they_should(ctx):
    base = mc.build(ctx, NOMINAL, 0)
    from designlab.sensors.strap.electrical import gauge_resistance

    pads = gauge_resistance(PART)["pads"]
    w = mc.build(ctx, NOMINAL | {"trace_width_scale": 1.0625}, 0)
    assert w["resistance_ohm"] == pytest.approx((1800.0 - pads) / 1.0625 + pads, rel=1e-9)
    r = mc.build(ctx, NOMINAL | {"resistivity_scale": 2.0}, 0)
    assert r["resistance_ohm"] == pytest.approx(3600.0, rel=1e-9)
    g = mc.build(ctx, NOMINAL | {"gauge_factor_scale": 1.2}, 0)
    assert g["sensitivity.sum_F_n"] == pytest.approx(1.2 * base["sensitivity.sum_F_n"], rel=0.02)
    assert g["resolution_mN.F_n"] < base["resolution_mN.F_n"]
    # the finger perimeter acts through the wrap only: with a slot
    slotted = mc.fem_stage(PART, CHEAP | {"slot": 2}, SHORT, FEMCache())
    a = mc.build(slotted, NOMINAL, 0)
    b = mc.build(slotted, NOMINAL | {"finger_perimeter_scale": 1.05}, 0)
    assert b["initial_strain"] > a["initial_strain"] > 0
    assert base["wrap_stress_MPa"] == 0.0
    from designlab.sensors.strap.prestrain import neo_hooke

    e = a["initial_strain"]
    assert a["wrap_stress_MPa"] == pytest.approx(12.0 * e * neo_hooke(e)["stress_over_linear"])
    stiff = mc.build(slotted, NOMINAL | {"tpu_modulus_scale": 1.1,
                                         "tissue_stiffness": 0.022}, 0)
    assert stiff["wrap_stress_MPa"] == pytest.approx(1.1 * a["wrap_stress_MPa"])
    assert mc.build(ctx, NOMINAL | {"finger_perimeter_scale": 1.05}, 0) == base


@pytest.mark.slow
def test_predict_strap_samples_runs_and_bad_input_is_one_line(tmp_path, run_cli):
    cfg = tmp_path / "mc.toml"
    cfg.write_text('[uncertainty]\nseed = 3\n'
                   'gauge_factor_scale = { dist = "normal", mean = 1.0, std = 0.1, lo = 0.7 }\n'
                   'tissue_stiffness = { dist = "uniform", lo = 0.002, hi = 0.03 }\n')
    out = tmp_path / "mc"
    rc, _, err = run_cli(["predict", "strap", "--samples", 12, "--uncertainty", cfg, "--out", out,
                       "--workers", 1, "--setting", "edge_length=2.0", "--setting", "order=1"])
    assert rc == 0, err
    doc = json.loads((out / "uncertainty.json").read_text())
    s = doc
    assert s["builds"] == 12 and s["ok"] + s["failed"] == 12
    # tissue below the grid (0.002-0.005 of 0.002-0.03) fails, counted with its reason
    assert s["failed"] >= 1 and any("outside the FEM grid" in e for e in s["failed_errors"])
    m = s["metrics"]["sensitivity.sum_F_n"]
    assert m["p5"] <= m["mean"] <= m["p95"] and m["drivers"]
    assert s["spec"]["inputs"]["gauge_factor_scale"]["std"] == 0.1
    for table, says in (('[uncertainty]\ngauge_factor = { dist = "uniform", lo = 1, hi = 2 }\n',
                         "gauge_factor_scale"),
                        ('[uncertainty]\ntpu_modulus_scale = { dist = "normal", mean = 1.0, '
                         'std = -0.1 }\n', "uncertainty.tpu_modulus_scale.std")):
        cfg.write_text(table)
        rc, _, err = run_cli(["predict", "strap", "--samples", 4, "--uncertainty", cfg,
                           "--out", tmp_path / "bad"])
        assert rc == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    rc, _, err = run_cli(["predict", "strap", "--samples", 4, "--measured", cfg,
                       "--out", tmp_path / "bad2"])
    assert rc == 2 and "--measured" in err


def test_the_solid_pulp_is_refused_before_any_fem(tmp_path):
    """The Monte Carlo scatters the Winkler support; with ``finger_model = solid`` its
    tissue_stiffness would do nothing: one line naming the setting, no FEM, no samples folder."""
    from designlab.errors import ParameterError

    with pytest.raises(ParameterError, match="finger_model='solid'.*'winkler' with --samples"):
        mc.fem_stage(ArchStrap(), {"finger_model": "solid"}, None, FEMCache(tmp_path / "fem"))
    assert not (tmp_path / "fem").exists() or not any((tmp_path / "fem").iterdir())
