"""Virtual hanging-weight test of the seed 001 cantilever fingertip (Section III, Tables II-III).

The FEM model (mm, N, MPa, s):

* meshed, printed ABS: the base and the bottom cap (they share nodes at their interface);
* the steel ball: a rigid 6-dof master at the ball centre (a free rigid body held by the sensors
  and the bolt); the detachable fingertip is rigidly seated on it and touches nothing else, so
  it passes the wrench of a load to the ball whatever its own compliance: it is not meshed for
  the readings (``mesh_fingertip=True`` meshes it and couples its seat to the ball);
* the three Honeywell FSS015 sensors: stiff springs between a point of the ball (the contact,
  ``-r_ball * axis``) and the floor of their well (distributing coupling), along the sensor axis
  45 deg from the vertical; the spring force is the reading (compression positive);
* the M2.5 cantilever bolt: a Timoshenko steel beam from the bolt-head seat under the cap (rigid
  coupling) to the point where it enters the ball; the threaded part is rigid with the ball;
* the cap's outer bottom (``cap_mount``) is fixed to the robot.

The fingertip passes the load to the ball and nothing else, so every sensor reading is a linear
function of the wrench at the ball centre: the test runs six unit-wrench load cases through the
load history once and combines them for every load point, height/radius and rotation (exact for
linear viscoelasticity).

Readings follow the paper: each weight is held ``hold_s``, the reading is the mean over the
``read_window_s`` before the next weight. Hysteresis: eq. (1) per sensor, averaged over the
sensors whose span is at least 10 % of the largest at that location (the paper notes that a
tension-side sensor with a tiny span inflates eq. (1)), then over the rotations.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from dataclasses import dataclass
from typing import Any, Callable, Collection

import numpy as np

from designlab.calibration.calibration_matrix import (condition_number, cross_talk_percent,
                                                      fit_calibration_matrix, geometric_matrix,
                                                      linearity_percent)
from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps
from designlab.sensors.fingertip.model import (
    FSS015_V_PER_N, WRENCH, FingertipModelSettings, build_model,
    check_locations, contact_settings, design_protocol, fem_key, mesh_fingertip, wrench_at_ball)
from designlab.sensors.fingertip.montecarlo import MONTE_CARLO
from designlab.sensors.protocols import HangingWeightTest
from designlab.sensors.definition import Physics


@dataclass
class FingertipPrediction:
    """Results of the virtual test (forces N, readings V, times s)."""

    t: np.ndarray
    load: np.ndarray                      # hanging load history, N
    unit_readings: np.ndarray             # (n_t, 6, 3) sensor force per unit wrench, N per (N|N mm)
    report: dict[str, Any]
    mesh: Any = None                      # the FEM mesh and its displacement (n_points, 3) mm
    displacement: Any = None              # under the largest load at the first G1 location
    condensed: Any = None                 # contact model: the CondensedFingertip it ran on
    settings: Any = None                  # the FingertipModelSettings of the run
    cache: Any = None                     # the FEMCache of the run and its FEM key
    fem_key: str | None = None
    materials: Any = None                 # the measured materials the run used (None: stand-ins)


def step_responses(model, sensors, tau_max: float, dt: float, t_end: float,
                   solver: str = "direct", settle: float = 7.0, info: dict | None = None
                   ) -> np.ndarray:
    """(n_h, 6, 3) sensor forces after a unit step of each unit wrench at t = 0, on a grid of
    ``dt`` up to ``settle * tau_max`` (after that the response is constant to exp(-settle),
    0.1 %, of the relaxing part) or ``t_end``, whichever is shorter. ``info``: gets the
    ``solver`` that ran."""
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    t_h = np.arange(0.0, min(t_end, settle * tau_max) + dt, dt)
    res = solve_history(model, History(t_h, {c: np.ones(len(t_h)) for c in WRENCH}),
                        batch=True, solver=solver)
    H = np.moveaxis(np.stack([res.spring_force(s) for s in sensors], axis=-1), 0, 1)
    if info is not None:
        info["solver"] = res.solvers[0].kind
    return H, res.displacement(-1)


def superpose_steps(H: np.ndarray, dt: float, t: np.ndarray, load: np.ndarray) -> np.ndarray:
    """Response per unit wrench (n_t, 6, 3), normalised by ``load``, of the piecewise-constant
    ``load(t)`` from the unit step responses ``H`` (Boltzmann superposition: exact for linear
    viscoelasticity)."""
    jumps = np.flatnonzero(np.diff(np.r_[0.0, load]))
    out = np.zeros((len(t),) + H.shape[1:])
    for j in jumps:
        dP = load[j] - (load[j - 1] if j > 0 else 0.0)
        lag = np.clip(np.rint((t[j:] - t[j]) / dt).astype(int), 0, len(H) - 1)
        out[j:] += dP * H[lag]
    return out / np.where(load > 0, load, 1.0)[:, None, None]


def _readings_for(unit: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(n_t, 3) sensor forces for wrench ``w`` per unit load (N) times the load amplitude."""
    return np.einsum("tcs,c->ts", unit, w)


