"""The seed 002 spring flexure's model below its sensor record: the virtual wrench test, wrench ->
pose -> estimated wrench, with the settings (:class:`FlexureModelSettings`), the spring as built
(:func:`helical_spring`, :func:`spring_as_built`, :func:`chain_truth`), :func:`run` and its
metrics (:func:`evaluate`). What the truth and the estimate are: docs/models/flexure_model.md.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps
from designlab.sensors.protocols import FlexureWrenchTest
from designlab.calibration.stiffness_fit import fit_stiffness
from designlab.errors import ModelError, ParameterError
from designlab.fem.settings import FEMSettings
from designlab.params import rng, validate
from designlab.sensors.flexure.spring import TWIST, WRENCH  # noqa: F401  (the 6x6's order)

K_F_UNITS = ("SI: N*m/rad (rotational), N/m (translational), N (couplings); rows m_x, m_y, m_z, "
             "f_x, f_y, f_z; columns w_x, w_y, w_z, v_x, v_y, v_z; frame {f}: spring centre, "
             "rigid with the fingertip")


@dataclass(frozen=True)
class FlexureModelSettings(FEMSettings):
    """Settings of the flexure test (mm, s). ``truth="chain"`` (default) is the beam chain of
    the spring as built, ``"timoshenko"`` the column closed form, ``"fem"`` the meshed helix
    (its mesh defaults: docs/models/flexure_model.md)."""

    truth: str = field(default="chain", metadata=rng(choices=("chain", "fem", "timoshenko"),
                       doc="stiffness of the built flexure"))
    seat: str = field(default="bonded", metadata=rng(
        choices=("bonded", "contact", "potted"),
        doc="chain truth: ground faces bonded to the discs (seed 002: epoxy), only seated "
            "(wire end bonded), or the whole dead turn potted"))
    working_load_N: float = field(default=10.0, metadata=rng(0, 1000, unit="N", doc=(
        "chain truth: axial compression at which the stiffness is linearised (seed 002: "
        "maximum fingertip force 10 N; 0: the unloaded spring)")))
    edge_length: float = field(default=2.0, metadata=rng(0.1, 10, unit="mm"))
    epsilon: float = field(default=0.06, metadata=rng(0.001, 1, unit="mm",
                           doc="fTetWild envelope of the FEM mesh"))
    base_set: str = "flexure_base"
    tip_set: str = "flexure_tip"
    pose_noise_mm: float = field(default=0.0, metadata=rng(0, 10, unit="mm",
                                 doc="std of the pose estimate per translation (paper: ~0.02)"))
    pose_noise_rad: float = field(default=0.0, metadata=rng(0, 1, unit="rad"))
    seed: int = field(default=0, metadata=rng(0, 2**31 - 1))
    hold_s: float = field(default=6.0, metadata=rng(0, 3600, lo_open=True, unit="s",
                          doc="hold per staircase level (Prony materials only)"))
    dt_s: float = field(default=0.5, metadata=rng(0, 60, lo_open=True, unit="s"))

    def __post_init__(self):
        validate(self)
        for name, default in (("base_set", "flexure_base"), ("tip_set", "flexure_tip")):
            if self.truth != "fem" and getattr(self, name) != default:   # else silently unused
                raise ParameterError(name, getattr(self, name), f"{default!r}: the face sets "
                                     "are read by truth = \"fem\" only")


def helical_spring(part):
    """The :class:`~designlab.sensors.flexure.spring.HelicalSpring` of a ``SpringFlexure`` (active coils,
    moduli of its wire material)."""
    from designlab.fem.materials import get_material
    from designlab.sensors.flexure.spring import HelicalSpring

    m = get_material(part.material)
    return HelicalSpring(wire_radius=part.wire_radius, mean_diameter=part.mean_diameter,
                         coils=part.active_coils, inactive_coils=0.0,
                         pitch_angle=part.pitch_angle, E=m.E, G=m.G)


def spring_as_built(part):
    """The :class:`~designlab.sensors.flexure.spring.HelicalSpring` of a ``SpringFlexure`` as
    built, for the beam chain: ``closed_ground`` -> ``active_coils + 2`` turns of which 2 are
    dead (one per end), ``plain`` -> ``active_coils`` turns, no dead turn; wire, diameter, pitch
    angle and the moduli of its wire material. The chain's seat-to-seat length is then the
    handbook ``n_a p + 2 d``, which is the part's ``length`` for ground ends (plain ends: the
    chain is clamped at the wire ends, ``n_a p``, the part embeds them ``r / 2`` into each
    disc)."""
    from designlab.fem.materials import get_material
    from designlab.sensors.flexure.spring import GROUND_DEAD_COILS, HelicalSpring

    m = get_material(part.material)
    dead = GROUND_DEAD_COILS if part.ends == "closed_ground" else 0.0
    return HelicalSpring(wire_radius=part.wire_radius, mean_diameter=part.mean_diameter,
                         coils=part.active_coils + dead, inactive_coils=dead,
                         pitch_angle=part.pitch_angle, E=m.E, G=m.G)


def chain_truth(part, settings: "FlexureModelSettings"):
    """The beam chain of ``part`` as built (:func:`spring_as_built`), seats of the part's disc
    material: a :class:`~designlab.sensors.flexure.beam_chain.ChainResult`."""
    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import ChainSettings

    cs = ChainSettings(seat=settings.seat, working_load_N=settings.working_load_N,
                       seat_material=getattr(part, "disc_material", "PLA"))
    return chain_stiffness(spring_as_built(part), cs)


def _wire_stress(part, protocol: FlexureWrenchTest, settings: "FlexureModelSettings",
                 chain=None) -> dict:
    """Wire stress and safety factor of the spring as built under the protocol's load cases
    (:func:`designlab.sensors.flexure.stress.wire_stress`): the closed form, and the beam
    chain beside it (the truth's own ``chain``, a ChainResult, when it ran) unless the truth is
    the Timoshenko column (no chain in that model)."""
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.stress import wire_stress

    cs = ChainSettings(seat=settings.seat, seat_material=getattr(part, "disc_material", "PLA"))
    use = settings.truth != "timoshenko"
    if use and chain is not None and chain.chain is not None:
        use = chain.chain
    return wire_stress(spring_as_built(part), protocol, cs, material=part.material, chain=use)


def _fem_model(mesh, settings: FlexureModelSettings, centre, materials=None):
    """Base clamped, tip rigid to a master at the spring centre, six unit wrench cases."""
    from designlab.fem.model import Model

    model = Model(mesh, materials)
    model.fix(settings.base_set)
    ref = model.rigid("tip_master", settings.tip_set, ref_point=centre)
    eye = np.eye(6)
    for i, name in enumerate(WRENCH):
        model.force(ref, force=eye[i, 3:], moment=eye[i, :3], case=name)
    return model, ref


@dataclass
class FlexurePrediction:
    """Virtual test results (N mm, N, mm, rad)."""

    wrenches: np.ndarray        # (n, 6) applied
    poses: np.ndarray           # (n, 6) twists X = K_true^-1 W (+ pose noise)
    estimated: np.ndarray       # (n, 6) K_design X
    K_true: np.ndarray          # 6x6, designlab units
    K_design: np.ndarray
    report: dict[str, Any]
    mesh: Any = None            # FEM mesh and displacement (n_points, 3) mm under the largest
    displacement: Any = None    # axial force of the protocol (None without the FEM)


def _fem_truth(part, protocol: FlexureWrenchTest, settings: FlexureModelSettings, mesh,
               materials, say, timings: dict):
    """The meshed helix's 6x6 at the spring centre by the solid FEM (no contact): (K_fem, its
    info, the FEM model, the mesh, the displacement under the protocol's largest axial force)."""
    t0 = time.perf_counter()
    if mesh is None:
        from designlab.mesh.meshing import mesh_part

        say("meshing")
        mesh = mesh_part(part, order=settings.order, edge_length=settings.edge_length,
                         quality=settings.mesh_quality, epsilon=settings.epsilon,
                         mesher=settings.mesher)
    timings["mesh"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say("assembling")
    model, ref = _fem_model(mesh, settings, np.asarray(part.spring_center, float), materials)
    system = model.build()
    timings["assemble"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say("solving 6 unit wrenches")
    from designlab.fem.static import solve_static

    res = solve_static(model, solver=settings.solver)
    C = np.column_stack([res.twist(ref, name) for name in WRENCH])
    u_vtu = res.displacement("f_z") * protocol.max_force_N
    timings["solve"] = time.perf_counter() - t0
    asym = float(np.linalg.norm(C - C.T) / np.linalg.norm(C))
    try:
        K_fem = np.linalg.inv((C + C.T) / 2)
    except np.linalg.LinAlgError:
        raise ModelError("FEM compliance of the flexure is singular: check the base/tip "
                         "sets") from None
    K_fem = (K_fem + K_fem.T) / 2
    fem_info = {"points": int(mesh.n_points), "cells": int(mesh.n_cells),
                "order": int(mesh.order), "dofs": int(system.n_dofs),
                "edge_length_mm": settings.edge_length, "asymmetry": asym,
                "solver": type(res.solver).__name__}
    return K_fem, fem_info, model, mesh, u_vtu


def _chain_truth_state(part, settings: FlexureModelSettings, say, timings: dict):
    """The beam chain of the spring as built: (chain, its info, K at the centre unloaded and
    at the working load or None)."""
    t0 = time.perf_counter()
    say("beam chain of the spring as built")
    chain = chain_truth(part, settings)
    K_chain = chain.K_centre
    K_chain_loaded = chain.at(chain.centre, loaded=True) if chain.K_loaded is not None \
        else None
    timings["solve"] += time.perf_counter() - t0
    chain_info = dict(chain.info, seat=settings.seat, working_load_N=settings.working_load_N)
    return chain, chain_info, K_chain, K_chain_loaded


def _pick_truth(settings: FlexureModelSettings, K: dict, chain, notes: list) -> np.ndarray:
    """The stiffness the built flexure answers with, by ``settings.truth``, with its note."""
    if settings.truth == "fem":
        notes.append("truth: FEM of the meshed helix (real pitch, ground ends, base clamped, "
                     "tip rigid)")
        return K["fem"]
    if settings.truth == "chain":
        loaded = K["chain_loaded"] is not None
        notes.append(f"truth: beam chain of the spring as built ({chain.coil.label}; seat "
                     f"{settings.seat}; "
                     + (f"linearised at the {settings.working_load_N:g} N axial working load)"
                        if loaded else "unloaded)"))
        return K["chain_loaded"] if loaded else K["chain"]
    notes.append("truth: Timoshenko column (closed form with the spring's active length); "
                 "no FEM")
    return K["timoshenko"]


def _poses(protocol: FlexureWrenchTest, K_true: np.ndarray, settings: FlexureModelSettings,
           notes: list) -> tuple[np.ndarray, np.ndarray]:
    """The protocol's wrenches and the poses ``X = K_true^-1 W`` (+ pose noise)."""
    W = protocol.wrenches()
    C_true = np.linalg.inv(K_true)
    X = W @ C_true.T
    if settings.pose_noise_mm > 0 or settings.pose_noise_rad > 0:
        rs = np.random.default_rng(settings.seed)
        X = X + rs.normal(size=X.shape) * np.r_[[settings.pose_noise_rad] * 3,
                                                [settings.pose_noise_mm] * 3]
        notes.append(f"pose noise: {settings.pose_noise_mm:g} mm, {settings.pose_noise_rad:g} "
                     f"rad (std, seed {settings.seed})")
    return W, X


def _elastic_hysteresis(notes: list) -> dict:
    notes.append("hysteresis 0 %: elastic model, not a prediction of the real flexure")
    return {"overall": 0.0, "by_location": {a: 0.0 for a in WRENCH},
            "note": "elastic model (no Prony series in the materials): no hysteresis by "
                    "construction; seed 002 measured 2-5 % of range on the real flexure"}


def _stiffness_entries(K: dict, K_true: np.ndarray, settings: FlexureModelSettings,
                       chain_info) -> dict:
    """The report's K_f entries (SI), one per model that ran (None where it did not)."""
    from designlab.sensors.flexure.spring import to_si

    si = {k: (to_si(v).tolist() if v is not None else None) for k, v in K.items()}
    K_fem = K["fem"]
    return {"K_f": to_si(K_true).tolist(), "K_f_units": K_F_UNITS,
            "K_f_source": settings.truth, "K_f_closed_form": si["design"],
            "K_f_timoshenko": si["timoshenko"], "K_f_fem": si["fem"],
            "K_f_chain": si["chain"], "K_f_chain_loaded": si["chain_loaded"],
            "chain": chain_info,
            "K_f_fem_over_closed_form": (np.diag(K_fem) / np.diag(K["design"])).tolist()
            if K_fem is not None else None,
            "condition_number": float(np.linalg.cond(to_si(K_true))),
            "condition_number_units": "cond of K_f in SI (mixed units: depends on them)"}


def _spring_entry(spring, part) -> dict:
    return {"wire_radius_mm": spring.wire_radius, "mean_diameter_mm": spring.mean_diameter,
            "active_coils": spring.active_coils, "pitch_angle_rad": spring.pitch_angle,
            "E_MPa": spring.E, "G_MPa": spring.G, "length_mm": float(part.length)}


def run(part=None, protocol: FlexureWrenchTest | None = None,
        settings: FlexureModelSettings | None = None, *, materials=None, mesh=None,
        progress: Callable[[str], None] | None = None, wire_stress: bool = True
        ) -> FlexurePrediction:
    """K_f (closed form, FEM), the protocol's wrenches through the true stiffness, the sensor's
    estimate through the designer's, the metrics and (``wire_stress``) the wire's stress and
    safety factor per load case (``report["stress"]``, :mod:`designlab.sensors.flexure.stress`;
    a safety factor below 2 warns)."""
    from designlab.geometry.flexure import SpringFlexure
    from designlab.sensors.flexure.spring import stiffness_timoshenko, stiffness_zero_pitch

    part = part or SpringFlexure()
    protocol = protocol or FlexureWrenchTest()
    settings = settings or FlexureModelSettings()
    say = progress or (lambda s: None)
    timings = {"mesh": 0.0, "assemble": 0.0, "solve": 0.0, "metrics": 0.0}
    spring = helical_spring(part)
    K = {"design": stiffness_zero_pitch(spring),
         "timoshenko": stiffness_timoshenko(spring, frame="centre"),
         "fem": None, "chain": None, "chain_loaded": None}
    notes = ["K_design: seed 002 closed form (zero pitch, many coils) at the spring centre"]
    fem_info = model = u_vtu = None
    if settings.truth == "fem" or mesh is not None:
        K["fem"], fem_info, model, mesh, u_vtu = _fem_truth(part, protocol, settings, mesh,
                                                            materials, say, timings)
    if K["fem"] is not None and getattr(part, "ends", None) == "closed_ground":
        notes.append("FEM helix: the closed end coils are modelled 0.1 d apart without coil "
                     "contact, so they deform like active coils and the FEM is softer than "
                     "the closed form's active turns (ratios in K_f_fem_over_closed_form)")
    chain = chain_info = None
    if settings.truth == "chain":
        chain, chain_info, K["chain"], K["chain_loaded"] = _chain_truth_state(part, settings,
                                                                              say, timings)
    K_true = _pick_truth(settings, K, chain, notes)
    K_design = K["design"]

    t0 = time.perf_counter()
    W, X = _poses(protocol, K_true, settings, notes)
    W_est = X @ K_design.T
    report = evaluate(W, X, W_est, K_true, K_design)
    hyst = _hysteresis(model, protocol, settings, K_design, say) if model is not None else None
    report["hysteresis_percent"] = _elastic_hysteresis(notes) if hyst is None else hyst
    timings["metrics"] = time.perf_counter() - t0

    report.update(_stiffness_entries(K, K_true, settings, chain_info))
    report["mesh"] = fem_info
    report["spring"] = _spring_entry(spring, part)
    if wire_stress:
        t0 = time.perf_counter()
        say("wire stress")
        report["stress"] = _wire_stress(part, protocol, settings, chain)
        timings["wire_stress"] = time.perf_counter() - t0
        for w in report["stress"]["warnings"]:
            warnings.warn(w, stacklevel=2)
    report["timings_s"] = timings
    report["notes"] = notes
    return FlexurePrediction(W, X, W_est, K_true, K_design, report, mesh, u_vtu)


def evaluate(W: np.ndarray, X: np.ndarray, W_est: np.ndarray, K_true: np.ndarray,
             K_design: np.ndarray) -> dict[str, Any]:
    """Wrench error statistics (Table I style), calibration fit, compliance (sensitivity)."""
    err = W - W_est
    scale = np.r_[[1e-3] * 3, [1.0] * 3]               # N mm -> N m for moments
    e_si = err * scale
    stats = {a: {"mean": float(e_si[:, i].mean()),
                 "std": float(e_si[:, i].std(ddof=1)) if len(e_si) > 1 else 0.0,
                 "max_abs": float(np.abs(e_si[:, i]).max())} for i, a in enumerate(WRENCH)}
    rel = {}
    for i, a in enumerate(WRENCH):
        on = np.abs(W[:, i]) > 0
        rel[a] = float(100 * np.mean(np.abs(err[on, i]) / np.abs(W[on, i]))) if on.any() else None
    fit = fit_stiffness(X, W)                              # what a calibration would find
    C = np.linalg.inv(K_true)
    return {
        "wrench_error": {"stats": stats,
                         "units": "moments N*m, forces N; error = applied - estimated",
                         "relative_percent_on_axis": rel,
                         "table_I_forces_N": {a: stats[f"f_{a}"] for a in "xyz"}},
        "calibration_matrix": (fit.K * _si()).tolist(),
        "calibration_units": "K fitted from (pose, wrench) pairs, SI like K_f (seed 002 Sec. V)",
        "calibration_fit": {"residual_rms": fit.residual_rms.tolist(),
                            "condition_number": fit.condition_number},
        "sensitivity": {
            "compliance_diagonal": {
                **{f"{a} per m_{a[-1]}": float(C[i, i]) for i, a in enumerate(TWIST[:3])},
                **{f"{a} per f_{a[-1]}": float(C[i, i]) for i, a in enumerate(TWIST[3:], 3)}},
            "units": "rad per N mm (rotations), mm per N (translations)",
            "compliance_matrix": C.tolist()},
        "applied_vs_estimated": {"applied": W.tolist(), "estimated": W_est.tolist(),
                                 "units": "N mm, N"},
    }


def _si() -> np.ndarray:
    from designlab.sensors.flexure.spring import SI_SCALE
    return SI_SCALE


def staircase(protocol: FlexureWrenchTest, settings: FlexureModelSettings):
    """(t, amplitude, level index) of a 0 -> 1 -> 0 staircase of ``protocol.steps`` levels,
    each held ``settings.hold_s`` (amplitude x the axis' maximum wrench)."""
    lev = np.linspace(0, 1, protocol.steps + 1)
    seq = np.concatenate([lev, lev[-2::-1]])
    n = max(1, int(round(settings.hold_s / settings.dt_s)))
    step = np.repeat(np.arange(len(seq)), n)
    t = np.arange(len(step)) * settings.dt_s
    return t, seq[step], step, seq


def _hysteresis(model, protocol: FlexureWrenchTest, settings: FlexureModelSettings, K_design,
                say) -> dict | None:
    """Eq. (1) per axis on the estimated wrench over a loading/unloading staircase, or None when
    every material is elastic."""
    if not any(m.prony is not None for m in model.region_materials.values()):
        return None
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    def twist_of(name, t, load):
        say(f"viscoelastic history {name}")
        return solve_history(model, History(t, {name: load}),
                             solver=settings.solver).twist("tip_master")

    return staircase_hysteresis(protocol, settings, K_design, twist_of,
                                f"Prony materials: staircase of {protocol.steps} levels, "
                                f"{settings.hold_s:g} s holds, reading at the end of each hold")


def staircase_hysteresis(protocol: FlexureWrenchTest, settings, K_design, twist_of, note: str
                         ) -> dict:
    """Eq. (1) per wrench axis on the estimated wrench ``X K_design^T`` over a 0 -> max -> 0
    :func:`staircase` of that axis alone (N*mm, N), read at the end of each hold.
    ``twist_of(name, t, load)`` gives the tip twists (n_t, 6) under ``load`` (n_t,) along the
    wrench axis ``name`` at the times ``t`` (s)."""
    t, a, step, seq = staircase(protocol, settings)
    if protocol.steps < 2:
        return {"overall": None, "by_location": {w: None for w in WRENCH},
                "note": "needs steps >= 2 for a loop"}
    amp = np.array([protocol.max_moment_Nmm] * 3 + [protocol.max_force_N] * 3)
    ends = np.array([np.nonzero(step == k)[0][-1] for k in range(len(seq))])
    by, loops = {}, {}
    for i, name in enumerate(WRENCH):
        reading = (twist_of(name, t, amp[i] * a) @ K_design.T)[ends, i]
        lu, su, ld, sd = loop_from_steps(amp[i] * seq, reading)
        by[name] = float(hysteresis_percent(lu, su, ld, sd))
        loops[name] = {"applied": (amp[i] * seq).tolist(), "estimated": reading.tolist()}
    return {"overall": float(np.mean(list(by.values()))), "by_location": by, "loops": loops,
            "note": note}
