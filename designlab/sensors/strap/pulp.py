"""Studies of the finger pulp under the strap as a solid layer (``finger_model = "solid"``):
Winkler against solid pulp (:func:`comparison`), the nonlinear strap and the wrap. Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from designlab.sensors.strap.model import strap_with_pulp
from designlab.sensors.strap.pulp_layer import (
    BONE, PULP, _principal_abs)


#: the comparison of ``python -m designlab.sensors.strap.pulp``: (label, settings overrides)
COMPARISON = (("winkler 0.02 N/mm^3", {}),
              ("solid (defaults)", {"finger_model": "solid"}),
              ("solid E 0.02 MPa", {"finger_model": "solid", "pulp_modulus": 0.02}),
              ("solid E 0.3 MPa", {"finger_model": "solid", "pulp_modulus": 0.3}),
              ("solid depth 5 mm", {"finger_model": "solid", "pulp_depth": 5.0}))


def comparison(cases=COMPARISON, slots=(0, 1, 2, 3), **settings) -> list[dict[str, Any]]:
    """Winkler against solid pulp on the default ArchStrap and protocol, elastic materials (the
    small-signal strain per newton, as the Monte Carlo reads it): per case and slot the sum
    and difference sensitivities (mV/N), the cross-talk (% per N) and the pulp's principal
    strain at the protocol's peak F_n. One FEM per case (the slot acts after the FEM)."""
    from designlab.geometry.strap import ArchStrap
    import designlab.sensors.strap.model as st
    from designlab.sensors.strap.model import elastic_materials
    from designlab.sensors.protocols import StrapLoadTest

    part, proto = ArchStrap(), StrapLoadTest()
    mats = elastic_materials(part)
    rows = []
    for label, kw in cases:
        for slot in slots:
            s = st.StrapModelSettings(**{"mesh_convergence": False, **settings, **kw}, slot=slot)
            r = st.run(part, proto, s, materials=mats).report
            sens, ct, f = r["sensitivity"]["V_per_N"], r["cross_talk_percent"], r["finger"]
            rows.append({"case": label, "slot": slot,
                         "sum_mV_per_N": 1e3 * sens["sum"]["F_n"],
                         "diff_mV_per_N": 1e3 * sens["diff"]["F_x"],
                         "F_x_in_sum_percent": ct["F_x_in_sum_per_N_percent"],
                         "F_n_in_diff_percent": ct["F_n_in_diff_per_N_percent"],
                         "pulp_max_strain_at_peak": f.get("pulp_max_principal_strain_at_peak_F_n"),
                         "pulp_p95_strain_at_peak": f.get("pulp_p95_principal_strain_at_peak_F_n"),
                         "cells": r["mesh"]["cells"]})
    return rows


def _gauge_stretch_strain(gauge, H: np.ndarray) -> float:
    """A gauge's mean nominal strain along its (reference) direction at displacement
    gradients H (m, nq, 3, 3): |F d| - 1, weighted as :class:`StrainGauge` weights its
    small strain (dx over the gauge's cells)."""
    basis = gauge.model.basis
    cells = gauge.cells
    x = basis.x[cells]
    d = gauge.direction(x) if callable(gauge.direction) else np.broadcast_to(
        np.asarray(gauge.direction, float), x.shape)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    Fd = d + np.einsum("eqij,eqj->eqi", H[cells], d)
    w = basis.dx[cells] / basis.dx[cells].sum()
    return float((w * (np.linalg.norm(Fd, axis=-1) - 1.0)).sum())


def _principal_biot(H: np.ndarray) -> np.ndarray:
    """Per quadrature point, the largest |principal stretch - 1| (H: (k, 3, 3))."""
    F = H + np.eye(3)
    C = np.einsum("...kI,...kJ->...IJ", F, F)
    return np.abs(np.sqrt(np.linalg.eigvalsh(C)) - 1.0).max(axis=-1)


