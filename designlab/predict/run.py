"""``designlab predict``: the virtual test of a design, before it is printed.

:func:`predict` builds the part from parameters, runs its sensor's virtual test as the paper
ran it (``SENSORS[name].run``), adds the discretisation error bar (a coarser mesh, in a forked
process where two CPUs are free) and the stress check, and returns a
:class:`~designlab.predict.record.Prediction`; :func:`predict_and_write` also writes it
(:func:`~designlab.predict.record.write_prediction`) with forked processes drawing the pictures.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

from designlab.errors import ParameterError
from designlab.predict.record import (Prediction, _deformed_args, _deformed_job, _design_png,
                                      _plots_job, _portable, write_prediction)
from designlab.predict.side import (_Pictures, _serial_occ, _Side, _use_parallel,
                                    _warm_matplotlib, _warm_pictures)
from designlab.sensors.protocols import protocol_for
from designlab.sensors.registry import get_sensor
from designlab.sensors.sensor import settings_from


def model_settings(name: str, values: dict[str, Any] | None):
    """The sensor's model settings from defaults and ``values`` (``--setting NAME=VALUE``)."""
    return settings_from(get_sensor(name).settings, values)


def protocol_from(name: str, path: str | Path | None = None,
                  values: dict[str, Any] | None = None, design=None):
    """The sensor's protocol: the paper's defaults (made to fit ``design`` where the sensor
    says how), a TOML file, and/or a dict of overrides (sweeps)."""
    sensor = get_sensor(name)
    return protocol_for(sensor.protocol, path, values, design, sensor.design_protocol)


def _check_model_path(name: str, model_path: str | Path) -> None:
    from designlab.loop.model import load_model
    from designlab.sensors.registry import SENSORS

    if get_sensor(name).apply_model is None:
        able = [n for n, s in SENSORS.items() if s.apply_model is not None]
        raise ParameterError("--model", str(model_path),
                             f"a loop model applies to the {', '.join(able)} only (not yet to "
                             f"the {name})")
    load_model(model_path)


def predict(name: Any, overrides: dict[str, Any] | None = None, *,
            protocol_path: str | Path | None = None, protocol: dict[str, Any] | None = None,
            settings: dict[str, Any] | None = None, model_path: str | Path | None = None,
            progress: Callable[[str], None] | None = None,
            fem_cache: str | Path | None = None, measured=None,
            parallel: bool | None = None, pictures: "_Pictures | None" = None) -> Prediction:
    """Run the virtual test of one design: ``name`` is a sensor name (then ``overrides`` are
    its parameters) or a part object (``designlab.Fingertip(h=3, r=9)``; ``overrides`` change
    it further). ``protocol_path``/``protocol``: a protocol TOML / overrides; ``settings``:
    model settings;
    ``model_path``: a loop's model.json whose learned effects correct the virtual test;
    ``fem_cache``: a folder where FEM stages are kept and reused (sweeps);
    ``measured``: measured printed-material records (a JSON file of
    :func:`~designlab.fem.materials.load_measured` or its records): the part's materials they
    name are replaced (:func:`measured_materials`) in the FEM, the readout and the stress;
    ``parallel``: run the coarse mesh of the error bar in a forked process beside the chosen
    mesh's run (same numbers: the same code on the same inputs); None: when two CPUs are free
    to this process and no ``fem_cache`` is given (a sweep's workers already use the cores);
    never once gmsh has run in this process (its threads do not survive a fork);
    ``pictures`` (:func:`predict_and_write`): its painter draws design.png instead of the
    coarse mesh's process, which is kept (with matplotlib imported) to draw the plots."""
    from designlab.fem.cache import FEMCache
    from designlab.params import as_dict

    name, overrides = _named(name, overrides)
    sensor = get_sensor(name)
    part, proto, sett, t_cad = _build(name, overrides, protocol_path, protocol, settings,
                                      model_path)
    cache = FEMCache(fem_cache)
    kw, mats, records = _run_kwargs(sensor, cache, part, measured)
    design = _painter_design(pictures, name, part)
    side = _start_side(sensor, part, proto, sett, kw, parallel, fem_cache, pictures)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = sensor.run(part, proto, sett, progress=progress, **kw)
            report = dict(result.report)
            early = _early_plots(sensor, pictures, name, result, report, model_path)
            cases = _early_deformed(sensor, pictures, part, proto, sett, result, cache, report)
            if sensor.finish is not None:
                sensor.finish(report, result, part, proto)
            side_out = side.first.get() if side is not None else None
            coarse, coarse_warnings = _side_coarse(side_out)
            report["mesh_convergence"] = _mesh_convergence(sensor, part, proto, sett, report,
                                                           kw, progress, coarse)
    finally:
        if side is not None and pictures is None:
            side.stop()
    if model_path is not None:
        _apply_model(sensor, report, result, model_path, proto, sett, part)
    report.setdefault("geometric_condition_number", None)
    if pictures is not None and pictures.plot_dir is not None:
        pictures.plots = _late_plots(sensor, pictures, name, result, report, early)
    t0 = time.perf_counter()
    if progress:
        progress("stress")
    if records:
        report["measured_materials"] = [dataclasses.asdict(r) for r in records]
    cases, stresses, stress_warn = _stress(sensor, part, proto, sett, result, cache, report,
                                           mats or None, cases)
    _add_timings(report, t_cad, time.perf_counter() - t0)
    return Prediction(name, as_dict(part), proto, sett, report, result,
                      # once each: the coarse-mesh run of the error bar repeats the run's
                      list(dict.fromkeys([str(w.message) for w in caught] + coarse_warnings
                                         + stress_warn)),
                      cases, stresses, design_png=design if design is not None
                      else (side_out or {}).get("design_png"))


