"""Coloured cadquery assemblies of a part's bodies, saved as STEP and glTF (atomically).

build123d and cadquery share the OCP kernel: each body's ``shape.wrapped`` (a ``TopoDS_Shape``)
is cast to a ``cadquery.Shape`` and added under the body's name with its colour. All bodies are
included, bought parts (ball, bolt, sensors) too.
"""

from __future__ import annotations

from pathlib import Path

import cadquery as cq

from designlab.atomic import atomic_path
from designlab.errors import OutputError
from designlab.geometry.body import Body


def assembly(part, name: str | None = None) -> cq.Assembly:
    """A ``cadquery.Assembly`` with one named, coloured child per body of ``part.build()``."""
    bodies: dict[str, Body] = part.build()
    name = name or type(part).__name__
    if name in bodies:  # cadquery needs unique names, the root's included
        name += "_assembly"
    assy = cq.Assembly(name=name)
    for body in bodies.values():
        shape = cq.Shape.cast(body.shape.wrapped)
        assy.add(shape, name=body.name, color=cq.Color(*body.color, 1.0))
    return assy


def _atomic(path: str | Path, write) -> Path:
    with atomic_path(path) as tmp:
        write(str(tmp))
    return Path(path)


def save_assembly_step(assy: cq.Assembly, path: str | Path) -> Path:
    """Coloured, named STEP (AP214 via XCAF) of ``assy``; written atomically."""
    from cadquery.occ_impl.exporters.assembly import exportAssembly

    def write(tmp):
        if not exportAssembly(assy, tmp):   # OpenCascade says no more than that
            import shutil

            free = shutil.disk_usage(Path(tmp).parent).free
            raise OutputError(f"STEP export of {path} failed (OpenCascade wrote no file; "
                              f"{free / 1e6:.3g} MB free on its disk)")
    return _atomic(path, write)


def save_assembly_gltf(assy: cq.Assembly, path: str | Path, tolerance: float = 0.05,
                       angular_tolerance: float = 0.2) -> Path:
    """Coloured glTF of ``assy`` (binary for ``.glb``, text for ``.gltf``), mm; atomic."""
    from cadquery.occ_impl.exporters.assembly import exportGLTF

    binary = Path(path).suffix.lower() == ".glb"

    def write(tmp):
        try:
            ok = exportGLTF(assy, tmp, binary=binary, tolerance=tolerance,
                            angularTolerance=angular_tolerance)
        finally:   # the writer's buffer file beside a .glb (left when the disk is full)
            if binary:
                Path(tmp).with_suffix(".bin.tmp").unlink(missing_ok=True)
        if not ok:
            raise OutputError(f"glTF export of {path} failed")
    return _atomic(path, write)
