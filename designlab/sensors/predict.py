"""``designlab predict``: the virtual test of a design, before it is printed.

:func:`predict` builds the part from parameters, runs its protocol's virtual test (fingertip:
hanging weights, seed 001; strap: fingertip loads, seed 000; flexure: wrenches, seed 002) and
returns one JSON-able prediction with the keys every caller relies on::

    {"design": {...}, "hysteresis_percent": {"overall": x, "by_location": {...}},
     "calibration_matrix": [[...]], "condition_number": x, "geometric_condition_number": x,
     "sensitivity": {...}, "K_f": [[...]] (flexure), "timings_s": {...}, ...}

:func:`write_prediction` writes ``prediction.json``, the PNG plots and a VTU of the deformed
sensor, each atomically.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from designlab import __version__
from designlab.sensors.protocols import load_protocol
from designlab.errors import ParameterError

if TYPE_CHECKING:
    from designlab.loop.loop import SensorModel

#: seed 001: measured condition number of A_opt (../shared/data/papers/fingertip_xu2014.json)
PAPER_CONDITION_NUMBER = 34.92


def _settings(part: str, values: dict[str, Any] | None):
    from designlab.params import with_overrides

    if part == "fingertip":
        from designlab.sensors.fingertip import FingertipModelSettings as S
    elif part == "strap":
        from designlab.sensors.strap import StrapModelSettings as S
    else:
        from designlab.sensors.flexure.virtual import FlexureModelSettings as S
    values = {k: (tuple(v) if isinstance(v, list) else v) for k, v in (values or {}).items()}
    try:
        return with_overrides(S, values)
    except ParameterError as exc:
        raise ParameterError(f"settings.{exc.name}", exc.value, exc.allowed) from None


def protocol_from(part: str, path: str | Path | None = None,
                  values: dict[str, Any] | None = None, design=None):
    """The part's protocol: defaults, a TOML file, and/or a dict of overrides (sweeps). For the
    fingertip the default follows the design's load table (II: tested, III: optimized)."""
    proto = load_protocol(part, path)
    if path is None and part == "fingertip" and getattr(design, "load_table", "II") == "III":
        proto = type(proto).preset("optimized")
    if path is None and part == "fingertip" and design is not None and not (
            values and {"g1_locations", "g2_locations"} & set(values)):
        # default locations: the table's points that lie on this design (a short fingertip
        # has no h1); the omitted ones are listed in the prediction
        known = design.load_points(0.0)
        proto = dataclasses.replace(
            proto, g1_locations=tuple(n for n in proto.g1_locations if n in known),
            g2_locations=tuple(n for n in proto.g2_locations if n in known))
    if values:
        data = dict(values)
        preset = data.pop("preset", None)
        if preset is not None:
            proto = type(proto).preset(preset)
        data = {k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()}
        names = {f.name for f in dataclasses.fields(proto)}
        for k in data:
            if k not in names:
                raise ParameterError(f"protocol.{k}", data[k], "one of " + ", ".join(sorted(names)))
        proto = dataclasses.replace(proto, **data)
    return proto


def run_virtual_test(part_name: str, part, protocol, settings, progress=None):
    if part_name == "fingertip":
        from designlab.sensors import fingertip as mod
    elif part_name == "strap":
        from designlab.sensors import strap as mod
    else:
        from designlab.sensors.flexure import virtual as mod
    return mod, mod.run(part, protocol, settings, progress=progress)


