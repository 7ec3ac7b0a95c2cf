"""The loop on the real stretch logs: fit on multisine_600s_1, validate on multisine_300s_2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from designlab.loop.base_models import specimen_stiffness_factor
from designlab.measured.dataset import load_card
from designlab.loop.loop import run_loop

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / "examples" / "stretch_card.toml"


@pytest.fixture(scope="module")
def stretch(shared):
    return load_card(CARD)


@pytest.fixture(scope="module")
def result(stretch):
    return run_loop(stretch, "stretch-fem")


def test_card_reads_train_and_validate(stretch):
    assert [s["role"] for s in stretch.segments] == ["train", "validate"]
    assert stretch.report["repaired_total"]["displacement"] >= 172 + 77
    assert stretch.dt == pytest.approx(0.1)


def test_specimen_base_is_physical(result):
    f = result.model.base.parameters["force"]
    r = result.model.base.parameters["resistance"]
    # silicone + carbon black: E of a few tenths of a MPa; FEM grips stiffen E A / L by a few %
    assert 0.1 < f["E_MPa"] < 1.0
    assert 1.0 < f["stiffness_factor"] < 1.1
    assert 800 < r["R0_ohm"] < 2000 and 1 < r["GF"] < 10


def test_stiffness_factor_converges_to_closed_form_for_a_slender_free_bar():
    # nu -> 0: the grips no longer resist lateral contraction, k -> E A / L
    assert specimen_stiffness_factor(40.0, 10.0, 4.0, 0.0, (8, 2, 1)) == pytest.approx(1.0,
                                                                                       abs=1e-6)


def test_force_improves_on_held_out_run(result):
    """The issue's force goal (<= 0.110 N on multisine_300s_2): relaxation first, then
    rate-independent hysteresis refitted jointly with it (0.1609 -> 0.1085 N measured)."""
    force = result.report["outputs"]["force"]
    assert force["effects"], force["verdict"]
    assert [e["name"] for e in force["effects"]][:2] == ["relaxation", "hysteresis"]
    assert force["effects"][1]["refitted_with_it"] == ["relaxation[displacement]"]
    assert force["error_after"] <= 0.110
    assert force["validation"]["runs"][0].endswith("multisine_300s_2.csv")


def test_resistance_goal_with_a_named_effect(result):
    """The resistance goal: <= 0.7x the base's error with a named physical effect, within 1.3x
    of the best peer (204.3 -> 131.3 ohm with one mPL cell; best peer NARX 165.4 ohm, trees
    200.4 ohm, measured)."""
    res = result.report["outputs"]["resistance"]
    assert res["effects"], res["verdict"]
    assert res["error_after"] <= 0.7 * res["error_before"]
    assert 0 < res["unexplained_fraction"] < 1
    assert res["residual_correlations"] and res["verdict"]
    assert res["peer"]["kind"] == "narx" and res["best_peer"] in ("narx", "gbt")
    assert res["error_after"] <= 1.3 * res["peer"]["error"]
    best = next(p for p in res["peers"] if p["kind"] == res["best_peer"])
    assert res["error_after"] <= 1.3 * best["error"]
    # no peer does better, but what remains is far above the noise floor and not white
    # (131.3 ohm, 8.6x the 15.2 ohm floor, lag-1 autocorrelation 0.98, measured)
    assert res["noise_floor"]["ratio_after"] > 1.5
    assert res["noise_floor"]["residual_lag1_autocorrelation"] > 0.5
    assert res["verdict_kind"] == "missing mechanism"
    # the verdict names what the residual correlates with and why no further library effect
    # is taken (the best remaining candidate's held-out gain is within noise)
    top = res["residual_correlations"][0]["variable"]
    assert f"correlates most with {top}" in res["verdict"]
    assert "no candidate lowers the held-out error by more than noise (best: " in res["verdict"]


def test_force_beside_the_peer(result):
    force = result.report["outputs"]["force"]
    assert force["peer"]["error"] > 0 and len(force["peers"]) == 2
    assert force["error_after"] <= 1.3 * force["peer"]["error"]
    # 0.1085 N is 8.6x the 0.0126 N noise floor (measured): structure remains
    assert force["verdict_kind"] == "missing mechanism"


@pytest.mark.slow
def test_two_runs_find_the_resistance_hysteresis(shared):
    """Selection across two runs of the specimen (leave-one-run-out): rate-independent
    hysteresis of the resistance carries over from the multisine to the sawtooth and back, and
    cuts the error on the third run by 30 %, level with the NARX
    peer."""
    ds = load_card(ROOT / "examples" / "stretch_runs_card.toml")
    res = run_loop(ds, "stretch-fem", outputs=["resistance"])
    assert res.report["selection"]["cv"] == "leave-one-run-out"
    out = res.report["outputs"]["resistance"]
    assert out["effects"] and out["effects"][0]["name"] == "hysteresis", out["verdict"]
    assert out["effects"][0]["evidence"]["cv"]["blocks_improved"] == 2
    assert out["error_after"] <= 0.7 * out["error_before"]
    assert out["error_after"] <= 1.3 * out["peer"]["error"]
    assert out["verdict_kind"] == "missing mechanism" and out["explained_of_learnable"] > 0.9


def _cli(base: str, out: Path) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "designlab.cli", "loop", "--data", str(CARD), "--base", base,
           "--out", str(out), "--output", "force"]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                          env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})


@pytest.mark.slow
def test_cli_loop_writes_outputs_and_continues(shared, tmp_path):
    out = tmp_path / "loop"
    run = _cli("stretch-fem", out)
    assert run.returncode == 0, run.stderr
    rep = json.loads((out / "loop.json").read_text())
    assert rep["output"] == "force" and rep["metric"] == "rmse"
    assert (out / "model.json").is_file() and (out / "timeseries_force.png").is_file()
    again = _cli(str(out / "model.json"), tmp_path / "l2")
    assert again.returncode == 0, again.stderr
    rep2 = json.loads((tmp_path / "l2" / "loop.json").read_text())
    assert rep2["error_before"] == pytest.approx(rep["error_after"], rel=1e-9)
    bad = _cli("nope", tmp_path / "l3")
    assert bad.returncode == 2 and "--base" in bad.stderr and "\n" not in bad.stderr.strip()
    assert not (tmp_path / "l3").exists()
