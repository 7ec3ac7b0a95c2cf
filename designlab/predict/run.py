"""``designlab predict``: the virtual test of a design, before it is printed.

:func:`predict` builds the part from parameters, runs its sensor's virtual test as the paper
ran it (``SENSORS[name].run``) and returns a :class:`Prediction`; its :meth:`Prediction.to_json`
has the keys every caller relies on::

    {"design": {...}, "hysteresis_percent": {"overall": x, "by_location": {...}},
     "calibration_matrix": [[...]], "condition_number": x, "geometric_condition_number": x,
     "sensitivity": {...}, "K_f": [[...]] (flexure), "timings_s": {...}, ...}

:func:`write_prediction` writes ``prediction.json``, ``model.json`` (the loop's format), the PNG
plots and a VTU of the deformed sensor, each atomically. Nothing here names a sensor: what
differs between sensors is in their :class:`~designlab.sensors.sensor.Sensor` record.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from designlab.version import __version__
from designlab.errors import ParameterError
from designlab.sensors.protocols import protocol_for
from designlab.sensors.registry import get_sensor
from designlab.sensors.sensor import linear_sensor_model, settings_from

if TYPE_CHECKING:
    from designlab.loop.model import SensorModel


def _plain(d: dict[str, Any]) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


@dataclass
class Prediction:
    """The virtual test of one design.

    sensor:   registry name (``SENSORS``)
    params:   the design's parameters (mm, deg)
    protocol, settings: the protocol and model-settings dataclasses that were run
    metrics:  hysteresis %, calibration matrix, condition number, sensitivity, K_f, timings (s),
              paper comparison... (the keys of ``prediction.json``)
    result:   the sensor's raw virtual-test result: time series, FEM mesh and displacement
    warnings: what the run warned about (range checks, rendering, safety factors below 2)
    load_cases, stresses: the load cases of the stress check and their von Mises fields
              (:mod:`designlab.fem.stress`; ``metrics["stress"]`` has the maxima)
    """

    sensor: str
    params: dict[str, Any]
    protocol: Any
    settings: Any
    metrics: dict[str, Any]
    result: Any = None
    warnings: list[str] = field(default_factory=list)
    load_cases: list[Any] = field(default_factory=list, repr=False)
    stresses: list[Any] = field(default_factory=list, repr=False)
    #: ``design.png`` rendered by the forked process of ``predict(parallel=True)``: PNG bytes,
    #: or the render's error, or the ticket of :func:`predict_and_write`'s painter; None:
    #: :func:`write_prediction` renders it
    design_png: "bytes | str | _Ticket | None" = field(default=None, repr=False)

    @property
    def design(self) -> dict[str, Any]:
        return {"part": self.sensor, "params": self.params}

    @property
    def hysteresis_percent(self) -> float:
        """Overall hysteresis, % of span (eq. 1 of seed 001)."""
        return float(self.metrics.get("hysteresis_percent", {}).get("overall", float("nan")))

    @property
    def condition_number(self) -> float:
        return float(self.metrics.get("condition_number", float("nan")))

    @property
    def K_f(self) -> np.ndarray | None:
        """6x6 stiffness of a flexure in SI (see ``metrics["K_f_units"]``), else None."""
        K = self.metrics.get("K_f")
        return None if K is None else np.asarray(K)

    @property
    def timings_s(self) -> dict[str, float]:
        return self.metrics.get("timings_s", {})

    # the sections of the report a sweep keeps (None: the sensor does not report it)
    @property
    def hysteresis(self) -> dict[str, Any] | None:
        """The hysteresis section: ``overall``, ``by_location``/``by_group``... (% of span)."""
        return self.metrics.get("hysteresis_percent")

    @property
    def geometric_condition_number(self) -> float | None:
        """Condition number of the ideal rigid geometry's calibration matrix (None where the
        sensor has none)."""
        v = self.metrics.get("geometric_condition_number")
        return None if v is None else float(v)

    @property
    def sensitivity(self) -> dict[str, Any] | None:
        return self.metrics.get("sensitivity")

    @property
    def linearity_percent_span(self) -> float | dict[str, float] | None:
        """Largest linearity error, % of span (per output where the sensor has several)."""
        return self.metrics.get("linearity_percent_span")

    @property
    def mesh_convergence(self) -> dict[str, Any] | None:
        """The discretisation error bar (:func:`_mesh_convergence`); None without a mesh."""
        return self.metrics.get("mesh_convergence")

    @property
    def fem_key(self) -> str | None:
        """Key of the cached FEM stage (designs with the same key share one FEM)."""
        return self.metrics.get("fem_key")

    @property
    def electrical(self) -> dict[str, Any] | None:
        return self.metrics.get("electrical")

    @property
    def stress(self) -> dict[str, Any] | None:
        """The stress check's maxima, critical body and safety factors (None: no mesh)."""
        return self.metrics.get("stress")

    @property
    def min_safety_factor(self) -> float | None:
        """Smallest safety factor (strength / von Mises) over bodies and load cases."""
        return (self.stress or {}).get("min_safety_factor")

    @property
    def paper_comparison(self) -> dict[str, Any] | None:
        """The sensor's comparison with its paper (None where it has none)."""
        return self.metrics.get("paper_comparison")

    @property
    def axial_share_through_sensors(self) -> float | None:
        """Share of the axial (z) load that goes through the sensors (load paths)."""
        lp = self.metrics.get("load_paths")
        return float(lp["share_through_sensors"]["z"]) if lp else None

    def to_json(self) -> dict[str, Any]:
        """The ``prediction.json`` document: the design, the protocol and model settings
        ``predict`` ran (``FEMSettings`` fields included), the version, the warnings, then the
        metrics. Those five keys are the Prediction's own: a metric of the same name does not
        replace them (a sensor reports its sub-models' settings under another key, e.g. the
        fingertip's ``contact_settings``)."""
        from designlab.params import as_dict

        head = {"design": self.design, "protocol": _plain(as_dict(self.protocol)),
                "settings": _plain(as_dict(self.settings)), "designlab": __version__,
                "warnings": list(self.warnings)}
        return {**head, **{k: v for k, v in self.metrics.items() if k not in head}}

    def sensor_model(self) -> "SensorModel":
        """The virtual test as a measured-data model (:func:`sensor_model`)."""
        return sensor_model(self.sensor, self.design, self.metrics, self.result)

    # ----- what a notebook or a script shows -----
    def summary_rows(self) -> list[tuple[str, str, str]]:
        """(quantity, value, unit) of the key results, error bars and the safety factor."""
        from designlab.predict.report import result_rows

        rows = [(r["name"], r["value"] + (f" ± {r['bar']}" if r["bar"] not in ("", "0") else ""),
                 r["unit"]) for r in result_rows(self.metrics)]
        crit = (self.metrics.get("stress") or {}).get("critical")
        if crit:
            rows.append(("critical body", f"{crit['body']} ({crit['material']}) under "
                         f"{crit['load_case']}", ""))
        tot = self.timings_s.get("total")
        if tot is not None:
            rows.append(("time", f"{tot:.1f}", "s"))
        return rows

    def summary(self) -> str:
        """The key results as text (also what ``print(pred)`` is not: that is the dataclass)."""
        rows = [("quantity", "value", "unit"), *self.summary_rows()]
        w = [max(len(r[i]) for r in rows) for i in range(3)]
        lines = [f"{self.sensor} virtual test ({get_sensor(self.sensor).paper})"]
        lines += ["  ".join(c.ljust(w[i]) for i, c in enumerate(r)).rstrip() for r in rows]
        lines += [f"warning: {x}" for x in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        import html

        body = "".join(f"<tr><td>{html.escape(a)}</td><td style='text-align:right'>"
                       f"{html.escape(b)}</td><td>{html.escape(c)}</td></tr>"
                       for a, b, c in self.summary_rows())
        warn = "".join(f"<li>{html.escape(x)}</li>" for x in self.warnings)
        return (f"<b>{html.escape(self.sensor)}</b> virtual test "
                f"({html.escape(get_sensor(self.sensor).paper)})<table><tr><th>quantity</th>"
                f"<th>value</th><th>unit</th></tr>{body}</table>"
                + (f"<p>warnings:</p><ul>{warn}</ul>" if warn else ""))

    def plot(self, out: str | Path | None = None) -> list[Path]:
        """The sensor's plots as PNG files in ``out`` (default: a new temporary folder); in a
        notebook they are also displayed."""
        import tempfile

        folder = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="designlab-"))
        folder.mkdir(parents=True, exist_ok=True)
        files = [Path(f) for f in get_sensor(self.sensor).plots(self.result, self.metrics,
                                                                   folder)]
        try:
            from IPython import get_ipython
            from IPython.display import Image, display

            if get_ipython() is not None:
                for f in files:
                    display(Image(filename=str(f)))
        except ImportError:
            pass
        return files

    def save(self, out: str | Path) -> list[Path]:
        """Everything ``designlab predict`` writes (:func:`write_prediction`)."""
        return write_prediction(self, out)


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

    from designlab.geometry.parts import make_part
    from designlab.params import as_dict

    if not isinstance(name, str):
        from designlab.geometry.parts import part_name

        obj = name
        name = part_name(obj)
        overrides = {**as_dict(obj), **(overrides or {})}
        overrides = {k: (tuple(v) if isinstance(v, list) else v) for k, v in overrides.items()}
    sensor = get_sensor(name)
    t0 = time.perf_counter()
    part = make_part(name, overrides or {})
    proto = protocol_from(name, protocol_path, protocol, design=part)
    sett = model_settings(name, settings)
    if model_path is not None:
        _check_model_path(name, model_path)
    t_cad = time.perf_counter() - t0
    t0 = time.perf_counter()
    part.build()
    t_cad += time.perf_counter() - t0
    cache = FEMCache(fem_cache)
    kw = {"cache": cache} if sensor.cached else {}
    mats, records = measured_materials(part, measured)
    if mats:
        kw["materials"] = mats
    side, side_out, design = None, None, None
    if pictures is not None:
        try:
            design = pictures.painter.submit(_design_png, name, _portable(part))
        except Exception as exc:  # noqa: BLE001 - a render is a convenience (as in-process)
            design = f"{type(exc).__name__}: {exc}"
    if _use_parallel(parallel, fem_cache) and _wants_convergence(sensor, sett):
        if pictures is None:        # one X server for both processes (if one is needed)
            from designlab.geometry.render import ensure_display

            ensure_display()
        side = _Side(None)
        side.first = side.submit(_side_work, sensor.name, part, proto, sett, kw,
                                 pictures is None)
        if pictures is not None:        # then it draws the plots: import matplotlib meanwhile
            side.submit(_warm_matplotlib)
            pictures.side = side
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
            if side_out is None or side_out.get("coarse") is None:
                coarse, coarse_warnings = None, []   # computed here (also: the side failed)
            else:
                coarse, coarse_warnings = side_out["coarse"], side_out["warnings"]
            report["mesh_convergence"] = _mesh_convergence(sensor, part, proto, sett, report,
                                                           kw, progress, coarse)
    finally:
        if side is not None and pictures is None:
            side.stop()
    if model_path is not None:
        report["uncorrected"] = {k: report[k] for k in ("hysteresis_percent", "condition_number",
                                                        "calibration_matrix") if k in report}
        report.update(sensor.apply_model(report, result, model_path, proto, sett, part=part))
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
    report["timings_s"] = {"cad": t_cad, **report.get("timings_s", {}),
                           "stress": time.perf_counter() - t0}
    report["timings_s"]["total"] = float(sum(v for v in report["timings_s"].values()
                                             if isinstance(v, (int, float))))
    return Prediction(name, as_dict(part), proto, sett, report, result,
                      # once each: the coarse-mesh run of the error bar repeats the run's
                      list(dict.fromkeys([str(w.message) for w in caught] + coarse_warnings
                                         + stress_warn)),
                      cases, stresses, design_png=design if design is not None
                      else (side_out or {}).get("design_png"))


