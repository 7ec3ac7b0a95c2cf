"""Optimisers against evaluations on a problem where every design changes the FEM: the load cell
(examples/sensors/load_cell.py) over its thickness, width and gauge position, maximising the
sensitivity norm with the safety factor at least 4 (coarse mesh, edge length 3 mm).

Methods: a Latin hypercube (the sweep, ``--budget`` designs), today's surrogate (a Latin
hypercube of half the budget, a radial-basis surrogate over it, its optimum evaluated) and two
Optuna samplers (TPE and NSGA-II, asked one trial at a time), each over ``--seeds`` seeds. For
every run: the best feasible sensitivity after n evaluations; per sampler, the evaluations it
needs to reach the Latin hypercube's best at ``--budget`` designs (same seed), median over seeds.
Writes ``--json`` (every curve) and the plot ``--plot`` (median best-so-far against evaluations).

    OMP_NUM_THREADS=1 python benchmarks/bench_optimizers.py [--seeds 3] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import statistics
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = {"part": str(ROOT / "examples" / "sensors" / "load_cell.py"),
          "parameters": {"thickness": [2.0, 8.0], "width": [6.0, 20.0],
                         "gauge_at": [4.0, 40.0]},
          "settings": {"model": {"edge_length": 3.0}},
          "objectives": {"sensitivity_norm": "max"},
          "constraints": {"min_safety_factor": {"min": 4.0}}}
METHODS = ("lhs", "surrogate", "tpe", "nsga2")


def curve(rows, cfg) -> list[float]:
    """Best feasible sensitivity norm after n evaluations (NaN before a feasible design)."""
    from designlab.optimize.study import best_so_far

    return [-v if v != float("inf") else float("nan") for v in best_so_far(rows, cfg)]


def run(job: tuple[str, int, int, str]) -> dict:
    """One method and seed in its own store; designs evaluated in this process, in order."""
    method, seed, budget, root = job
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.space import sweep_config

    out = Path(root) / f"{method}-{seed}"
    ex = LocalExecutor(1)
    if method == "lhs":
        from designlab.optimize.sweep import run_sweep

        cfg = sweep_config({**CONFIG, "method": "lhs", "samples": budget, "seed": seed})
        rows = run_sweep(cfg, out, executor=ex).rows
    elif method == "surrogate":
        from designlab.optimize.optimizer import optimize

        cfg = sweep_config({**CONFIG, "method": "lhs", "samples": budget // 2, "seed": seed})
        res = optimize(cfg, out, method="surrogate", executor=ex, seed=seed)
        rows = [*res.sweep.rows, res.chosen]        # the surrogate's optimum: one evaluation
    else:
        from designlab.optimize.study import run_study

        cfg = sweep_config({**CONFIG, "seed": seed})
        rows = run_study(cfg, out, method, trials=budget * 5 // 8, batch=1, executor=ex,
                         seed=seed).sweep.rows
    return {"method": method, "seed": seed, "best": curve(rows, cfg)}


def to_reach(best: list[float], target: float) -> int | None:
    """Evaluations until the best reaches ``target`` (None: not within the run)."""
    return next((i + 1 for i, v in enumerate(best) if v == v and v >= target), None)


def summary(runs: list[dict], budget: int) -> list[dict]:
    """Per method: median best at a few budgets and median evaluations to reach the Latin
    hypercube's best at ``budget`` (same seed; a run that does not reach it counts as
    beyond its length)."""
    lhs = {r["seed"]: r["best"][budget - 1] for r in runs if r["method"] == "lhs"}
    out = []
    for m in METHODS:
        rs = [r for r in runs if r["method"] == m]
        reach = [to_reach(r["best"], lhs[r["seed"]]) or len(r["best"]) + 1 for r in rs]
        at = {n: statistics.median(r["best"][min(n, len(r["best"])) - 1] for r in rs)
              for n in (8, 16, 32, 64)}
        out.append({"method": m, "evaluations": max(len(r["best"]) for r in rs),
                    "median_best_at": at, "to_reach_lhs_best": reach,
                    "median_to_reach": statistics.median(reach),
                    "reached_in_all": all(n <= len(r["best"]) for n, r in zip(reach, rs))})
    return out


def plot(runs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for m in METHODS:
        curves = [r["best"] for r in runs if r["method"] == m]
        n = min(len(c) for c in curves)
        med = np.nanmedian(np.array([c[:n] for c in curves], float), axis=0)
        ax.plot(np.arange(1, n + 1), med, label=f"{m} (median of {len(curves)} seeds)")
    ax.set_xlabel("evaluations (FEM designs)")
    ax.set_ylabel("best feasible sensitivity norm")
    ax.set_title("load cell: max sensitivity, safety factor >= 4")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--budget", type=int, default=64)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results"
                    / "bench_optimizers.json")
    ap.add_argument("--plot", type=Path, default=ROOT / "docs" / "img" / "bench_optimizers.png")
    ap.add_argument("--one", nargs=3, metavar=("METHOD", "SEED", "DIR"),
                    help="run one method and seed, its curve into DIR (used by the others)")
    a = ap.parse_args()
    if a.one:
        method, seed, root = a.one
        doc = run((method, int(seed), a.budget, root))
        (Path(root) / f"{method}-{seed}.json").write_text(json.dumps(doc))
        return
    with tempfile.TemporaryDirectory() as root:
        jobs = [(m, s) for m in METHODS for s in range(a.seeds)]
        with ThreadPoolExecutor(a.jobs) as pool:     # each run in its own process
            list(pool.map(lambda j: subprocess.run(
                [sys.executable, __file__, "--budget", str(a.budget), "--one", j[0],
                 str(j[1]), root], check=True), jobs))
        runs = [json.loads((Path(root) / f"{m}-{s}.json").read_text()) for m, s in jobs]
    rows = summary(runs, a.budget)
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps({"config": CONFIG | {"part": "examples/sensors/load_cell.py"},
                                  "budget": a.budget, "summary": rows, "runs": runs}, indent=1))
    plot(runs, a.plot)
    print(f"{'method':10} {'evals':>5} " + " ".join(f"{'best@' + str(n):>9}" for n in
                                                    (8, 16, 32, 64))
          + f" {'to reach LHS@' + str(a.budget):>16}  per seed")
    for r in rows:
        print(f"{r['method']:10} {r['evaluations']:5d} "
              + " ".join(f"{v:9.4f}" for v in r["median_best_at"].values())
              + f" {r['median_to_reach']:16g}  {r['to_reach_lhs_best']}")
    print(f"-> {a.json}, {a.plot}")


if __name__ == "__main__":
    main()
