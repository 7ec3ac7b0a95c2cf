"""Verification cases of the FEM against closed forms, manufactured solutions, exact
viscoelastic responses and CalculiX.

Each case function returns a list of case dicts ``{"name", "quantity", "value", "reference",
"rel_error", "tolerance", "passed"}``; :func:`run_cases` runs them all and :func:`write_report`
writes ``verify.json`` atomically. Units: mm, N, MPa, s.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import numpy as np
import scipy.sparse.linalg as spla

from designlab.errors import ParameterError
from designlab.fem.assembly import cell_basis, stiffness
from designlab.fem.elements import tet_element, tet_quadrature
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.prony import Prony
from designlab.fem.static import solve_static
from designlab.mesh.tetmesh import TetMesh, box_tet_mesh

#: the elastic material of the static cases (MPa)
ELASTIC = Material("verify", E=2000.0, nu=0.3)


def case(name: str, quantity: str, value: float, reference: float, tolerance: float,
         rel_error: float | None = None) -> dict:
    """One verification result; ``rel_error`` defaults to |value - reference| / |reference|."""
    if rel_error is None:
        rel_error = abs(value - reference) / abs(reference) if reference != 0 else abs(value)
    rel_error = float(rel_error)
    return {"name": name, "quantity": quantity, "value": float(value),
            "reference": float(reference), "rel_error": rel_error, "tolerance": float(tolerance),
            "passed": bool(np.isfinite(rel_error) and rel_error <= tolerance)}


# --------------------------------------------------------------------------- meshes


def distorted_box(nx: int, ny: int, nz: int, size=(2.0, 1.0, 1.5), amount: float = 0.25,
                  order: int = 1, seed: int = 0) -> TetMesh:
    """Box mesh whose interior corner nodes are moved randomly by up to ``amount`` of the
    local spacing (straight-sided cells); TET10 mid-nodes are placed after distortion."""
    m = box_tet_mesh(*size, nx, ny, nz)
    h = np.array(size) / [nx, ny, nz]
    bnodes = np.unique(np.concatenate([f.ravel() for f in m.facet_sets.values()]))
    inner = np.setdiff1d(np.arange(m.n_points), bnodes)
    rng = np.random.default_rng(seed)
    pts = m.points.copy()
    pts[inner] += amount * h * rng.uniform(-1, 1, (len(inner), 3))
    m = TetMesh(pts, m.cells, m.region, m.region_names, m.materials, m.facet_sets)
    return m.quadratic() if order == 2 else m


def _boundary_nodes(mesh: TetMesh) -> np.ndarray:
    return np.unique(np.concatenate([np.asarray(f).ravel() for f in mesh.facet_sets.values()]))


def _elem(order: int) -> str:
    return "TET4" if order == 1 else "TET10"


# --------------------------------------------------------------------------- static cases


def patch_test(orders=(1, 2)) -> list[dict]:
    """Displacement patch test on a distorted mesh: a linear field prescribed on the boundary
    is reproduced exactly inside, and so is its constant stress."""
    A = 1e-3 * np.array([[1.0, 0.4, -0.3], [0.2, -0.6, 0.5], [-0.7, 0.1, 0.8]])
    c = np.array([0.01, -0.02, 0.03])
    out = []
    for order in orders:
        mesh = distorted_box(3, 3, 3, order=order, seed=1)
        model = Model(mesh, materials={"block": ELASTIC})
        model.prescribe(_boundary_nodes(mesh), displacement=lambda x: x @ A.T + c)
        res = solve_static(model, solver="direct")
        exact = mesh.points @ A.T + c
        u = res.displacement()
        eps = 0.5 * (A + A.T)
        lam, mu = ELASTIC.lame
        sig = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
        sig_v = np.array([sig[0, 0], sig[1, 1], sig[2, 2], sig[0, 1], sig[0, 2], sig[1, 2]])
        s = res.stress()
        name = f"patch test {_elem(order)}"
        out.append(case(name, "max|u-u_exact|/max|u_exact|",
                        np.abs(u - exact).max() / np.abs(exact).max(), 0.0, 1e-10))
        out.append(case(name, "max|sig-sig_exact|/max|sig_exact|",
                        np.abs(s - sig_v).max() / np.abs(sig_v).max(), 0.0, 1e-9))
    return out


def stiffness_symmetry(orders=(1, 2)) -> list[dict]:
    """K is symmetric to round-off: max |K - K^T| / max |K|."""
    out = []
    for order in orders:
        mesh = distorted_box(4, 3, 3, order=order, seed=2)
        K = stiffness(cell_basis(mesh), *ELASTIC.lame)
        asym = abs(K - K.T).max() / abs(K).max()
        out.append(case(f"symmetry of K {_elem(order)}", "max|K-K^T|/max|K|", asym, 0.0, 1e-13))
    return out


def rigid_body_modes(orders=(1, 2)) -> list[dict]:
    """A free body has exactly six zero-energy modes: the 6 smallest eigenvalues of K are
    ~0 relative to the 7th (a spurious 7th zero-energy mode would make the ratio ~1)."""
    out = []
    for order in orders:
        mesh = distorted_box(4, 2, 3, order=order, seed=3)
        K = stiffness(cell_basis(mesh), *ELASTIC.lame).tocsc()
        scale = abs(K).max()
        lam = np.sort(spla.eigsh(K, k=8, sigma=-1e-3 * scale, which="LM",
                                 return_eigenvectors=False))
        name = f"rigid-body modes {_elem(order)}"
        out.append(case(name, "max|lambda_1..6|/lambda_7", np.abs(lam[:6]).max() / lam[6],
                        0.0, 1e-9))
    return out


def _cantilever_model(order: int, n=(20, 2, 2), nu: float = 0.0, L=100.0, b=10.0, h=10.0,
                      P=5.0, E=2000.0, two_materials: bool = False) -> Model:
    mesh = box_tet_mesh(L, b, h, *n)
    materials = {"block": Material("beam", E=E, nu=nu)}
    if two_materials:
        cen = mesh.points[mesh.cells].mean(axis=1)
        region = (cen[:, 0] > L / 2).astype(np.int64)
        mesh = TetMesh(mesh.points, mesh.cells, region, {0: "block", 1: "tip"}, {},
                       mesh.facet_sets)
        materials["tip"] = Material("soft", E=E / 4, nu=0.45)
    if order == 2:
        mesh = mesh.quadratic()
    model = Model(mesh, materials=materials)
    model.fix("xmin")
    model.traction("xmax", (0.0, 0.0, -P / (b * h)))
    return model


def timoshenko_tip_deflection(P, L, b, h, E, nu) -> float:
    """Tip deflection (mm) of a rectangular cantilever, end shear P (N): bending + shear
    (kappa = 10 (1 + nu) / (12 + 11 nu), Cowper)."""
    I, G = b * h ** 3 / 12, E / (2 * (1 + nu))
    kappa = 10 * (1 + nu) / (12 + 11 * nu)
    return P * L ** 3 / (3 * E * I) + P * L / (kappa * G * b * h)


def cantilever(n=(20, 2, 2)) -> list[dict]:
    """TET10 cantilever (L/h = 10, nu = 0, clamped root) tip deflection vs Timoshenko beam
    theory (with nu = 0 the 3-D clamp adds no constraint stiffening)."""
    L, b, h, P, E = 100.0, 10.0, 10.0, 5.0, 2000.0
    model = _cantilever_model(2, n=n, L=L, b=b, h=h, P=P, E=E)
    res = solve_static(model)
    tip = model.nodes("xmax")
    w = -res.displacement()[tip, 2].mean()
    ref = timoshenko_tip_deflection(P, L, b, h, E, 0.0)
    return [case("cantilever TET10 vs Timoshenko", "tip deflection (mm)", w, ref, 0.01)]


def _mms(lam: float, mu: float):
    """Manufactured solution on the unit cube: u = a sin(pi x) sin(pi y) sin(pi z), zero on
    the boundary, and its body force b = -div sigma (N/mm^3)."""
    a = np.array([1.0, -0.5, 0.75]) * 1e-2
    pi = math.pi

    def u(x):
        s = np.sin(pi * x)
        return (s[..., 0] * s[..., 1] * s[..., 2])[..., None] * a

    def b(x):
        s, c = np.sin(pi * x), np.cos(pi * x)
        phi = s[..., 0] * s[..., 1] * s[..., 2]
        H = np.empty(x.shape[:-1] + (3, 3))
        for i in range(3):
            for j in range(3):
                if i == j:
                    H[..., i, i] = -pi ** 2 * phi
                else:
                    k = 3 - i - j
                    H[..., i, j] = pi ** 2 * c[..., i] * c[..., j] * s[..., k]
        # -div sigma = -(lam + mu) grad(div u) - mu lap u
        return -(lam + mu) * (H @ a) + 3 * mu * pi ** 2 * phi[..., None] * a

    return u, b


def _l2_error(mesh: TetMesh, u: np.ndarray, u_exact, degree: int = 4) -> float:
    """Relative L2 error of the FE field ``u`` (n, 3) against ``u_exact(x)`` on a
    straight-sided mesh (constant Jacobian per cell), degree-``degree`` quadrature."""
    q = tet_quadrature(degree)
    N = tet_element(mesh.cells.shape[1]).N(q.points)            # (nq, nn)
    x = np.einsum("qa,eai->eqi", N, mesh.points[mesh.cells])
    dx = 6.0 * mesh.corner_volumes[:, None] * q.weights[None]
    ue = u_exact(x)
    uh = np.einsum("qa,eai->eqi", N, u[mesh.cells])
    return math.sqrt((((uh - ue) ** 2).sum(-1) * dx).sum() / (((ue ** 2).sum(-1)) * dx).sum())


def convergence_rates(levels: dict[int, tuple[int, ...]] | None = None) -> list[dict]:
    """Observed order of the L2 displacement error under uniform refinement, manufactured
    solution with Dirichlet boundary: 2 for TET4, 3 for TET10 (rate of the finest pair)."""
    levels = levels or {1: (4, 8, 16), 2: (2, 4, 8)}
    lam, mu = ELASTIC.lame
    u_ex, b = _mms(lam, mu)
    out = []
    for order, ns in levels.items():
        errs, hs = [], []
        for n in ns:
            mesh = box_tet_mesh(1.0, 1.0, 1.0, n, n, n)
            mesh = mesh.quadratic() if order == 2 else mesh
            model = Model(mesh, materials={"block": ELASTIC})
            model.fix(_boundary_nodes(mesh))
            model.body_force(b)
            u = solve_static(model, solver="amg").displacement()   # AMG-CG, rtol 1e-10
            errs.append(_l2_error(mesh, u, u_ex))
            hs.append(1.0 / n)
        rate = math.log(errs[-2] / errs[-1]) / math.log(hs[-2] / hs[-1])
        expected = order + 1.0
        out.append(case(f"convergence {_elem(order)} n={','.join(map(str, ns))}",
                        "L2 order of u", rate, expected, 0.1))
    return out


# --------------------------------------------------------------------------- CalculiX


def _distorted_block_model() -> Model:
    """Distorted TET10 block: clamped at x = 0, non-uniform prescribed displacement at x = max,
    traction on top: exercises prescribed values, loads and curved-free straight cells."""
    mesh = distorted_box(6, 3, 4, size=(12.0, 6.0, 8.0), order=2, seed=4)
    model = Model(mesh, materials={"block": ELASTIC})
    model.fix("xmin")
    model.prescribe("xmax", displacement=lambda x: np.column_stack(
        [0.01 + 0.002 * x[:, 1], -0.003 * x[:, 2], 0.02 * np.sin(x[:, 1] / 6.0)]))
    model.traction("zmax", (0.5, -0.2, -1.0))
    return model


def calculix_models() -> dict[str, Model]:
    """The models compared node by node with CalculiX."""
    return {
        "distorted TET10 prescribed+traction": _distorted_block_model(),
        "cantilever TET10 nu=0": _cantilever_model(2),
        "cantilever TET10 2 materials": _cantilever_model(2, n=(20, 3, 3), nu=0.3,
                                                            two_materials=True),
        "cantilever TET4 2 materials": _cantilever_model(1, n=(20, 3, 3), nu=0.3,
                                                           two_materials=True),
    }


def compare_with_calculix(model: Model, threads: int = 1):
    """Solve ``model`` (fixed/prescribed dofs and nodal loads only, no couplings or springs)
    with ours and with CalculiX. Returns (max |u - u_ccx| / max |u_ccx|, ours, CalculixResult)."""
    from designlab.fem.calculix import solve_calculix

    res = solve_static(model)
    sys_ = res.system
    if model.refs or model.springs:
        raise ParameterError("model", "couplings/springs", "plain constraints and loads only")
    n3 = 3 * model.n_points
    dofs = np.nonzero(sys_.constrained[:n3])[0]
    case_ = sys_.cases[0]
    k = sys_.case_index(case_)
    prescribed = np.column_stack([dofs // 3, dofs % 3, sys_.G[dofs, k]])
    forces = sys_.F[:n3, k].reshape(-1, 3)
    mats = {rid: (m.E, m.nu) for rid, m in model.region_materials.items()}
    ref = solve_calculix(model.mesh, mats, prescribed, forces, threads=threads)
    u = res.displacement(case_)
    err = np.abs(u - ref.displacement).max() / np.abs(ref.displacement).max()
    return float(err), u, ref


def calculix_cases(threads: int = 1) -> list[dict]:
    """Node-by-node comparison with CalculiX on the same meshes and load vectors
    (CalculiX prints 7 significant digits)."""
    out = []
    for name, model in calculix_models().items():
        err, u, ref = compare_with_calculix(model, threads)
        out.append(case(f"CalculiX {ref.ccx_version} {name}",
                        "max|u-u_ccx|/max|u_ccx|", err, 0.0, 1e-5))
    return out


# --------------------------------------------------------------------------- running


def default_cases(reference: str | None = None, threads: int = 1) -> list[tuple[str, Callable]]:
    """(title, function) of every case to run; ``reference="calculix"`` adds the CalculiX ones."""
    cases = [("patch test", patch_test), ("symmetry of K", stiffness_symmetry),
             ("rigid-body modes", rigid_body_modes), ("cantilever", cantilever),
             ("convergence", convergence_rates), ("viscoelastic", viscoelastic_cases)]
    if reference is not None:
        if reference != "calculix":
            raise ParameterError("--reference", reference, "calculix")
        cases.append(("CalculiX", lambda: calculix_cases(threads)))
    return cases


def run_cases(reference: str | None = None, threads: int = 1,
              progress: Callable[[str], None] | None = None) -> list[dict]:
    """Run every case; ``progress(title)`` is called after each group."""
    out = []
    for title, fn in default_cases(reference, threads):
        out.extend(fn())
        if progress is not None:
            progress(title)
    return out


def write_report(cases: list[dict], path: str | Path) -> Path:
    """Write ``{"cases": [...], "passed": bool}`` as JSON atomically (temp file + replace)."""
    from designlab.atomic import atomic_write_json

    payload = {"cases": cases, "passed": all(c["passed"] for c in cases)}
    return atomic_write_json(path, payload, indent=2)


__all__ = ["case", "distorted_box", "patch_test", "stiffness_symmetry", "rigid_body_modes",
           "cantilever", "timoshenko_tip_deflection", "convergence_rates", "calculix_models",
           "compare_with_calculix", "calculix_cases", "default_cases", "run_cases",
           "write_report", "viscoelastic_cases"]


# --------------------------------------------------------------------------- viscoelastic


#: Prony terms of the viscoelastic cases (shear; bulk terms added per case)
VISCO_E0, VISCO_NU = 50.0, 0.4
VISCO_G = Prony(g=(0.3, 0.25), tau=(1.0, 10.0))


def _uniaxial_bar(prony: Prony, L: float = 20.0, a: float = 4.0) -> Model:
    """Bar on three symmetry planes (x=0, y=0, z=0): uniaxial stress, lateral faces free."""
    mesh = box_tet_mesh(L, a, a, 5, 2, 2)
    mat = Material("visco", E=VISCO_E0, nu=VISCO_NU, prony=prony)
    model = Model(mesh, materials={"block": mat})
    model.fix("xmin", "x")
    model.fix("ymin", "y")
    model.fix("zmin", "z")
    return model


def viscoelastic_cases() -> list[dict]:
    """Uniaxial relaxation and creep of a Prony bar (TET4, uniform state) by the history solver
    vs the exact state-space responses of :mod:`designlab.fem.prony_fit`.

    1. ramp (2 s) and hold of the strain, shear and bulk relaxing alike: the recursion is exact;
    2. step strain, shear relaxing, bulk elastic: the lateral strain is not linear within a
       step, O(dt^2) error;
    3. step stress (creep), shear and bulk relaxing with different times: O(dt^2) error.
    """
    from designlab.fem.prony_fit import creep_compliance, stress_response
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    L, a, eps0, sig0 = 20.0, 4.0, 0.01, 0.5
    alike = Prony(g=VISCO_G.g, tau=VISCO_G.tau, k=VISCO_G.g, k_tau=VISCO_G.tau)
    both = Prony(g=VISCO_G.g, tau=VISCO_G.tau, k=(0.2,), k_tau=(3.0,))
    out = []
    for name, prony, hist, tol in [
        ("relaxation ramp-hold, G K alike (exact)", alike,
         History.piecewise([0.0, 2.0, 50.0], [0.0, 1.0, 1.0], case="pull", dt=0.25), 1e-9),
        ("relaxation step, K elastic", VISCO_G,
         History.step_hold(50.0, 200, {"pull": 1.0}), 0.01),
    ]:
        model = _uniaxial_bar(prony, L, a)
        model.prescribe("xmax", displacement=(eps0 * L, None, None), case="pull")
        res = solve_history(model, hist)
        sig = res.wrench("xmax")[:, 3] / (a * a)
        ref = stress_response(VISCO_E0, prony, hist.t, eps0 * hist.amplitude("pull"), nu=VISCO_NU)
        out.append(case(f"viscoelastic {name}", "max|sig-sig_exact|/max|sig_exact|",
                        np.abs(sig - ref).max() / np.abs(ref).max(), 0.0, tol))
    model = _uniaxial_bar(both, L, a)
    model.traction("xmax", (sig0, 0.0, 0.0), case="load")
    hist = History.step_hold(50.0, 200, {"load": 1.0})
    res = solve_history(model, hist)
    eps = res.U[3 * model.nodes("xmax")].mean(axis=0) / L
    ref = sig0 * creep_compliance(VISCO_E0, both, hist.t, nu=VISCO_NU)
    out.append(case("viscoelastic creep step, G K relax",
                    "max|eps-eps_exact|/max|eps_exact|", np.abs(eps - ref).max() / ref.max(),
                    0.0, 0.01))
    out.append(case("viscoelastic creep step, G K relax",
                    "strain at t = 50 s", eps[-1], ref[-1], 0.01))
    return out