#: the pulp laws :func:`nonlinear_comparison` knows: neo-Hookean (the nearly incompressible
#: hyperelastic body, mu and kappa of the linear E and nu) and St-Venant-Kirchhoff (the
#: linear law with exact kinematics). SVK is not run by default: at nu 0.49 under
#: compression it softens and loses stability (measured: no equilibrium past F_n = 3.08 N at
#: edge_length 3), the known defect of SVK in compression, not a property of the pulp
PULP_LAWS = ("neo-Hooke", "SVK")


def nonlinear_comparison(steps: int = 10, laws=("neo-Hooke",), part=None, protocol=None,
                         shear: bool = False, say=lambda s: None,
                         **settings) -> dict[str, Any]:
    """The strap with the solid pulp at the protocol's peak normal force (F_n only), linear
    (``solve_static``, as ``strap.run`` does) against geometrically nonlinear
    (:func:`designlab.fem.hyperelastic.solve_hyperelastic`): the strap's bodies as
    St-Venant-Kirchhoff solids of their elastic materials, the pulp per ``laws`` (neo-Hookean:
    mu = E / (2 (1 + nu)), kappa = E / (3 (1 - 2 nu)) of ``pulp_modulus``, ``pulp_poisson``,
    the same small-strain limit as the linear pulp; SVK: the linear law, large kinematics).
    With ``finger_model = "winkler"`` (a setting) the finger is the linear springs and only
    the strap is nonlinear (row "none"): the strap's geometric nonlinearity alone.
    The worn mesh is the stress-free reference in every case (the wrap's prestress stays
    in closed form, strap_fit) and the loads are dead loads.

    Returns {"linear": {...}, law: {...}}, each with the gauge strains at the peak (Ch1, Ch2,
    sum; linear: per newton x peak), the pulp's and the strap's largest and 95th-percentile
    principal strain (linear: |eigenvalue| of the small strain; nonlinear: |stretch - 1|),
    and for the nonlinear cases the small-strain gauge reading of the nonlinear displacement,
    the curve (F_n, Ch1, Ch2) per increment, the secant and the
    local (last increment) sum sensitivity relative to the linear one, and the solver's
    summary; plus the linear sum sensitivity in mV/N (``strap.run``'s report on the same
    mesh: the nonlinear mV/N is that times the ratio, the readout being linear in strain).
    ``shear``: also the difference channel (Ch1 - Ch2) under the protocol's shear F_x at the
    peak F_n, nonlinear (one more solve of both loads) against the linear F_x case."""
    from designlab.fem.hyperelastic import NeoHooke
    from designlab.fem.static import solve_static
    from designlab.geometry.strap import ArchStrap
    import designlab.sensors.strap.model as st
    from designlab.sensors.strap.model import elastic_materials
    from designlab.sensors.protocols import StrapLoadTest

    part = ArchStrap() if part is None else part
    proto = StrapLoadTest() if protocol is None else protocol
    s = st.StrapModelSettings(**{"mesh_convergence": False, "finger_model": "solid",
                                 **settings})
    solid = s.finger_model == "solid"
    if not solid:                  # Winkler springs: no pulp body, the strap alone nonlinear
        laws = ("none",)
    mats = elastic_materials(part)
    say("meshing")
    flat = st.mesh_strap(part, s)
    model, gauges, _ = st.build_model(part, flat, s, mats)
    ch = list(st.CHANNELS)
    peak = float(proto.normal_N)
    mesh = model.mesh
    pulp = mesh.region == mesh.region_id(PULP) if solid else np.zeros(mesh.n_cells, bool)
    n3 = 3 * model.n_points

    def strain_stats(a, sel):
        return _strain_stats(a, sel, mesh.n_cells)

    say("linear")
    res = solve_static(model, solver=s.solver)
    u1 = res.U[:n3, res.system.case_index("F_n")]
    e1 = [float(gauges[c].strain(u1)) for c in ch]
    eps = _principal_abs(np.asarray(model.B @ u1).reshape(-1, 6)) * peak
    out: dict[str, Any] = {"peak_F_n_N": peak, "cells": int(mesh.n_cells),
                           "pulp_cells": int(pulp.sum()), "dofs": int(model.n_dofs),
                           "finger_model": s.finger_model, "pulp_E_MPa": s.pulp_modulus,
                           "pulp_nu": s.pulp_poisson, "edge_length_mm": s.edge_length}
    lin = {"gauge_strain_at_peak": [peak * e for e in e1] + [peak * (e1[0] + e1[1])]}
    lin["pulp_max_strain"], lin["pulp_p95_strain"] = strain_stats(eps, pulp)
    lin["strap_max_strain"], lin["strap_p95_strain"] = strain_stats(eps, ~pulp)
    report = st.run(part, proto, s, materials=mats, mesh=flat).report
    lin["sum_mV_per_N"] = 1e3 * report["sensitivity"]["V_per_N"]["sum"]["F_n"]
    out["linear"] = lin
    for law in laws:
        if law not in PULP_LAWS + (("none",) if not solid else ()):
            raise ValueError(f"laws: {law!r} is not one of {PULP_LAWS}")
        hyper = {PULP: NeoHooke.from_linear(s.pulp_modulus, s.pulp_poisson)} \
            if law == "neo-Hooke" else {}
        row = _nonlinear_row(model, gauges, hyper, law, peak, steps, s.solver, lin, pulp, say)
        if shear:
            row["shear"] = _shear_row(model, gauges, hyper, law, peak, float(proto.shear_N),
                                      steps, s.solver, res, row, say)
        out[law] = row
    return out