def solve_fem(part, protocol: HangingWeightTest, settings: FingertipModelSettings,
              materials=None, mesh=None, say: Callable[[str], None] = lambda s: None
              ) -> dict[str, Any]:
    """The FEM stage: mesh, model, and the sensor forces per unit wrench at the ball.

    Returns plain arrays: ``H`` (n_h, 6, 3) step responses on the grid ``dt_s`` (one row when
    no material relaxes), ``U_unit`` (6, n_points, 3) displacement per unit wrench (long time),
    the mesh (``points``, ``cells``, ``region``), ``dofs``, ``viscoelastic``, timings (s),
    ``mesher`` (gmsh, tetwild: the fallback, or given), ``mesh_attempts`` and ``solver`` (the
    linear solver that ran)."""
    from designlab.fem.static import solve_static
    from designlab.fem.solvers import choose_solver

    timings = {}
    t0 = time.perf_counter()
    if mesh is None:
        say("meshing")
        made = mesh_fingertip(part, settings, detailed=True)
        mesh, mesher, attempts = made.mesh, made.mesher, list(made.attempts)
    else:
        mesher, attempts = "given", []
    timings["mesh"] = time.perf_counter() - t0
    info: dict[str, str] = {}
    t0 = time.perf_counter()
    say("assembling")
    model, names = build_model(part, mesh, settings, materials)
    timings["assemble"] = time.perf_counter() - t0
    t, _, _ = protocol.time_history()
    t0 = time.perf_counter()
    taus = [tau for m in model.region_materials.values() if m.prony is not None
            for tau in (*m.prony.tau, *m.prony.k_tau)]
    extra: dict[str, Any] = {}
    if settings.contact:
        # the contact model's structure: condensed at the ball and the wells (one factorisation
        # at the structure's moduli); the linear readings and fields come from the same solve
        from designlab.sensors.fingertip.contact import condense_fingertip

        say("condensing the structure at the ball and the sensor wells")
        cf, H6, U_unit = condense_fingertip(part, mesh, settings, settings.structure_moduli,
                                            materials, with_fields=True)
        H = H6[None]
        extra = cf.to_arrays()
        taus = []          # one static solve at the chosen moduli (no step responses)
        # condense_fingertip keeps its solve to itself: the kind choose_solver gives its model
        # (every DOF; the unit loads at the masters and the model's own cases)
        info["solver"] = choose_solver(int(cf.n_dofs_fem), settings.solver,
                                       n_rhs=len(cf.C) + len(WRENCH) + 1)
    elif taus:
        say("viscoelastic step responses")
        H, U_unit = step_responses(model, names["sensors"], max(taus), protocol.dt_s, t[-1],
                                   settings.solver, info=info)
    else:
        say("static solve")
        res = solve_static(model, solver=settings.solver)
        info["solver"] = res.solver.kind
        H = np.array([[[res.spring_force(s, c) for s in names["sensors"]] for c in WRENCH]])
        U_unit = np.stack([res.displacement(c) for c in WRENCH])
    timings["solve"] = time.perf_counter() - t0
    return {"H": H, "U_unit": U_unit, "points": mesh.points, "cells": mesh.cells,
            "region": mesh.region, "region_names": np.array([mesh.region_names[k]
                                                             for k in sorted(mesh.region_names)]),
            "region_materials": np.array([mesh.materials[mesh.region_names[k]]
                                          for k in sorted(mesh.region_names)]),
            "dofs": np.array(model.n_dofs), "viscoelastic": np.array(bool(taus)),
            "material_relaxation": np.array(json.dumps(
                {m.name: m.source for m in model.region_materials.values()})),
            "timings": np.array([timings["mesh"], timings["assemble"], timings["solve"]]),
            "mesher": np.array(mesher), "mesh_attempts": np.array(attempts, dtype=str),
            "solver": np.array(info["solver"]), **extra}


