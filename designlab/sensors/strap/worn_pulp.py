"""The strap as it is worn on a hyperelastic pulp: the band closed on a nearly incompressible
neo-Hookean pulp by a geometrically nonlinear prestress step, then the sensing load, against
the present model (linear strap on linear Winkler springs, the wrap's prestrain as closed-form
factors). Details: docs/guide/strap_sizes.md ("The pulp model").

The prestress step: the strap's bodies (band and traces) carry a stress-free reference stretch
G = I - eps0 / (1 + eps0) d d along the band (d the worn centreline direction): the band is
shorter than the path it is worn on by the factor 1 / (1 + eps0), eps0 the closed-form initial
strain of the slot or size on a rigid finger (:func:`prestrain.initial_strain`). Starting from
the worn mesh, :func:`designlab.fem.hyperelastic.solve_hyperelastic` ramps G in and finds the
equilibrium: the band pulls in against the pulp (bonded, its bone face fixed) and the tabs
(fixed on the nail plate). The sensing load is then a small F_n increment on the pad from that
state: the gauges' elastic strain (relative to the printed length) per newton is the
small-signal sensitivity at the operating point, as the present model's is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from designlab.errors import ParameterError

#: the pulp's Poisson's ratio (assumed: no source read gives one for the fingertip; nearly
#: incompressible, kappa / mu = 50)
PULP_POISSON = 0.49
#: the strap model's mesh edge for the pulp model (mm): the coarse mesh keeps the nonlinear
#: solves to seconds; the ratios it reports are taken on one mesh for every model
EDGE_MM = 3.0
#: the sensing increment of F_n (N): small enough for a tangent (the ratio to the present
#: model at 0.1 N and at 0.01 N agree to 0.6 %, docs/guide/strap_sizes.md)
SENSE_N = 0.1
#: prestress increments per 0.1 of initial strain (at least one)
PRE_STEPS_PER_0_1 = 1

ASSUMPTIONS = (
    "pulp: compressible neo-Hookean, mu and kappa of E and nu (NeoHooke.from_linear), nu "
    f"{PULP_POISSON} assumed (no cited value); E at the ends of the one cited fingertip "
    "modulus range (an effective Hertz modulus of the whole fingertip, read from an "
    "abstract, designlab/data/fingertip_pulp.json): the two ends give the band",
    "pulp geometry: the strap model's solid layer (3 mm deep under the arch legs, bonded to "
    "the strap, its bone face fixed, free sides); the tabs fixed on the nail plate",
    "strap bodies: neo-Hookean of their elastic E and nu (the present model's stand-in law "
    "for the printed TPU, compressible); instantaneous moduli (no relaxation)",
    "wrap: the band shorter than its worn path by 1 / (1 + eps0) along the worn centreline, "
    "eps0 the rigid-finger initial strain; the stress-free reference of the band's bending is "
    "the worn shape (the flat print's bending, a few-percent effect, is in "
    "docs/hyperelastic.md, wrap_equilibrium)",
    "sensitivity: the gauges' elastic strain along the band, relative to the printed length, "
    f"per newton of a {SENSE_N:g} N F_n increment at the worn state; the readout's divider "
    "at the gauges' worn strain; dead load on the pad",
    "present model: the same mesh, linear, Winkler springs (0.02 N/mm^3), the worn mesh "
    "stress-free, times the closed-form prestrain factor at eps0 (incompressible neo-Hookean "
    "tangent, gauge operating point)",
)


def band_prestretch(model, part, settings, eps0: float, bodies) -> np.ndarray:
    """(m, nq, 3, 3) inverse reference stretch: I + eps0 d d in the cells of ``bodies`` (d the
    worn centreline direction at each quadrature point), I elsewhere."""
    import designlab.sensors.strap.model as st

    x = model.basis.x                                            # (m, nq, 3)
    d = st.centreline_direction(part, settings)(x)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    pre = np.broadcast_to(np.eye(3), x.shape + (3,)).copy()
    mesh = model.mesh
    sel = np.isin(mesh.region, [mesh.region_id(b) for b in bodies])
    pre[sel] += eps0 * np.einsum("eqi,eqj->eqij", d[sel], d[sel])
    return pre


def _gauge_reading(gauges, cont, u) -> list[float]:
    """The gauges' elastic stretch strain |F_e d| - 1 (mean over their cells) at ``u``."""
    from designlab.sensors.strap.pulp import _gauge_stretch_strain

    n3 = 3 * cont.model.n_points
    He = cont.elastic_gradient(cont.displacement_gradient(u[:n3]))
    return [_gauge_stretch_strain(g, He) for g in gauges.values()]


