import subprocess
import sys
import textwrap
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from designlab.errors import ParameterError
from designlab.optimize.executors import DaskExecutor, LocalExecutor
from designlab.optimize.pareto import non_dominated
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep
from sweep_fixtures import quadratic

CFG = {"part": "fingertip", "method": "grid",
       "parameters": {"h": {"range": [0.0, 4.0], "levels": 3}, "r": {"values": [6.0, 8.0]}},
       "objectives": {"condition_number": "min", "printed_volume_mm3": "min"},
       "constraints": {"printable": True}}


def test_grid_lhs_sobol_designs():
    c = sweep_config(CFG)
    d = c.designs()
    assert len(d) == 6 and {x["h"] for x in d} == {0.0, 2.0, 4.0}
    lhs = sweep_config({**CFG, "method": "lhs", "samples": 7,
                        "parameters": {"h": [0.0, 4.0], "r": [6.0, 9.0]}}).designs()
    assert len(lhs) == 7 and all(0 <= x["h"] <= 4 and 6 <= x["r"] <= 9 for x in lhs)
    # Latin hypercube: one sample per stratum in each dimension
    assert len({int(x["h"] / 4 * 7) for x in lhs}) == 7
    sob = sweep_config({**CFG, "method": "sobol", "samples": 5,
                        "parameters": {"h": [0.0, 4.0]}}).designs()
    assert len(sob) == 8


@pytest.mark.parametrize("bad, name", [({"part": "wing"}, "part"), ({"method": "random"}, "method"),
                                       ({"parameters": {}}, "parameters"),
                                       ({"parameters": {"h": [3, 1]}}, "parameters.h.range"),
                                       ({"objectives": {"x": "smallest"}}, "objectives.x"),
                                       ({"fixed": {"h": 1.0}}, "fixed.h"),
                                       ({"colour": 1}, "colour"),
                                       # every metric is one number: a list target ranked
                                       # designs by a distance to no value the user asked for
                                       ({"objectives": {"condition_number": {"target": [2, 6]}}},
                                        "objectives.condition_number.target"),
                                       ({"objectives": {"condition_number": {"target": 1e308}}},
                                        "objectives.condition_number.target"),
                                       ({"objectives": {"condition_number": {"target": -2e9}}},
                                        "objectives.condition_number.target")])
def test_bad_configs(bad, name):
    with pytest.raises(ParameterError) as e:
        sweep_config({**CFG, **bad})
    assert e.value.name == name


def test_a_target_picks_the_design_nearest_to_it(tmp_path):
    """``{target = x}`` ranks designs by |value - x|: the design whose condition number is the
    target is chosen, at the largest target allowed too."""
    from designlab.optimize.space import MAX_TARGET

    cfg = {"part": "fingertip", "method": "grid", "fixed": {"r": 7.0},
           "parameters": {"h": {"values": [0.0, 1.0, 2.0, 3.0]}}}
    # condition number 1 + (h - 2)^2 + 1: 6, 3, 2, 3; the farthest target: the largest value
    for target, chosen in ((2.0, 2.0), (6.0, 6.0), (MAX_TARGET, 6.0)):
        c = sweep_config({**cfg, "objectives": {"condition_number": {"target": target}}})
        res = run_sweep(c, tmp_path / str(target), evaluator=quadratic,
                        executor=LocalExecutor(1))
        best = next(r for r in res.rows if r["key"] == res.best_key)
        assert best["condition_number"] == chosen


def test_pareto_mask():
    F = np.array([[1, 5], [2, 2], [3, 3], [5, 1], [np.nan, 0]])
    assert non_dominated(F).tolist() == [True, True, False, True, False]