def run(part, protocol: HangingWeightTest | None = None,
        settings: FingertipModelSettings | None = None, *, materials=None, mesh=None,
        progress: Callable[[str], None] | None = None, cache=None) -> FingertipPrediction:
    """Mesh (unless given), build, run the load history, and evaluate the metrics. ``cache``
    (:class:`~designlab.fem.cache.FEMCache`): the FEM stage is computed once per
    :func:`fem_key` and reused by every design that shares it (an (h, r) sweep)."""
    from designlab.fem.cache import timed_stage
    from designlab.mesh.tetmesh import TetMesh

    protocol = protocol or HangingWeightTest()
    settings = settings or FingertipModelSettings()
    check_locations(part, protocol)
    say = progress or (lambda s: None)
    key = None if mesh is not None else fem_key(part, protocol, settings, materials)
    fem, reused, stage_timings = timed_stage(
        lambda: solve_fem(part, protocol, settings, materials, mesh, say), key, cache)
    t, load, step = protocol.time_history()
    if bool(fem["viscoelastic"]):
        unit = superpose_steps(fem["H"], protocol.dt_s, t, load)
    else:
        unit = np.broadcast_to(fem["H"][0], (len(t), 6, 3)).copy()
    t0 = time.perf_counter()
    condensed = None
    if settings.contact:
        from designlab.sensors.fingertip.contact import CondensedFingertip, run_contact_test

        say("contact model: tightening and the load history")
        condensed = CondensedFingertip.from_arrays(fem)
        report = run_contact_test(part, protocol, contact_settings(settings), condensed,
                                  rotations_deg=settings.rotations_deg)
        contact_timings = report.pop("timings_s")
    else:
        report = evaluate(part, protocol, settings, t, load, step, unit)
        hp = report["hysteresis_percent"]           # the linear model has no readout noise
        hp["overall_noise_free"] = hp["overall"]
        hp["by_group_noise_free"] = dict(hp["by_group"])
        report["model"] = "linear (bilateral sensor springs, ABS relaxation)"
    report["timings_s"] = stage_timings
    if settings.contact:
        report["timings_s"].update({f"contact_{k}": v for k, v in contact_timings.items()})
    report["timings_s"]["metrics"] = time.perf_counter() - t0
    names = [str(n) for n in fem["region_names"]]
    mesh = TetMesh(fem["points"], fem["cells"], fem["region"], dict(enumerate(names)),
                   dict(zip(names, (str(m) for m in fem["region_materials"]))))
    report["mesh"] = {"points": int(mesh.n_points), "cells": int(mesh.n_cells),
                      "order": int(mesh.order), "dofs": int(fem["dofs"]),
                      "mesher": str(fem["mesher"]),
                      "attempts": [str(a) for a in fem["mesh_attempts"]],
                      "solver": str(fem["solver"])}
    report["fem_reused"] = reused
    report["fem_key"] = key[:16] if key is not None else None
    report["viscoelastic"] = bool(fem["viscoelastic"])
    report["material_relaxation"] = json.loads(str(fem["material_relaxation"]))
    first = protocol.g1_locations[0] if protocol.g1_locations else protocol.g2_locations[0]
    pts = part.load_points(settings.rotations_deg[0])
    u = None
    if first in pts:
        w = wrench_at_ball(*pts[first]) * float(load.max())
        u = np.einsum("c,cpk->pk", w, fem["U_unit"])
        report["vtu_load"] = {"location": first, "load_N": float(load.max())}
    return FingertipPrediction(t, load, unit, report, mesh, u, condensed, settings, cache, key,
                               materials)