def _biot(H: np.ndarray, sel: np.ndarray) -> tuple[float, float]:
    """Largest and 95th-percentile |principal stretch - 1| over the cells ``sel``."""
    F = H[sel].reshape(-1, 3, 3) + np.eye(3)
    lam = np.sqrt(np.linalg.eigvalsh(np.einsum("kiI,kiJ->kIJ", F, F)))
    a = np.abs(lam - 1.0).max(axis=-1)
    return float(a.max()), float(np.percentile(a, 95.0))


def hyperelastic_response(model, gauges, hyper: dict, pre: np.ndarray | None,
                          sense_N: float, pre_steps: int, solver: str = "auto"
                          ) -> dict[str, Any]:
    """The prestress step (``pre`` ramped in over ``pre_steps``; none when None) and the
    sensing increment of ``sense_N`` on ``model`` (its F_n case): the gauges' elastic strain
    after the wrap, their sum's change per newton, the solves' summaries and the final
    state's displacement gradient."""
    from designlab.fem.hyperelastic import Continuum, solve_hyperelastic

    cont = Continuum.of(model, hyper).with_pre(pre)
    u0, wrap = None, None
    if pre is not None:
        r0 = solve_hyperelastic(model, hyper, cases={"F_n": 0.0}, steps=pre_steps, pre=pre,
                                ramp_pre=True, solver=solver)
        u0, wrap = r0.u, r0.summary()
    e0 = _gauge_reading(gauges, cont, np.zeros(model.n_dofs) if u0 is None else u0)
    r1 = solve_hyperelastic(model, hyper, cases={"F_n": sense_N}, steps=1, pre=pre, u0=u0,
                            solver=solver)
    e1 = _gauge_reading(gauges, cont, r1.u)
    H0 = cont.displacement_gradient((np.zeros(model.n_dofs) if u0 is None else u0)
                                    [:3 * model.n_points])
    return {"gauge_strain_worn": e0, "sum_strain_per_N": (sum(e1) - sum(e0)) / sense_N,
            "wrap_solve": wrap, "sense_solve": r1.summary(), "H_worn": H0}


def _factors(eps: float, material, R0: float, R_fixed: float) -> dict[str, float]:
    """The closed-form prestrain factors at ``eps``: mechanical (E over the incompressible
    neo-Hookean tangent) and electrical (the divider's slope at the strained gauge)."""
    from designlab.sensors.strap.prestrain import neo_hooke, operating_point

    e = max(float(eps), 0.0)
    op = operating_point(e, R0, material.gauge_factor, material.gauge_quadratic, R_fixed)
    return {"mechanical": 1.0 / neo_hooke(e)["tangent_over_E"],
            "electrical": op["electrical_factor"]}


def _check(initial_strain: float, finger_radius: float, moduli, sense_N: float) -> None:
    """One-line errors for values outside the model's range."""
    if not (0.0 <= initial_strain < 1.0):
        raise ParameterError("initial_strain", initial_strain, "in [0, 1) (a worn band)")
    if not (3.0 <= finger_radius <= 20.0):
        raise ParameterError("finger_radius", finger_radius, "3-20 mm")
    if not moduli or any(not (0.001 <= float(E) <= 10.0) for E in moduli):
        raise ParameterError("pulp_E", moduli, "pulp moduli in 0.001-10 MPa")
    if not (0.0 < sense_N <= 5.0):
        raise ParameterError("sense_N", sense_N, "in (0, 5] N")