def _two_cpus(parallel: bool | None) -> bool:
    """``parallel`` resolved: None -> at least two CPUs free to this process and a process that
    may have children (not a daemonic pool worker)."""
    import multiprocessing as mp
    import os

    if parallel is not None:
        return bool(parallel)
    if mp.current_process().daemon:
        return False
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except AttributeError:                  # not Linux
        return (os.cpu_count() or 1) >= 2


def _use_parallel(parallel: bool | None, fem_cache) -> bool:
    """``predict``'s ``parallel`` resolved: never once gmsh ran in this process; True -> yes;
    None -> two CPUs (:func:`_two_cpus`) and no ``fem_cache`` (a sweep: its workers use the
    cores)."""
    import sys

    if "gmsh" in sys.modules or parallel is False:
        # gmsh's thread pool does not survive a fork (the child's mesher would wait for
        # threads it does not have): the first predict of a process forks before any meshing
        return False
    if parallel:
        return True
    return fem_cache is None and _two_cpus(None)


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


def _portable(part):
    from designlab.geometry.render import portable_items

    return portable_items(part.build())


DESIGN_PNG_SIZE = (1000, 750)
DEFORMED_PNG_SIZE = (1000, 750)


def _warm_pictures() -> None:
    """The painter's first job (:func:`predict_and_write`): the drawing libraries (VTK/pyvista,
    matplotlib) imported while the caller imports and builds the CAD."""
    _warm_matplotlib()
    import pyvista.plotting  # noqa: F401


