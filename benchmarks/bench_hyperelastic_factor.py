"""Where a Newton iteration of designlab.fem.hyperelastic spends its time on a 9600-cell TET10
block (38.7k free DOF): assembly (stress, internal force, tangent) vs PARDISO's analysis +
factorisation (phase 12, what ``factorize`` does every iteration) vs the numerical
factorisation alone (phase 22: what reusing the symbolic analysis would cost).

    .venv/bin/python benchmarks/bench_hyperelastic_factor.py

Reaches into PardisoSolver's private ``_call``/``_a`` to time phase 22: a measurement, not an
API. Wall and CPU seconds, best of 2.
"""

from __future__ import annotations

import json
import time

import numpy as np
import scipy.sparse as sp

from designlab.fem.model import Model
from designlab.fem.hyperelastic import Continuum, NeoHooke
from designlab.fem.materials import Material
from designlab.fem.solvers import PardisoSolver, has_pardiso
from designlab.mesh.tetmesh import box_tet_mesh


def timed(fn):
    best = None
    for _ in range(2):
        t, c = time.perf_counter(), time.process_time()
        fn()
        r = (time.perf_counter() - t, time.process_time() - c)
        best = r if best is None or r[0] < best[0] else best
    return {"wall_s": round(best[0], 3), "cpu_s": round(best[1], 3)}


def main():
    mesh = box_tet_mesh(20, 10, 10, 20, 10, 8, material="soft").quadratic()
    m = Model(mesh, {"block": Material("soft", E=1.0, nu=0.45)})
    m.fix("zmin")
    m.prescribe("zmax", (0.0, 0.0, -2.0))
    cont = Continuum.of(m, {"block": NeoHooke.from_linear(1.0, 0.45)})
    system = m.build()
    u = np.zeros(3 * mesh.n_points)
    m.basis
    out = {"cells": int(mesh.n_cells), "free_dofs": int(system.T.shape[1])}

    def assemble():
        P, A = cont.stress(cont.displacement_gradient(u), True)
        cont.internal_force(P)
        return cont.tangent(A)
    out["assembly"] = timed(assemble)
    K = system.reduce(system.K(assemble()))
    if has_pardiso():
        out["pardiso_phase12_analysis_and_factor"] = timed(lambda: PardisoSolver(K))
        s = PardisoSolver(K)
        Ku = sp.triu(K, format="csr")
        Ku.sort_indices()

        def refactor():
            s._a = np.ascontiguousarray(Ku.data * 1.01)
            s._call(22, np.zeros((1, s.n)), np.zeros((1, s.n)), 1)
        out["pardiso_phase22_factor_only"] = timed(refactor)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
