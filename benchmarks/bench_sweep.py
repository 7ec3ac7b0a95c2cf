"""Sweep throughput: designs per minute with 1 and 2 local workers, and the cached re-run.

    python benchmarks/bench_sweep.py [designs]

Uses the fingertip (h, r) grid of examples/sweep_fingertip_quick.toml (coarse mesh) so each
design is a full CAD -> mesh -> viscoelastic FEM -> protocol prediction.
"""

import sys
import tempfile
import time
from pathlib import Path

from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep

CONFIG = Path(__file__).resolve().parents[1] / "examples" / "sweep_fingertip_quick.toml"


def main(n: int) -> None:
    import tomllib

    data = tomllib.loads(CONFIG.read_text())
    levels = max(2, round(n ** 0.5))
    data["parameters"] = {"h": {"range": [0.0, 6.0], "levels": levels},
                          "r": {"range": [6.0, 9.0], "levels": levels}}
    cfg = sweep_config(data)
    n = len(cfg.designs())
    print(f"{n} designs of {CONFIG.name} ({levels} x {levels} grid)")
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            res = run_sweep(cfg, d, executor=LocalExecutor(workers))
            wall = time.perf_counter() - t0
            print(f"workers={workers}: {wall:7.1f} s, {60 * n / wall:5.2f} designs/min, "
                  f"{res.failed} failed", flush=True)
            t0 = time.perf_counter()
            again = run_sweep(cfg, d, executor=LocalExecutor(workers))
            print(f"  cached re-run: {time.perf_counter() - t0:.2f} s "
                  f"({again.reused} reused, {again.new} new)", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
