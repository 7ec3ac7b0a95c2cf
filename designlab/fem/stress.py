"""Stress of a solved mesh under named load cases, and the safety factor of every body against
its material's strength (:attr:`designlab.fem.materials.Material.strength`).

The stress of a load case is computed from its displacement with the *long-time* moduli
(``E (1 - sum g)`` of a Prony series; elastic materials: ``E``): a virtual test reads its
load after holding it, and the displacement handed in is the long-time one. For a single
material the stress field of a load is independent of the modulus; where two materials meet,
the relaxed moduli give the stress that carries the held load.

Units: MPa, mm. Von Mises per cell is the largest over the cell's quadrature points; the nodal
field (for a VTU) is the largest over the cells that share the node.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from designlab.fem.materials import Material, get_material
from designlab.fem.static import elastic_stress, von_mises
from designlab.mesh.tetmesh import TetMesh

#: below this safety factor a prediction warns
WARN_SAFETY_FACTOR = 2.0


def relaxed(material: Material) -> Material:
    """The material with its long-time moduli (shear and bulk relax by their Prony terms)."""
    p = material.prony
    if p is None:
        return material
    G, K = material.G * p.g_inf, material.K * (p.k_inf if p.k else 1.0)
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    return dataclasses.replace(material, E=E, nu=nu, prony=None)


@dataclass
class CaseStress:
    """Von Mises stress of one load case: per cell (m,), per node (n,), MPa."""

    name: str
    description: str
    cell: np.ndarray
    node: np.ndarray


def _region_materials(mesh: TetMesh, materials: Mapping[str, Material | str] | None
                      ) -> dict[int, Material]:
    out = {}
    for rid in np.unique(mesh.region):
        body = mesh.region_names.get(int(rid), str(rid))
        spec = (materials or {}).get(body, mesh.materials.get(body))
        out[int(rid)] = spec if isinstance(spec, Material) else get_material(spec)
    return out


def case_stresses(mesh: TetMesh, cases: Mapping[str, tuple[str, np.ndarray]],
                  materials: Mapping[str, Material | str] | None = None) -> list[CaseStress]:
    """Von Mises stress of each load case ``{name: (description, displacement (n, 3) mm)}``."""
    from designlab.fem.assembly import cell_basis, strain_operator

    mats = {rid: relaxed(m) for rid, m in _region_materials(mesh, materials).items()}
    lut_G, lut_K = (np.zeros(max(mats) + 1) for _ in range(2))
    for rid, m in mats.items():
        lut_G[rid], lut_K[rid] = m.G, m.K
    G, K = lut_G[mesh.region], lut_K[mesh.region]
    B = strain_operator(cell_basis(mesh))
    out = []
    for name, (desc, u) in cases.items():
        eps = (B @ np.asarray(u, float).reshape(-1)).reshape(mesh.n_cells, -1, 6)
        vm = von_mises(elastic_stress(eps, K, G)).max(axis=1)
        node = np.zeros(mesh.n_points)
        for j in range(mesh.cells.shape[1]):
            np.maximum.at(node, mesh.cells[:, j], vm)
        out.append(CaseStress(name, desc, vm, node))
    return out


def stress_report(mesh: TetMesh, stresses: list[CaseStress],
                  materials: Mapping[str, Material | str] | None = None) -> dict[str, Any]:
    """The ``stress`` section of ``prediction.json``: per load case and body the largest von
    Mises stress, where (cell centroid, mm), the material's strength and the safety factor;
    the smallest safety factor over everything and where it is."""
    mats = _region_materials(mesh, materials)
    centroids = mesh.points[mesh.cells[:, :4]].mean(axis=1)
    cases: dict[str, Any] = {}
    worst: dict[str, Any] | None = None
    for cs in stresses:
        bodies = {}
        for rid, mat in mats.items():
            body = mesh.region_names.get(rid, str(rid))
            idx = np.flatnonzero(mesh.region == rid)
            if not len(idx):
                continue
            k = idx[int(np.argmax(cs.cell[idx]))]
            smax = float(cs.cell[k])
            sf = (mat.strength / smax if mat.strength is not None and smax > 0
                  else (float("inf") if mat.strength is not None else None))
            entry = {"material": mat.name, "max_von_mises_MPa": smax,
                     "at_mm": [float(x) for x in centroids[k]], "strength_MPa": mat.strength,
                     "safety_factor": sf}
            bodies[body] = entry
            if sf is not None and (worst is None or sf < worst["safety_factor"]):
                worst = {"load_case": cs.name, "body": body, **entry}
        cases[cs.name] = {"description": cs.description, "bodies": bodies}
    strengths = {m.name: {"strength_MPa": m.strength, "basis": m.strength_basis,
                          "source": m.strength_source} for m in mats.values()}
    return {
        "method": ("von Mises stress of each load case from its long-time displacement with "
                   "the relaxed moduli; largest over a cell's quadrature points; safety factor "
                   "= material strength / largest von Mises stress of the body"),
        "load_cases": cases,
        "materials": strengths,
        "min_safety_factor": None if worst is None else worst["safety_factor"],
        "critical": worst,
        "max_von_mises_MPa": max((float(cs.cell.max()) for cs in stresses), default=None),
        "warn_below": WARN_SAFETY_FACTOR,
    }


def stress_warnings(report: Mapping[str, Any]) -> list[str]:
    """One line per body and load case whose safety factor is below
    :data:`WARN_SAFETY_FACTOR`, and one per material without a documented strength."""
    out = []
    for name, case in report.get("load_cases", {}).items():
        for body, e in case["bodies"].items():
            sf = e.get("safety_factor")
            if sf is not None and sf < WARN_SAFETY_FACTOR:
                x, y, z = e["at_mm"]
                out.append(f"safety factor {sf:.2g} < {WARN_SAFETY_FACTOR:g} in {body} "
                           f"({e['material']}) under {name}: von Mises "
                           f"{e['max_von_mises_MPa']:.3g} MPa vs strength "
                           f"{e['strength_MPa']:.3g} MPa at ({x:.1f}, {y:.1f}, {z:.1f}) mm")
    for m, s in report.get("materials", {}).items():
        if s.get("strength_MPa") is None:
            out.append(f"{m}: no documented strength, no safety factor for its bodies")
    return out
