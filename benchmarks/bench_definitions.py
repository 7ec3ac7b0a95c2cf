"""Sensor definitions at speed: ``designlab predict`` of the printed six-axis F/T sensor (about 50k
DOF at its default mesh) against ``designlab predict fingertip`` in the same run, in pairs
(goal: at most twice the fingertip's wall time, median of the pairs), and a sweep of the load
cell whose every design changes the FEM (goal: at least 10 designs per minute).

    OMP_NUM_THREADS=1 python benchmarks/bench_definitions.py [--pairs 3] [--designs 12]

Each command runs in a fresh process (``python -m designlab.cli``); wall and CPU (user + sys of
the process tree) are measured around it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FT = ROOT / "examples" / "sensors" / "printed_ft.py"
LOAD_CELL = ROOT / "examples" / "sensors" / "load_cell.py"
GOAL_RATIO = 2.0
GOAL_DESIGNS_PER_MIN = 10.0


def timed(args: list[str]) -> tuple[float, float]:
    """(wall s, CPU s of the process tree) of ``designlab ARGS``."""
    t0, r0 = time.perf_counter(), os.times()
    proc = subprocess.run([sys.executable, "-m", "designlab.cli", *args], capture_output=True,
                          text=True, cwd=ROOT)
    wall, r1 = time.perf_counter() - t0, os.times()
    if proc.returncode:
        sys.exit(f"designlab {' '.join(args)} failed ({proc.returncode}): "
                 f"{proc.stderr.strip()[-300:]}")
    return wall, (r1.children_user - r0.children_user) + (r1.children_system - r0.children_system)


def predict_pairs(pairs: int, tmp: Path) -> None:
    rows = []
    for i in range(pairs):
        ft = timed(["predict", str(FT), "--out", str(tmp / f"ft{i}")])
        tip = timed(["predict", "fingertip", "--out", str(tmp / f"tip{i}")])
        rows.append((ft, tip))
        print(f"pair {i + 1}: printed F/T {ft[0]:.1f} s wall ({ft[1]:.1f} s CPU), fingertip "
              f"{tip[0]:.1f} s wall ({tip[1]:.1f} s CPU): ratio {ft[0] / tip[0]:.2f} wall, "
              f"{ft[1] / tip[1]:.2f} CPU", flush=True)
    wall = statistics.median(a[0] / b[0] for a, b in rows)
    cpu = statistics.median(a[1] / b[1] for a, b in rows)
    print(f"predict printed F/T / predict fingertip, median of {pairs} pairs: {wall:.2f} wall, "
          f"{cpu:.2f} CPU (goal: <= {GOAL_RATIO:g} wall)")


def sweep_rate(designs: int, tmp: Path) -> None:
    cfg = tmp / "sweep.toml"
    cfg.write_text(f'part = "{LOAD_CELL}"\nmethod = "lhs"\nsamples = {designs}\nseed = 1\n'
                   "[parameters]\nthickness = [3.0, 6.0]\nwidth = [8.0, 16.0]\n"
                   "[objectives]\nsensitivity_norm = \"max\"\n")
    wall, cpu = timed(["sweep", str(cfg), "--out", str(tmp / "sweep")])
    rate = designs / wall * 60.0
    print(f"sweep of {designs} load cell designs (every one a new mesh and FEM): {wall:.1f} s "
          f"wall, {cpu:.1f} s CPU, {rate:.1f} designs per minute (goal: >= "
          f"{GOAL_DESIGNS_PER_MIN:g})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--designs", type=int, default=12)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        predict_pairs(args.pairs, Path(d))
        sweep_rate(args.designs, Path(d))


if __name__ == "__main__":
    main()