def _warm_matplotlib() -> None:
    """The coarse mesh's process, once done (:func:`predict_and_write`): matplotlib imported
    for the plots it will draw."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


@dataclass
class _Pictures:
    """:func:`predict_and_write`'s forked helpers: the ``painter`` (drawing libraries imported
    first thing; design.png, deformed.png) and the coarse mesh's process (``side``, set by
    :func:`predict`; the plots), or the painter alone."""

    painter: _Side
    side: _Side | None = None
    #: where the plots are drawn before the output is staged (beside ``--out``: one file
    #: system), and their job, sent as soon as the report is complete (before the stress)
    plot_dir: Path | None = None
    #: [(the group of plots (None: all), its job)]
    plots: "list[tuple[tuple[str, ...] | None, _Ticket]] | None" = None
    #: deformed.png's job, sent as soon as the run is done (into ``plot_dir``)
    deformed: "_Ticket | None" = None

    @property
    def plotter(self) -> _Side:
        return self.side if self.side is not None and not self.side._dead else self.painter

    def stop(self) -> None:
        for p in (self.painter, self.side):
            if p is not None:
                p.stop()


def _design_png(name: str, items) -> bytes:
    """``design.png`` of the part as built (bodies coloured, legend of body and material) from
    its :func:`~designlab.geometry.render.portable_items`: the PNG bytes (drawn by the
    painter, the coarse mesh's process or this one)."""
    import tempfile

    from designlab.geometry.render import render_items

    with tempfile.TemporaryDirectory(prefix="designlab-") as d:
        path = Path(d) / "design.png"
        render_items(items, path, size=DESIGN_PNG_SIZE, title=f"{name}: the design")
        return path.read_bytes()


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


def _plots_job(sensor_name: str, result, metrics, stage: Path,
               only: tuple[str, ...] | None = None) -> list[str]:
    """The sensor's plots (``only`` this group of them: ``Sensor.plot_groups``) into ``stage``
    (a drawing process's job): their file names."""
    sensor = get_sensor(sensor_name)
    files = sensor.plots(result, metrics, stage) if only is None else \
        sensor.plots(result, metrics, stage, only=only)
    return [Path(f).name for f in files]


def _vtu_job(path: Path, mesh, point_data, cell_data, field_data) -> bool:
    """deformed.vtu (:func:`~designlab.fem.output.write_vtu`; the painter's job, or here)."""
    from designlab.fem.output import write_vtu

    write_vtu(path, mesh, point_data=point_data, cell_data=cell_data, field_data=field_data)
    return True


def _deformed_job(path: Path, mesh, u, kw: dict[str, Any]) -> str:
    """deformed.png (the painter's job): '' when drawn, else the error in words."""
    from designlab.fem.output import write_png

    try:
        write_png(path, mesh, u, **kw)
        return ""
    except Exception as exc:  # noqa: BLE001 - rendering is a convenience; the VTU is the result
        return str(exc)


def _serial_occ() -> None:
    """In a forked child: OpenCascade's thread pool is the parent's (its threads are not in the
    child), so a parallel ``BRepMesh`` or Boolean would wait for ever; tessellate and run the
    Booleans on the calling thread (the same triangles and shapes). build123d asks every
    Boolean to run in parallel (``SetRunParallel(True)``): the setter itself is made to ask for
    the serial algorithm. Once per process."""
    global _OCC_SERIAL
    if _OCC_SERIAL:
        return
    _OCC_SERIAL = True
    try:
        import OCP.BRepMesh as brepmesh
        from OCP.BOPAlgo import BOPAlgo_Options
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Algo
    except ImportError:
        return
    cls = brepmesh.BRepMesh_IncrementalMesh

    def serial(shape, *args):
        if len(args) >= 4:
            args = (*args[:3], False, *args[4:])
        return cls(shape, *args)

    brepmesh.BRepMesh_IncrementalMesh = serial
    for owner in (BRepAlgoAPI_Algo, BOPAlgo_Options):
        setter = owner.SetRunParallel
        owner.SetRunParallel = (lambda set_: lambda self, flag: set_(self, False))(setter)


_OCC_SERIAL = False


class _Side:
    """``fn()`` in a forked child while the caller goes on; ``first.get()`` is its return
    value (pickled through a pipe), or None when the child failed or died (the caller then computes
    in-process: same result, and the error, if any, raised where it belongs). The child dies
    with the parent (``PR_SET_PDEATHSIG``) and :meth:`stop` kills it if it is still running:
    it never outlives the call. ``fn=None``: a child that only takes jobs (:meth:`submit`).

    After ``fn`` the child serves jobs: :meth:`submit` sends ``(job, args)`` (a module-level
    function and picklable arguments) and returns a :class:`_Ticket`; jobs run one after the
    other in the order sent, results come back in that order."""

    def __init__(self, fn: Callable[[], Any] | None):
        import multiprocessing as mp
        import os
        import queue
        import threading

        ctx = mp.get_context("fork")
        self._recv, send = ctx.Pipe(duplex=False)
        jobs, self._jobs = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_side_main, args=(fn, send, jobs, os.getpid()),
                                 daemon=True)
        self._proc.start()
        send.close()
        jobs.close()
        self._sent = 0 if fn is None else 1      # results the child owes, in order
        self._got: list[Any] = []                # results received (index = ticket)
        self._dead = False
        self._feed_failed = False
        self.first = _Ticket(self, 0) if fn is not None else None
        # jobs go down the pipe from a thread: a child stuck without reading (a lock copied
        # from the parent) fills the pipe, and a send from the caller would then block for ever
        # where :meth:`_wait` would have found the child stalled
        self._outbox: queue.Queue = queue.Queue()
        self._feeder = threading.Thread(target=self._feed, daemon=True)
        self._feeder.start()

    def _feed(self) -> None:
        """The feeding thread: sends the jobs in order; a failed send (the child gone) ends it.
        Only this thread writes to the job pipe, and :meth:`stop` closes it after this thread
        has ended (closed under a write in progress, its descriptor could be reused by another
        file and the rest of the job written there)."""
        while (data := self._outbox.get()) is not None:
            try:
                self._jobs.send_bytes(data)
            except Exception:  # noqa: BLE001 - the child is gone: _wait finds it and gives up
                self._feed_failed = True
                return

    #: a child whose CPU time has not moved for this long (wall s) waits on something it will
    #: never get (a lock or a thread pool copied from the parent): it is killed and the work is
    #: done in-process
    STALL_S = 20.0

    def submit(self, job: Callable[..., Any], *args: Any) -> "_Ticket":
        """Run ``job(*args)`` in the child after what it was given before."""
        from multiprocessing.reduction import ForkingPickler

        ticket = _Ticket(self, self._sent)
        self._sent += 1
        if not self._dead:
            try:
                data = bytes(ForkingPickler.dumps((job, args)))   # what Connection.send sends
            except (TypeError, AttributeError, __import__("pickle").PicklingError):
                self._give_up()
            else:
                self._outbox.put(data)
        return ticket

    def _wait(self, index: int) -> Any:
        while len(self._got) <= index and not self._dead:
            try:
                while not self._recv.poll(1.0):
                    if (not self._proc.is_alive() or self._feed_failed
                            or self._stalled()):
                        raise EOFError
                ok, value = self._recv.recv()
                self._got.append(value if ok else None)
            except (EOFError, OSError):
                self._give_up()
        return self._got[index] if index < len(self._got) else None

    def _give_up(self) -> None:
        self._dead = True
        self.stop()

    def _stalled(self) -> bool:
        """True once the child's CPU time (Linux ``/proc``) has not changed for ``STALL_S``."""
        try:
            with open(f"/proc/{self._proc.pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            cpu = int(fields[11]) + int(fields[12])          # utime + stime (ticks)
        except (OSError, IndexError, ValueError):
            return False
        now = time.monotonic()
        if getattr(self, "_cpu", None) != cpu:
            self._cpu, self._since = cpu, now
            return False
        return now - self._since > self.STALL_S

    def stop(self) -> None:
        if self._proc.is_alive():
            self._proc.kill()
        self._proc.join()
        self._outbox.put(None)          # the feeding thread ends (a send in progress fails:
        self._feeder.join(10.0)         # the reader is gone), then its pipe is closed
        self._recv.close()
        if not self._feeder.is_alive():
            self._jobs.close()
        self._dead = True


@dataclass
class _Ticket:
    """A job sent to a :class:`_Side`: :meth:`get` waits for its result (None: it failed)."""

    side: _Side
    index: int

    def get(self) -> Any:
        """The result (None: the job failed, or the child died or stalled)."""
        return self.side._wait(self.index)


def _side_main(fn, send, jobs, parent: int) -> None:
    """The child of :class:`_Side`: ``fn``, then the jobs as they come. A thread reads the
    jobs and another sends the results, so neither side's pipe can fill while the other is
    blocked writing to it (a job and a result both larger than a pipe's buffer)."""
    import queue
    import threading

    from designlab.atomic import die_with_parent

    die_with_parent(parent)
    todo: queue.Queue = queue.Queue()
    done: queue.Queue = queue.Queue()

    def read():
        while True:
            try:
                todo.put(jobs.recv())
            except (EOFError, OSError):
                todo.put(None)
                return

    def write():
        while (value := done.get()) is not None:
            try:
                send.send(value)
            except Exception as exc:  # noqa: BLE001 - e.g. not picklable: the parent recomputes
                send.send((False, f"{type(exc).__name__}: {exc}"))

    def run(call):
        try:
            return (True, call())
        except BaseException as exc:  # noqa: BLE001 - the parent recomputes and raises
            return (False, f"{type(exc).__name__}: {exc}")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        if fn is not None:
            done.put(run(fn))
        threading.Thread(target=read, daemon=True).start()
        while (item := todo.get()) is not None:
            job, args = item
            done.put(run(lambda: job(*args)))
        done.put(None)
        writer.join()
        send.close()
    finally:
        # leave at once: no flush of stdio buffers copied from the parent (its progress bar's
        # output would be written twice, or wait on a lock another parent thread held at the
        # fork)
        import os

        os._exit(0)


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


def _deformed_args(sensor_name: str, mesh, u, cases) -> tuple[np.ndarray, dict[str, Any]]:
    """deformed.png's displacement (the first load case's, else ``u``) and drawing settings."""
    first = cases[0] if cases else None
    if first is not None:
        u = np.asarray(first.displacement)
    png = {"size": DEFORMED_PNG_SIZE, "title": sensor_name,
           "loads": [(first.point, first.direction, first.force_N)]
           if first is not None and first.point is not None else (),
           "case": first.description if first is not None else ""}
    return np.asarray(u), png


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


def sensor_model(name: str, design: dict[str, Any], report: dict[str, Any], result
                 ) -> "SensorModel":
    """The virtual test as a measured-data model (``designlab-model`` JSON, the loop's format):
    a linear base from the loads to the sensor outputs with the FEM's long-time gains
    (``Sensor.gains``), so that ``designlab loop --base DIR/model.json`` simulates a measured
    test with the prediction and looks for what the model lacks in the residual."""
    outs, units = get_sensor(name).gains(report, result)
    return linear_sensor_model(outs, units, {"source": f"designlab predict {name}",
                                             "design": design, "designlab": __version__})


def write_prediction(prediction: Prediction, out: str | Path,
                     timings: dict[str, tuple[float, float]] | None = None,
                     parallel: bool | None = None, pictures: "_Pictures | None" = None
                     ) -> list[Path]:
    """prediction.json, model.json (:func:`sensor_model`), the plots, and deformed.vtu
    (+ deformed.png) in ``out``, written as a set: every file goes to a hidden staging folder
    beside ``out`` first (a full disk or a kill then leaves ``out`` as it was); a new or empty
    ``out`` is that folder renamed, else the files are renamed into ``out`` with
    ``prediction.json`` removed first and renamed last (no ``prediction.json``: no complete
    set). Staging folders of killed writers (their PID is in the name) are removed.
    ``timings``: a dict that gets ``{stage: (wall s, CPU s)}`` of the writing stages (plots,
    deformed.vtu, deformed.png, model.json, design.png, report), for the benchmark. ``parallel``:
    the plots are drawn by a forked process while this one writes the VTU, the renders and the
    model (the same files; a failed child's plots are drawn here); None: when two CPUs are free
    to this process. ``pictures`` (:func:`predict_and_write`): forked processes that have the
    drawing libraries imported draw the plots and deformed.png and write deformed.vtu instead
    (what they fail to draw or write is done here)."""
    import gc
    import os
    import re
    import shutil
    import tempfile

    from designlab.atomic import os_error, atomic_write_json, ensure_dir, pid_alive

    out = Path(out)
    parent = ensure_dir(out.resolve().parent)
    final = out.resolve()
    if final.exists() and not final.is_dir():
        from designlab.errors import OutputError

        raise OutputError(f"--out={str(out)!r} is not allowed: a directory (it is a file)")
    stale = re.compile(r"^\." + re.escape(final.name) + r"\.staging\.(\d+)\.")
    for p in parent.iterdir():
        m = stale.match(p.name)
        if m and not pid_alive(int(m[1])):
            shutil.rmtree(p, ignore_errors=True)
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{final.name}.staging.{os.getpid()}.",
                                      dir=parent))
    except OSError as exc:
        raise os_error(final, exc) from None
    clock = _StageClock(timings)
    plotter = None
    # the prediction leaves ~500k objects the collector tracks (CAD, mesher, FEM modules and
    # results); the figures and renders allocate many short-lived ones, and each full
    # collection would walk them all again (~0.9 s CPU of the writing): freeze them until done
    gc.freeze()
    try:
        result = prediction.result
        plots_job, deformed_job = None, None
        names: list[str] = []
        plot_args = (prediction.sensor, result, prediction.metrics, stage)
        # early: the groups are being drawn since before the stress check (predict_and_write)
        early = pictures is not None and pictures.plots is not None
        if pictures is not None and not early:
            plots_job = pictures.plotter.submit(_plots_job, *plot_args)
        elif pictures is None and _two_cpus(parallel):
            plotter = _Side(lambda: _plots_job(*plot_args))
            plots_job = plotter.first
        elif pictures is None:
            names = _plots_job(*plot_args)
            clock("plots")
        mesh, u = getattr(result, "mesh", None), getattr(result, "displacement", None)
        vtu_job = None
        if mesh is not None and u is not None:
            pdata, cdata = {"displacement": u}, {}
            for c, st in zip(prediction.load_cases, prediction.stresses):
                if c.vtu:
                    pdata[f"displacement {c.name} (mm)"] = np.asarray(c.displacement)
                    pdata[f"von Mises {c.name} (MPa)"] = st.node
                    cdata[f"von Mises {c.name} (MPa)"] = st.cell
            regions = sorted(mesh.region_names)
            vtu = (stage / "deformed.vtu", mesh, pdata, cdata,
                   {"region_ids": [int(r) for r in regions],
                    "region_names": [mesh.region_names[r] for r in regions],
                    "region_materials": [mesh.materials.get(mesh.region_names[r], "")
                                         for r in regions],
                    "load_cases": [f"{c.name}: {c.description}"
                                   for c in prediction.load_cases if c.vtu]})
            if pictures is not None:        # the painter has pyvista imported: it writes it
                vtu_job = pictures.painter.submit(_vtu_job, *vtu)
            else:
                _vtu_job(*vtu)
                clock("deformed.vtu")
            names.append("deformed.vtu")
            u, png = _deformed_args(prediction.sensor, mesh, u, prediction.load_cases)
            if pictures is not None and pictures.deformed is not None:   # sent by predict
                deformed_job = pictures.deformed
            elif pictures is not None:
                deformed_job = pictures.painter.submit(_deformed_job, stage / "deformed.png",
                                                       mesh, u, png)
            else:
                _deformed_png(prediction, stage, mesh, u, png, names)
                clock("deformed.png")
        prediction.sensor_model().save(stage / "model.json")
        names.append("model.json")
        clock("model.json")
        names += _design_render(prediction, stage)
        clock("design.png")
        if vtu_job is not None and vtu_job.get() is None:   # the painter failed: write here
            _vtu_job(*vtu)
        if deformed_job is not None:
            err = deformed_job.get()
            if err is None:                 # the painter failed: draw here
                _deformed_png(prediction, stage, mesh, u, png, names)
            elif err:
                prediction.warnings.append(f"deformed.png not rendered: {err}")
            else:
                if deformed_job is pictures.deformed:       # drawn beside the staging folder
                    os.replace(pictures.plot_dir / "deformed.png", stage / "deformed.png")
                names.append("deformed.png")
            clock("deformed.png (waited for the painter)")
        if early:
            drawn = []
            for group, job in pictures.plots:
                got = job.get()
                if got is None:             # the child failed: draw here (raises its error)
                    got = _plots_job(*plot_args, group)
                else:
                    for n in got:
                        os.replace(pictures.plot_dir / n, stage / n)
                drawn += got
            names = drawn + names
            clock("plots (waited for the drawing processes)")
        elif plots_job is not None:
            drawn = plots_job.get()
            if drawn is None:               # the child failed: draw here (raises its error)
                drawn = _plots_job(*plot_args)
            names = drawn + names
            clock("plots (waited for the plotting process)")
        doc = prediction.to_json()
        atomic_write_json(stage / "run.json", run_manifest(f"predict {prediction.sensor}",
                                                           {"settings": doc["settings"],
                                                            "protocol": doc["protocol"],
                                                            "design": doc["design"]}))
        names.append("run.json")
        write_prediction_report(doc, stage, final, [stage / n for n in names])
        names.append("report.html")
        atomic_write_json(stage / "prediction.json", doc)
        names.append("prediction.json")
        clock("report")
        os.chmod(stage, 0o777 & ~_umask())
        if not final.exists() or not any(final.iterdir()):
            if final.exists():
                final.rmdir()
            os.rename(stage, final)
        else:
            (final / "prediction.json").unlink(missing_ok=True)
            for name in names:
                os.replace(stage / name, final / name)  # prediction.json is the last
            shutil.rmtree(stage, ignore_errors=True)
    except OSError as exc:  # a full or read-only disk: one line, nothing half-written
        shutil.rmtree(stage, ignore_errors=True)
        from designlab.errors import DesignlabError

        if isinstance(exc, DesignlabError):
            raise
        raise os_error(final, exc) from None
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    finally:
        if plotter is not None:
            plotter.stop()
        gc.unfreeze()
    return [out / n for n in names]


