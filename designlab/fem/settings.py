"""Settings every virtual test shares: the mesh (edge length, element order, quality preset) and
the linear solver (mm)."""

from __future__ import annotations

from dataclasses import dataclass, field

from designlab.fem.solvers import SOLVERS
from designlab.mesh.meshing import MESHERS
from designlab.mesh.meshing import PRESETS as MESH_QUALITY
from designlab.params import rng, validate


@dataclass(frozen=True)
class FEMSettings:
    """Mesh and solver settings of a virtual test. A sensor's settings class derives from this
    one and may change the defaults (``edge_length`` of a thin strap differs from a helix)."""

    edge_length: float = field(default=2.0, metadata=rng(0.1, 10, unit="mm",
                               doc="ideal tetrahedron edge length"))
    order: int = field(default=2, metadata=rng(choices=(1, 2), doc="1 = TET4, 2 = TET10"))
    mesh_quality: str = field(default="coarse", metadata=rng(
        choices=tuple(MESH_QUALITY), doc="meshing preset: scales the edge length and the "
        "part's local refinement"))
    mesher: str = field(default="auto", metadata=rng(
        choices=MESHERS, doc="auto: gmsh from the B-rep, fTetWild if gmsh fails; tetwild: the "
        "previous pipeline (tessellate, then fTetWild)"))
    solver: str = field(default="auto", metadata=rng(choices=SOLVERS,
                        doc="linear solver (designlab.fem.solvers; auto: SuperLU on small "
                            "models, PARDISO/CHOLMOD on large ones where installed)"))
    mesh_convergence: bool = field(default=True, metadata=rng(
        doc="also solve one coarser mesh (edge_length x coarse_factor) and report each "
            "metric's change: the prediction's discretisation error bar"))
    coarse_factor: float = field(default=1.5, metadata=rng(1.1, 4, doc="edge length ratio of "
                                                          "the coarser mesh"))

    def __post_init__(self):
        validate(self)