def _named(name: Any, overrides: dict[str, Any] | None) -> tuple[str, dict[str, Any] | None]:
    """(sensor name, parameters) of ``predict``'s ``name``: a sensor name as it is, a part
    object by its name with its parameters under ``overrides`` (lists made tuples)."""
    from designlab.params import as_dict

    if isinstance(name, str):
        return name, overrides
    from designlab.geometry.parts import part_name

    merged = {**as_dict(name), **(overrides or {})}
    return part_name(name), {k: (tuple(v) if isinstance(v, list) else v)
                             for k, v in merged.items()}


def _build(name: str, overrides: dict[str, Any] | None, protocol_path, protocol, settings,
           model_path) -> tuple[Any, Any, Any, float]:
    """The part (built), its protocol and model settings, the loop model checked, and the
    time it took (s: ``timings_s["cad"]``)."""
    from designlab.geometry.parts import make_part

    t0 = time.perf_counter()
    part = make_part(name, overrides or {})
    proto = protocol_from(name, protocol_path, protocol, design=part)
    sett = model_settings(name, settings)
    if model_path is not None:
        _check_model_path(name, model_path)
    t_cad = time.perf_counter() - t0
    t0 = time.perf_counter()
    part.build()
    return part, proto, sett, t_cad + (time.perf_counter() - t0)


def _run_kwargs(sensor, cache, part, measured) -> tuple[dict[str, Any], dict[str, Any], list]:
    """The keyword arguments of ``sensor.run`` (the FEM cache of a cached sensor, the measured
    materials), those materials and their records (:func:`measured_materials`)."""
    kw: dict[str, Any] = {"cache": cache} if sensor.cached else {}
    mats, records = measured_materials(part, measured)
    if mats:
        kw["materials"] = mats
    return kw, mats, records


def _painter_design(pictures: _Pictures | None, name: str, part):
    """design.png sent to the painter of ``pictures`` (its ticket; the error as text when it
    could not be sent; None without a painter)."""
    if pictures is None:
        return None
    try:
        return pictures.painter.submit(_design_png, name, _portable(part))
    except Exception as exc:  # noqa: BLE001 - a render is a convenience (as in-process)
        return f"{type(exc).__name__}: {exc}"


