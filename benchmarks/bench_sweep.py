"""Sweep throughput of the README's main job: fingertip (h, r) designs per minute.

    OMP_NUM_THREADS=1 python benchmarks/bench_sweep.py [designs] [--no-peer]

Ours: the sweep as shipped (gmsh mesh, one FEM per distinct model kept in OUT/fem and shared
by every (h, r) design, mesh-convergence check included). It reports the first design (which
computes the FEM at both mesh levels) and the rate of the others once the FEM is cached, with
1 and 2 local workers; then the cached re-run. Peer in the same run: the previous pipeline,
every design meshed with fTetWild and solved again (``mesher = "tetwild"``, no FEM reuse),
on 2 designs with 2 workers. Settings as examples/sweep_fingertip_quick.toml.

Besides the wall-clock rate it prints the CPU time per design (this process and its finished
worker processes, ``getrusage``): on a shared machine the wall rate depends on the other load,
the CPU per design does not; ``60 * workers / cpu_per_design`` is the rate with idle cores.
The printability check casts its rays with Embree where ``embreex`` is installed (VTK
otherwise); the line ``rays:`` says which ran.
"""

import resource
import sys
import tempfile
import time
from pathlib import Path

from designlab.fem.cache import clear_memory
from designlab.optimize.evaluate import evaluate_design
from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep

CONFIG = Path(__file__).resolve().parents[1] / "examples" / "sweep_fingertip_quick.toml"


def _config(levels_h: int, levels_r: int, model: dict | None = None, offset: float = 0.0):
    import tomllib

    data = tomllib.loads(CONFIG.read_text())
    # h >= 3 mm: every design has the Table II load points (a lower 6 mm radius one fails fast
    # and would flatter the rate); h and r move only the load points, so one FEM serves all
    data["parameters"] = {"h": {"range": [3.0 + offset, 9.0 + offset], "levels": levels_h},
                          "r": {"range": [6.0, 9.0], "levels": levels_r}}
    if model:
        data["settings"]["model"] = {**data["settings"]["model"], **model}
    return sweep_config(data)


def _no_reuse(task):
    """The previous pipeline: every design meshes and solves its own FEM."""
    clear_memory()
    return evaluate_design({**task, "fem_cache": None})


def _cpu() -> float:
    """CPU seconds of this process and of its reaped children (the pool's workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main(n: int, peer: bool) -> None:
    from designlab.geometry.printability import ray_backend

    print(f"rays: {ray_backend()}", flush=True)
    side = max(2, round(n ** 0.5))
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            run_sweep(_config(1, 1), d, executor=LocalExecutor(1))
            first = time.perf_counter() - t0
            cfg = _config(side, side, offset=0.5)      # other designs, the same FEM
            t0, c0 = time.perf_counter(), _cpu()
            res = run_sweep(cfg, d, executor=LocalExecutor(workers))
            wall, cpu = time.perf_counter() - t0, _cpu() - c0
            m = len(cfg.designs())
            print(f"ours, workers={workers}: first design {first:6.1f} s (FEM at 2 mesh levels); "
                  f"then {m} designs in {wall:6.1f} s = {60 * m / wall:6.1f} designs/min, "
                  f"{res.failed} failed; CPU {cpu / m:5.2f} s per design (worker start-up "
                  f"included) = {60 * workers * m / cpu:6.1f} designs/min on {workers} idle "
                  f"core(s)", flush=True)
            t0 = time.perf_counter()
            again = run_sweep(cfg, d, executor=LocalExecutor(workers))
            print(f"  cached re-run: {time.perf_counter() - t0:.2f} s ({again.reused} reused)",
                  flush=True)
    if peer:
        cfg = _config(2, 1, model={"mesher": "tetwild"})
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            res = run_sweep(cfg, d, executor=LocalExecutor(2), evaluator=_no_reuse)
            wall = time.perf_counter() - t0
            m = len(cfg.designs())
            print(f"peer (fTetWild, every design re-solved), workers=2: {m} designs in "
                  f"{wall:6.1f} s = {60 * m / wall:6.2f} designs/min, {res.failed} failed",
                  flush=True)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(int(args[0]) if args else 16, "--no-peer" not in sys.argv)
