"""Build / tessellate / check / export / mesh time of every default part (seconds, one run each).

Peer in the same run: our tessellation (OpenCascade BRepMesh read into numpy, then one trimesh
merge) against build123d's own ``Shape.tessellate`` (Vector lists) followed by the same merge, at
the print tolerance (0.01 mm, 0.2 rad). ``mesh`` is :func:`designlab.geometry.meshing.mesh_part`
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

    s = shape if isinstance(shape, Shape) else Shape.cast(shape.wrapped)
    verts, tris = s.tessellate(tol, ang)
    v = np.array([(p.X, p.Y, p.Z) for p in verts])
    return trimesh.Trimesh(v, np.asarray(tris), process=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--no-mesh", action="store_true", help="skip tetrahedral meshing")
    args = ap.parse_args()
    try:
        from designlab.geometry.meshing import mesh_part
    except ImportError:
        mesh_part = None
    rows = []
    for name in args.parts.split(","):
        part = make_part(name, None, None)
        bodies, t_build = timed(part.build)
        printed = [b for b in bodies.values() if b.printed]
        t_ours = t_peer = 0.0
        n_tri = 0
        for b in printed:
            # fresh shapes each time: OpenCascade caches a triangulation on the shape
            m, dt = timed(tessellate, make_part(name, None, None).build()[b.name].shape,
                          PRINT_TOLERANCE, PRINT_ANGULAR_TOLERANCE)
            t_ours += dt
            n_tri += len(m.faces)
            m2, dt = timed(build123d_tessellate, make_part(name, None, None).build()[b.name].shape,
                           PRINT_TOLERANCE, PRINT_ANGULAR_TOLERANCE)
            t_peer += dt
            assert abs(m2.volume - m.volume) <= 1e-6 * abs(m.volume), (b.name, m.volume, m2.volume)
        prepared, t_check = timed(prepare, name, make_part(name, None, None).build())
        with tempfile.TemporaryDirectory() as tmp:
            _, t_write = timed(write, prepared, tmp, ("stl", "3mf", "step", "gltf"), False)
            _, t_png = timed(write, prepared, tmp, ("3mf",), True)
        t_mesh = float("nan")
        n_tet = 0
        if mesh_part is not None and not args.no_mesh:
            mesh, t_mesh = timed(mesh_part, make_part(name, None, None))
            n_tet = mesh.n_cells
        rows.append((name, len(bodies), n_tri, t_build, t_ours, t_peer, t_check, t_write,
                     t_png, t_mesh, n_tet))
    head = ("part", "bodies", "print tris", "build", "tessellate", "b123d peer", "build+check",
            "write stl/3mf/step/glb", "3mf+png", "mesh", "tets")
    print(" | ".join(head))
    print(" | ".join("---" for _ in head))
    for r in rows:
        print(" | ".join([r[0], str(r[1]), str(r[2])] + [f"{x:.2f} s" for x in r[3:10]]
                         + [str(r[10])]))
    print("\nseconds, one run each on this machine; 'build+check' includes the tessellation "
          "and the printability checks")


if __name__ == "__main__":
    main()