def _fingertip_extras(report: dict[str, Any], prediction, part, protocol) -> None:
    """Paper comparison and what drives the condition number (seed 001 Section IV)."""
    from designlab.sensors.fingertip import WRENCH

    unit = prediction.unit_readings[-1]                       # (6 wrench, 3 sensors), N per N
    axes, _ = part.sensor_axes()
    # share of each applied force component carried by the three sensors (rest: bolt + cap)
    share = {ax: float(np.abs(axes[:, i] @ (-unit[i]))) for i, ax in enumerate("xyz")}
    cond = report["condition_number"]
    report["load_paths"] = {
        "share_through_sensors": share,
        "share_through_bolt_and_cap": {k: 1.0 - v for k, v in share.items()},
        "unit_wrench_sensor_forces_N": {w: unit[i].tolist() for i, w in enumerate(WRENCH)},
    }
    report["paper_comparison"] = {
        "condition_number_paper": PAPER_CONDITION_NUMBER,
        "condition_number_predicted": cond,
        "geometric_condition_number": report["geometric_condition_number"],
        "explanation": (
            f"The ideal rigid geometry of eq. 8 gives {report['geometric_condition_number']:.3f}. "
            f"In the model only {100 * share['z']:.1f} % of an axial force P_z reaches the sensors "
            f"(radial: {100 * share['x']:.0f} % / {100 * share['y']:.0f} %); the rest goes through "
            "the preloaded M2.5 bolt and the printed bottom cap in parallel, so the axial "
            f"sensitivity is {share['x'] / max(share['z'], 1e-12):.0f}x lower than the radial one "
            f"and cond(A) rises to {cond:.1f} (paper: {PAPER_CONDITION_NUMBER}). The paper blames "
            "the same path (the bolt pushed out by P_z, the elastic bottom cap). What the model "
            "leaves out: contact compliance and friction at the ball/sensor contacts, the bolt's "
            "preload state, printing anisotropy; the cap support (setting cap_support) moves the "
            "share of P_z most."),
    }
    peak = report.get("peak_sensor_force_N", 0.0)
    protocol.check_sensor_range(peak, "FSS015 sensor")


def apply_learned_effects(prediction: dict[str, Any], result, model_path: str | Path, protocol,
                          settings) -> dict[str, Any]:
    """The loop -> predict direction (strap): the effects a measured-data loop learned on a
    printed strap (``model.json`` of ``designlab loop``) are added to this design's virtual-test
    channels (their base is this design's FEM, not the measured one), and the metrics are
    evaluated again on the corrected channels. Returns the corrected report."""
    from designlab.sensors import strap as strap_test
    from designlab.measured.dataset import from_arrays
    from designlab.loop.loop import SensorModel, load_model

    if prediction["design"]["part"] != "strap":
        raise ParameterError("--model", str(model_path),
                             "a loop model applies to the strap's channel time series only "
                             "(fingertip and flexure: not yet)")
    learned = load_model(model_path)
    missing = [o for o in ("Ch1", "Ch2") if o not in learned.outputs]
    if missing:
        raise ParameterError("--model", str(model_path),
                             f"a model with outputs Ch1 and Ch2 (it has {', '.join(learned.outputs)})")
    base = sensor_model(prediction, result)
    # transfer the mechanisms, not the measured sensor's refit of its own affine base
    def mechanism(f):
        return dataclasses.replace(f, nuisance=(), alpha=(0.0,) * int(bool(f.effect.intercept)))

    model = SensorModel(base.base, {o: [mechanism(f) for f in learned.effects.get(o, [])]
                                    for o in ("Ch1", "Ch2")},
                        base.units, learned.inputs, learned.provenance)
    data = from_arrays(result.t, {"F_n": result.F_n, "F_x": result.F_x},
                       {"Ch1": result.dV[:, 0], "Ch2": result.dV[:, 1]},
                       units={"F_n": "N", "F_x": "N", "Ch1": "V", "Ch2": "V"})
    dV = np.column_stack([model.predict(data, o) for o in ("Ch1", "Ch2")])
    report = strap_test.evaluate(protocol, settings, result.t, result.F_n, result.F_x, dV,
                                 result.strain)
    report["learned_effects"] = {o: [f.effect.name for f in model.effects[o]]
                                 for o in ("Ch1", "Ch2")}
    report["learned_from"] = str(model_path)
    return report


