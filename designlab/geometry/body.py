"""A named solid with a material: what every part's ``build()`` returns.

``FacetSelector`` is how a part names boundary regions for analysis without knowing the mesh:
a function of boundary-triangle centroids and outward unit normals (both (k, 3), mm) returning a
boolean mask. The mesher applies it to the boundary of the tetrahedral mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

FacetSelector = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class Body:
    """One printable/meshable solid.

    name:     unique within the part, e.g. ``"strap"``, ``"trace_left"``, ``"fingertip"``
    shape:    a build123d ``Part``/``Solid`` (OCP kernel), mm
    material: a material name known to :mod:`designlab.fem.materials`
    color:    RGB in 0..1, for rendering and coloured STEP/glTF
    extruder: 1-based extruder for multi-material 3MF (strap = 1, traces = 2)
    printed:  False for bought parts (steel ball, bolt, force sensors): not exported for printing
    """

    name: str
    shape: Any
    material: str
    color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    extruder: int = 1
    printed: bool = True
