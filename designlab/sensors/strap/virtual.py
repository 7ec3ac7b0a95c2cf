"""The seed 000 arch strap as a sensor: its physics :data:`WORN_STRAP` (its definition's plug-in) and the hooks
that run on the virtual test's result (plots, the loop's gains, the stress load cases, the
force-error test); the model itself is :mod:`designlab.sensors.strap.model`. Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import atomic_savefig
from designlab.errors import ParameterError
from designlab.sensors.strap.montecarlo import MONTE_CARLO
from designlab.sensors.strap.validation import validate
from designlab.sensors.protocols import StrapLoadTest
from designlab.sensors.definition import Physics
from designlab.sensors.sensor import linear_sensor_model
from designlab.sensors.strap.model import (
    CHANNELS, StrapModelSettings, StrapPrediction, evaluate, pad_frame,
    run)


# ------------------------------------------------------------------------------------ stress

def load_envelope(fn: np.ndarray, fx: np.ndarray) -> list[tuple[float, float, int]]:
    """The protocol's load states whose stresses bound every other one: the vertices of the
    convex hull of its (F_n, F_x) path without the unloaded origin, as (F_n, F_x, first sample
    index). Von Mises stress is a convex function of the loads of a linear model (a seminorm of
    a linear map), so its largest value over the whole history is reached at one of them:
    exact, not a sample. A path on one line (no shear) gives its end points."""
    from scipy.spatial import ConvexHull, QhullError

    P = np.column_stack([fn, fx])
    pts, first = np.unique(np.round(P, 12), axis=0, return_index=True)
    try:
        idx = ConvexHull(pts).vertices
    except (QhullError, ValueError):          # collinear (or too few) states: the extremes
        d = pts[np.argmax(np.abs(pts).sum(1))]
        proj = pts @ (d / max(np.linalg.norm(d), 1e-300))
        idx = np.unique([int(np.argmin(proj)), int(np.argmax(proj))])
    out = [(float(pts[i, 0]) + 0.0, float(pts[i, 1]) + 0.0, int(first[i])) for i in idx
           if np.abs(pts[i]).max() > 0]
    return sorted(out, key=lambda c: c[2])


def load_cases(part, protocol: StrapLoadTest, settings: StrapModelSettings, result, cache=None):
    """Stress load cases (``Sensor.load_cases``): every vertex of the protocol's load envelope
    (:func:`load_envelope`) as the long-time displacement ``F_n U_n + F_x U_x`` (exact
    superposition of the unit cases of the FEM stage); written to the VTU: the largest F_n, the
    largest and the smallest F_x. A result without the unit displacements (an older FEM stage)
    gives its one displacement at the peak normal force."""
    from designlab.sensors.sensor import LoadCase

    if getattr(result, "mesh", None) is None:
        return []
    frame = pad_frame(part, settings)
    t, fn, fx = protocol.time_history()
    n_stair = (2 * protocol.n_steps + 1) * max(1, int(round(protocol.step_hold_s / protocol.dt_s)))
    U = result.unit_displacement
    if U is None:
        if result.displacement is None:
            return []
        k = int(np.argmax(fn))
        return [LoadCase("peak F_n", f"F_n {fn[k]:.3g} N, F_x {fx[k]:+.3g} N at t = {t[k]:.3g} s "
                         "(displacement of the history at the peak normal force)",
                         result.displacement, frame["centre"], frame["n"], float(fn[k]))]
    env = load_envelope(fn, fx)
    if not env:
        return []
    top = max(range(len(env)), key=lambda i: (env[i][0], env[i][1]))
    show = {top, max(range(len(env)), key=lambda i: (env[i][1], env[i][0])),
            min(range(len(env)), key=lambda i: (env[i][1], -env[i][0]))}
    out = []
    for i, (Fn, Fx, k) in enumerate(env):
        force = Fn * frame["n"] + Fx * frame["t"]
        size = float(np.linalg.norm(force))
        where = "staircase" if k < n_stair else "grasp cycle"
        out.append(LoadCase(f"F_n {Fn:.3g} N, F_x {Fx:+.3g} N",
                            f"pad load F_n {Fn:.4g} N (outward normal) and F_x {Fx:+.4g} N "
                            f"(along the strap) at t = {t[k]:.4g} s of the {where}; long-time "
                            "displacement", np.asarray(U) @ np.array([Fn, Fx]), frame["centre"],
                            force / size, size, vtu=i in show))
    # the largest F_n first: the deformed render shows it
    return [out[top]] + out[:top] + out[top + 1:]


# ------------------------------------------------------------------------------------ plots

def _save(fig, path: Path) -> Path:
    return atomic_savefig(fig, path, dpi=120)


def plots(prediction: StrapPrediction, report: dict[str, Any] | None, out_dir: str | Path
          ) -> list[Path]:
    """PNGs: time series, sum/difference vs F_n/F_x, hysteresis loop of the staircase.
    ``report``: the prediction's metrics (default: the virtual test's own report)."""
    from designlab.sensors.plotstyle import (close, figure, legend_outside, loading_style,
                                             series_style, unloading_style)

    out = Path(out_dir)
    report = prediction.report if report is None else report
    s = report["series"]
    t = np.asarray(s["t_s"])
    paths = []
    fig, ax = figure(3, 1, width=9, height=7.5, sharex=True, fixed=True, top=0.95,
                     hspace=0.1)
    for i, (y, lab) in enumerate(((s["F_n_N"], "normal force F_n"), (s["F_x_N"], "shear force F_x"))):
        ax[0].plot(t, y, color=series_style(i)["color"], label=lab)
    ax[0].set_ylabel("force (N)")
    for i, (k, lab) in enumerate((("dCh1_V", "Ch1 (left gauge)"), ("dCh2_V", "Ch2 (right gauge)"))):
        ax[1].plot(t, 1e3 * np.asarray(s[k]), color=series_style(i + 2)["color"], label=lab)
    ax[1].set_ylabel("channel change (mV)")
    for i, (k, lab) in enumerate((("sum_V", "Ch1 + Ch2"), ("diff_V", "Ch1 - Ch2"))):
        ax[2].plot(t, 1e3 * np.asarray(s[k]), color=series_style(i + 4)["color"], label=lab)
    ax[2].set_ylabel("sum / difference (mV)")
    ax[2].set_xlabel("time (s)")
    for a in ax:
        legend_outside(a)
        a.grid(alpha=0.3)
    fig.suptitle("strap virtual load test (seed 000)")
    paths.append(_save(fig, out / "strap_time_series.png"))
    close(fig)

    fig, ax = figure(1, 2, width=10, height=4.2, fixed=True, top=0.88)
    ax[0].plot(s["F_n_N"], 1e3 * np.asarray(s["sum_V"]), ls="", ms=3, **series_style(4))
    ax[0].set_xlabel("normal force F_n (N)")
    ax[0].set_ylabel("Ch1 + Ch2 (mV)")
    ax[1].plot(s["F_x_N"], 1e3 * np.asarray(s["diff_V"]), ls="", ms=3, **series_style(5))
    ax[1].set_xlabel("shear force F_x (N)")
    ax[1].set_ylabel("Ch1 - Ch2 (mV)")
    for a in ax:
        a.grid(alpha=0.3)
    fig.suptitle("sum reads the normal force, difference the shear force")
    paths.append(_save(fig, out / "strap_sum_diff.png"))
    close(fig)

    loops = report.get("loops") or {}
    if loops:
        fig, ax = figure(width=7, height=4.2, fixed=True, top=0.9)
        fnl = np.asarray(loops["F_n_N"])
        k = int(np.argmax(fnl))
        for i, name in enumerate(("sum", "Ch1", "Ch2")):
            y = 1e3 * np.asarray(loops["readings_V"][name])
            ax.plot(fnl[:k + 1], y[:k + 1], label=f"{name}, loading", **loading_style(i))
            ax.plot(fnl[k:], y[k:], label=f"{name}, unloading", **unloading_style(i))
        h = report["hysteresis_percent"]["by_location"]
        ax.set_title(f"staircase loop: hysteresis sum {h['sum']:.2g} %")
        ax.set_xlabel("normal force F_n (N)")
        ax.set_ylabel("reading (mV)")
        legend_outside(ax)
        ax.grid(alpha=0.3)
        paths.append(_save(fig, out / "strap_hysteresis.png"))
        close(fig)
    return paths


# ------------------------------------------------------------------------ the loop, both ways

def gains(report: dict[str, Any], prediction: StrapPrediction | None = None) -> tuple[dict, dict]:
    """Loop base: F_n, F_x (N) -> Ch1, Ch2 (V, change from unloaded), the virtual test's
    sensitivities."""
    sens = report["sensitivity"]["V_per_N"]
    outs = {ch: {"F_n": float(sens[ch]["F_n"]), "F_x": float(sens[ch]["F_x"])}
            for ch in CHANNELS}
    return outs, {o: "V" for o in outs}


def apply_model(report: dict[str, Any], prediction: StrapPrediction, model_path: str | Path,
                protocol: StrapLoadTest, settings: StrapModelSettings, part=None
                ) -> dict[str, Any]:
    """loop -> predict: the effects a measured-data loop learned on a printed strap
    (``model.json`` of ``designlab loop``) are added to this design's virtual-test channels
    (their base is this design's FEM, not the measured one), and the metrics are evaluated
    again on the corrected channels. Returns the corrected report."""
    import dataclasses

    from designlab.loop.model import SensorModel, load_model
    from designlab.measured.dataset import from_arrays

    learned = load_model(model_path)
    missing = [o for o in CHANNELS if o not in learned.outputs]
    if missing:
        raise ParameterError("--model", str(model_path),
                             f"a model with outputs Ch1 and Ch2 (it has {', '.join(learned.outputs)})")
    outs, units = gains(report, prediction)
    base = linear_sensor_model(outs, units, {})

    # transfer the mechanisms, not the measured sensor's refit of its own affine base
    def mechanism(f):
        return dataclasses.replace(f, nuisance=(), alpha=(0.0,) * int(bool(f.effect.intercept)))

    model = SensorModel(base.base, {o: [mechanism(f) for f in learned.effects.get(o, [])]
                                    for o in CHANNELS},
                        base.units, learned.inputs, learned.provenance)
    data = from_arrays(prediction.t, {"F_n": prediction.F_n, "F_x": prediction.F_x},
                       {"Ch1": prediction.dV[:, 0], "Ch2": prediction.dV[:, 1]},
                       units={"F_n": "N", "F_x": "N", "Ch1": "V", "Ch2": "V"})
    dV = np.column_stack([model.predict(data, o) for o in CHANNELS])
    out = evaluate(protocol, settings, prediction.t, prediction.F_n, prediction.F_x, dV,
                   prediction.strain)
    out["learned_effects"] = {o: [f.effect.name for f in model.effects[o]] for o in CHANNELS}
    out["learned_from"] = str(model_path)
    return out


def finish(report: dict[str, Any], prediction: StrapPrediction, part, protocol) -> None:
    """The strap's calibration with its electrical noise, as seed 000 fitted it (in place):
    ``report["force_error_test"]`` (:func:`designlab.sensors.strap.noise.run_strap_force_test`:
    sum/difference lines fitted on virtual loads at the protocol's amplitudes, the force error
    per axis on held-out loads, split into Johnson noise, ADC noise and model error; it uses
    the sensitivities and the divider already in the report: no FEM)."""
    from designlab.sensors.strap.noise import StrapForceTest, run_strap_force_test

    test = StrapForceTest(normal_N=float(protocol.normal_N), shear_N=float(protocol.shear_N))
    report["force_error_test"] = run_strap_force_test(report, test)


#: the strap's physics (:class:`~designlab.sensors.definition.Physics`), plugged into its
#: definition (:class:`designlab.sensors.strap.definition.ArchStrap`): the strap worn around
#: the finger (the wrap, the finger's support), the traces' piezoresistive divider readout
WORN_STRAP = Physics(
    name="worn strap", paper="seed 000 (TPU arch strap with two printed strain-gauge traces)",
    protocol=StrapLoadTest, settings=StrapModelSettings, run=run, plots=plots, gains=gains,
    hooks=dict(apply_model=apply_model, finish=finish, cached=True, load_cases=load_cases,
               uncertainty=MONTE_CARLO, validate=validate))