def _deformed_png(prediction: Prediction, stage: Path, mesh, u, png: dict[str, Any],
                  names: list[str]) -> None:
    """deformed.png drawn in this process (a failure is a warning: the VTU is the result)."""
    from designlab.fem.output import write_png

    try:
        write_png(stage / "deformed.png", mesh, np.asarray(u), **png)
        names.append("deformed.png")
    except Exception as exc:  # rendering is a convenience; the VTU is the result
        prediction.warnings.append(f"deformed.png not rendered: {exc}")


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


class _StageClock:
    """Calls ``clock(stage)`` store the wall and CPU time since the previous call in
    ``timings`` (None: nothing is measured)."""

    def __init__(self, timings: dict[str, tuple[float, float]] | None):
        self.timings = timings
        self.last = (time.perf_counter(), time.process_time())

    def __call__(self, stage: str) -> None:
        if self.timings is None:
            return
        now = (time.perf_counter(), time.process_time())
        self.timings[stage] = (now[0] - self.last[0], now[1] - self.last[1])
        self.last = now


def run_manifest(what: str, settings: dict[str, Any]) -> dict[str, Any]:
    """``run.json``: what wrote a folder (the command as typed, designlab version, date,
    settings); ``--out`` checks it before reusing a folder."""
    from designlab.predict.report import command_line, now

    return {"format": "designlab-run", "version": 1, "what": what, "command": command_line(),
            "designlab": __version__, "date": now(), "settings": settings}


