"""End-to-end ``predict fingertip`` (CAD -> mesh -> FEM -> full G1 + G2 protocol, six rotations)
for the default design, with the time split by stage. Goal: under 60 s on a 2-core machine.

    OMP_NUM_THREADS=2 python benchmarks/bench_predict.py [edge_length_mm ...]
"""

import sys
import time

from designlab.sensors.predict import predict


def main(edges) -> None:
    print(f"{'edge mm':>8} {'dofs':>8} {'cad':>6} {'mesh':>6} {'assem':>6} {'solve':>6} "
          f"{'metric':>6} {'total':>7} {'wall':>7}  cond   hyst%")
    for e in edges:
        t0 = time.perf_counter()
        pred = predict("fingertip", {}, settings={"edge_length": e}).to_json()
        wall = time.perf_counter() - t0
        ts = pred["timings_s"]
        print(f"{e:8.2f} {pred['mesh']['dofs']:8d} {ts['cad']:6.2f} {ts['mesh']:6.2f} "
              f"{ts['assemble']:6.2f} {ts['solve']:6.2f} {ts['metrics']:6.2f} {ts['total']:7.2f} "
              f"{wall:7.2f}  {pred['condition_number']:.2f}  "
              f"{pred['hysteresis_percent']['overall']:.4f}", flush=True)


if __name__ == "__main__":
    main([float(x) for x in sys.argv[1:]] or [2.5])
