"""FEM benchmark against peers in the same run: assembly vs scikit-fem, static solve scaling,
end to end vs CalculiX, a 100-step viscoelastic run vs static solves, peak memory.

Run (figures in the README were taken with):
    OMP_NUM_THREADS=1 /work/venv/bin/python benchmarks/bench_fem.py
Options: --sizes 7,10,16,23 (hexes per side of the TET10 cube: 10k, 28k, 108k, 311k DOF),
--assembly-n 16, --visco-n 10, --threads 1 (CalculiX threads), --no-ccx, --quick,
--only assembly,scaling,ccx,visco,memory.
Goals: assembly >= 2x faster than scikit-fem; 100k DOF static solve < 5 s on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time

import numpy as np

from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.assembly import block_pattern, cell_basis, stiffness
from designlab.fem.prony import Prony
from designlab.mesh.tetmesh import box_tet_mesh

MAT = Material("ABS-like", E=2200.0, nu=0.35)


class Seconds(float):
    """Wall-clock seconds that also carry the process CPU seconds (``.cpu``): on a shared,
    loaded machine the CPU time of this single-threaded process is the unloaded estimate."""

    def __new__(cls, wall: float, cpu: float):
        obj = super().__new__(cls, wall)
        obj.cpu = cpu
        return obj

    def __format__(self, spec):
        return f"{float(self):{spec}} s (cpu {self.cpu:{spec}})"


def clock(f):
    t, c = time.perf_counter(), time.process_time()
    out = f()
    return out, Seconds(time.perf_counter() - t, time.process_time() - c)


def cube(n: int):
    """TET10 cube of n^3 hexes (6 tets each), 10 mm side."""
    return box_tet_mesh(10.0, 10.0, 10.0, n, n, n).quadratic()


def block_model(mesh) -> Model:
    """Clamped bottom, shear + compression traction on top (a sensor-like load)."""
    model = Model(mesh, materials={"block": MAT})
    model.fix("zmin")
    model.traction("zmax", (0.05, 0.0, -0.1))
    return model


def end_to_end(n: int, solver: str = "auto"):
    """Mesh given -> Model -> assembled, constrained, solved: (seconds, result)."""
    mesh = cube(n)
    res, t = clock(lambda: solve_static(block_model(mesh), solver=solver))
    return t, res


# --------------------------------------------------------------------------- sections


def bench_assembly(n: int, rows: list) -> None:
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet
    from skfem.models.elasticity import linear_elasticity

    m4 = box_tet_mesh(10.0, 10.0, 10.0, n, n, n)
    mesh = m4.quadratic()
    lam, mu = MAT.lame
    ndof = 3 * mesh.n_points

    def ours():
        b = cell_basis(mesh)
        block_pattern(mesh)
        return b, stiffness(b, lam, mu)

    (basis, K), t_ours = clock(ours)
    _, t_ours_re = clock(lambda: stiffness(basis, lam, mu))

    def theirs():
        sm = MeshTet(np.ascontiguousarray(m4.points.T), np.ascontiguousarray(m4.cells.T))
        sb = Basis(sm, ElementVector(ElementTetP2()), intorder=2)   # 4-point rule, as ours
        return sb, linear_elasticity(lam, mu).assemble(sb)

    (sb, Ks), t_skfem = clock(theirs)
    _, t_skfem_re = clock(lambda: linear_elasticity(lam, mu).assemble(sb))
    fro = np.sqrt((K.data ** 2).sum()), np.sqrt((Ks.data ** 2).sum())
    same = abs(fro[0] - fro[1]) / fro[1]
    rows += [("", "", ""),
             (f"ASSEMBLY TET10 K, {ndof:,} DOF, {mesh.n_cells:,} cells", "", ""),
             ("ours: basis + pattern + K (cold)", f"{t_ours:.2f}", f"nnz {K.nnz:,}"),
             ("scikit-fem 12: Basis + assemble (cold)", f"{t_skfem:.2f}",
              f"ratio {t_skfem / t_ours:.1f}x wall, {t_skfem.cpu / t_ours.cpu:.1f}x cpu (goal >= 2x)"),
             ("ours: K again (basis, pattern cached)", f"{t_ours_re:.2f}", ""),
             ("scikit-fem: assemble again (Basis reused)", f"{t_skfem_re:.2f}",
              f"ratio {t_skfem_re / t_ours_re:.1f}x wall, {t_skfem_re.cpu / t_ours_re.cpu:.1f}x cpu"),
             ("same matrix? |‖K‖F - ‖K_skfem‖F| / ‖K_skfem‖F", f"{same:.1e}", "")]


def bench_scaling(sizes, rows: list) -> dict:
    rows += [("", "", ""), ("STATIC SOLVE vs DOF (end to end: Model -> u; solver auto)", "", "")]
    out, amg = {}, {}
    for n in sizes:
        t, res = end_to_end(n)
        nd = 3 * res.model.n_points
        lin = res.solver
        extra = f"{lin.kind}, setup {lin.setup_seconds:.2f} s"
        if lin.kind == "amg":
            extra += f", CG its {lin.iterations}"
            amg[nd] = t
        rows.append((f"{nd:>9,} DOF (n={n})", f"{t:.2f}", extra))
        out[nd] = t
        if lin.kind != "amg":
            t2, r2 = end_to_end(n, "amg")
            amg[nd] = t2
            rows.append((f"{nd:>9,} DOF (n={n}) with amg", f"{t2:.2f}",
                         f"setup {r2.solver.setup_seconds:.2f} s, CG its {r2.solver.iterations}"))
    for label, series in (("auto", out), ("amg", amg)):
        if len(series) >= 2:
            d = np.log(np.array(list(series.keys()), float))
            p = np.polyfit(d, np.log([float(v) for v in series.values()]), 1)[0]
            pc = np.polyfit(d, np.log([v.cpu for v in series.values()]), 1)[0]
            rows.append((f"growth exponent t ~ DOF^p ({label}, least squares)", f"p = {p:.2f}",
                         f"cpu: p = {pc:.2f}"))
    big = [k for k in out if k >= 90_000]
    if big:
        k = min(big)
        rows.append(("goal: ~100k DOF in < 5 s", f"{out[k]:.2f}",
                     f"wall {'MET' if out[k] < 5 else 'MISSED'}, cpu {'MET' if out[k].cpu < 5 else 'MISSED'}"))
    return out


def bench_calculix(n: int, threads: int, rows: list) -> None:
    from designlab.fem.verify import compare_with_calculix

    mesh = cube(n)
    model = block_model(mesh)
    t0 = time.perf_counter()
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    err, _, ref = compare_with_calculix(model, threads=threads)
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    ccx_cpu = (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)
    total = time.perf_counter() - t0
    t_ours, _ = end_to_end(n)
    rows += [("", "", ""),
             (f"END TO END vs CalculiX {ref.ccx_version} (SPOOLES, {threads} thread(s)), "
              f"{3 * mesh.n_points:,} DOF", "", ""),
             ("ours (Model -> u)", f"{t_ours:.2f}", ""),
             ("ccx run", f"{ref.wall_time_s:.2f} s (cpu {ccx_cpu:.2f})",
              f"+ deck/read {ref.total_time_s - ref.wall_time_s:.2f} s; ratio ccx/ours "
              f"{ref.wall_time_s / t_ours:.1f}x wall, {ccx_cpu / t_ours.cpu:.1f}x cpu"),
             ("agreement max|u - u_ccx| / max|u_ccx|", f"{err:.1e}", f"(total {total:.1f} s)")]


def bench_visco(n: int, rows: list) -> None:
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    mesh = cube(n)
    mat = Material("tpu", E=12.0, nu=0.45, prony=Prony(g=(0.3, 0.2), tau=(0.5, 5.0)))
    model = Model(mesh, materials={"block": mat})
    model.fix("zmin")
    model.traction("zmax", (0.0, 0.0, -0.01), case="press")
    rs, t_static = clock(lambda: solve_static(model))
    _, t_direct = clock(lambda: solve_static(model, solver="direct"))
    hist = History.step_hold(10.0, 99, {"press": 1.0})                  # 100 time points
    hres, t_hist = clock(lambda: solve_history(model, hist))
    kinds = ", ".join(f"{s.kind} (setup {s.setup_seconds:.1f} s)" for s in hres.solvers)
    rows += [("", "", ""),
             (f"VISCOELASTIC 100 steps, {3 * mesh.n_points:,} DOF (solver auto)", "", ""),
             ("one static solve (auto)", f"{t_static:.2f}", rs.solver.kind),
             ("one static solve (direct)", f"{t_direct:.2f}", ""),
             ("100-step history (auto)", f"{t_hist:.2f}",
              f"= {t_hist / t_static:.1f} static (auto) = {t_hist / t_direct:.1f} static (direct) wall; "
              f"cpu {t_hist.cpu / t_static.cpu:.1f} / {t_hist.cpu / t_direct.cpu:.1f}; {kinds}")]


def child_peak_memory(n: int) -> None:
    """(subprocess) solve the n-cube end to end, print peak RSS in MB."""
    t, res = end_to_end(n)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0       # kB on Linux
    print(f"{3 * res.model.n_points} {float(t):.3f} {rss:.1f}")


def bench_memory(n: int, rows: list) -> None:
    cmd = [sys.executable, __file__, "--child-memory", str(n)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.split()
    nd, t, rss = int(out[0]), float(out[1]), float(out[2])
    rows += [("", "", ""), (f"PEAK MEMORY, static solve {nd:,} DOF (fresh process)", "", ""),
             ("max RSS (includes Python + numpy/scipy imports)", f"{rss:.0f} MB", f"solve {t:.2f} s")]


class _Printer(list):
    """A list of (label, value, note) rows that prints each row as soon as it is added."""

    def __iadd__(self, rows):
        for r in rows:
            self.append(r)
        return self

    def append(self, row):
        super().append(row)
        x, y, z = row
        print(f"{x:<52}  {y:>20}  {z}".rstrip(), flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="7,10,16,23")
    ap.add_argument("--assembly-n", type=int, default=16)
    ap.add_argument("--visco-n", type=int, default=10)
    ap.add_argument("--ccx-n", type=int, default=16)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--no-ccx", action="store_true")
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test of the script)")
    ap.add_argument("--only", default="assembly,scaling,ccx,visco,memory",
                    help="comma-separated sections to run")
    ap.add_argument("--child-memory", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child_memory is not None:
        child_peak_memory(a.child_memory)
        return
    if a.quick:
        a.sizes, a.assembly_n, a.visco_n, a.ccx_n = "4,6", 6, 4, 6
    sizes = [int(s) for s in a.sizes.split(",")]
    rows: list = _Printer()
    rows += [("designlab FEM benchmark", time.strftime("%Y-%m-%d %H:%M"),
                   f"{os.cpu_count()} cores, load avg {os.getloadavg()[0]:.1f}, "
                   f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")]
    only = set(a.only.split(","))
    if "assembly" in only:
        bench_assembly(a.assembly_n, rows)
    if "scaling" in only:
        bench_scaling(sizes, rows)
    if "ccx" in only and not a.no_ccx and shutil.which("ccx"):
        bench_calculix(a.ccx_n, a.threads, rows)
    if "visco" in only:
        bench_visco(a.visco_n, rows)
    if "memory" in only:
        bench_memory(a.ccx_n, rows)
    rows.append(("load average at the end", f"{os.getloadavg()[0]:.1f}", ""))


if __name__ == "__main__":
    main()
