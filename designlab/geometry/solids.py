"""Small shape helpers shared by the parametric parts (build123d, mm).

``single_solid`` turns a boolean result into the one valid ``Solid`` a :class:`Body` holds;
``annular_sector`` is the planar building block of the strap's arch and meanders.
"""

from __future__ import annotations

import math

import numpy as np
from build123d import CenterArc, Face, Line, Solid, Vector, Wire

from designlab.errors import ModelError


def single_solid(shape, name: str) -> Solid:
    """The single solid of ``shape`` (a Part/Compound/Solid); anything else is a ModelError."""
    solids = shape.solids() if hasattr(shape, "solids") else [shape]
    if len(solids) != 1:
        raise ModelError(f"{name}: boolean result has {len(solids)} solids, expected 1")
    s = solids[0]
    if not s.is_valid:
        raise ModelError(f"{name}: the solid is not valid (OCC check failed)")
    return s


def annular_sector(center: tuple[float, float], r_in: float, r_out: float,
                   phi0: float, phi1: float, z: float = 0.0) -> Face:
    """Planar ring sector in the plane ``z``: radii ``[r_in, r_out]`` mm, angles ``[phi0, phi1]``
    rad measured from +y towards +x (``phi = 0`` is the arch apex direction)."""
    if not (0 <= r_in < r_out and phi1 > phi0):
        raise ModelError(f"bad annular sector r=[{r_in}, {r_out}] phi=[{phi0}, {phi1}]")
    cx, cy = center
    # build123d angles: degrees from +x counter-clockwise
    start = 90.0 - math.degrees(phi1)
    size = math.degrees(phi1 - phi0)
    c = Vector(cx, cy, z)

    def pt(r: float, phi: float) -> Vector:
        return Vector(cx + r * math.sin(phi), cy + r * math.cos(phi), z)

    outer = CenterArc(c, r_out, start, size)
    if r_in > 0:
        inner = CenterArc(c, r_in, start, size)
        edges = [outer, Line(pt(r_out, phi0), pt(r_in, phi0)), inner,
                 Line(pt(r_in, phi1), pt(r_out, phi1))]
    else:
        edges = [outer, Line(pt(r_out, phi0), c), Line(c, pt(r_out, phi1))]
    return Face(Wire(edges))


def polygon_face(points, z: float = 0.0) -> Face:
    """Planar polygon face in the plane ``z`` with normal +z (points (k, 2), any orientation)."""
    pts = np.asarray(points, dtype=float)
    x, y = pts[:, 0], pts[:, 1]
    if np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) < 0:
        pts = pts[::-1]
    return Face(Wire.make_polygon([(q[0], q[1], z) for q in pts], close=True))


def volume(shape, eps: float = 1e-7) -> float:
    """Volume (mm^3) integrated to relative precision ``eps``: OCC's default (``shape.volume``)
    is off by ~0.5 % on trimmed swept B-spline faces such as a ground spring's ends."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, props, eps)
    return float(props.Mass())


def unit(v) -> np.ndarray:
    """``v`` scaled to unit length (float array)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)