def _strain_stats(a, sel, n_cells: int):
    """Largest and 95th-percentile strain over the cells ``sel`` (None, None when empty)."""
    a = a.reshape(n_cells, -1)[sel].ravel()
    if not len(a):
        return None, None
    return float(a.max()), float(np.percentile(a, 95.0))


def _nonlinear_row(model, gauges, hyper: dict, law: str, peak: float, steps: int, solver,
                   lin: dict, pulp: np.ndarray, say) -> dict[str, Any]:
    """One pulp law's geometrically nonlinear solve at the peak F_n: the gauge strains, the
    curve per increment, the principal strains and the sensitivity relative to the linear."""
    from designlab.fem.hyperelastic import Continuum, solve_hyperelastic

    ch = list(gauges)
    n3 = 3 * model.n_points
    curve = []

    def record(lam, u):
        H = r_cont.displacement_gradient(u[:n3])
        curve.append([lam * peak] + [_gauge_stretch_strain(gauges[c], H) for c in ch]
                     + [float(gauges[c].strain(u)) for c in ch])
        say(f"{law}: F_n {lam * peak:.3g} N")

    r_cont = Continuum.of(model, hyper)
    r = solve_hyperelastic(model, hyper, cases={"F_n": peak}, steps=steps,
                           solver=solver, on_increment=record)
    H = r.displacement_gradient()
    biot = _principal_biot(H.reshape(-1, 3, 3))
    c = np.array(curve)
    tot = c[:, 1] + c[:, 2]
    row = {"gauge_strain_at_peak": [float(c[-1, 1]), float(c[-1, 2]), float(tot[-1])],
           # the linear gauges' measure (small strain B u) of the nonlinear solution:
           # how much of the difference is the measure, how much the displacement field
           "gauge_small_strain_of_nonlinear_u": [float(c[-1, 3]), float(c[-1, 4]),
                                                 float(c[-1, 3] + c[-1, 4])],
           "curve": [[round(float(v), 8) for v in line[:3]] for line in c]}
    n_cells = model.mesh.n_cells
    row["pulp_max_strain"], row["pulp_p95_strain"] = _strain_stats(biot, pulp, n_cells)
    row["strap_max_strain"], row["strap_p95_strain"] = _strain_stats(biot, ~pulp, n_cells)
    lin_sum = lin["gauge_strain_at_peak"][2]
    row["secant_sum_over_linear"] = float(tot[-1] / lin_sum)
    row["local_sum_over_linear"] = float((tot[-1] - tot[-2]) / (c[-1, 0] - c[-2, 0])
                                         / (lin_sum / peak)) if len(c) > 1 else None
    row["sum_mV_per_N_secant"] = lin["sum_mV_per_N"] * row["secant_sum_over_linear"]
    row["solver"] = r.summary()
    return row