def worn_pulp(part=None, finger_radius: float = 9.0, initial_strain: float | None = None,
              slot: int | None = None, pulp_E=None, pulp_nu: float = PULP_POISSON,
              sense_N: float = SENSE_N, edge_length: float = EDGE_MM, solver: str = "auto",
              say=lambda s: None) -> dict[str, Any]:
    """The sum-channel sensitivity of ``part`` worn on a finger of ``finger_radius`` with the
    hyperelastic pulp (prestress step, then the sensing increment) against the present
    model, per pulp modulus of ``pulp_E`` (default: the ends of the cited fingertip range)
    and as a band (min, max over them).

    The initial strain: ``initial_strain``, or that of ``slot`` on the finger's perimeter
    (rigid finger), or 0. Per modulus: the present model's sum sensitivity (V/N: the
    linear Winkler model's, times the closed-form prestrain factor at eps0), the same with
    the linear solid pulp (the pulp model alone, no nonlinearity), the hyperelastic one, and
    their ratios: ``hyperelastic_over_present`` (the pulp model's effect),
    ``linear_solid_over_present`` (the solid pulp, linear) and ``nonlinear_over_linear``
    (hyperelastic over linear solid: the nonlinearity at the worn strain, with the
    mechanical part ``nonlinear_over_linear_mechanical`` without the readout's operating
    point), the gauges' worn strain against eps0 and the pulp's worn strain."""
    _check(0.0 if initial_strain is None else initial_strain, finger_radius,
           (0.1,) if pulp_E is None else tuple(pulp_E), sense_N)
    from designlab.fem.hyperelastic import NeoHooke
    from designlab.fem.static import solve_static
    from designlab.geometry.strap import ArchStrap
    import designlab.sensors.strap.model as st
    from designlab.sensors.strap.fit import cited_pulp_moduli
    from designlab.sensors.strap.prestrain import initial_strain as eps_of
    from designlab.sensors.strap.pulp_layer import PULP

    moduli = tuple(float(E) for E in (cited_pulp_moduli() if pulp_E is None else pulp_E))
    _check(0.0 if initial_strain is None else initial_strain, finger_radius, moduli, sense_N)
    part = ArchStrap() if part is None else part
    if initial_strain is None:
        initial_strain = 0.0 if slot is None else eps_of(part, 2 * math.pi * finger_radius,
                                                          slot)
    eps0 = float(initial_strain)
    _check(eps0, finger_radius, moduli, sense_N)
    base = dict(mesh_convergence=False, edge_length=edge_length,
                finger_radius=round(float(finger_radius), 4), solver=solver)
    s_w = st.StrapModelSettings(**base)
    mats = st.elastic_materials(part)
    say("meshing")
    flat = st.mesh_strap(part, s_w)
    say("present model (linear, Winkler)")
    rep = st.run(part, settings=s_w, materials=mats, mesh=flat).report
    S0 = float(rep["sensitivity"]["V_per_N"]["sum"]["F_n"])
    model_w, g_w, _ = st.build_model(part, flat, s_w, mats)
    lin_w = _sum_strain_per_N(model_w, g_w, solve_static(model_w, solver=solver))
    trace = mats[st.GAUGE_REGIONS[0]]
    R0 = next(iter(g_w.values())).R0
    f0 = _factors(eps0, trace, R0, s_w.divider_ohm)
    present = S0 * f0["mechanical"] * f0["electrical"]
    n_pre = max(1, math.ceil(PRE_STEPS_PER_0_1 * eps0 / 0.1))
    rows = []
    for E in moduli:
        say(f"pulp E {E:g} MPa")
        s_s = st.StrapModelSettings(**base, finger_model="solid", pulp_modulus=E,
                                    pulp_poisson=pulp_nu)
        model, gauges, _ = st.build_model(part, flat, s_s, mats)
        lin_s = _sum_strain_per_N(model, gauges, solve_static(model, solver=solver))
        mesh = model.mesh
        strap_bodies = [b for b in mesh.region_names.values() if b != PULP]
        hyper = {PULP: NeoHooke.from_linear(E, pulp_nu)}
        for b in strap_bodies:
            m = model.region_materials[mesh.region_id(b)]
            hyper[b] = NeoHooke.from_linear(m.E, m.nu)
        pre = band_prestretch(model, part, s_s, eps0, strap_bodies) if eps0 > 0 else None
        h = hyperelastic_response(model, gauges, hyper, pre, sense_N, n_pre, solver)
        eps_worn = float(np.mean(h["gauge_strain_worn"]))
        fw = _factors(eps_worn, trace, R0, s_w.divider_ohm)
        hyper_V = S0 * h["sum_strain_per_N"] / lin_w * fw["electrical"]
        lin_solid_V = S0 * lin_s / lin_w * f0["mechanical"] * f0["electrical"]
        pulp = mesh.region == mesh.region_id(PULP)
        pmax, p95 = _biot(h["H_worn"], pulp)
        rows.append({
            "pulp_E_MPa": E, "pulp_nu": pulp_nu,
            "sum_F_n_V_per_N": {"present": present, "linear_solid_pulp": lin_solid_V,
                                "hyperelastic": hyper_V},
            "hyperelastic_over_present": hyper_V / present,
            "linear_solid_over_present": lin_solid_V / present,
            "nonlinear_over_linear": hyper_V / lin_solid_V,
            "nonlinear_over_linear_mechanical": h["sum_strain_per_N"]
            / (lin_s * f0["mechanical"]),
            "gauge_strain_worn": eps_worn,
            "gauge_strain_worn_over_rigid": eps_worn / eps0 if eps0 > 0 else None,
            "pulp_max_strain_worn": pmax, "pulp_p95_strain_worn": p95,
            "solves": {"wrap": h["wrap_solve"], "sense": h["sense_solve"]}})
    return {"initial_strain_rigid": eps0, "finger_radius_mm": float(finger_radius),
            "edge_length_mm": edge_length, "cells": int(model.mesh.n_cells),
            "dofs": int(model.n_dofs), "sense_N": sense_N,
            "present_sum_F_n_V_per_N": present, "by_modulus": rows,
            "band": _band(rows), "assumptions": list(ASSUMPTIONS)}


