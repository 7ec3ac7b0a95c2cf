"""The README's figure and measured numbers come from ``scripts/readme_figures.py``: the
committed figure is what the script draws, and the README's main-job table and the flexure's
column of its measured-numbers table agree with a fresh run within their error bars (slow: it runs
the main job, ``designlab optimize examples/sweep_fingertip_quick.toml``, and ``designlab predict
flexure``). The fingertip and strap columns are checked by the script's full run
(``python scripts/readme_figures.py --check``)."""

from __future__ import annotations

import copy
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rf():
    spec = importlib.util.spec_from_file_location("readme_figures",
                                                  ROOT / "scripts" / "readme_figures.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def readme():
    return (ROOT / "README.md").read_text(encoding="utf-8")


def _from_readme(rf, readme):
    """Results equal to the README's own main-job table (bars as printed)."""
    import re

    block = rf.BLOCK.search(readme).group(2)
    n = rf.NUM
    designs = []
    for h, r, g1, g1b, c, cb, mark in re.findall(
            rf"^\| {n} \| {n} \| {n} \| {n} \| {n} \| {n} \| ([^|]*)\|$", block, re.M):
        designs.append({"h": float(h), "r": float(r),
                        "G1": {"value": float(g1), "bar": float(g1b)},
                        "cond": {"value": float(c), "bar": float(cb)},
                        "chosen": mark.strip() == "chosen", "not_distinguishable": False})
    return {"main_job": {"designs": designs}}


def test_half_unit_and_agreement(rf):
    assert rf._half_unit("9166") == 0.5
    assert rf._half_unit("0.0092") == pytest.approx(5e-5)
    assert rf._half_unit("7.8e-06") == pytest.approx(5e-8)
    assert rf.agrees("9166", 9165.8, 0.0) and not rf.agrees("9166", 9165.4, 0.0)
    assert rf.agrees("8.47", 8.9, 0.63)          # within the mesh error bar
    assert not rf.agrees("8.47", 9.2, 0.63)


def test_readme_has_the_main_job_table_and_agrees_with_itself(rf, readme):
    res = _from_readme(rf, readme)
    assert len(res["main_job"]["designs"]) == 4
    assert sum(d["chosen"] for d in res["main_job"]["designs"]) == 1
    assert rf.check(readme, res) == []


def test_a_number_off_by_more_than_its_bar_is_named(rf, readme):
    res = _from_readme(rf, readme)
    bad = copy.deepcopy(res)
    d = next(d for d in bad["main_job"]["designs"] if d["chosen"])
    d["G1"]["value"] += 10 * max(d["G1"]["bar"], 1e-4)
    errors = rf.check(readme, bad)
    assert len(errors) == 1 and "G1 hysteresis" in errors[0], errors
    flipped = copy.deepcopy(res)
    for d in flipped["main_job"]["designs"]:
        d["chosen"] = not d["chosen"]
    assert any("chosen" in e for e in rf.check(readme, flipped))
    assert rf.check("no block here", res)[0].startswith("README has no main-job block")


def test_prediction_table_is_parsed(rf, readme):
    """The flexure column as printed agrees with itself, and a moved K_f entry is named."""
    cells = rf._table_row(readme, "other")
    kf = [float(x) for x in cells[2].split("K_f diagonal ")[1].split(" (")[0].split(",")]
    cond = float(rf._table_row(readme, "condition number")[2].split()[0])
    res = {"flexure": {"condition_number": {"value": cond, "bar": 0.0},
                       "hysteresis": {"value": 0.0, "bar": 0.0}, "K_f_diagonal": kf}}
    assert rf.check(readme, res) == []
    res["flexure"]["K_f_diagonal"][3] *= 1.01
    assert ["flexure K_f[3,3]" in e for e in rf.check(readme, res)] == [True]


def test_the_committed_figure_is_the_one_the_script_draws(rf, tmp_path):
    from PIL import Image

    fresh = np.asarray(Image.open(rf.fingertip_figure(tmp_path / "f.png")).convert("RGB"), float)
    committed = np.asarray(Image.open(rf.FIGURE).convert("RGB"), float)
    assert fresh.shape == committed.shape
    assert np.abs(fresh - committed).mean() < 1.0, \
        "run: python scripts/readme_figures.py --only figure"
    assert "docs/img/fingertip_loads.png" in (ROOT / "README.md").read_text(encoding="utf-8")


@pytest.mark.slow
def test_readme_agrees_with_a_fresh_main_job_and_flexure(rf, readme):
    results = rf.measure(["main-job", "flexure"])
    assert len(results["main_job"]["designs"]) == 4
    assert rf.check(readme, results) == []