def _start_side(sensor, part, proto, sett, kw, parallel: bool | None, fem_cache,
                pictures: _Pictures | None) -> _Side | None:
    """The coarse mesh's forked process (:func:`_side_work`) when ``predict`` runs in
    parallel and the settings want the error bar (None: computed here); with ``pictures`` it
    then imports matplotlib and becomes their second drawing process."""
    if not (_use_parallel(parallel, fem_cache) and _wants_convergence(sensor, sett)):
        return None
    if pictures is None:        # one X server for both processes (if one is needed)
        from designlab.geometry.render import ensure_display

        ensure_display()
    side = _Side(None)
    side.first = side.submit(_side_work, sensor.name, part, proto, sett, kw, pictures is None)
    if pictures is not None:        # then it draws the plots: import matplotlib meanwhile
        side.submit(_warm_matplotlib)
        pictures.side = side
    return side


def _side_coarse(side_out: dict[str, Any] | None) -> tuple[dict[str, float] | None, list[str]]:
    """The coarse run's values and warnings from the side process (None, []: computed here,
    also when the side failed)."""
    if side_out is None or side_out.get("coarse") is None:
        return None, []
    return side_out["coarse"], side_out["warnings"]


def _apply_model(sensor, report: dict[str, Any], result, model_path, proto, sett, part) -> None:
    """The loop model's corrections applied to ``report``, the uncorrected values kept under
    ``uncorrected``."""
    report["uncorrected"] = {k: report[k] for k in ("hysteresis_percent", "condition_number",
                                                    "calibration_matrix") if k in report}
    report.update(sensor.apply_model(report, result, model_path, proto, sett, part=part))


def _add_timings(report: dict[str, Any], t_cad: float, t_stress: float) -> None:
    """``timings_s``: the CAD, the sensor's own stages, the stress check and their total."""
    report["timings_s"] = {"cad": t_cad, **report.get("timings_s", {}), "stress": t_stress}
    report["timings_s"]["total"] = float(sum(v for v in report["timings_s"].values()
                                             if isinstance(v, (int, float))))


def _wants_convergence(sensor, settings) -> bool:
    """Whether :func:`_mesh_convergence` runs a coarse mesh for these settings."""
    if not getattr(settings, "mesh_convergence", False):
        return False
    return sensor.meshed is None or bool(sensor.meshed(settings))


def _side_work(name: str, part, protocol, settings, kw, render: bool = True) -> dict[str, Any]:
    """What the forked process of ``predict(parallel=True)`` computes (a job of its
    :class:`_Side`; the sensor by its registry name): the coarse run's convergence values and
    warnings (:func:`_coarse_values`), then (``render``) ``design.png`` (:func:`_design_png`;
    bytes, or the error as text)."""
    sensor = get_sensor(name)
    _serial_occ()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        coarse = _coarse_values(sensor, part, protocol, settings, kw, None)
    out: dict[str, Any] = {"coarse": coarse, "warnings": [str(w.message) for w in caught]}
    if not render:
        return out
    try:
        out["design_png"] = _design_png(sensor.name, _portable(part))
    except Exception as exc:  # noqa: BLE001 - a render is a convenience (as in-process)
        out["design_png"] = f"{type(exc).__name__}: {exc}"
    return out


def _early_plots(sensor, pictures: "_Pictures | None", name: str, result, report, model_path
                 ) -> list:
    """The plot groups that read only the run's report (``Sensor.plots_before_finish``), sent
    as soon as the run is done, alternately to the painter and the coarse mesh's process, while
    this process finishes the report (paper comparison, error bar, stress): [(process, group,
    job)]. None are early with a loop model (its corrections change what they show) or without
    a second drawing process."""
    if (pictures is None or pictures.plot_dir is None or model_path is not None
            or pictures.plotter is pictures.painter or not sensor.plots_before_finish):
        return []
    both = (pictures.painter, pictures.plotter)     # alternately, the painter first
    groups = [g for g in sensor.plot_groups if set(g) <= sensor.plots_before_finish]
    return [(both[i % 2], g, both[i % 2].submit(_plots_job, name, result, report,
                                                 pictures.plot_dir, g))
            for i, g in enumerate(groups)]


