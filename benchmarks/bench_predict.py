"""``designlab predict`` end to end, by stage, with the peak memory after each stage; ours (gmsh
mesh, auto solver) side by side with the previous pipeline (``mesher=tetwild``,
``solver=direct``) in the same run.

    OMP_NUM_THREADS=1 python benchmarks/bench_predict.py [fingertip strap ...] [--no-peer]
    OMP_NUM_THREADS=1 python benchmarks/bench_predict.py --contact   (goal: < 2 s, relaxation kept)
    OMP_NUM_THREADS=1 python benchmarks/bench_predict.py --calculix  (the CalculiX peer alone)

CalculiX peer (with the fingertip, unless ``--no-peer``): the fingertip's own mesh (gmsh TET10 of
base and cap, the default settings) as a plain linear static problem both solvers can state: the
cap's mounting face fixed, a 1 MPa traction along each sensor's axis on its well floor (the
sensors pushing on the base), ABS. Ours (``solve_static``, the auto solver) and ``ccx``
(``designlab.fem.calculix``, one thread, SPOOLES) on the same nodes, elements and load vector;
printed: both times and the largest nodal displacement difference (ccx prints 7 digits).

Each prediction runs in a fresh process (no FEM cache from an earlier one), so the times are
what a user's first ``designlab predict PART`` costs, including the coarser mesh of the
discretisation error bar (``mesh_convergence``). Goals: fingertip <= 10 s, its mesh
<= 2 s; strap <= 15 s. ``cpu`` counts the imports the prediction needs (OpenCascade, gmsh,
scipy...); ``+ write`` is what ``designlab predict --out`` adds: ``write_prediction`` (the
plots, the loop model, the design render, the report) into a temporary folder; its stages are
printed on the ``write`` line (wall / CPU s each). The run is the CLI's
(``predict_and_write``): ``forked`` is the CPU of its forked helpers (the painter: drawing
libraries, design.png, deformed.png; the coarse mesh's process: the error bar, then the
plots), counted in the end-to-end CPU; they are reaped after the writing, so their CPU shows
on the ``write`` side.
"""

import json
import multiprocessing as mp
import resource
import sys
import time