def predict(part_name: str, overrides: dict[str, Any] | None = None, *,
            protocol_path: str | Path | None = None, protocol: dict[str, Any] | None = None,
            settings: dict[str, Any] | None = None, model_path: str | Path | None = None,
            progress: Callable[[str], None] | None = None) -> tuple[dict[str, Any], Any, Any]:
    """Run the virtual test of one design: (prediction dict, the test module, its raw result).
    ``model_path``: a loop's model.json whose learned effects correct the virtual test (strap)."""
    from designlab.geometry.parts import PARTS, make_part
    from designlab.params import as_dict

    if part_name not in PARTS:
        raise ParameterError("part", part_name, "one of " + ", ".join(PARTS))
    t0 = time.perf_counter()
    part = make_part(part_name, overrides or {})
    proto = protocol_from(part_name, protocol_path, protocol, design=part)
    sett = _settings(part_name, settings)
    if model_path is not None:
        if part_name != "strap":
            raise ParameterError("--model", str(model_path),
                                 "a loop model applies to the strap only (fingertip, flexure: "
                                 "not yet)")
        from designlab.loop.loop import load_model

        load_model(model_path)
    t_cad = time.perf_counter() - t0
    t0 = time.perf_counter()
    part.build()
    t_cad += time.perf_counter() - t0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mod, result = run_virtual_test(part_name, part, proto, sett, progress)
        report = dict(result.report)
        if part_name == "fingertip":
            _fingertip_extras(report, result, part, proto)
            table = load_protocol("fingertip")
            if part.load_table == "III":
                table = type(table).preset("optimized")
            report["locations_omitted"] = [
                n for n in (*table.g1_locations, *table.g2_locations)
                if n not in (*proto.g1_locations, *proto.g2_locations)]
    if model_path is not None:
        report["uncorrected"] = {k: report[k] for k in ("hysteresis_percent", "condition_number",
                                                        "calibration_matrix") if k in report}
        report.update(apply_learned_effects({"design": {"part": part_name}, **report}, result,
                                            model_path, proto, sett))
    report.setdefault("geometric_condition_number", None)
    report["timings_s"] = {"cad": t_cad, **report.get("timings_s", {})}
    report["timings_s"]["total"] = float(sum(v for v in report["timings_s"].values()
                                             if isinstance(v, (int, float))))
    out = {"design": {"part": part_name, "params": as_dict(part)},
           "protocol": {k: (list(v) if isinstance(v, tuple) else v)
                        for k, v in as_dict(proto).items()},
           "settings": {k: (list(v) if isinstance(v, tuple) else v)
                        for k, v in as_dict(sett).items()},
           "designlab": __version__, "warnings": [str(w.message) for w in caught], **report}
    return out, mod, result