def _sum_strain_per_N(model, gauges, res) -> float:
    """The linear gauges' sum strain per newton of F_n."""
    u = res.U[:3 * model.n_points, res.system.case_index("F_n")]
    return float(sum(g.strain(u) for g in gauges.values()))


BAND_KEYS = ("hyperelastic_over_present", "linear_solid_over_present", "nonlinear_over_linear",
             "nonlinear_over_linear_mechanical", "gauge_strain_worn", "pulp_p95_strain_worn")


def _band(rows: list[dict]) -> dict[str, dict[str, float]]:
    """min / max over the moduli of each ratio (the band where the sources disagree)."""
    out = {}
    for k in BAND_KEYS:
        v = [r[k] for r in rows if r[k] is not None]
        out[k] = {"min": float(min(v)), "max": float(max(v))} if v else None
    v = [r["sum_F_n_V_per_N"]["hyperelastic"] for r in rows]
    out["hyperelastic_sum_F_n_V_per_N"] = {"min": float(min(v)), "max": float(max(v))}
    return out


if __name__ == "__main__":
    # python -m designlab.sensors.strap.worn_pulp [finger_radius=R] [slot=K | initial_strain=E]
    import json
    import sys
    import warnings

    warnings.simplefilter("ignore")
    kw = {k: (int(v) if k == "slot" else float(v))
          for k, v in (a.split("=", 1) for a in sys.argv[1:])}
    res = worn_pulp(say=lambda m: print(m, file=sys.stderr, flush=True), **kw)
    print(json.dumps(res, indent=1))
