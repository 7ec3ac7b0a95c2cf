"""Build / tessellate / check / export / mesh time of every default part (seconds, one run each).

Peer in the same run: our tessellation (OpenCascade BRepMesh with an *absolute* chordal tolerance,
read into numpy, one trimesh merge) against build123d's own ``Shape.tessellate`` followed by the
same merge, both asked for 0.01 mm / 0.2 rad from an un-meshed shape. build123d passes the tolerance
as *relative* to edge size, so its mesh is coarser: the table gives time and the largest relative
volume error against the exact B-rep volume (OpenCascade GProp) over the printed bodies. ``mesh`` is :func:`designlab.mesh.meshing.mesh_part`
with the part's defaults (fTetWild), when that module is available.

    OMP_NUM_THREADS=1 python benchmarks/bench_geometry.py [--no-mesh] [--parts strap,fingertip]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
import trimesh

from designlab.geometry.export import (PRINT_ANGULAR_TOLERANCE, PRINT_TOLERANCE, prepare,
                                       write)
from designlab.geometry.parts import PARTS, make_part
from designlab.geometry.tessellate import tessellate


def timed(fn, *a, **k):
    t0 = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t0


def build123d_tessellate(shape, tol, ang):
    """The peer: build123d's tessellation, merged the same way."""
    from build123d import Shape
    from OCP.BRepTools import BRepTools

    s = shape if isinstance(shape, Shape) else Shape.cast(shape.wrapped)
    BRepTools.Clean_s(s.wrapped)  # mesh from scratch, like ours (no cached triangulation)
    verts, tris = s.tessellate(tol, ang)
    v = np.array([(p.X, p.Y, p.Z) for p in verts])
    return trimesh.Trimesh(v, np.asarray(tris), process=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--no-mesh", action="store_true", help="skip tetrahedral meshing")
    args = ap.parse_args()
    try:
        from designlab.mesh.meshing import mesh_part
    except ImportError:
        mesh_part = None
    head = ("part", "bodies", "print tris", "build", "tessellate (vol err)",
            "b123d peer (vol err)", "build+check", "write stl/3mf/step/glb", "3mf+png", "mesh",
            "tets")
    print(" | ".join(head))
    print(" | ".join("---" for _ in head), flush=True)
    for name in args.parts.split(","):
        part = make_part(name, None, None)
        bodies, t_build = timed(part.build)
        printed = [b for b in bodies.values() if b.printed]
        t_ours = t_peer = 0.0
        err_ours = err_peer = 0.0
        n_tri = 0
        for b in printed:
            exact = b.shape.volume
            m, dt = timed(tessellate, b.shape, PRINT_TOLERANCE, PRINT_ANGULAR_TOLERANCE)
            t_ours += dt
            n_tri += len(m.faces)
            err_ours = max(err_ours, abs(m.volume - exact) / exact)
            m2, dt = timed(build123d_tessellate, b.shape, PRINT_TOLERANCE,
                           PRINT_ANGULAR_TOLERANCE)
            t_peer += dt
            err_peer = max(err_peer, abs(m2.volume - exact) / exact)
        prepared, t_check = timed(prepare, name, make_part(name, None, None).build())
        with tempfile.TemporaryDirectory() as tmp:
            _, t_write = timed(write, prepared, tmp, ("stl", "3mf", "step", "gltf"), False)
            _, t_png = timed(write, prepared, tmp, ("3mf",), True)
        t_mesh = float("nan")
        n_tet = 0
        if mesh_part is not None and not args.no_mesh:
            mesh, t_mesh = timed(mesh_part, make_part(name, None, None))
            n_tet = mesh.n_cells
        cells = [name, str(len(bodies)), str(n_tri), f"{t_build:.2f} s",
                 f"{t_ours:.2f} s ({err_ours:.1e})", f"{t_peer:.2f} s ({err_peer:.1e})"]
        cells += [f"{x:.2f} s" for x in (t_check, t_write, t_png, t_mesh)] + [str(n_tet)]
        print(" | ".join(cells), flush=True)
    print("\nseconds, one run each on this machine; 'build+check' includes the tessellation "
          "and the printability checks")


if __name__ == "__main__":
    main()