def _late_plots(sensor, pictures: "_Pictures", name: str, result, report, early: list) -> list:
    """The plot groups not drawn early (:func:`_early_plots`) sent with the finished report:
    all groups, [(group, job)] (the early ones first). The report is read as it is now (the
    stress check adds nothing the plots show); a sensor whose plots come in groups has them
    drawn by both processes at once, each group to the process with fewer groups so far (ties:
    the coarse mesh's process, as the painter also draws deformed.png and writes the VTU)."""
    both = [pictures.painter, pictures.plotter] if pictures.plotter is not pictures.painter \
        else [pictures.painter]
    if early:
        drawing = {g for _, g, _ in early}
        groups = tuple(g for g in sensor.plot_groups if g not in drawing)
    else:
        groups = sensor.plot_groups if len(both) == 2 and sensor.plot_groups else (None,)
    taken = [sum(p is q for p, _, _ in early) for q in both]
    late = []
    for g in groups:
        k = min(range(len(both)), key=lambda i: (taken[i], -i))    # fewer; ties: the last
        taken[k] += 1
        late.append((g, both[k].submit(_plots_job, name, result, report, pictures.plot_dir, g)))
    return [(g, t) for _, g, t in early] + late


def _early_deformed(sensor, pictures: "_Pictures | None", part, protocol, settings, result,
                    cache, report) -> list | None:
    """deformed.png sent to the painter as soon as the run is done (it shows the first load
    case, which needs the run alone): the load cases (None: not sent, they are made later)."""
    mesh, u = getattr(result, "mesh", None), getattr(result, "displacement", None)
    if pictures is None or pictures.plot_dir is None or mesh is None or u is None:
        return None
    cases = _load_cases(sensor, part, protocol, settings, result, cache, report)
    u, png = _deformed_args(sensor.name, mesh, u, cases)
    pictures.deformed = pictures.painter.submit(
        _deformed_job, pictures.plot_dir / "deformed.png", mesh, u, png)
    return cases


def measured_materials(part, measured) -> tuple[dict[str, Any], list]:
    """({body: material with the measured properties}, records) for the part's meshed bodies
    whose material a record of ``measured`` names (a JSON path or records; None: none). A
    record naming a material the part does not use is a one-line error."""
    from designlab.fem.materials import Material, get_material, load_measured, with_measured

    if measured is None:
        return {}, []
    records = load_measured(measured) if isinstance(measured, (str, Path)) else list(measured)
    built = part.build()
    bodies = {}
    for name in part.mesh_bodies():
        spec = built[name].material
        bodies[name] = spec if isinstance(spec, Material) else get_material(spec)
    used = sorted({m.name for m in bodies.values()})
    for r in records:
        if r.material not in used:
            raise ParameterError("measured", r.material, "a material of this part: "
                                 + ", ".join(used))
    mats = {b: with_measured(m, records) for b, m in bodies.items()
            if any(r.material == m.name for r in records)}
    return mats, records


def _load_cases(sensor, part, protocol, settings, result, cache, report) -> list:
    """The load cases of the virtual test: ``Sensor.load_cases``, else the result's one
    displacement ([] without one)."""
    from designlab.sensors.sensor import LoadCase

    if sensor.load_cases is not None:
        return sensor.load_cases(part, protocol, settings, result, cache)
    if getattr(result, "displacement", None) is None:
        return []
    info = report.get("vtu_load") or {}
    text = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                     for k, v in info.items())
    return [LoadCase("design load", "the largest load of the virtual test"
                     + (f" ({text})" if text else ""), result.displacement)]


def _stress(sensor, part, protocol, settings, result, cache, report, materials=None,
            cases=None):
    """The load cases of the virtual test (``cases``, else :func:`_load_cases`), their von
    Mises stress and the ``stress`` section of the report (None when the prediction has no
    mesh); ``materials``: the run's body overrides (measured)."""
    from designlab.fem.stress import case_stresses, stress_report, stress_warnings

    mesh = getattr(result, "mesh", None)
    if mesh is None:                    # a mesh-free model may give its own (the flexure's wire)
        report.setdefault("stress", None)
        return [], [], []
    if cases is None:
        cases = _load_cases(sensor, part, protocol, settings, result, cache, report)
    if not cases:
        report["stress"] = None
        return [], [], []
    stresses = case_stresses(mesh, {c.name: (c.description, c.displacement) for c in cases},
                             materials)
    report["stress"] = stress_report(mesh, stresses, materials)
    return cases, stresses, stress_warnings(report["stress"])