def evaluate(part, protocol: HangingWeightTest, settings: FingertipModelSettings, t, load, step,
             unit: np.ndarray) -> dict[str, Any]:
    """Hysteresis per location, calibration matrix, condition numbers, sensitivity."""
    masks = protocol.read_masks(t, step)
    seq = protocol.sequence_g
    locs = {"G1": protocol.g1_locations, "G2": protocol.g2_locations}
    check_locations(part, protocol)
    by_location: dict[str, float] = {}
    group_mean: dict[str, float] = {}
    S_rows, P_rows, loop_data = [], [], {}
    response: dict[str, list[float]] = {}
    for group, names in locs.items():
        vals = []
        for name in names:
            hs = []
            for rot in settings.rotations_deg:
                p, d = part.load_points(rot)[name]
                w = wrench_at_ball(p, d)
                force = _readings_for(unit, w) * load[:, None]                # (n_t, 3) N
                reading = FSS015_V_PER_N * force                              # V
                S = np.array([reading[m].mean(axis=0) for m in masks])       # (steps, 3)
                lu, su, ld, sd = loop_from_steps(seq, S)
                span = np.abs(su[-1] - su[0])
                keep = span >= 0.1 * span.max()
                h = hysteresis_percent(lu, su, ld, sd)
                hs.append(float(np.mean(h[keep])))
                # calibration load set: applied force vector vs reading change at max weight
                k = int(np.argmax(seq))
                P_rows.append(d * (load[masks[k]].mean() - load[masks[0]].mean()))
                S_rows.append(S[k] - S[0])
                if rot == settings.rotations_deg[0]:
                    loop_data[name] = {"weights_g": seq.tolist(), "readings_V": S.tolist()}
                    response[name] = (S[k] - S[0]).tolist()
            if hs:
                by_location[name] = float(np.mean(hs))
                vals.append(by_location[name])
        if vals:
            group_mean[group] = float(np.mean(vals))
    S_all, P_all = np.array(S_rows), np.array(P_rows)
    A, fit = fit_calibration_matrix(S_all, P_all)
    P_est = S_all @ A.T
    G = geometric_matrix()
    kmax = int(np.argmax(seq))
    lin = []
    for name, ld in loop_data.items():
        S = np.array(ld["readings_V"])[: kmax + 1]
        for ch in range(3):
            if np.ptp(S[:, ch]) > 0:
                lin.append(linearity_percent(seq[: kmax + 1], S[:, ch]))
    sens = np.linalg.pinv(A)            # V per N along x, y, z (rows: sensors)
    overall = float(np.mean(list(by_location.values()))) if by_location else float("nan")
    return {
        "hysteresis_percent": {"overall": overall, "by_group": group_mean,
                               "by_location": by_location},
        "calibration_matrix": A.tolist(),
        "calibration_units": "N per V (P = A S)",
        "condition_number": condition_number(A),
        "geometric_matrix": G.tolist(),
        "geometric_condition_number": condition_number(G),
        "calibration_fit": fit,
        "sensitivity": {"V_per_N": {ax: float(np.linalg.norm(sens[:, i]))
                                    for i, ax in enumerate("xyz")},
                        "matrix_V_per_N": sens.tolist()},
        "linearity_percent_span": float(max(lin)) if lin else float("nan"),
        "cross_talk_percent": cross_talk_percent(P_all, P_est).tolist(),
        "loops": loop_data,
        "response_at_max_V": response,
        "peak_sensor_force_N": float(np.abs(np.array(S_rows)).max() / FSS015_V_PER_N)
        if S_rows else 0.0,
        "applied_vs_estimated": {"applied_N": P_all.tolist(), "estimated_N": P_est.tolist()},
    }


# ------------------------------------------------------------------ prediction: finish, plots, loop

