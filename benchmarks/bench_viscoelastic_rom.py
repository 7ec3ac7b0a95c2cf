"""Full against reduced-order viscoelastic march (``solve_history(method="full"|"reduced")``) on
the strap's default model and protocol (F_n and F_x, 511 steps): wall and CPU s of each march
(factorisation included), the reduced basis' size and certified residual, and the largest
difference of the gauge strain histories (over each channel's largest |strain|) and of the
displacement at the peak normal force (over its largest |u|); the reduced march run twice must
give bit-identical strains; the long-time (relaxed) displacements factorised
(``long_time_displacements``) against the reduced basis' (``HistoryResult.long_time``).
``--coarse F``: the mesh ``F`` times coarser (the error bar's).

    python benchmarks/bench_viscoelastic_rom.py [--coarse 1.6]
"""

import dataclasses
import sys
import time

import numpy as np


def main(coarse: float = 1.0) -> None:
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import long_time_displacements, solve_history
    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap import virtual as S
    from designlab.sensors.strap import model as strap_model
    from designlab.sensors.protocols import StrapLoadTest

    part, protocol = ArchStrap(), StrapLoadTest()
    settings = S.StrapModelSettings()
    settings = dataclasses.replace(settings, edge_length=settings.edge_length * coarse)
    model, gauges, _ = strap_model.build_model(part, strap_model.mesh_strap(part, settings), settings)
    model.build()
    t, fn, fx = protocol.time_history()
    history = History(t, {"F_n": fn, "F_x": fx})
    peak = int(np.argmax(fn))
    print(f"strap, edge {settings.edge_length:g} mm: {model.n_dofs} DOF, {len(t)} steps")
    out = {}
    for method in ("full", "reduced", "reduced"):
        w0, c0 = time.perf_counter(), time.process_time()
        res = solve_history(model, history, solver=settings.solver, forces=False,
                            method=method)
        strain = np.column_stack([res.linear(gauges[c].strain) for c in S.CHANNELS])
        u = res.displacement(peak)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        extra = (f", basis {res.basis_size}, residual {res.rom_residual:.2e}"
                 if res.march == "reduced" else "")
        print(f"  {method:8s} march {res.march}: {wall:6.2f} s wall, {cpu:6.2f} s CPU{extra}")
        if method in out:
            print(f"  reduced run twice, strains bit-identical: "
                  f"{np.array_equal(out[method][0], strain)}")
        out[method] = (strain, u)
        if method == "reduced" and res.long_time() is not None:
            red_long = res.long_time()
    w0, c0 = time.perf_counter(), time.process_time()
    U_long = long_time_displacements(model, solver=settings.solver)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    print(f"  long-time displacements factorised: {wall:.2f} s wall, {cpu:.2f} s CPU; from the "
          f"reduced basis: residual {red_long[1]:.2e}, max |difference| / max |u| "
          f"{np.abs(red_long[0] - U_long).max() / np.abs(U_long).max():.2e}")
    (sf, uf), (sr, ur) = out["full"], out["reduced"]
    d = np.abs(sr - sf).max(axis=0) / np.abs(sf).max(axis=0)
    du = np.abs(ur - uf).max() / np.abs(uf).max()
    print(f"  gauge strain max |reduced - full| / max |full|: Ch1 {d[0]:.2e}, Ch2 {d[1]:.2e}")
    print(f"  u at the peak F_n max |reduced - full| / max |full|: {du:.2e}")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(float(args[args.index("--coarse") + 1]) if "--coarse" in args else 1.0)
