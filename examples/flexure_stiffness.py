"""Seed 002 end to end: spring 6x6 closed form -> camera frame -> virtual experiment -> fit -> Table I.

Run from the project root:  python examples/flexure_stiffness.py [--fem]

1. The closed-form K_f of the Visiflex spring (catalogue reading of the paper's parameters, see
   docs/validation/flexure.md), moved to the camera frame with seed 002 eq. 3.
2. A virtual LIPMM experiment: 92 random fingertip poses, wrenches from a "true" stiffness (the
   paper's measured K_c) plus sensor noise; the 21-entry least-squares fit recovers K_c.
3. The reverse use on 410 test poses seen through a noisy pose estimate (the camera's ~20 um
   mean error): force error mean/std per axis, as in the paper's Table I.
4. With --fem: the meshed helix's 6x6 next to the closed form (needs the parts/meshing helpers).
"""

from __future__ import annotations

import sys

import numpy as np

from designlab.sensors.flexure.report import camera_offset, load_paper, to_frame
from designlab.calibration.stiffness_fit import fit_stiffness, force_error_stats, wrench_from_twist
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG, stiffness_ratios, stiffness_zero_pitch, to_si

np.set_printoptions(precision=4, suppress=True, linewidth=120)
paper = load_paper()

# 1. closed form and frames
K_f = to_si(stiffness_zero_pitch(VISIFLEX_CATALOG))
h = camera_offset(paper)
K_c = to_frame(K_f, "camera", h)
print("K_f at the spring centre (SI):\n", K_f)
print(f"camera frame {1e3 * h:.2f} mm below the spring centre; K_c:\n", K_c)
print("ratios ours :", {k: round(float(v), 6) for k, v in stiffness_ratios(K_f).items()})
print("ratios paper:", {k: round(float(v), 6) for k, v in stiffness_ratios(paper["K_f_theory"]).items()})

# 2. virtual experiment and fit (92 model points as in the paper)
rng = np.random.default_rng(0)
K_true = (paper["K_c_measured"] + paper["K_c_measured"].T) / 2


def poses(k):
    return np.hstack([rng.uniform(-0.05, 0.05, (k, 3)), rng.uniform(-0.002, 0.002, (k, 3))])


noise = np.array([3e-3] * 3 + [0.05] * 3)          # ATI-like: 3 N*mm moments, 0.05 N forces
X_model = poses(92)
F_model = wrench_from_twist(K_true, X_model) + rng.normal(size=X_model.shape) * noise
fit = fit_stiffness(X_model, F_model, weights=1 / noise)
print("fitted K_c (SI):\n", fit.K)
print("max |fit - true| / standard error:",
      float(np.max(np.abs(fit.K - K_true)[np.triu_indices(6)] / fit.std_errors)))
print("residual RMS per wrench component:", fit.residual_rms, " cond(K):", round(fit.condition_number))

# 3. wrench from pose on 410 test points with a noisy pose estimate
X_test = poses(410)
F_test = wrench_from_twist(K_true, X_test)
X_est = X_test + rng.normal(size=X_test.shape) * np.array([1e-3] * 3 + [3e-5] * 3)
stats = force_error_stats(F_test, wrench_from_twist(fit.K, X_est))
print("force error (N), ours vs paper Table I:")
for a in "xyz":
    p = paper["table_I"][a]
    print(f"  {a}: mean {stats[a]['mean']:+.4f} std {stats[a]['std']:.4f}   "
          f"paper mean {p['mean']:+.4f} std {p['std']:.4f}")

# 4. FEM (optional, takes a minute)
if "--fem" in sys.argv:
    from designlab.sensors.flexure.helix_fem import fem_stiffness

    fem = fem_stiffness(VISIFLEX_CATALOG)
    print(f"FEM {fem.n_nodes} nodes, asymmetry {fem.asymmetry:.1e}; K at the centre (SI):\n",
          fem.K_centre_si)
    print("FEM / closed form, diagonal:", np.diag(fem.K_centre_si) / np.diag(K_f))
