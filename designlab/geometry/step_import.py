"""Named solids from a STEP file: the geometry of a sensor definition drawn in any CAD program.

A STEP file written as an assembly (AP214/AP242 with XCAF names: FreeCAD, Onshape, SolidWorks,
Fusion and designlab's own export write one) names each part; :func:`step_solids` returns
``{name: build123d solid}`` in mm, each placed where the assembly puts it, for a definition's
``bodies()``::

    solids = dl.step_solids(Path(__file__).parent / "my_sensor.step")
    return {"beam": dl.Solid(solids["beam"], "PLA")}
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from designlab.errors import ParameterError

#: {(path, size, mtime): solids} of the files read in this process
_READ: dict[tuple, dict[str, Any]] = {}


def step_solids(path: str | Path) -> dict[str, Any]:
    """``{part name: build123d Solid}`` of the STEP file at ``path``: one solid per named part
    (the file's units converted to mm); a one-line error naming the file when it cannot be read,
    names no part, names one twice or a part holds no solid or several."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise ParameterError("step", str(p), "an existing STEP file (.step or .stp)")
    st = p.stat()
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _READ:
        _READ.clear()
        _READ[key] = _read(p)
    return dict(_READ[key])


def _read(p: Path) -> dict[str, Any]:
    import cadquery as cq
    from build123d import Solid

    try:
        assy = cq.Assembly.importStep(str(p))
    except Exception as exc:  # noqa: BLE001 - OCCT's reader: any failure is a bad file
        raise ParameterError("step", str(p), f"a readable STEP file ({type(exc).__name__})"
                             ) from None
    out: dict[str, Any] = {}

    def walk(node, loc) -> None:
        here = loc * node.loc
        if node.obj is not None:
            shape = node.obj if isinstance(node.obj, cq.Shape) else node.obj.val()
            solids = shape.moved(here).Solids()
            if len(solids) != 1:
                raise ParameterError(f"step part {node.name}", f"{len(solids)} solids",
                                     f"one solid per named part of {p.name}")
            if node.name in out:
                raise ParameterError("step", node.name, f"part names used once in {p.name}")
            out[node.name] = Solid(solids[0].wrapped)
        for child in node.children:
            walk(child, here)

    walk(assy, cq.Location())
    if not out:
        raise ParameterError("step", str(p), "a STEP file with named solid parts (an assembly)")
    return out
