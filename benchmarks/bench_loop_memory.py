"""Memory of `designlab loop` on a long run: peak resident set and CPU time of the command.

The data (written to a temporary folder, about 29 MB for the default 1 000 000 samples):
t in 1 ms steps, displacement P = 1 + sin t (mm), force F = 2 + 3 P + 0.05 N(0, 1) (N, seed 0);
one run, the loop's default settings, at most two effects (`--max-effects 2`), NARX peer on.

    python benchmarks/bench_loop_memory.py [N_SAMPLES]

prints the command's peak RSS (MB) and CPU seconds (user + system) of the child process, and
the loop's memory budget as loop.json reports it (the fits on at most
``designlab.loop.loop.FIT_SAMPLES`` training samples, decimated beyond; the NARX peer on at most
``PEER_ROWS`` rows; validation on every held-out sample). The README's Limits line quotes it.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CARD = """
[[files]]
path = "run.csv"
[time]
column = "t"
[inputs]
displacement = { column = "P", unit = "mm" }
[outputs]
force = { column = "F", unit = "N" }
"""


def write_case(folder: Path, n: int) -> Path:
    t = np.arange(n) * 1e-3
    P = 1.0 + np.sin(t)
    F = 2.0 + 3.0 * P + 0.05 * np.random.default_rng(0).standard_normal(n)
    np.savetxt(folder / "run.csv", np.column_stack([t, P, F]), delimiter=",",
               header="t,P,F", comments="", fmt="%.6f")
    (folder / "card.toml").write_text(CARD)
    return folder / "card.toml"


def main(n: int = 1_000_000) -> None:
    exe = Path(sys.executable).with_name("designlab")
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        card = write_case(folder, n)
        size = (folder / "run.csv").stat().st_size / 1e6
        t0 = time.perf_counter()
        rc = subprocess.run([str(exe), "loop", "--data", str(card), "--out", str(folder / "o"),
                             "--max-effects", "2"], capture_output=True, text=True).returncode
        wall = time.perf_counter() - t0
        report = folder / "o" / "loop.json"
        budget = json.loads(report.read_text()).get("budget") if report.is_file() else None
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"loop on {n} samples ({size:.0f} MB CSV): exit {rc}, peak RSS "
          f"{ru.ru_maxrss / 1024:.0f} MB, CPU {ru.ru_utime + ru.ru_stime:.0f} s, wall {wall:.0f} s")
    if budget:
        print(f"budget: {budget['train_samples']} training samples, fits on "
              f"{budget['fit_samples']} (decimation {budget['decimation']}), validation on "
              f"{budget['validation_samples']}, NARX peer on at most {budget['peer_rows']} rows")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000)
