"""``designlab strap-sizes`` end to end: 5 sizes for 1000 fingers drawn from the shipped table
(all adults), in a fresh process, wall and CPU time (goal: under 2 minutes), with the time of
``--sizes auto``'s search alone.

    OMP_NUM_THREADS=1 python benchmarks/bench_strap_sizes.py [--population all|men|women]

The CLI's run: the drawn fingers, the sizes, a static FEM per size (5) and one of the paper's
strap, the prestrain factors per finger, the 3MF of each size, sizes.json and sizes.md.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

GOAL_S = 120.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--population", default="all")
    ap.add_argument("--fingers", type=int, default=1000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "designlab.cli", "strap-sizes", "--population",
               args.population, "--sizes", "5", "--fingers", str(args.fingers),
               "--out", os.path.join(d, "sizes")]
        t0 = time.perf_counter()
        r0 = os.times()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        r1 = os.times()
        cpu = (r1.children_user - r0.children_user) + (r1.children_system - r0.children_system)
        if proc.returncode:
            sys.exit(f"strap-sizes failed ({proc.returncode}): {proc.stderr.strip()}")
    from designlab.sensors.strap import population as pp, sizes as sz
    from designlab.sensors.strap.fit import default_target

    import designlab.geometry.strap  # noqa: F401  (the CAD import, not the search)

    pop = pp.draw(args.population, args.fingers, 0)
    t1 = time.perf_counter()
    n, tried = sz.auto_count(pop, default_target())
    auto = time.perf_counter() - t1
    load = os.getloadavg()[0]
    print(f"strap-sizes --sizes 5 --fingers {args.fingers} --population {args.population}: "
          f"{wall:.1f} s wall, {cpu:.1f} s CPU (load {load:.1f}); goal < {GOAL_S:g} s: "
          f"{'met' if wall < GOAL_S else 'missed'}")
    print(f"--sizes auto search: {n} sizes ({100 * tried[-1]['share_within_goal']:.1f} % within "
          f"the {sz.GOAL_SPREAD_PERCENT:g} % spread) in {auto:.2f} s")


if __name__ == "__main__":
    main()