def load_paths(prediction: FingertipPrediction, part) -> dict[str, Any]:
    """What drives the condition number (seed 001 Section IV): the share of each applied force
    component carried by the three sensors (the rest: the bolt and the cap) and the sensor
    forces per unit wrench, from the FEM's long-time unit readings."""
    unit = prediction.unit_readings[-1]                       # (6 wrench, 3 sensors), N per N
    axes, _ = part.sensor_axes()
    share = {ax: float(np.abs(axes[:, i] @ (-unit[i]))) for i, ax in enumerate("xyz")}
    return {"share_through_sensors": share,
            "share_through_bolt_and_cap": {k: 1.0 - v for k, v in share.items()},
            "unit_wrench_sensor_forces_N": {w: unit[i].tolist() for i, w in enumerate(WRENCH)}}


def finish(report: dict[str, Any], prediction: FingertipPrediction, part,
           protocol: HangingWeightTest) -> None:
    """The load paths (:func:`load_paths`); the calibration error budget
    (``force_error_test``: the FSS015/DAQ readout noise through the paper's calibration, force
    error per axis on held-out points beside Fig. 9, on the FEM this prediction solved:
    :func:`designlab.sensors.fingertip.calibration.prediction_force_error`); the table's load
    points this design lacks. The paper comparison is ``designlab validate fingertip``'s
    (:func:`validate`): the contact run's own is left out of the prediction."""
    report.pop("paper_comparison", None)
    report["load_paths"] = load_paths(prediction, part)
    if prediction.condensed is None:
        # the contact run checked the range and overforce (preload included) itself
        protocol.check_sensor_range(report.get("peak_sensor_force_N", 0.0), "FSS015 sensor")
    t0 = time.perf_counter()
    from designlab.sensors.fingertip.calibration import prediction_force_error

    report["force_error_test"] = prediction_force_error(part, protocol, prediction)
    report.setdefault("timings_s", {})["force_error_test"] = time.perf_counter() - t0
    table = HangingWeightTest.preset("optimized") if part.load_table == "III" else HangingWeightTest()
    report["locations_omitted"] = [
        n for n in (*table.g1_locations, *table.g2_locations)
        if n not in (*protocol.g1_locations, *protocol.g2_locations)]


def table_ii_sensor(part, prediction: FingertipPrediction):
    """The paper's tested sensor (:meth:`CantileverFingertip.table_ii`) with its own condensed
    structure, at this prediction's model settings and materials: a function returning
    ``(design, CondensedFingertip)`` (its FEM from ``prediction.cache``, computed once). The
    prediction's own when the design is that sensor."""
    from designlab.fem.cache import FEMCache, timed_stage
    from designlab.sensors.fingertip.contact import CondensedFingertip

    tested, proto = type(part).table_ii(), HangingWeightTest()
    if tested == part and prediction.condensed is not None:
        return lambda: (tested, prediction.condensed)
    settings, materials = prediction.settings, prediction.materials

    def get():
        cache = prediction.cache if prediction.cache is not None else FEMCache()
        fem, _, _ = timed_stage(lambda: solve_fem(tested, proto, settings, materials),
                                fem_key(tested, proto, settings, materials), cache)
        return tested, CondensedFingertip.from_arrays(fem)

    return get


