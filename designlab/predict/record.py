"""The record of a prediction and its writer.

:class:`Prediction` is the virtual test of one design; its :meth:`Prediction.to_json` has the
keys every caller relies on::

    {"design": {...}, "hysteresis_percent": {"overall": x, "by_location": {...}},
     "calibration_matrix": [[...]], "condition_number": x, "geometric_condition_number": x,
     "sensitivity": {...}, "K_f": [[...]] (flexure), "timings_s": {...}, ...}

:func:`write_prediction` writes ``prediction.json``, ``model.json`` (the loop's format), the PNG
plots, a VTU of the deformed sensor, ``run.json`` and ``report.html`` as one set. Nothing here
names a sensor: what differs between sensors is in their
:class:`~designlab.sensors.sensor.Sensor` record.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from designlab.predict.side import _Pictures, _Side, _Ticket, _two_cpus
from designlab.sensors.registry import get_sensor
from designlab.sensors.sensor import linear_sensor_model
from designlab.version import __version__

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
    #: or the render's error, or the ticket of the painter of
    #: :func:`~designlab.predict.run.predict_and_write`; None: :func:`write_prediction` renders it
    design_png: "bytes | str | _Ticket | None" = field(default=None, repr=False)

    @property
    def design(self) -> dict[str, Any]:
        return {"part": self.sensor, "params": self.params}

    @property
    def hysteresis_percent(self) -> float:
        """Overall hysteresis, % of span (eq. 1 of seed 001)."""
        v = (self.metrics.get("hysteresis_percent") or {}).get("overall")
        return float("nan") if v is None else float(v)

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
        """The discretisation error bar (:func:`~designlab.predict.run._mesh_convergence`); None
        without a mesh."""
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
    def axial_share_through_sensors(self) -> float | None:
        """Share of the axial (z) load that goes through the sensors (load paths)."""
        lp = self.metrics.get("load_paths")
        return float(lp["share_through_sensors"]["z"]) if lp else None

    def to_json(self) -> dict[str, Any]:
        """The ``prediction.json`` document: the design, the protocol and model settings
        ``predict`` ran (``FEMSettings`` fields included), the version, the warnings, the
        definitions (readable name, definition and unit of each top-level metric present), then
        the metrics. Those six keys are the Prediction's own: a metric of the same name does not
        replace them (a sensor reports its sub-models' settings under another key, e.g. the
        fingertip's ``contact_settings``)."""
        from designlab.params import as_dict
        from designlab.sensors.labels import METRICS

        head = {"design": self.design, "protocol": _plain(as_dict(self.protocol)),
                "settings": _plain(as_dict(self.settings)), "designlab": __version__,
                "warnings": list(self.warnings),
                "definitions": {k: f"{name} [{unit}]" if unit else name
                                for k, (name, unit) in METRICS.items() if k in self.metrics}}
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


def _portable(part):
    from designlab.geometry.render import portable_items

    return portable_items(part.build())


DESIGN_PNG_SIZE = (1000, 750)
DEFORMED_PNG_SIZE = (1000, 750)


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
    to this process. ``pictures`` (:func:`~designlab.predict.run.predict_and_write`): forked
    processes that have the drawing libraries imported draw the plots and deformed.png and
    write deformed.vtu instead (what they fail to draw or write is done here)."""
    import gc
    import shutil

    from designlab.atomic import os_error

    out = Path(out)
    final, stage = _new_staging(out)
    w = _Staging(prediction, stage, final, _StageClock(timings), pictures)
    # the prediction leaves ~500k objects the collector tracks (CAD, mesher, FEM modules and
    # results); the figures and renders allocate many short-lived ones, and each full
    # collection would walk them all again: freeze them until done
    gc.freeze()
    try:
        _start_plots(w, parallel)
        _start_mesh_files(w)
        _write_model_and_design(w)
        _finish_vtu(w)
        _finish_deformed(w)
        _finish_plots(w)
        _write_documents(w)
        _publish(stage, final, w.names)
    except OSError as exc:  # a full or read-only disk: one line, nothing half-written
        shutil.rmtree(stage, ignore_errors=True)
        from designlab.errors import DesignlabError, OutputError

        if isinstance(exc, OutputError):     # it names the file in --out, not the staging one
            raise OutputError(str(exc).replace(str(stage), str(final))) from None
        if isinstance(exc, DesignlabError):
            raise
        raise os_error(final, exc) from None
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    finally:
        if w.plotter is not None:
            w.plotter.stop()
        gc.unfreeze()
    return [out / n for n in w.names]


@dataclass
class _Staging:
    """One :func:`write_prediction`: the staging folder, the files written to it so far (in
    the order of the set) and the jobs of the forked processes it waits for."""

    prediction: Prediction
    stage: Path
    final: Path
    clock: "_StageClock"
    pictures: _Pictures | None
    names: list[str] = field(default_factory=list)
    #: the plotting process forked here (``parallel`` without ``pictures``)
    plotter: _Side | None = None
    plots_job: _Ticket | None = None
    vtu_job: _Ticket | None = None
    #: deformed.vtu's arguments (:func:`_vtu_job`)
    vtu: tuple | None = None
    deformed_job: _Ticket | None = None
    #: deformed.png's mesh, displacement and drawing settings (:func:`_deformed_args`)
    deformed: tuple | None = None

    @property
    def early(self) -> bool:
        """The plot groups are being drawn since before the stress check (predict_and_write)."""
        return self.pictures is not None and self.pictures.plots is not None

    @property
    def plot_args(self) -> tuple:
        p = self.prediction
        return (p.sensor, p.result, p.metrics, self.stage)


def _new_staging(out: Path) -> tuple[Path, Path]:
    """(``out`` resolved, a new staging folder beside it); staging folders of killed writers
    are removed, an ``out`` that is a file is a one-line error."""
    import os
    import re
    import shutil
    import tempfile

    from designlab.atomic import ensure_dir, os_error, pid_alive

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
    return final, stage


def _start_plots(w: _Staging, parallel: bool | None) -> None:
    """The plots: sent to a drawing process of ``pictures`` (unless sent early), to a process
    forked here (two CPUs), or drawn now."""
    pictures = w.pictures
    if pictures is not None and not w.early:
        w.plots_job = pictures.plotter.submit(_plots_job, *w.plot_args)
    elif pictures is None and _two_cpus(parallel):
        plot_args = w.plot_args
        w.plotter = _Side(lambda: _plots_job(*plot_args))
        w.plots_job = w.plotter.first
    elif pictures is None:
        w.names = _plots_job(*w.plot_args)
        w.clock("plots")


def _vtu_fields(prediction: Prediction, mesh, u) -> tuple[dict, dict, dict]:
    """deformed.vtu's point, cell and field data: the displacement, each shown load case's
    displacement and von Mises stress, the regions with their bodies and materials."""
    shown = [(c, st) for c, st in zip(prediction.load_cases, prediction.stresses) if c.vtu]
    point: dict[str, Any] = {"displacement": u}
    for c, st in shown:
        point[f"displacement {c.name} (mm)"] = np.asarray(c.displacement)
        point[f"von Mises {c.name} (MPa)"] = st.node
    cell = {f"von Mises {c.name} (MPa)": st.cell for c, st in shown}
    regions = sorted(mesh.region_names)
    bodies = [mesh.region_names[r] for r in regions]
    field_data = {"region_ids": [int(r) for r in regions], "region_names": bodies,
                  "region_materials": [mesh.materials.get(b, "") for b in bodies],
                  "load_cases": [f"{c.name}: {c.description}"
                                 for c in prediction.load_cases if c.vtu]}
    return point, cell, field_data


def _start_mesh_files(w: _Staging) -> None:
    """deformed.vtu and deformed.png (a prediction with a mesh and a displacement): sent to
    the painter of ``pictures`` (or taken from what predict sent it), else written now."""
    p, pictures = w.prediction, w.pictures
    mesh, u = getattr(p.result, "mesh", None), getattr(p.result, "displacement", None)
    if mesh is None or u is None:
        return
    w.vtu = (w.stage / "deformed.vtu", mesh, *_vtu_fields(p, mesh, u))
    if pictures is not None:        # the painter has pyvista imported: it writes it
        w.vtu_job = pictures.painter.submit(_vtu_job, *w.vtu)
    else:
        _vtu_job(*w.vtu)
        w.clock("deformed.vtu")
    w.names.append("deformed.vtu")
    u, png = _deformed_args(p.sensor, mesh, u, p.load_cases)
    w.deformed = (mesh, u, png)
    if pictures is not None and pictures.deformed is not None:   # sent by predict
        w.deformed_job = pictures.deformed
    elif pictures is not None:
        w.deformed_job = pictures.painter.submit(_deformed_job, w.stage / "deformed.png",
                                                 mesh, u, png)
    else:
        _deformed_png(p, w.stage, mesh, u, png, w.names)
        w.clock("deformed.png")


def _write_model_and_design(w: _Staging) -> None:
    """model.json (:func:`sensor_model`) and design.png (:func:`_design_render`)."""
    w.prediction.sensor_model().save(w.stage / "model.json")
    w.names.append("model.json")
    w.clock("model.json")
    w.names += _design_render(w.prediction, w.stage)
    w.clock("design.png")


def _finish_vtu(w: _Staging) -> None:
    """deformed.vtu written here when the painter failed to."""
    if w.vtu_job is not None and w.vtu_job.get() is None:
        _vtu_job(*w.vtu)


def _finish_deformed(w: _Staging) -> None:
    """The painter's deformed.png: moved in when drawn beside the staging folder, drawn here
    when the painter failed, a warning when the drawing itself failed."""
    import os

    if w.deformed_job is None:
        return
    err = w.deformed_job.get()
    if err is None:                 # the painter failed: draw here
        _deformed_png(w.prediction, w.stage, *w.deformed, w.names)
    elif err:
        w.prediction.warnings.append(f"deformed.png not rendered: {err}")
    else:
        if w.deformed_job is w.pictures.deformed:       # drawn beside the staging folder
            os.replace(w.pictures.plot_dir / "deformed.png", w.stage / "deformed.png")
        w.names.append("deformed.png")
    w.clock("deformed.png (waited for the painter)")


def _early_plot_files(w: _Staging) -> list[str]:
    """The groups sent early: moved in from where they were drawn, or drawn here when their
    process failed (which raises the plots' error, if any)."""
    import os

    drawn: list[str] = []
    for group, job in w.pictures.plots:
        got = job.get()
        if got is None:
            got = _plots_job(*w.plot_args, group)
        else:
            for n in got:
                os.replace(w.pictures.plot_dir / n, w.stage / n)
        drawn += got
    return drawn


def _finish_plots(w: _Staging) -> None:
    """The plots drawn by other processes, put first in the set (a failed child's are drawn
    here)."""
    if w.early:
        drawn, what = _early_plot_files(w), "plots (waited for the drawing processes)"
    elif w.plots_job is not None:
        drawn = w.plots_job.get()
        if drawn is None:               # the child failed: draw here (raises its error)
            drawn = _plots_job(*w.plot_args)
        what = "plots (waited for the plotting process)"
    else:
        return
    w.names = drawn + w.names
    w.clock(what)


def _write_documents(w: _Staging) -> None:
    """run.json, report.html and prediction.json (the last of the set)."""
    from designlab.atomic import atomic_write_json

    doc = w.prediction.to_json()
    atomic_write_json(w.stage / "run.json", run_manifest(
        f"predict {w.prediction.sensor}", {k: doc[k] for k in ("settings", "protocol", "design")}))
    w.names.append("run.json")
    write_prediction_report(doc, w.stage, w.final, [w.stage / n for n in w.names])
    w.names.append("report.html")
    atomic_write_json(w.stage / "prediction.json", doc)
    w.names.append("prediction.json")
    w.clock("report")


def _publish(stage: Path, final: Path, names: list[str]) -> None:
    """The staging folder becomes ``final`` (new or empty), else its files are renamed into
    it, ``prediction.json`` removed first and renamed last; a folder by a file's name stops
    the set before anything moves."""
    import os
    import shutil

    os.chmod(stage, 0o777 & ~_umask())
    if not final.exists() or not any(final.iterdir()):
        if final.exists():
            final.rmdir()
        os.rename(stage, final)
    else:
        for name in names:   # what would stop a rename, before the first one
            if (final / name).is_dir() and not (final / name).is_symlink():
                from designlab.errors import OutputError

                raise OutputError(f"cannot write {final / name}: it is a directory")
        (final / "prediction.json").unlink(missing_ok=True)
        for name in names:
            os.replace(stage / name, final / name)  # prediction.json is the last
        shutil.rmtree(stage, ignore_errors=True)


def _deformed_png(prediction: Prediction, stage: Path, mesh, u, png: dict[str, Any],
                  names: list[str]) -> None:
    """deformed.png drawn in this process (a failure is a warning: the VTU is the result)."""
    from designlab.fem.output import write_png

    try:
        write_png(stage / "deformed.png", mesh, np.asarray(u), **png)
        names.append("deformed.png")
    except Exception as exc:  # rendering is a convenience; the VTU is the result
        prediction.warnings.append(f"deformed.png not rendered: {exc}")


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
