"""FEM 6x6 stiffness of a flexure: base clamped, tip coupled to a rigid 6-dof master (mm, N, MPa).

Six unit load cases at the master (three moments, three forces) give the columns of the
compliance ``C`` (twist (w, v) per wrench (m, f)); ``K = C^-1``. The compliance of a symmetric
linear model is symmetric, so ``||C - C^T|| / ||C||`` measures round-off and solver error only;
``K`` is returned symmetrised. :func:`stiffness_6x6` works on any mesh with a base and a tip set;
:func:`fem_stiffness` meshes a helical spring flexure (the parts helper's ``SpringFlexure``) and
expresses the result at the spring centre, as the closed form (:mod:`designlab.sensors.flexure.spring`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.sensors.flexure.spring import HelicalSpring, to_si
from designlab.fem.static import solve_static
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import TetMesh

Progress = Callable[[str, int, int], None]
_CASES = (("m_x", (0, 0, 0), (1, 0, 0)), ("m_y", (0, 0, 0), (0, 1, 0)), ("m_z", (0, 0, 0), (0, 0, 1)),
          ("f_x", (1, 0, 0), (0, 0, 0)), ("f_y", (0, 1, 0), (0, 0, 0)), ("f_z", (0, 0, 1), (0, 0, 0)))


@dataclass(frozen=True)
class FlexureFEM:
    """FEM 6x6 of a flexure. ``K`` (N*mm/rad, N/mm, N) in a frame at ``master`` (global axes);
    ``C_raw`` the unsymmetrised compliance; ``centre`` the point where :attr:`K_centre` sits."""

    K: np.ndarray
    C_raw: np.ndarray
    master: np.ndarray
    centre: np.ndarray
    asymmetry: float
    n_nodes: int
    n_cells: int
    cell_nodes: int
    solver: str

    def at(self, point) -> np.ndarray:
        """K expressed in a frame at ``point`` (mm, global axes)."""
        return transform_stiffness(self.K, transform(translation=self.master - np.asarray(point, float)))

    @property
    def K_centre(self) -> np.ndarray:
        """K at the spring centre, designlab units."""
        return self.at(self.centre)

    @property
    def K_centre_si(self) -> np.ndarray:
        """K at the spring centre, SI (N*m/rad, N/m, N)."""
        return to_si(self.K_centre)

    def summary(self) -> dict:
        return {"n_nodes": self.n_nodes, "n_cells": self.n_cells, "cell_nodes": self.cell_nodes,
                "asymmetry": self.asymmetry, "master_mm": self.master.tolist(),
                "centre_mm": self.centre.tolist(), "solver": self.solver,
                "K_master": self.K.tolist(), "K_centre_si": self.K_centre_si.tolist()}


def stiffness_6x6(mesh: TetMesh, base: str, tip: str, master=None, centre=None,
                  materials: dict | None = None, solver: str = "auto",
                  progress: Progress | None = None) -> FlexureFEM:
    """6x6 stiffness of ``mesh`` with the set ``base`` clamped and ``tip`` rigid to a master.

    master: point of the 6-dof master (mm; default the centroid of the tip nodes).
    centre: reference point reported as :attr:`FlexureFEM.K_centre` (default midway between the
            base and tip centroids).
    """
    step = progress or (lambda text, done, total: None)
    step("assembling", 0, 3)
    model = Model(mesh, materials=materials)
    model.fix(base)
    ref = model.rigid("tip_master", tip, ref_point=master)
    for name, f, m in _CASES:
        model.force(ref, force=f, moment=m, case=name)
    step("solving 6 load cases", 1, 3)
    res = solve_static(model, solver=solver)
    step("compliance", 2, 3)
    C = np.column_stack([res.twist(ref, name) for name, _, _ in _CASES])
    asym = float(np.linalg.norm(C - C.T) / np.linalg.norm(C))
    Cs = (C + C.T) / 2
    try:
        K = np.linalg.inv(Cs)
    except np.linalg.LinAlgError:
        raise ModelError("FEM compliance of the flexure is singular: check the base/tip sets") from None
    K = (K + K.T) / 2
    base_c = mesh.points[model.nodes(base)].mean(axis=0)
    tip_c = mesh.points[model.nodes(tip)].mean(axis=0)
    cen = (base_c + tip_c) / 2 if centre is None else np.asarray(centre, float)
    step("done", 3, 3)
    return FlexureFEM(K=K, C_raw=C, master=np.asarray(ref.x, float), centre=cen, asymmetry=asym,
                      n_nodes=mesh.n_points, n_cells=mesh.n_cells, cell_nodes=mesh.cells.shape[1],
                      solver=type(res.solver).__name__)


def flexure_from_spring(spring: HelicalSpring, **kw):
    """The parts helper's ``SpringFlexure`` with this spring's wire, diameter, pitch and coils.

    ``inactive_coils`` 0 -> plain ends, 2 -> closed-and-ground ends (one dead coil each end);
    other values have no geometry and raise ParameterError. ``kw`` sets disc parameters (by
    default the part's, widened/narrowed to clear the coil; the discs are not meshed).
    """
    from designlab.geometry.flexure import SpringFlexure

    ends = {0.0: "plain", 2.0: "closed_ground"}.get(float(spring.inactive_coils))
    if ends is None:
        raise ParameterError("inactive_coils", spring.inactive_coils,
                             "0 (plain ends) or 2 (closed and ground ends) for the FEM geometry")
    R, r = spring.mean_radius, spring.wire_radius
    defaults = {f.name: f.default for f in dataclasses.fields(SpringFlexure)}
    kw.setdefault("disc_radius", max(defaults["disc_radius"], R + r + 1.0))
    kw.setdefault("disc_bore", max(0.0, min(defaults["disc_bore"], R - r - 1.0)))
    return SpringFlexure(wire_radius=r, mean_diameter=spring.mean_diameter,
                         pitch_angle=spring.pitch_angle, active_coils=spring.active_coils,
                         ends=ends, **kw)


def spring_material(spring: HelicalSpring) -> Material:
    """Isotropic wire material with the spring's E and G (nu = E / 2G - 1)."""
    return Material("spring_wire", E=spring.E, nu=spring.E / (2.0 * spring.G) - 1.0,
                    source="HelicalSpring E, G")


def fem_stiffness(spring, edge_length: float | None = None, order: int = 2,
                  quality: str = "default", solver: str = "direct",
                  progress: Progress | None = None) -> FlexureFEM:
    """FEM 6x6 of a spring flexure: mesh the helix, clamp ``flexure_base``, rigid ``flexure_tip``.

    spring:      a :class:`~designlab.sensors.flexure.spring.HelicalSpring` (its E, G are used for the wire)
                 or a ``SpringFlexure`` (its material name is used).
    edge_length: tet edge length, mm (default: the wire radius).
    solver:      "direct" by default: a slender wire has little fill-in (114k TET10 dofs of the
                 Visiflex helix factor in ~10 s) while AMG-CG converges slowly on it.
    The master sits on the axis at the tip face (``z = length``); :attr:`FlexureFEM.K_centre` is
    at the spring centre ``(0, 0, length / 2)``, the closed form's frame.
    """
    from designlab.mesh.meshing import mesh_part

    step = progress or (lambda text, done, total: None)
    if isinstance(spring, HelicalSpring):
        flexure, materials = flexure_from_spring(spring), {"spring": spring_material(spring)}
    else:
        flexure, materials = spring, None
    h = flexure.wire_radius if edge_length is None else float(edge_length)
    if not (np.isfinite(h) and h > 0):
        raise ParameterError("edge_length", edge_length, "a number > 0 mm")
    step("meshing the helix (fTetWild)", 0, 4)
    mesh = mesh_part(flexure, order=order, edge_length=h, quality=quality)
    L = float(flexure.length)

    def sub(text, done, total):
        step(text, 1 + done, 4)

    return stiffness_6x6(mesh, "flexure_base", "flexure_tip", master=(0.0, 0.0, L),
                         centre=(0.0, 0.0, L / 2), materials=materials, solver=solver,
                         progress=sub)
