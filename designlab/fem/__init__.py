"""Finite elements: TET4/TET10 elasticity, Prony viscoelasticity, large deformation, contacts,
transducers and solvers (mm N MPa s).

The sensor-free solver layer the sensor models stand on: a :class:`Model` (mesh, materials,
supports, loads, couplings, springs) solved by :func:`solve_static` or, over time,
:func:`solve_history`. A tour of the API: docs/reference/fem.md.
"""

from designlab.fem.materials import MATERIALS, Material, get_material
from designlab.fem.model import Model, RefPoint, Spring, System
from designlab.fem.solvers import factorize
from designlab.fem.static import StaticResult, solve_static
from designlab.fem.history import History, HistoryResult
from designlab.fem.viscoelastic import solve_history

__all__ = ["MATERIALS", "Material", "get_material", "Model", "RefPoint", "Spring", "System",
           "factorize", "StaticResult", "solve_static", "History", "HistoryResult",
           "solve_history"]