def _shear_row(model, gauges, hyper: dict, law: str, peak: float, sx: float, steps: int,
               solver, res, row: dict, say) -> dict[str, Any]:
    """The difference channel's response to the protocol's shear at the peak normal force:
    (F_n, F_x) = (peak, shear) minus (peak, 0), against the linear shear case ``res``."""
    from designlab.fem.hyperelastic import solve_hyperelastic

    ch = list(gauges)
    n3 = 3 * model.n_points
    say(f"{law}: F_n {peak:g} N + F_x {sx:g} N")
    r2 = solve_hyperelastic(model, hyper, cases={"F_n": peak, "F_x": sx}, steps=steps,
                            solver=solver)
    H2 = r2.displacement_gradient()
    g2 = [_gauge_stretch_strain(gauges[c], H2) for c in ch]
    g_peak = row["gauge_strain_at_peak"]
    d_nl = (g2[0] - g2[1]) - (g_peak[0] - g_peak[1])
    ux = res.U[:n3, res.system.case_index("F_x")]
    ex = [float(gauges[k].strain(ux)) for k in ch]
    d_lin = sx * (ex[0] - ex[1])
    return {"F_x_N": sx, "gauge_strain_at_peak_with_shear": g2,
            "diff_strain_of_shear": float(d_nl),
            "linear_diff_strain_of_shear": float(d_lin),
            "diff_over_linear": float(d_nl / d_lin),
            "solver": r2.summary()}


def wrap_kinematics(part=None, **settings) -> dict[str, Any]:
    """The strains of the wrap itself (flat print -> worn, :func:`strap.wrap_points`), which the
    linear model leaves out (the worn mesh is its stress-free reference): the map's exact
    strain on the flat mesh, u = wrap(X) - X, H = grad u: the largest |principal stretch - 1|
    (max and 95th percentile over the strap's quadrature points), the gauges' mean stretch
    along the centreline |F d| - 1 (d the flat centreline direction), the largest rotation
    of F's polar decomposition relative to the one at the apex (the tabs go round the finger:
    ~pi), and for contrast the small strain (B u) of the same displacement (what a linear
    analysis of the wrap would read). Kinematics only: the map
    is the model's wrap (inner face isometric, thickness along the cone's normal: bending
    about the inner face), not an equilibrium (a free band bends about its mid-plane)."""
    from designlab.fem.model import Model
    from designlab.fem.hyperelastic import Continuum
    from designlab.geometry.strap import ArchStrap
    import designlab.sensors.strap.model as st
    from designlab.sensors.strap.model import elastic_materials

    part = ArchStrap() if part is None else part
    s = st.StrapModelSettings(**{"mesh_convergence": False, **settings})
    flat = st.mesh_strap(part, s)
    model = Model(flat, elastic_materials(part))
    u = (st.wrap_points(part, flat.points, s.finger_radius) - flat.points).ravel()
    H = Continuum.of(model, {}).displacement_gradient(u)
    biot = _principal_biot(H.reshape(-1, 3, 3))
    F = H.reshape(-1, 3, 3) + np.eye(3)
    Uu, _, Vt = np.linalg.svd(F)
    R = Uu @ Vt                                           # rotation of the polar decomposition
    # relative to the rotation at the apex (the frames of the flat and worn meshes differ by
    # a fixed rotation, which no strain depends on)
    apex = np.argmin(np.linalg.norm(model.basis.x.reshape(-1, 3)
                                    - [0.0, part.arch_height, 0.0], axis=1))
    Rrel = np.einsum("kij,lj->kil", R, R[apex])
    angle = np.arccos(np.clip((np.einsum("kii->k", Rrel) - 1) / 2, -1, 1))
    small = _principal_abs(np.asarray(model.B @ u).reshape(-1, 6))
    flat_s = dataclasses.replace(s, configuration="flat")
    d = st.centreline_direction(part, flat_s)
    out = {"finger_radius_mm": s.finger_radius, "thickness_mm": float(part.thickness),
           "strap_max_strain": float(biot.max()),
           "strap_p95_strain": float(np.percentile(biot, 95.0)),
           "max_rotation_rad": float(angle.max()),
           "small_strain_reading_max": float(small.max()),
           "small_strain_reading_p95": float(np.percentile(small, 95.0))}
    from designlab.fem.transducers import StrainGauge

    for ch, reg in zip(st.CHANNELS, st.GAUGE_REGIONS):
        g = StrainGauge(model, st.gauge_cells(part, flat, reg), direction=d, name=ch,
                        gauge_factor=1.0)
        out[f"{ch}_stretch_strain"] = _gauge_stretch_strain(g, H)
        out[f"{ch}_small_strain_reading"] = float(g.strain(u))
    return out