def paper_comparison_of(part=None, settings: FingertipModelSettings | None = None,
                        progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """A design's virtual test beside seed 001 (default: the paper's Table III design at the
    default model settings): its own run (the protocol its load table gives), its load paths,
    then :func:`designlab.sensors.fingertip.validation.comparison` with the Table II sensor on
    its own structure. Returns ``{"paper_comparison": ..., "load_paths": ...}``."""
    from designlab.fem.cache import FEMCache
    from designlab.geometry.fingertip import CantileverFingertip
    from designlab.sensors.fingertip.validation import comparison

    part = part if part is not None else CantileverFingertip()
    settings = settings or FingertipModelSettings()
    protocol = design_protocol(HangingWeightTest(), part, None)
    prediction = run(part, protocol, settings, progress=progress, cache=FEMCache())
    report = dict(prediction.report)
    report["load_paths"] = load_paths(prediction, part)
    if progress:
        progress("the paper's Table II sensor and Table III design")
    tested = None if settings.mesh_fingertip else table_ii_sensor(part, prediction)
    return {"paper_comparison": comparison(part, protocol, prediction, report, tested),
            "load_paths": report["load_paths"]}


def validate(details: dict[str, Any], out: str | Path | None = None,
             progress: Callable[[str], None] | None = None) -> list:
    """``designlab validate fingertip``: the goal rows of :func:`paper_comparison_of` at the
    defaults (:func:`designlab.sensors.fingertip.validation.goal_rows`); ``details`` gets the
    comparison and the load paths, ``out`` the figure ``paper_comparison.png``."""
    from designlab.sensors.fingertip.validation import draw, goal_rows

    details.update(paper_comparison_of(progress=progress))
    if out is not None:
        details["figures"] = [draw(details["paper_comparison"], out).name]
    return goal_rows(details["paper_comparison"], details["load_paths"])


def gains(report: dict[str, Any], prediction: FingertipPrediction) -> tuple[dict, dict]:
    """Loop base: the wrench at the ball centre (f_x, f_y, f_z in N; m_x, m_y, m_z in N mm) ->
    sensor_1..3 (V), the FEM's long-time gains."""
    G = FSS015_V_PER_N * prediction.unit_readings[-1]               # (6 wrench, 3 sensors)
    outs = {f"sensor_{k + 1}": {w: float(G[i, k]) for i, w in enumerate(WRENCH)}
            for k in range(3)}
    return outs, {o: "V" for o in outs}


def plots(prediction: FingertipPrediction, report: dict[str, Any], out: Path,
          only: Collection[str] | None = None) -> list[Path]:
    """Hysteresis loops, reading vs weight per location, applied vs estimated (seed 001 Fig. 9).
    Every figure on a fixed grid (:func:`~designlab.sensors.plotstyle.figure`; constrained
    layout cost ~1.2 s CPU of the four figures), saved without ``bbox_inches="tight"`` (drawn
    once, not twice). ``only``: the file names to draw (:data:`PLOT_GROUPS`: ``designlab
    predict`` has two processes draw a group each); None: all."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from designlab.atomic import atomic_path

    def save(fig, name):
        path = Path(out) / name
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=110)
        plt.close(fig)
        return path

    def want(name):
        return only is None or name in only

    files = []
    loops = report["loops"]
    names = list(loops)
    if want("hysteresis_loops.png"):
        files.append(save(_loops_figure(loops, names), "hysteresis_loops.png"))
    if want("hysteresis_by_location.png"):
        files.append(save(_by_location_figure(report, names), "hysteresis_by_location.png"))
    if want("applied_vs_estimated.png"):
        files.append(save(_applied_figure(report), "applied_vs_estimated.png"))
    return files


#: the fingertip's plots in groups that ``designlab predict``'s two drawing processes draw
#: (:func:`plots`'s ``only``), one group each, while the report is finished: both read only
#: the run's report
PLOT_GROUPS = (("hysteresis_loops.png", "hysteresis_by_location.png"),
               ("applied_vs_estimated.png",))
PLOTS_BEFORE_FINISH = frozenset(PLOT_GROUPS[0] + PLOT_GROUPS[1])


def _loops_figure(loops: dict[str, Any], names: list[str]):
    """Readings vs weight, loading and unloading, per sensor (rotation 0)."""
    from matplotlib.lines import Line2D

    from designlab.sensors.plotstyle import (figure, legend_outside, loading_style,
                                             series_style, unloading_style)

    fig, axes = figure(1, 3, width=14, height=4.4, fixed=True, top=0.84)
    fig.subplots_adjust(left=0.05, right=0.9, bottom=0.12)
    for k, ax in enumerate(axes):
        for i, n in enumerate(names):
            w = np.array(loops[n]["weights_g"])
            s = 1e3 * np.array(loops[n]["readings_V"])[:, k]
            top = int(np.argmax(w))
            ax.plot(w[: top + 1], s[: top + 1] - s[0], **loading_style(i))
            ax.plot(w[top:], s[top:] - s[0], **unloading_style(i))
        ax.set_title(f"sensor {'rgb'[k]} (azimuth {(270, 30, 150)[k]} deg)")
        ax.set_xlabel("hanging weight (g)")
        ax.set_ylabel("reading change (mV)")
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], ls="", **{k: v for k, v in series_style(i).items()}, label=n)
               for i, n in enumerate(names)]
    handles += [Line2D([], [], color="k", ls="-", marker="o", label="loading"),
                Line2D([], [], color="k", ls="--", marker="o", mfc="white", label="unloading")]
    legend_outside(fig, handles=handles, title="load point")
    fig.suptitle("hysteresis loops: loading (solid, filled) and unloading (dashed, open), "
                 "rotation 0")
    return fig


def _by_location_figure(report: dict[str, Any], names: list[str]):
    """Hysteresis (eq. 1) per load point."""
    from designlab.sensors.plotstyle import figure, series_style

    fig, ax = figure(width=7, height=4, fixed=True, top=0.9)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.13)
    h = report["hysteresis_percent"]["by_location"]
    ax.bar(list(h), list(h.values()), color=[series_style(names.index(n))["color"]
                                             if n in names else "0.5" for n in h])
    ax.set_xlabel("load point")
    ax.set_ylabel("hysteresis (% of span, eq. 1)")
    ax.set_title(f"mean over sensors and rotations; overall "
                 f"{report['hysteresis_percent']['overall']:.3g} %")
    ax.grid(alpha=0.3, axis="y")
    return fig


def _applied_figure(report: dict[str, Any]):
    """Applied vs estimated forces of the calibration (seed 001 Fig. 9)."""
    from designlab.sensors.plotstyle import figure, legend_outside, series_style

    ae = report["applied_vs_estimated"]
    P, E = np.array(ae["applied_N"]), np.array(ae["estimated_N"])
    fig, axes = figure(1, 3, width=13, height=4.2, fixed=True, top=0.9)
    fig.subplots_adjust(left=0.05, right=0.87, bottom=0.12)
    for i, ax in enumerate(axes):
        ax.plot(P[:, i], E[:, i], ls="", ms=4, label="calibration loads", **series_style(i))
        lim = [min(P[:, i].min(), E[:, i].min()), max(P[:, i].max(), E[:, i].max())]
        ax.plot(lim, lim, "k--", lw=0.8, label="estimated = applied")
        ax.set_xlabel(f"applied force P_{'xyz'[i]} (N)")
        ax.set_ylabel(f"estimated force P_{'xyz'[i]} (N)")
        ax.grid(alpha=0.3)
    legend_outside(axes[-1])
    fig.suptitle(f"calibration (seed 001 Fig. 9): cond(A) = {report['condition_number']:.1f}")
    return fig


def apply_model(*args, **kw):
    """loop -> predict: :func:`designlab.sensors.fingertip.loop.apply_model`."""
    from designlab.sensors.fingertip.loop import apply_model as apply

    return apply(*args, **kw)


def load_cases(*args, **kw):
    """Stress load cases: :func:`designlab.sensors.fingertip.loads.load_cases`."""
    from designlab.sensors.fingertip.loads import load_cases as cases

    return cases(*args, **kw)


#: the fingertip's physics (:class:`~designlab.sensors.definition.Physics`), plugged into its
#: definition (:class:`designlab.sensors.fingertip.definition.CantileverFingertip`): the
#: frictional contact at the ball with the bolt preload (contact=false: the linear test)
BALL_CONTACT = Physics(
    name="ball contact", paper="seed 001 (cantilever fingertip on a ball and three FSS015 sensors)",
    protocol=HangingWeightTest, settings=FingertipModelSettings, run=run, plots=plots, gains=gains,
    hooks=dict(
        plot_groups=PLOT_GROUPS, plots_before_finish=PLOTS_BEFORE_FINISH, finish=finish,
        design_protocol=design_protocol, cached=True, apply_model=apply_model,
        load_cases=load_cases, uncertainty=MONTE_CARLO, validate=validate,
        convergence=("condition_number", "hysteresis_percent.overall",
                     "hysteresis_percent.overall_noise_free",
                     "hysteresis_percent.by_group_noise_free.G1")))