def fingertip_plots(result, report: dict[str, Any], out: Path) -> list[Path]:
    """Hysteresis loops, reading vs weight per location, applied vs estimated (seed 001 Fig. 9)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from designlab.atomic import atomic_savefig

    def save(fig, name):
        return atomic_savefig(fig, out / name, dpi=110)

    files = []
    loops = report["loops"]
    names = list(loops)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for k, ax in enumerate(axes):
        for n in names:
            w = np.array(loops[n]["weights_g"])
            s = np.array(loops[n]["readings_V"])[:, k]
            ax.plot(w, 1e3 * (s - s[0]), ".-", label=n)
        ax.set_title(f"sensor {'rgb'[k]} (azimuth {(270, 30, 150)[k]} deg)")
        ax.set_xlabel("hanging weight, g")
        ax.set_ylabel("reading change, mV")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("hysteresis loops: loading and unloading (rotation 0)")
    files.append(save(fig, "hysteresis_loops.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    h = report["hysteresis_percent"]["by_location"]
    ax.bar(list(h), list(h.values()))
    ax.set_ylabel("hysteresis, % (eq. 1)")
    ax.set_title(f"mean over sensors and rotations; overall "
                 f"{report['hysteresis_percent']['overall']:.3g} %")
    files.append(save(fig, "hysteresis_by_location.png"))

    ae = report["applied_vs_estimated"]
    P, E = np.array(ae["applied_N"]), np.array(ae["estimated_N"])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for i, ax in enumerate(axes):
        ax.plot(P[:, i], E[:, i], "o", ms=3)
        lim = [min(P[:, i].min(), E[:, i].min()), max(P[:, i].max(), E[:, i].max())]
        ax.plot(lim, lim, "k--", lw=0.8)
        ax.set_xlabel(f"applied P_{'xyz'[i]}, N")
        ax.set_ylabel(f"estimated P_{'xyz'[i]}, N")
        ax.grid(alpha=0.3)
    fig.suptitle(f"calibration (seed 001 Fig. 9): cond(A) = {report['condition_number']:.1f}")
    files.append(save(fig, "applied_vs_estimated.png"))
    return files


def sensor_model(prediction: dict[str, Any], result) -> "SensorModel":
    """The virtual test as a measured-data model (``designlab-model`` JSON, the loop's format):
    a linear base from the loads to the sensor outputs with the FEM's long-time gains, so that
    ``designlab loop --base DIR/model.json`` simulates a measured test with the prediction and
    looks for what the model lacks in the residual.

    fingertip: inputs f_x, f_y, f_z (N) and m_x, m_y, m_z (N mm) at the ball centre -> outputs
    sensor_1..3 (V); strap: F_n, F_x (N) -> Ch1, Ch2 (V, change from unloaded); flexure:
    m_x..f_z (N mm, N) -> twist w_x..v_z (rad, mm) through the compliance K_f^-1."""
    from designlab.loop.base_models import Base
    from designlab.loop.loop import SensorModel

    part = prediction["design"]["part"]
    if part == "fingertip":
        from designlab.sensors.fingertip import FSS015_V_PER_N, WRENCH

        G = FSS015_V_PER_N * result.unit_readings[-1]               # (6 wrench, 3 sensors)
        outs = {f"sensor_{k + 1}": {w: float(G[i, k]) for i, w in enumerate(WRENCH)}
                for k in range(3)}
        units = {o: "V" for o in outs}
    elif part == "strap":
        sens = prediction["sensitivity"]["V_per_N"]
        outs = {ch: {"F_n": float(sens[ch]["F_n"]), "F_x": float(sens[ch]["F_x"])}
                for ch in ("Ch1", "Ch2")}
        units = {o: "V" for o in outs}
    else:
        from designlab.sensors.flexure.virtual import WRENCH

        C = np.linalg.inv(result.K_true)                                 # designlab units
        twist = ("w_x", "w_y", "w_z", "v_x", "v_y", "v_z")
        outs = {tw: {w: float(C[i, j]) for j, w in enumerate(WRENCH)} for i, tw in enumerate(twist)}
        units = {o: ("rad" if o.startswith("w") else "mm") for o in outs}
    base = Base("linear", {o: tuple(g) for o, g in outs.items()},
                {o: {"intercept": 0.0, "gains": g} for o, g in outs.items()})
    return SensorModel(base, {}, units, {},
                       {"source": f"designlab predict {part}", "design": prediction["design"],
                        "designlab": __version__})


def write_prediction(prediction: dict[str, Any], mod, result, out: str | Path) -> list[Path]:
    """prediction.json, model.json (:func:`sensor_model`), the plots, and deformed.vtu
    (+ deformed.png) in ``out``."""
    from designlab.atomic import atomic_write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    part = prediction["design"]["part"]
    if part == "fingertip":
        files += fingertip_plots(result, prediction, out)
    else:
        files += list(mod.plots(result, out))
    mesh, u = getattr(result, "mesh", None), getattr(result, "displacement", None)
    if mesh is not None and u is not None:
        from designlab.fem.output import write_png, write_vtu

        files.append(write_vtu(out / "deformed.vtu", mesh, point_data={"displacement": u}))
        try:
            files.append(Path(write_png(out / "deformed.png", mesh, np.asarray(u))))
        except Exception as exc:  # rendering is a convenience; the VTU is the result
            prediction.setdefault("warnings", []).append(f"deformed.png not rendered: {exc}")
    sensor_model(prediction, result).save(out / "model.json")
    files.append(out / "model.json")
    atomic_write_json(out / "prediction.json", prediction)
    files.append(out / "prediction.json")
    return files