def wrap_equilibrium(steps: int = 25, part=None, protocol=None, rtol: float = 1e-9,
                     max_iter: int = 60, say=lambda s: None, **settings) -> dict[str, Any]:
    """The wrap as an equilibrium, then the protocol's peak F_n on the wrapped strap.

    The strap's cells keep the flat (printed) mesh as their reference; the pulp's cells the
    worn one (the pulp is stress-free on the finger, not flat): one mesh, a per-cell reference
    (the pulp's displacement gradient is taken from x - X_worn). Putting on: the nail plate
    and the pulp's bone face are prescribed to :func:`strap.wrap_points` (the tabs on the
    nail, the bone in place), Newton starts from the wrap map itself (u = wrap(X) - X
    everywhere) and finds the equilibrium: the band springs back against the bonded pulp.
    Then F_n up to the peak in ``steps`` increments (dead load along the worn pad normal,
    distributing coupling on the pad). Strap St-Venant-Kirchhoff, pulp neo-Hookean (as
    :func:`nonlinear_comparison`). Returns the gauges' centreline stretch (|F d| - 1 from
    the flat print) in the map, after the wrap's equilibrium and at the peak, the signal
    (peak minus wrapped) per channel and summed, the strap's and pulp's largest / p95
    |principal stretch - 1| after the wrap, Newton iteration counts. Each increment is a
    Newton loop with a backtracking line search, no step cuts: the first increments on the
    prestressed band converge slowly (0.2 N increments: 25, 19, 16 ... 4 iterations at edge
    3 mm, 40, 28, 23 ... 4 on the default mesh; 1 N increments did not converge in 40),
    hence 25 increments and up to 60 iterations by default."""
    from designlab.geometry.strap import ArchStrap
    import designlab.sensors.strap.model as st
    from designlab.sensors.protocols import StrapLoadTest

    part = ArchStrap() if part is None else part
    proto = StrapLoadTest() if protocol is None else protocol
    s = st.StrapModelSettings(**{"mesh_convergence": False, **settings,
                                 "finger_model": "solid"})
    say("meshing")
    wp = _WrapProblem(part, s)
    system, mesh, pulp, n3 = wp.system, wp.mesh, wp.pulp, wp.n3
    grad, read = wp.grad, wp.read

    def equilibrium(u, lam):
        return wp.equilibrium(u, lam, rtol, max_iter)

    w = wp.w
    u_map = np.zeros(system.n_dofs)
    u_map[:n3] = w.ravel()
    out: dict[str, Any] = {"cells": int(mesh.n_cells), "dofs": int(wp.model.n_dofs),
                           "gauge_stretch_map": read(u_map)}
    say("wrap equilibrium")
    u, hist = equilibrium(u_map, 0.0)
    out["wrap_iterations"] = len(hist) - 1
    out["wrap_residuals"] = [float(v) for v in hist]
    g0 = read(u)
    out["gauge_stretch_wrapped"] = g0
    biot = _principal_biot(grad(u).reshape(-1, 3, 3)).reshape(mesh.n_cells, -1)
    out["strap_max_strain_wrapped"] = float(biot[~pulp].max())
    out["strap_p95_strain_wrapped"] = float(np.percentile(biot[~pulp], 95.0))
    out["pulp_max_strain_wrapped"] = float(biot[pulp].max())
    out["pulp_p95_strain_wrapped"] = float(np.percentile(biot[pulp], 95.0))
    peak = float(proto.normal_N)
    curve, its = [], []
    for k in range(1, steps + 1):
        lam = peak * k / steps
        say(f"F_n {lam:.3g} N")
        u, hist = equilibrium(u, lam)
        its.append(len(hist) - 1)
        gk = read(u)
        curve.append([lam, gk[0] - g0[0], gk[1] - g0[1]])
    out["load_iterations"] = its
    out["signal_curve"] = curve
    out["signal_at_peak"] = [curve[-1][1], curve[-1][2], curve[-1][1] + curve[-1][2]]
    biot = _principal_biot(grad(u).reshape(-1, 3, 3)).reshape(mesh.n_cells, -1)
    out["pulp_p95_strain_at_peak"] = float(np.percentile(biot[pulp], 95.0))
    return out


