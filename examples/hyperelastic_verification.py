"""Print the verification numbers of designlab.fem.hyperelastic (docs/hyperelastic.md).

    .venv/bin/python examples/hyperelastic_verification.py

The same problems as tests/fem/test_hyperelastic.py, with the measured errors printed instead of
asserted: tangent vs central differences, uniaxial stretch vs the closed form, the small-strain
limit vs solve_static, and CalculiX (*HYPERELASTIC, NEO HOOKE, NLGEOM) on a bonded block at
30 % compression and a cantilever at 59 % tip deflection; plus the cost of one Newton
iteration's assembly on a 9600-cell TET10 block.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.hyperelastic import (Continuum, NeoHooke, solve_calculix_neo_hooke,  # noqa: E402
                                        solve_hyperelastic, uniaxial_closed_form)
from designlab.fem.materials import Material  # noqa: E402
from designlab.mesh.tetmesh import box_tet_mesh  # noqa: E402

MAT = Material("soft", E=1.0, nu=0.45)
STIFF = Material("stiff", E=20.0, nu=0.3)
NH = NeoHooke.from_linear(MAT.E, MAT.nu)


def two_bodies(order):
    mesh = box_tet_mesh(8.0, 2.0, 2.0, 4, 2, 2, material="ABS")
    x = mesh.points[mesh.cells[:, :4]].mean(1)[:, 0]
    mesh = dataclasses.replace(mesh, region=(x > 4.0).astype(np.int64),
                               region_names={0: "soft", 1: "stiff"},
                               materials={"soft": "soft", "stiff": "stiff"})
    return mesh.quadratic() if order == 2 else mesh


def tangent_error(order):
    mesh = two_bodies(order)
    cont = Continuum.of(Model(mesh, {"soft": MAT, "stiff": STIFF}), {"soft": NH})
    u = 0.03 * np.random.default_rng(7).standard_normal(3 * mesh.n_points)
    K = cont.tangent(cont.stress(cont.displacement_gradient(u), True)[1]).toarray()
    Kfd = np.zeros_like(K)
    for j in range(len(u)):
        d = np.zeros_like(u)
        d[j] = 1e-6
        f = [cont.internal_force(cont.stress(cont.displacement_gradient(u + s * d), False)[0])
             for s in (1, -1)]
        Kfd[:, j] = (f[0] - f[1]) / 2e-6
    return float(np.abs(K - Kfd).max() / np.abs(K).max())


def uniaxial_error(order, stretch):
    nh = NeoHooke.from_linear(1.0, 0.4)
    L = (2.0, 3.0, 4.0)
    mesh = box_tet_mesh(*L, 2, 2, 3, material="soft")
    mesh = mesh.quadratic() if order == 2 else mesh
    m = Model(mesh, {"block": MAT})
    m.fix("xmin", "x")
    m.fix("ymin", "y")
    m.fix("zmin", "z")
    m.prescribe("xmax", ((stretch - 1) * L[0], None, None))
    r = solve_hyperelastic(m, {"block": nh}, steps=4, rtol=1e-12)
    P11, _ = uniaxial_closed_form(nh, stretch)
    f = r.reactions()[m.nodes("xmax"), 0].sum() / (L[1] * L[2])
    return float(abs(f / P11 - 1)), float(P11)


def small_strain(order, scale):
    m = Model(two_bodies(order), {"soft": MAT, "stiff": STIFF})
    m.fix("xmin")
    m.traction("xmax", (0.0, 0.0, -scale))
    lin = solve_static(m).displacement()
    nl = solve_hyperelastic(m, {"soft": NH}, steps=1, rtol=1e-12).displacement()
    return float(np.abs(nl - lin).max() / np.abs(lin).max()), float(np.abs(lin).max() / 8.0)


def ccx_block(order):
    nh = NeoHooke.from_linear(1.0, 0.45)
    mesh = box_tet_mesh(10, 10, 10, 4, 4, 4, material="soft")
    mesh = mesh.quadratic() if order == 2 else mesh
    m = Model(mesh, {"block": MAT})
    m.fix("zmin")
    m.prescribe("zmax", (0.0, 0.0, -3.0))
    t = time.perf_counter()
    r = solve_hyperelastic(m, {"block": nh}, steps=5)
    ours = time.perf_counter() - t
    u = r.displacement()
    bot, top = m.nodes("zmin"), m.nodes("zmax")
    pres = np.array([(n, d, 0.0) for n in bot for d in range(3)]
                    + [(n, d, -3.0 if d == 2 else 0.0) for n in top for d in range(3)])
    t = time.perf_counter()
    uc = solve_calculix_neo_hooke(mesh, {0: nh}, pres, np.zeros((mesh.n_points, 3)),
                                  increment=0.2)
    ccx = time.perf_counter() - t
    lam = r.principal_stretches()
    return {"max_err_over_max_u": float(np.abs(u - uc).max() / np.abs(u).max()),
            "bulge_mm": float(np.abs(u[:, :2]).max()),
            "linear_bulge_mm": float(np.abs(solve_static(m).displacement()[:, :2]).max()),
            "stretch_min": float(lam.min()), "stretch_max": float(lam.max()),
            "ours_s": round(ours, 2), "ccx_s": round(ccx, 2), **r.summary()}


def ccx_cantilever(increment):
    nh = NeoHooke.from_linear(1.0, 0.45)
    mesh = box_tet_mesh(20, 2, 2, 10, 2, 2, material="soft").quadratic()
    m = Model(mesh, {"block": MAT})
    m.fix("xmin")
    tip = m.nodes("xmax")
    f = np.zeros((mesh.n_points, 3))
    f[tip, 2] = -0.01 / len(tip)
    m.nodal_force(tip, (0.0, 0.0, -0.01 / len(tip)))
    r = solve_hyperelastic(m, {"block": nh}, steps=10)
    u = r.displacement()
    pres = np.array([(n, d, 0.0) for n in m.nodes("xmin") for d in range(3)])
    uc = solve_calculix_neo_hooke(mesh, {0: nh}, pres, f, increment=increment)
    return {"ccx_increment": increment,
            "max_err_over_max_u": float(np.abs(u - uc).max() / np.abs(u).max()),
            "tip_deflection_over_length": float(-u[tip, 2].mean() / 20),
            "max_axial_green_strain": float(np.abs(r.green_strain()[..., 0]).max()),
            **r.summary()}


def assembly_cost():
    mesh = box_tet_mesh(20, 10, 10, 20, 10, 8, material="soft").quadratic()
    m = Model(mesh, {"block": MAT})
    cont = Continuum.of(m, {"block": NH})
    u = np.zeros(3 * mesh.n_points)
    m.basis
    out = []
    for _ in range(3):
        t, c = time.perf_counter(), time.process_time()
        P, A = cont.stress(cont.displacement_gradient(u), True)
        cont.internal_force(P)
        cont.tangent(A)
        out.append((time.perf_counter() - t, time.process_time() - c))
    w, c = min(out)
    return {"cells": int(mesh.n_cells), "dofs": int(3 * mesh.n_points),
            "stress_force_tangent_wall_s": round(w, 3), "cpu_s": round(c, 3)}


if __name__ == "__main__":
    rows = {"tangent_fd_rel_err": {f"TET{4 if o == 1 else 10}": tangent_error(o) for o in (1, 2)},
            "uniaxial_rel_err": {f"TET{4 if o == 1 else 10} stretch {s}": uniaxial_error(o, s)[0]
                                 for o in (1, 2) for s in (1.5, 0.7)},
            "small_strain_vs_linear": {f"TET{4 if o == 1 else 10} traction {s:g}":
                                       small_strain(o, s) for o in (1, 2) for s in (1e-8, 1e-5)}}
    if shutil.which("ccx"):
        rows["calculix_block_30pc"] = {f"TET{4 if o == 1 else 10}": ccx_block(o) for o in (1, 2)}
        rows["calculix_cantilever"] = [ccx_cantilever(i) for i in (0.05, 0.1)]
    rows["assembly"] = assembly_cost()
    print(json.dumps(rows, indent=1, default=float))
