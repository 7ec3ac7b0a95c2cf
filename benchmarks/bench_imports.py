"""Import cost on the command's path, each case in fresh interpreters, alternating with its peer
(so a drift of the machine's speed hits both), CPU seconds of the child (user + sys):

- ``import build123d`` with sympy put off (``designlab.geometry._lazy``, what designlab does)
  vs with sympy imported first (the stand-in then does nothing: build123d's own import);
- ``import vtk`` after ``import pyvista.plotting``, timed inside the interpreter (what
  ``import vtk`` adds beyond pyvista's modules: the renders import the VTK classes from their
  own modules instead).

    python benchmarks/bench_imports.py [--pairs 8]
"""

import argparse
import resource
import statistics
import subprocess
import sys

CASES = {
    "build123d, sympy put off": "import designlab.geometry, build123d",
    "build123d, sympy imported (peer)": "import sympy, designlab.geometry, build123d",
}
PAIRS = (("build123d, sympy put off", "build123d, sympy imported (peer)"),)
VTK = ("import time, pyvista.plotting; t = time.process_time(); import vtk; "
       "print(time.process_time() - t)")


def cpu_of(code: str) -> float:
    """CPU seconds (user + sys) of a fresh interpreter running ``code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=8, help="alternating pairs per comparison")
    n = ap.parse_args().pairs
    for ours, peer in PAIRS:
        cpu_of(CASES[ours]), cpu_of(CASES[peer])            # warm the file cache
        a, b = [], []
        for _ in range(n):
            a.append(cpu_of(CASES[ours]))
            b.append(cpu_of(CASES[peer]))
        ratio = [x / y for x, y in zip(a, b)]
        print(f"{ours:38s} {statistics.median(a):6.2f} s CPU (median of {n})")
        print(f"{peer:38s} {statistics.median(b):6.2f} s CPU")
        print(f"{'ratio, pair by pair':38s} {statistics.median(ratio):6.3f} "
              f"({min(ratio):.3f}-{max(ratio):.3f})\n")
    extra = [float(subprocess.run([sys.executable, "-c", VTK], check=True, capture_output=True,
                                  text=True).stdout) for _ in range(n)]
    print(f"{'import vtk after pyvista.plotting':38s} {statistics.median(extra):6.2f} s CPU "
          f"(median of {n}, {min(extra):.2f}-{max(extra):.2f})")


if __name__ == "__main__":
    main()