class _WrapProblem:
    """The strap on its solid pulp for :func:`wrap_equilibrium`: the strap's cells referred to
    the flat print, the pulp's to the worn mesh, the nail plate and bone prescribed to the wrap
    map, F_n on the pad; its displacement gradient, forces, gauge reading and Newton loop."""

    def __init__(self, part, s):
        import types

        from designlab.fem.assembly import cell_basis
        from designlab.fem.hyperelastic import Continuum, NeoHooke
        from designlab.fem.model import Model
        from designlab.fem.transducers import StrainGauge
        import designlab.sensors.strap.model as st
        from designlab.sensors.strap.model import elastic_materials

        self.s = s
        flat = st.mesh_strap(part, s)
        mesh = self.mesh = strap_with_pulp(part, flat, s)
        worn = st.worn_mesh(part, mesh, s.finger_radius)
        model = Model(mesh, st.finger_materials(s, elastic_materials(part)))

        def wrap_u(x):
            return st.wrap_points(part, x, s.finger_radius) - x

        model.prescribe("nail_plate", wrap_u, case="wrap")
        model.prescribe(BONE, wrap_u, case="wrap")
        frame = st.pad_frame(part, s)
        pad = model.distributing_coupling("pad", "finger_contact",
                                          ref_point=(0.0, part.arch_height, 0.0))
        model.force(pad, force=frame["n"], case="F_n")
        system = self.system = model.build()
        self.n3 = 3 * model.n_points
        pulp = self.pulp = mesh.region == mesh.region_id(PULP)
        bf, bw = model.basis, cell_basis(worn)
        sel = pulp[:, None]
        self.mixed = dataclasses.replace(bf, dNdx=np.where(sel[..., None, None], bw.dNdx, bf.dNdx),
                                         dx=np.where(sel, bw.dx, bf.dx),
                                         x=np.where(sel[..., None], bw.x, bf.x))
        proxy = types.SimpleNamespace(basis=self.mixed, mesh=mesh,
                                      region_materials=model.region_materials)
        self.cont = Continuum.of(proxy, {PULP: NeoHooke.from_linear(s.pulp_modulus,
                                                                    s.pulp_poisson)})
        self.w = wrap_u(mesh.points)
        self.F = system.F[:, system.case_index("F_n")]
        self.g = system.G[:, system.case_index("wrap")]
        d = st.centreline_direction(part, dataclasses.replace(s, configuration="flat"))
        self.gauges = [StrainGauge(model, st.gauge_cells(part, flat, reg), direction=d, name=c,
                                   gauge_factor=1.0)
                       for c, reg in zip(st.CHANNELS, st.GAUGE_REGIONS)]
        self.model = model

    def grad(self, u):
        cells, pulp = self.mesh.cells, self.pulp
        ue = u[:self.n3].reshape(-1, 3)[cells]
        ue[pulp] -= self.w[cells[pulp]]
        return np.einsum("eai,eqaJ->eqiJ", ue, self.mixed.dNdx, optimize=True)

    def forces(self, u, tangent):
        P, A = self.cont.stress(self.grad(u), tangent)
        fi = np.zeros(self.system.n_dofs)
        fi[:self.n3] = self.cont.internal_force(P)
        return fi, (self.system.K(self.cont.tangent(A)) if tangent else None)

    def read(self, u):
        H = self.grad(u)
        return [_gauge_stretch_strain(gg, H) for gg in self.gauges]

    def equilibrium(self, u, lam, rtol: float, max_iter: int):
        """Newton with a backtracking line search from ``u`` at the F_n factor ``lam``:
        (displacement, residual history)."""
        from designlab.errors import ModelError
        from designlab.fem.solvers import MANY_RHS, factorize

        system, F, g = self.system, self.F, self.g
        T, Tt = system.T, system.T.T.tocsr()
        q = u[system.free_dofs] if T.nnz == T.shape[1] else None
        if q is None:
            raise ModelError("wrap_equilibrium: rigid couplings are not supported")
        hist = []
        for it in range(max_iter + 1):
            u = T @ q + g
            fi, K = self.forces(u, True)
            r = Tt @ (fi - lam * F)
            ref = max(np.linalg.norm(lam * F), np.linalg.norm(fi), 1e-300)
            rn = np.linalg.norm(r) / ref
            hist.append(rn)
            if rn <= rtol:
                return u, hist
            dq = factorize(system.reduce(K), self.s.solver, n_rhs=MANY_RHS).solve(-r)
            step = 1.0
            for _ in range(8):
                try:
                    ft, _ = self.forces(T @ (q + step * dq) + g, False)
                    if np.linalg.norm(Tt @ (ft - lam * F)) / ref < rn:
                        break
                except ModelError:
                    pass
                step *= 0.5
            q = q + step * dq
        raise ModelError(f"wrap_equilibrium: no convergence at F_n factor {lam:g} "
                         f"(residuals {[float(v) for v in hist]})")


