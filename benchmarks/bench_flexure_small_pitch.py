"""A small-pitch helix (5 plain coils, pitch angle 0.08 rad, spring index 5) against the
zero-pitch closed form (docs/validation/flexure.md), with straight-sided and curved TET10 (the
default): FEM / closed form at the spring centre per diagonal term, the compliance's asymmetry
and the CPU time of each.

    .venv/bin/python benchmarks/bench_flexure_small_pitch.py
"""

import time

import numpy as np

from designlab.sensors.flexure.helix_fem import fem_stiffness
from designlab.sensors.flexure.spring import HelicalSpring, stiffness_zero_pitch


def main() -> None:
    s = HelicalSpring(wire_radius=2.0, mean_diameter=20.0, coils=5.0, pitch_angle=0.08)
    K = stiffness_zero_pitch(s)
    for curved in (False, True):
        t = time.process_time()
        fem = fem_stiffness(s, edge_length=2.0, quality="coarse", curved=curved)
        r = np.diag(fem.K_centre) / np.diag(K)
        print(f"{'curved' if curved else 'straight'}: {fem.n_nodes} nodes; FEM / closed form "
              f"(w_x w_y w_z v_x v_y v_z) {np.round(r, 3)}; asymmetry {fem.asymmetry:.1e}; "
              f"{time.process_time() - t:.0f} s CPU")


if __name__ == "__main__":
    main()