def test_sweep_records_failures_caches_and_resumes(tmp_path):
    c = sweep_config(CFG)
    r1 = run_sweep(c, tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    assert r1.new == 6 and r1.failed == 2
    errs = [r for r in r1.rows if r["status"] == "error"]
    assert all("deliberately failing" in r["error"] for r in errs)
    best = next(r for r in r1.rows if r["key"] == r1.best_key)
    assert best["status"] == "ok" and best["feasible"]
    table = pq.read_table(tmp_path / "results.parquet")
    assert table.num_rows == 6 and len(set(table.column("key").to_pylist())) == 6
    r2 = run_sweep(c, tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    assert r2.new == 0 and r2.reused == 6
    assert [r["key"] for r in r2.rows] == [r["key"] for r in r1.rows]


@pytest.mark.slow
def test_process_pool_and_dask_give_identical_results(tmp_path):
    from distributed import LocalCluster

    c = sweep_config(CFG)
    local = run_sweep(c, tmp_path / "a", evaluator=quadratic, executor=LocalExecutor(2))
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                      dashboard_address=None) as cluster:
        dask = run_sweep(c, tmp_path / "b", evaluator=quadratic,
                         executor=DaskExecutor(cluster.scheduler_address))
    strip = lambda rows: [{k: v for k, v in r.items() if k != "elapsed_s"} for r in rows]
    assert strip(local.rows) == strip(dask.rows)
    assert local.best_key == dask.best_key and local.pareto_keys == dask.pareto_keys


@pytest.mark.slow
def test_kill_9_then_resume(tmp_path):
    script = textwrap.dedent(f"""
        import sys; sys.path.insert(0, {str(__import__('pathlib').Path(__file__).parents[1])!r})
        from designlab.optimize.space import sweep_config
        from designlab.optimize.sweep import run_sweep
        from designlab.optimize.executors import LocalExecutor
        from sweep_fixtures import slow_quadratic
        cfg = {CFG!r}
        cfg["parameters"] = {{"h": {{"range": [0.0, 3.0], "levels": 4}}, "r": [6.0, 9.0]}}
        run_sweep(sweep_config(cfg), {str(tmp_path)!r}, evaluator=slow_quadratic,
                  executor=LocalExecutor(1))
    """)
    proc = subprocess.Popen([sys.executable, "-c", script])
    rows = tmp_path / "results"
    deadline = time.time() + 60
    while time.time() < deadline and len(list(rows.glob("*.parquet")) if rows.is_dir() else []) < 3:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    n_before = len(list(rows.glob("*.parquet")))
    assert 3 <= n_before < 12
    from sweep_fixtures import slow_quadratic
    cfg = dict(CFG, parameters={"h": {"range": [0.0, 3.0], "levels": 4}, "r": [6.0, 9.0]})
    res = run_sweep(sweep_config(cfg), tmp_path, evaluator=slow_quadratic,
                    executor=LocalExecutor(1))
    assert res.reused >= n_before and res.reused + res.new == 12
    assert not list(tmp_path.rglob("*.tmp"))
    keys = pq.read_table(tmp_path / "results.parquet").column("key").to_pylist()
    assert len(keys) == 12 and len(set(keys)) == 12


def test_surrogate_finds_the_bowl_minimum(tmp_path):
    from designlab.optimize.optimizer import optimize

    cfg = sweep_config({**CFG, "parameters": {"h": {"range": [0.0, 3.0], "levels": 4},
                                              "r": {"range": [6.0, 9.0], "levels": 4}},
                        "objectives": {"condition_number": "min"}})
    res = optimize(cfg, tmp_path, method="surrogate", evaluator=quadratic,
                   executor=LocalExecutor(1))
    assert res.method == "surrogate"
    assert abs(res.chosen_params["h"] - 2.0) < 0.2 and abs(res.chosen_params["r"] - 8.0) < 0.2
    assert res.chosen["condition_number"] < 1.05


def test_de_and_pareto(tmp_path):
    from designlab.optimize.optimizer import optimize

    cfg = sweep_config({**CFG, "parameters": {"h": [0.0, 3.0], "r": [6.0, 9.0]},
                        "objectives": {"condition_number": "min"}})
    res = optimize(cfg, tmp_path / "de", method="de", evaluator=quadratic,
                   executor=LocalExecutor(1), maxiter=8, popsize=5)
    assert res.chosen["condition_number"] < 1.3
    par = optimize(sweep_config(CFG), tmp_path / "p", evaluator=quadratic,
                   executor=LocalExecutor(1))
    assert par.method == "pareto" and par.chosen["key"] in par.sweep.pareto_keys


@pytest.mark.slow
def test_report_writes_plots_and_html(tmp_path):
    from designlab.optimize.report import write_report

    c = sweep_config(CFG)
    r = run_sweep(c, tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    files = write_report(tmp_path, r.rows, c, r.pareto_keys, r.best_key)
    assert files["pareto"].stat().st_size > 1000 and files["sensitivity"].stat().st_size > 1000
    page = files["html"].read_text()
    assert "data:image/png;base64" in page and "deliberately failing" in page


def test_error_bars_and_indistinguishable_designs():
    """Bars: |value - coarse|; a shared FEM compares the difference at both mesh levels, two
    FEMs add their bars; designs within the bar of their difference are ties; an unknown bar
    (NaN) is unknown, not 0."""
    from designlab.optimize.sweep import (compare_to_best, difference_error, error_bar,
                                          indistinguishable)

    cfg = sweep_config({**CFG, "objectives": {"condition_number": "min"}})

    def row(key, v, c, fem, volume=100.0):
        return {"key": key, "status": "ok", "feasible": True, "condition_number": v,
                "mesh_convergence.condition_number.coarse": c, "fem_key": fem,
                "printed_volume_mm3": volume}

    best = row("a", 10.0, 10.5, "F")
    same_fem_close = row("b", 10.1, 10.7, "F")     # d = 0.1, d_coarse = 0.2 -> bar 0.1: tie
    same_fem_far = row("c", 10.3, 10.8, "F")       # d = 0.3, d_coarse = 0.3 -> bar 0: distinct
    other_fem = row("d", 10.8, 10.0, "G")           # d = 0.8, bars 0.5 + 0.8: tie
    exact = {"key": "e", "status": "ok", "feasible": True, "condition_number": 12.0,
             "mesh_convergence": None, "printed_volume_mm3": 100.0}
    no_bar = {"key": "f", "status": "ok", "feasible": True, "condition_number": 10.05,
              "printed_volume_mm3": 100.0}            # no coarse value: its bar is unknown
    assert error_bar(best, "condition_number") == pytest.approx(0.5)
    assert error_bar(exact, "condition_number") == 0.0
    assert np.isnan(error_bar(no_bar, "condition_number"))
    assert error_bar(no_bar, "printed_volume_mm3") == 0.0         # the CAD's: exact
    assert difference_error(same_fem_close, best, "condition_number") == pytest.approx(0.1)
    assert difference_error(same_fem_far, best, "condition_number") == pytest.approx(0.0)
    assert difference_error(other_fem, best, "condition_number") == pytest.approx(1.3)
    assert np.isnan(difference_error(no_bar, best, "condition_number"))
    rows = [best, same_fem_close, same_fem_far, other_fem, exact, no_bar]
    assert compare_to_best(rows, cfg, "a") == (["b", "d"], ["f"])
    assert indistinguishable(rows, cfg, "a") == ["b", "d"]
    # several objectives (Pareto): a tie must be within the bars on all of them; beyond the bar
    # on one (here the exact printed volume) tells the designs apart, even where another's bar
    # is unknown
    pareto = sweep_config(CFG)
    assert list(pareto.objectives) == ["condition_number", "printed_volume_mm3"]
    bigger = row("g", 10.1, 10.7, "F", volume=101.0)          # tie on cond., apart on volume
    unknown_bigger = {**no_bar, "key": "h", "printed_volume_mm3": 120.0}
    rows2 = rows + [bigger, unknown_bigger]
    assert compare_to_best(rows2, pareto, "a") == (["b", "d"], ["f"])
    # a config that turned the error bar off: unknown everywhere, nothing is a tie
    off = sweep_config({**CFG, "objectives": {"condition_number": "min"},
                        "settings": {"model": {"mesh_convergence": False}}})
    assert np.isnan(error_bar(exact, "condition_number", off))
    assert compare_to_best([best, exact, no_bar], off, "a") == ([], ["e", "f"])


def test_unknown_error_bars_are_a_warning_not_a_tie(tmp_path):
    """The analytic evaluator has no mesh error bars: no design is called a tie of the best,
    and the sweep says that the comparison is unknown."""
    c = sweep_config({**CFG, "objectives": {"condition_number": "min"}})
    r = run_sweep(c, tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    ok = [x for x in r.rows if x["status"] == "ok"]
    assert len(ok) == 4 and r.best_key is not None
    assert r.tie_keys == [] and sorted(r.unknown_keys) == sorted(
        x["key"] for x in ok if x["key"] != r.best_key)
    assert any("unknown, not zero" in w for w in r.warnings)


@pytest.mark.slow
def test_optimize_exports_the_row_it_reports(tmp_path):
    """The chosen design's re-prediction (with the sweep's FEM cache) equals its table row."""
    import json

    from designlab.cli import main

    cfg = tmp_path / "s.toml"
    cfg.write_text('part = "fingertip"\nmethod = "grid"\n[parameters]\n'
                   'h = { range = [0.0, 4.0], levels = 2 }\n[fixed]\nr = 9.0\n'
                   '[settings]\nmodel = { edge_length = 4.0, order = 1 }\n'
                   '[objectives]\ncondition_number = "min"\n')
    main(["optimize", str(cfg), "--out", str(tmp_path / "o"), "--workers", "1",
          "--format", "stl", "--method", "pareto"])
    summary = json.loads((tmp_path / "o" / "optimize.json").read_text())
    pred = json.loads((tmp_path / "o" / "chosen" / "prediction" / "prediction.json").read_text())
    assert pred["condition_number"] == summary["chosen"]["condition_number"]
    assert pred["hysteresis_percent"]["overall"] == summary["chosen"]["hysteresis_percent.overall"]
    assert "choice" in summary and isinstance(summary["not_distinguishable"], list)
    # fine + coarse FEM and the paper designs' comparison, each once: a second optimize of the
    # same config adds none
    n_fem = len(list((tmp_path / "o" / "fem").glob("*.npz")))
    assert n_fem >= 2
    main(["optimize", str(cfg), "--out", str(tmp_path / "o"), "--workers", "1",
          "--format", "stl", "--method", "pareto"])
    assert len(list((tmp_path / "o" / "fem").glob("*.npz"))) == n_fem