if __name__ == "__main__":
    # python -m designlab.sensors.strap.pulp [--nonlinear | --wrap] [NAME=VALUE ...]
    import json
    import sys
    import warnings

    from designlab.sensors.sensor import settings_from
    from designlab.sensors.strap.model import StrapModelSettings

    warnings.simplefilter("ignore")
    args = [a for a in sys.argv[1:] if a not in ("--nonlinear", "--wrap", "--wrap-equilibrium")]
    extra = dict(a.split("=", 1) for a in args)
    base = settings_from(StrapModelSettings, extra)  # parses and checks NAME=VALUE as --setting
    extra = {k: getattr(base, k) for k in extra}
    if "--wrap-equilibrium" in sys.argv[1:]:
        print(json.dumps(wrap_equilibrium(say=lambda m: print(m, file=sys.stderr, flush=True),
                                          **extra), indent=1))
        sys.exit(0)
    if "--wrap" in sys.argv[1:]:
        print(json.dumps(wrap_kinematics(**extra), indent=1))
        sys.exit(0)
    if "--nonlinear" in sys.argv[1:]:
        print(json.dumps(nonlinear_comparison(shear=True, say=lambda m: print(
            m, file=sys.stderr, flush=True), **extra), indent=1))
        sys.exit(0)
    for row in comparison(**extra):
        print(json.dumps({k: round(v, 4) if isinstance(v, float) else v
                          for k, v in row.items()}), flush=True)
