"""FEM core timings: assembly, static solve per solver, and a 100-step viscoelastic run.

Run: OMP_NUM_THREADS=1 /work/venv/bin/python benchmarks/bench_fem_solvers.py [n]
(box_tet_mesh(n x n x n hexes).quadratic(); n = 16 gives 107,811 DOF). Prints a table.
"""

from __future__ import annotations

import sys
import time


from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.assembly import block_pattern, cell_basis, stiffness
from designlab.fem.prony import Prony

from designlab.fem.history import History
from designlab.fem.viscoelastic import solve_history
from designlab.mesh.tetmesh import box_tet_mesh


def clock(f):
    t = time.perf_counter()
    out = f()
    return out, time.perf_counter() - t


def main(n: int = 16, solvers=("amg", "direct"), visco_n: int = 10) -> None:
    rows = []
    mesh = box_tet_mesh(40.0, 10.0, 10.0, n, n, n).quadratic()
    ndof = 3 * mesh.n_points
    basis, tb = clock(lambda: cell_basis(mesh))
    _, tp = clock(lambda: block_pattern(mesh))
    K, tk = clock(lambda: stiffness(basis, 1.0, 1.0))
    _, tk2 = clock(lambda: stiffness(basis, 1.0, 1.0))
    rows += [("TET10 mesh", f"{ndof} DOF, {mesh.n_cells} cells", ""),
             ("basis (Jacobians, gradients)", f"{tb:.3f} s", ""),
             ("sparsity pattern (once per mesh)", f"{tp:.3f} s", ""),
             ("stiffness assembly", f"{tk:.3f} s", f"repeat {tk2:.3f} s, nnz {K.nnz}"),
             ("assembly total, first call", f"{tb + tp + tk:.3f} s", "")]
    mat = Material("m", E=2200.0, nu=0.35)
    for s in solvers:
        if s == "direct" and ndof > 40_000:
            rows.append((f"static solve ({s})", "skipped", "> 40000 DOF "
                         "(SuperLU took 416 s at 108k DOF on this machine)"))
            continue
        model = Model(mesh, materials={"block": mat})
        model.fix("xmin")
        model.traction("xmax", (0.0, 0.0, -0.01), case="tip")
        model.traction("xmax", (0.0, 0.01, 0.0), case="side")
        res, ts = clock(lambda: solve_static(model, solver=s))
        extra = f"setup {res.solver.setup_seconds:.2f} s"
        if s == "amg":
            extra += f", CG iterations {res.solver.iterations}"
        rows.append((f"static solve, 2 load cases ({s})", f"{ts:.2f} s", extra))
    # viscoelastic: 100 steps on a smaller mesh, compared with its static solve
    vm = box_tet_mesh(40.0, 10.0, 10.0, visco_n, visco_n, visco_n).quadratic()
    pr = Prony(g=(0.3, 0.2), tau=(0.5, 5.0))
    model = Model(vm, materials={"block": Material("tpu", E=12.0, nu=0.45, prony=pr)})
    model.fix("xmin")
    model.traction("xmax", (0.0, 0.0, -0.01), case="hang")
    rows.append(("visco mesh", f"{3 * vm.n_points} DOF", ""))
    for s in ("direct", "amg"):
        _, t_static = clock(lambda: solve_static(model, solver=s))
        hist = History.step_hold(10.0, 99, {"hang": 1.0})
        hres, t_hist = clock(lambda: solve_history(model, hist, solver=s))
        rows += [(f"static solve ({s})", f"{t_static:.2f} s", ""),
                 (f"100-step history ({s})", f"{t_hist:.2f} s",
                  f"{t_hist / t_static:.1f} static solves, {hres.factorizations} "
                  "factorisations")]
    w = max(len(r[0]) for r in rows)
    for a, b, c in rows:
        print(f"{a:<{w}}  {b:>28}  {c}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 16)