def _design_render(prediction: Prediction, stage: Path) -> list[str]:
    """``design.png``: the part as built (bodies coloured, legend of body and material)."""
    from designlab.geometry.parts import make_part

    from designlab.atomic import atomic_write_bytes

    done = prediction.design_png
    if isinstance(done, _Ticket):               # drawn by predict_and_write's painter
        done = prediction.design_png = done.get()
    if done is None:                            # nobody drew it (or the painter failed): here
        try:
            part = make_part(prediction.sensor, {k: (tuple(v) if isinstance(v, list) else v)
                                                 for k, v in prediction.params.items()})
            done = _design_png(prediction.sensor, _portable(part))
        except Exception as exc:  # a render is a convenience; the prediction is the result
            done = f"{type(exc).__name__}: {exc}"
    if isinstance(done, str):
        prediction.warnings.append(f"design.png not rendered: {done}")
        return []
    atomic_write_bytes(stage / "design.png", done)
    return ["design.png"]


def write_prediction_report(doc: dict[str, Any], folder: Path, final: Path,
                            files: list[Path], title: str | None = None) -> Path:
    """``report.html`` of one prediction (the shared template, :mod:`report_html`): links are
    relative to ``folder``, which becomes ``final``."""
    from designlab.predict.report import prediction_sections, render_report

    name = doc["design"]["part"]
    sensor = get_sensor(name)
    renders = [(folder / "design.png", "the design (printed bodies opaque, bought parts "
                "see-through)")] if (folder / "design.png").is_file() else []
    if (folder / "deformed.png").is_file():
        renders.append((folder / "deformed.png", "deformed under the first load case (warped, "
                        "coloured by displacement)"))
    ctx = prediction_sections(doc, folder, part_cls=sensor.part, settings_cls=sensor.settings,
                              protocol_cls=sensor.protocol, render_pngs=renders)
    ctx["plots"] = [f for f in ctx["plots"] if not f["caption"].startswith(("design", "deformed"))]
    from designlab.predict.report import file_links

    links = file_links(folder, [*files, folder / "prediction.json"])
    if not (folder / "prediction.json").exists():
        links.append({"href": "prediction.json", "name": "prediction.json", "what": "JSON"})
    ctx.update(title=title or f"designlab predict {name}",
               subtitle=f"virtual test of a {name} design as {sensor.paper} ran it",
               files=links)
    return render_report(folder / "report.html", ctx)


def _umask() -> int:
    import os

    m = os.umask(0)
    os.umask(m)
    return m