def _dig(report: dict[str, Any], path: str) -> float:
    v: Any = report
    for k in path.split("."):
        v = v.get(k) if isinstance(v, dict) else None
    return float(v) if isinstance(v, (int, float)) else float("nan")


def _coarse_settings(settings):
    return dataclasses.replace(settings, mesh_convergence=False,
                               edge_length=settings.edge_length * settings.coarse_factor)


def _coarse_values(sensor, part, protocol, settings, kw, progress) -> dict[str, float]:
    """The sensor's convergence metrics (``sensor.convergence``) of the run on the coarser mesh
    (``edge_length x coarse_factor``)."""
    say = (lambda s: progress(f"coarse mesh: {s}")) if progress else None
    coarse = dict(sensor.run(part, protocol, _coarse_settings(settings), progress=say,
                             **kw).report)
    return {path: _dig(coarse, path) for path in sensor.convergence}


def _mesh_convergence(sensor, part, protocol, settings, report, kw, progress,
                      coarse: dict[str, float] | None = None) -> dict[str, Any] | None:
    """The discretisation error bar: the sensor's convergence metrics at the chosen mesh and at
    one coarser level (``edge_length x coarse_factor``), and their relative change. None when
    the prediction rests on no mesh or the setting is off. ``coarse``: the coarse run's values
    (:func:`_coarse_values`) when computed already (``predict(parallel=True)``)."""
    if not _wants_convergence(sensor, settings):
        return None
    if coarse is None:
        coarse = _coarse_values(sensor, part, protocol, settings, kw, progress)
    out: dict[str, Any] = {"edge_length_mm": settings.edge_length,
                           "coarse_edge_length_mm": _coarse_settings(settings).edge_length}
    for path in sensor.convergence:
        v, c = _dig(report, path), coarse[path]
        rel = abs(v - c) / abs(v) if np.isfinite(v) and np.isfinite(c) and v != 0 else None
        out[path] = {"value": v, "coarse": c, "rel_change": rel}
    return out


def predict_and_write(name: Any, overrides: dict[str, Any] | None = None, *,
                      out: str | Path, parallel: bool | None = None,
                      timings: dict[str, tuple[float, float]] | None = None,
                      **kw: Any) -> tuple[Prediction, list[Path]]:
    """:func:`predict` then :func:`write_prediction` (``designlab predict --out``), with a
    painter: a process forked first, before the CAD is imported, that imports the drawing
    libraries while this one builds the part, then draws design.png, deformed.png and the plots
    while this one computes and writes (the same files as one process). Parallel when
    :func:`predict` would fork (``parallel``, two CPUs, no FEM cache, gmsh not yet run)."""
    import os
    import shutil
    import tempfile

    pictures = None
    if _use_parallel(parallel, kw.get("fem_cache")):
        from designlab.geometry.render import ensure_display

        # the X server (if one is needed) is this process's child: stopped and reaped at exit
        # however the painter ends (started by the painter, a killed painter would leave it a
        # zombie; stopped by the painter, a bad input would wait for the painter's imports)
        ensure_display()
        pictures = _Pictures(_Side(_warm_pictures))
        final = Path(out).resolve()
        try:    # named like write_prediction's staging folder: a killed run's is cleaned up
            pictures.plot_dir = Path(tempfile.mkdtemp(
                prefix=f".{final.name}.staging.{os.getpid()}.plots.", dir=final.parent))
        except OSError:                     # no such folder yet, read-only...: plot later
            pictures.plot_dir = None
    try:
        prediction = predict(name, overrides, parallel=parallel, pictures=pictures, **kw)
        if kw.get("progress"):
            kw["progress"]("writing")
        files = write_prediction(prediction, out, timings=timings, parallel=parallel,
                                 pictures=pictures)
    finally:
        if pictures is not None:
            pictures.stop()
            if pictures.plot_dir is not None:
                shutil.rmtree(pictures.plot_dir, ignore_errors=True)
    return prediction, files
