"""PARDISO (``fem.solvers.PardisoSolver``: Cholesky, no iterative refinement) against SuperLU
(``DirectSolver``) on TET10 boxes of growing size: factorisation and one solve, CPU s on one
thread; and, where pypardiso's own wrapper is importable, its LU (mtype 11, PARDISO's default
iterative refinement) on the same matrix. What ``PARDISO_MIN_DOFS`` rests on.

    OMP_NUM_THREADS=1 python benchmarks/bench_pardiso.py [largest n, default 12]
"""

import sys
import time

import numpy as np


def main(n_max: int = 12) -> None:
    from designlab.fem.materials import Material
    from designlab.fem.model import Model
    from designlab.fem.solvers import DirectSolver, PardisoSolver
    from designlab.mesh.tetmesh import box_tet_mesh

    print(f"{'DOF':>7s} {'solver':>16s} {'factor s':>9s} {'solve ms':>9s} {'rel. residual':>13s}")
    for n in (3, 4, 6, 8, 10, 12, 14, 16):
        if n > n_max:
            break
        mesh = box_tet_mesh(40.0, 10.0, 10.0, 2 * n, n, n).quadratic()
        model = Model(mesh, {b: Material("m", E=2200.0, nu=0.35)
                             for b in mesh.region_names.values()})
        model.fix(np.nonzero(mesh.points[:, 0] < 1e-9)[0])
        system = model.build()
        K = system.reduce(system.K())
        F = np.random.default_rng(0).standard_normal(K.shape[0])
        rows = [("pardiso Cholesky", PardisoSolver)]
        if K.shape[0] <= 60_000:
            rows.append(("SuperLU", DirectSolver))
        for label, cls in rows:
            c0 = time.process_time()
            s = cls(K)
            c1 = time.process_time()
            reps = 20
            for _ in range(reps):
                x = s.solve(F)
            c2 = time.process_time()
            res = np.linalg.norm(K @ x - F) / np.linalg.norm(F)
            print(f"{K.shape[0]:7d} {label:>16s} {c1 - c0:9.3f} {(c2 - c1) / reps * 1e3:9.2f} "
                  f"{res:13.2e}", flush=True)
        try:
            import pypardiso
        except ImportError:
            continue
        c0 = time.process_time()
        o = pypardiso.PyPardisoSolver(mtype=11)
        o.set_statistical_info_off()
        o.factorize(K)
        c1 = time.process_time()
        for _ in range(reps):
            x = o.solve(K, F)
        c2 = time.process_time()
        res = np.linalg.norm(K @ x - F) / np.linalg.norm(F)
        print(f"{K.shape[0]:7d} {'pypardiso LU':>16s} {c1 - c0:9.3f} {(c2 - c1) / reps * 1e3:9.2f} "
              f"{res:13.2e}", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 12)
