"""Meshing benchmark: the three default parts through ``mesh_part`` (TET10), gmsh from the
B-rep (ours, the default) side by side with the previous pipeline as the peer (tessellate, then
fTetWild: ``mesher="tetwild"``) at the same settings, in the same run.

Goal: a part in about a second (the fingertip <= 2 s). Reported per part, mesher and setting:
cells, nodes, DOF, wall and CPU seconds, worst region volume error and element quality, and
the peer/ours CPU ratio. A second peer (full run only): fTetWild's own CSG mode
(``pytetwild.tetrahedralize_csg`` with a union tree) on the strap's tessellated bodies.

Run from the project root:  OMP_NUM_THREADS=1 python benchmarks/bench_meshing.py [--quick]
(``--quick``: coarse preset only, no CSG peer.) The machine load makes wall times noisy; the
CPU column is the process's own time (fTetWild runs in a child: its CPU is counted via
``os.times``).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from designlab.mesh.quality import mesh_quality  # noqa: E402
from designlab.mesh.meshing import mesh_part_detailed  # noqa: E402
from designlab.geometry.parts import make_part  # noqa: E402


def _cpu() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run(name: str, **kw) -> dict:
    part = make_part(name)
    t0, c0 = time.perf_counter(), _cpu()
    res = mesh_part_detailed(part, order=2, **kw)
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    q = mesh_quality(res.mesh)
    vol = res.region_volumes()
    err = max(abs(vol[b] / v - 1) for b, v in res.body_volumes.items())
    return {"part": name, "mesher": res.mesher,
            "setting": ", ".join(f"{k}={v}" for k, v in kw.items() if k != "mesher"),
            "cells": res.mesh.n_cells, "nodes": res.mesh.n_points, "dof": 3 * res.mesh.n_points,
            "wall_s": wall, "cpu_s": cpu, "vol_err_pct": 100 * err,
            "min_dihedral": q.min_dihedral_deg, "rr_mean": q.radius_ratio_mean,
            "edge_mm": res.edge_length}


def csg_peer(edge_length: float) -> dict:
    """fTetWild CSG union of the strap's bodies (regions = input markers)."""
    import pytetwild

    from designlab.geometry.tessellate import tessellate

    part = make_part("strap")
    built = part.build()
    names = part.mesh_bodies()
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for n in names:
            tessellate(built[n].shape).export(f"{tmp}/{n}.obj")
            paths.append(f"{tmp}/{n}.obj")
        tree: object = paths[-1]
        for p in reversed(paths[:-1]):
            tree = {"operation": "union", "left": p, "right": tree}
        with open(f"{tmp}/tree.json", "w") as fh:
            json.dump(tree, fh)
        s = tessellate(built[names[0]].shape)
        diag = float(np.linalg.norm(s.bounds[1] - s.bounds[0]))
        t0, c0 = time.perf_counter(), _cpu()
        # fTetWild's CSG mode logs to stdout: silence it at the file-descriptor level
        saved = os.dup(1)
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            try:
                grid = pytetwild.tetrahedralize_csg(f"{tmp}/tree.json", epsilon=0.02 / diag,
                                                    edge_length_r=edge_length / diag,
                                                    stop_energy=15.0, coarsen=False,
                                                    num_threads=1)
            finally:
                os.dup2(saved, 1)
                os.close(saved)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
    marker = np.asarray(grid["marker"])
    vols = grid.compute_cell_sizes(length=False, area=False)["Volume"]
    body = [built[n].shape.volume for n in names]
    err = max(abs(vols[marker == k + 1].sum() / v - 1) for k, v in enumerate(body))
    return {"part": "strap (CSG peer)", "mesher": "fTetWild CSG", "setting": f"edge_length={edge_length:.3g}, refine=False",
            "cells": grid.n_cells, "nodes": grid.n_points, "dof": float("nan"), "wall_s": wall,
            "cpu_s": cpu, "vol_err_pct": 100 * err, "min_dihedral": float("nan"),
            "rr_mean": float("nan"), "edge_mm": edge_length}


def main() -> None:
    quick = "--quick" in sys.argv
    rows = []
    settings = [dict(quality="coarse", refine=False)]
    if not quick:
        settings += [dict(quality="default", refine=False), dict(quality="default", refine=True)]
    for name in ("strap", "fingertip", "flexure"):
        for kw in settings:
            ours = run(name, mesher="gmsh", **kw)
            peer = run(name, mesher="tetwild", **kw)
            peer["peer/ours cpu"] = peer["cpu_s"] / ours["cpu_s"]
            rows += [ours, peer]
    if not quick:
        ours = next(r for r in rows if r["part"] == "strap" and r["mesher"] == "tetwild"
                    and r["setting"] == "quality=default, refine=False")
        rows.append(csg_peer(ours["edge_mm"]))
    table = Table(title="designlab mesh: default parts (TET10)")
    cols = ["part", "mesher", "setting", "edge_mm", "cells", "dof", "wall_s", "cpu_s",
            "peer/ours cpu", "vol_err_pct", "min_dihedral", "rr_mean"]
    for c in cols:
        table.add_column(c, justify="left" if c in ("part", "mesher", "setting") else "right")
    for r in rows:
        table.add_row(*[f"{r.get(c):.3g}" if isinstance(r.get(c), float) else str(r.get(c, ""))
                        for c in cols])
    Console(width=170).print(table)


if __name__ == "__main__":
    main()