def _one(part: str, settings: dict, conn) -> None:
    """``designlab predict PART --out DIR`` as the CLI runs it (``predict_and_write``: the
    painter and the coarse mesh's process beside the run); the prediction ends at the
    "writing" stage, the rest is the writing."""
    import tempfile

    from designlab.predict.run import predict_and_write

    marks, at_write = [], {}

    def progress(stage: str) -> None:
        now = time.perf_counter()
        if stage == "writing":
            at_write.update(t=now, cpu=time.process_time(), kids=_children_cpu(),
                            peak=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
            return
        marks.append((stage, now, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))

    write_stages: dict = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        pred, _ = predict_and_write(part, {}, out=d, settings=settings, progress=progress,
                                    timings=write_stages)
    end, cpu_end, kids = time.perf_counter(), time.process_time(), _children_cpu()
    wall, cpu, kids0, peak = (at_write["t"] - t0, at_write["cpu"], at_write["kids"],
                              at_write["peak"])
    # the forked helpers are reaped once the writing is done: their CPU shows up at the end
    write_wall, write_cpu = end - at_write["t"], cpu_end - cpu
    m = pred.metrics
    conn.send({"wall": wall, "cpu": cpu, "kids_cpu": kids0, "write_kids_cpu": kids - kids0,
               "peak_MB": peak, "timings": m["timings_s"],
               "write_wall": write_wall, "write_cpu": write_cpu, "write_stages": write_stages,
               "dofs": m.get("mesh", {}).get("dofs") or m.get("mesh", {}).get("dof"),
               "mesher": m.get("mesh", {}).get("mesher"), "solver": m.get("mesh", {}).get("solver"),
               "marks": [(s, t - t0, r) for s, t, r in marks],
               "cond": m.get("condition_number"),
               "hyst": m.get("hysteresis_percent", {}).get("overall"),
               "mesh_convergence": m.get("mesh_convergence")})
    conn.close()


def _children_cpu() -> float:
    """CPU s of this process's finished children (predict's forked helpers: the coarse mesh and
    design.png beside the run, the plots beside the renders)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(part: str, settings: dict) -> dict:
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_one, args=(part, settings, send))
    p.start()
    send.close()
    out = recv.recv()
    p.join()
    return out


def main(parts, peer: bool) -> None:
    for part in parts:
        rows = [("ours", {})]
        if peer:
            rows.append(("peer: fTetWild + SuperLU", {"mesher": "tetwild", "solver": "direct"}))
        for label, settings in rows:
            r = run(part, settings)
            ts = r["timings"]
            print(f"{part:9s} {label:26s} wall {r['wall']:6.1f} s  cpu {r['cpu']:6.1f} s "
                  f"(+ {r['kids_cpu']:.1f} s forked)  + write wall {r['write_wall']:5.1f} s cpu "
                  f"{r['write_cpu']:5.1f} s (+ {r['write_kids_cpu']:.1f} s forked)  "
                  f"end to end wall {r['wall'] + r['write_wall']:5.1f} s cpu "
                  f"{r['cpu'] + r['kids_cpu'] + r['write_cpu'] + r['write_kids_cpu']:5.1f} s  "
                  f"peak RSS {r['peak_MB']:6.0f} MB  dofs {r['dofs']}  "
                  f"mesher {r['mesher']}  solver {r['solver']}  "
                  + "  ".join(f"{k} {v:.2f}" for k, v in ts.items() if isinstance(v, float)),
                  flush=True)
            print("    stages (s, peak MB): " + ", ".join(f"{s} @ {t:.1f} s {m:.0f} MB"
                                                       for s, t, m in r["marks"]))
            print("    write (wall / cpu s): " + ", ".join(
                f"{s} {w:.2f} / {c:.2f}" for s, (w, c) in r["write_stages"].items()))
            print(f"    condition number {r['cond']:.4g}, hysteresis {r['hyst']:.4g} %, "
                  f"mesh_convergence {json.dumps(r['mesh_convergence'])}", flush=True)
        if peer and part == "fingertip":
            calculix_peer()     # after the rows: it meshes here, and a fork of a process that
            #                     ran gmsh does not run predict's helpers (predict.py)


def calculix_peer() -> None:
    """Ours and CalculiX on the fingertip's mesh (see the module docstring)."""
    from designlab.fem.model import Model
    from designlab.fem.calculix import ccx_path
    from designlab.fem.verify import compare_with_calculix
    from designlab.geometry.fingertip import CantileverFingertip
    from designlab.sensors.fingertip.model import FingertipModelSettings, mesh_fingertip

    ccx_path()                                  # one line if ccx is not installed
    part, fs = CantileverFingertip(), FingertipModelSettings()
    t0 = time.perf_counter()
    made = mesh_fingertip(part, fs, detailed=True)
    t_mesh = time.perf_counter() - t0
    mesh = made.mesh
    model = Model(mesh)
    model.fix("cap_mount")
    axes, _ = part.sensor_axes()
    for k, a in enumerate(axes):                # the sensor pushes the floor outward (+axis)
        model.traction(f"sensor_well_{k + 1}", tuple(float(x) for x in a))
    t0 = time.perf_counter()
    rel, u, ref = compare_with_calculix(model, threads=1)
    both = time.perf_counter() - t0
    ours = both - ref.total_time_s              # compare_with_calculix = our solve + ccx
    diff = float(abs(u - ref.displacement).max())
    print(f"fingertip mesh ({made.mesher}, TET10, {3 * mesh.n_points} DOF, meshed in "
          f"{t_mesh:.1f} s): cap mount fixed, 1 MPa on each well floor along its sensor axis",
          flush=True)
    print(f"    ours (solve_static, assembly + factorisation + solve): {ours:6.2f} s", flush=True)
    print(f"    CalculiX {ref.ccx_version} (1 thread): {ref.wall_time_s:6.2f} s ccx run, "
          f"{ref.total_time_s:6.2f} s with writing the deck and reading the result", flush=True)
    print(f"    max |u - u_ccx| = {diff:.3g} mm of max |u_ccx| = "
          f"{float(abs(ref.displacement).max()):.4g} mm (relative {rel:.2g})", flush=True)


def contact_protocol(repeats: int = 3) -> None:
    """The goal: the full Table II protocol of the contact model (14 locations x 6
    rotations x preconditioning + measured loop, the ABS relaxation kept: the default
    ``structure_moduli="relaxing"``) in < 2 s once the FEM is condensed. Wall and process time
    of the best of ``repeats`` runs on the default mesh; beside it, alternating, the same
    protocol on the relaxed structure (``structure_moduli="long_time"``: the same long-time
    condensation without the instantaneous one)."""
    import dataclasses
    import warnings

    from designlab.geometry.fingertip import CantileverFingertip
    from designlab.sensors.fingertip.model import FingertipModelSettings, mesh_fingertip
    from designlab.sensors.fingertip.model import ContactSettings
    from designlab.sensors.fingertip.contact import condense_fingertip, run_contact_test
    from designlab.sensors.protocols import HangingWeightTest

    part, fs = CantileverFingertip.table_ii(), FingertipModelSettings()   # the Table II sensor
    relaxing = condense_fingertip(part, mesh_fingertip(part, fs), fs, "relaxing")
    cases = {"default (relaxing)": (relaxing, ContactSettings()),
             "long_time": (dataclasses.replace(relaxing, C_instant=None,
                                               structure_moduli="long_time"),
                           ContactSettings(structure_moduli="long_time"))}
    best = {k: (float("inf"), float("inf")) for k in cases}
    for _ in range(repeats):
        for name, (cf, settings) in cases.items():
            w0, c0 = time.perf_counter(), time.process_time()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                run_contact_test(part, HangingWeightTest(), settings, cf)
            best[name] = min(best[name], (time.perf_counter() - w0, time.process_time() - c0))
    d, r = best["default (relaxing)"], best["long_time"]
    print(f"contact model, full Table II protocol after condensation, ABS relaxation kept "
          f"(default): wall {d[0]:.2f} s, cpu {d[1]:.2f} s (goal < 2 s): "
          f"{'met' if d[0] < 2.0 else 'not met'}; on the relaxed structure "
          f"(structure_moduli=long_time): wall {r[0]:.2f} s, cpu {r[1]:.2f} s; ratio "
          f"{d[0] / r[0]:.1f}x", flush=True)


if __name__ == "__main__":
    if "--contact" in sys.argv:
        contact_protocol()
        sys.exit(0)
    if "--calculix" in sys.argv:
        calculix_peer()
        sys.exit(0)
    names = [a for a in sys.argv[1:] if not a.startswith("--")] or ["fingertip", "strap"]
    main(names, "--no-peer" not in sys.argv)
