"""The one HTML report of ``predict``, ``sweep`` and ``optimize``: a Jinja2 template
(``designlab/templates/report.html.j2``) filled from a context dict; images are embedded as data
URIs (the page is self-contained), links point at the files beside it.

:func:`prediction_sections` turns a prediction (``prediction.json`` and its plots) into the
sections every report shows for a design: render(s), key results with their error bars, stress
and safety factor, paper vs predicted, plots, parameter/settings/protocol tables, files.
``optimize/report.py`` adds the sweep's designs, the objectives and why the design was chosen.
Nothing here names a sensor kind.
"""

from __future__ import annotations

import base64
import datetime
import shlex
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from designlab.version import __version__
from designlab.geometry.api import field_rows
from designlab.sensors.labels import fmt_value, metric_name_unit

#: file kinds linked from a report, with what they are
FILE_KINDS = {".stl": "STL (one body)", ".3mf": "3MF (print job)", ".step": "STEP (CAD)",
              ".stp": "STEP (CAD)", ".gltf": "glTF", ".glb": "glTF", ".vtu": "VTU (FEM fields)",
              ".json": "JSON", ".parquet": "Parquet table", ".csv": "CSV table",
              ".png": "PNG image", ".html": "HTML"}

#: metrics shown first in a prediction's result table, in this order
KEY_METRICS = ("hysteresis_percent.overall", "condition_number", "geometric_condition_number",
               "linearity_percent_span", "sensitivity.V_per_N.x", "sensitivity.V_per_N.y",
               "sensitivity.V_per_N.z", "stress.min_safety_factor", "stress.max_von_mises_MPa")


def command_line(argv: Iterable[str] | None = None) -> str:
    """The command as typed (``designlab ...``, also when run as ``python -m designlab.cli``),
    quoted for a shell."""
    args = list(sys.argv if argv is None else argv)
    if args and Path(args[0]).name in ("designlab", "__main__.py"):
        args = ["designlab", *args[1:]]
    return " ".join(shlex.quote(a) for a in args)


def now() -> str:
    """Local date and time with its UTC offset."""
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M:%S %z")


def data_uri(path: str | Path) -> str:
    """A PNG/SVG/JPEG file as a ``data:`` URI."""
    p = Path(path)
    mime = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg",
            ".jpeg": "image/jpeg"}.get(p.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64," + base64.b64encode(p.read_bytes()).decode()


def png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode()


def dig(d: Mapping[str, Any] | None, path: str) -> Any:
    v: Any = d
    for k in path.split("."):
        v = v.get(k) if isinstance(v, Mapping) else None
    return v


def _num(v: Any) -> str:
    if isinstance(v, bool) or v is None:
        return fmt_value(v)
    if isinstance(v, (int, float)):
        return "inf" if v == float("inf") else f"{v:.4g}"
    return fmt_value(v)


def error_bar_of(pred: Mapping[str, Any], key: str) -> float | None:
    """|value - value on one coarser mesh| of a metric (``mesh_convergence``); 0 when the
    prediction rests on no mesh, None when not computed for this metric."""
    mc = pred.get("mesh_convergence")
    if mc is None:
        return 0.0 if "mesh_convergence" in pred and not pred.get("mesh") else None
    e = mc.get(key)
    if not isinstance(e, Mapping):
        return None
    v, c = e.get("value"), e.get("coarse")
    if v is None or c is None:
        return None
    return abs(float(v) - float(c))


def result_rows(pred: Mapping[str, Any], keys: Iterable[str] = KEY_METRICS,
                notes: Mapping[str, str] | None = None) -> list[dict[str, str]]:
    rows = []
    for k in keys:
        v = dig(pred, k)
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        name, unit = metric_name_unit(k)
        bar = error_bar_of(pred, k)
        rows.append({"name": name, "value": _num(v), "bar": "" if bar is None else _num(bar),
                     "unit": unit, "note": (notes or {}).get(k, "")})
    fe = pred.get("force_error_test")
    if isinstance(fe, Mapping) and isinstance(fe.get("per_axis"), Mapping):
        for a, e in fe["per_axis"].items():
            k = f"force_error_test.per_axis.{a}.std"
            bar = error_bar_of(pred, k)
            rows.append({"name": f"force error std, {a}", "value": _num(e.get("std")),
                         "bar": "" if bar is None else _num(bar), "unit": "N",
                         "note": "held-out points of the virtual calibration with the noise "
                                 "budget (Force error section)"})
    K = pred.get("K_f")
    if K is not None:
        diag = ", ".join(f"{K[i][i]:.4g}" for i in range(len(K)))
        rows.append({"name": "K_f diagonal", "value": diag, "bar": "",
                     "unit": str(pred.get("K_f_units", "SI")), "note": ""})
    return rows


def stress_section(stress: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """Per body: the load case with the largest von Mises stress, its safety factor."""
    if not stress:
        return None
    worst: dict[str, dict[str, Any]] = {}
    for case, c in stress["load_cases"].items():
        for body, e in c["bodies"].items():
            if body not in worst or e["max_von_mises_MPa"] > worst[body]["max_von_mises_MPa"]:
                worst[body] = {**e, "case": case, "description": c["description"]}
    warn = stress.get("warn_below", 2.0)
    rows = [{"body": b, "material": e["material"], "case": e["description"],
             "vm": _num(e["max_von_mises_MPa"]),
             "at": ", ".join(f"{x:.1f}" for x in e["at_mm"]),
             "strength": _num(e["strength_MPa"]) if e["strength_MPa"] is not None else "not documented",
             "sf": _num(e["safety_factor"]) if e["safety_factor"] is not None else "-",
             "bad": e["safety_factor"] is not None and e["safety_factor"] < warn}
            for b, e in worst.items()]
    crit = stress.get("critical")
    if crit:
        summary = (f"Smallest safety factor {crit['safety_factor']:.3g} ({crit['body']}, "
                   f"{crit['material']}, load case {crit['load_case']}) over "
                   f"{len(stress['load_cases'])} load case(s); below {warn:g} is a warning.")
    else:
        summary = "No body has a documented strength: no safety factor."
    mats = [{"name": n, "strength": _num(m["strength_MPa"]) if m["strength_MPa"] is not None
             else "-", "basis": m.get("basis", ""), "source": m.get("source", "")}
            for n, m in stress.get("materials", {}).items()]
    return {"rows": rows, "summary": summary, "method": stress.get("method", ""),
            "materials": mats}


def _paper_per_axis(fe: Mapping[str, Any]) -> dict[str, Mapping[str, Any]]:
    """The paper's force error per axis where the test carries it: ``paper_table_I`` or
    ``paper.force_error_per_axis_N`` ({axis: {mean, std, ...}}); {} when the paper prints none."""
    for cand in (fe.get("paper_table_I"), dig(fe, "paper.force_error_per_axis_N")):
        if isinstance(cand, Mapping) and all(isinstance(v, Mapping) for v in cand.values()):
            return dict(cand)
    return {}


def _paper_text(fe: Mapping[str, Any]) -> str:
    paper = fe.get("paper")
    if isinstance(paper, str):
        return paper
    if isinstance(paper, Mapping):
        parts = [str(paper[k]) for k in ("figure", "finding", "source", "note", "fit")
                 if isinstance(paper.get(k), str)]
        return "; ".join(parts)
    return ""


def force_error_section(pred: Mapping[str, Any]) -> dict[str, Any] | None:
    """``force_error_test`` (the calibration with the sensor's noise budget): force error per
    axis on held-out points (mean, std, max |e|, rms) beside the paper's where it prints
    them, the split of the std into its mechanisms, the budget's inputs. None without one."""
    fe = pred.get("force_error_test")
    if not isinstance(fe, Mapping) or not isinstance(fe.get("per_axis"), Mapping):
        return None
    paper = _paper_per_axis(fe)
    rows = []
    for a, e in fe["per_axis"].items():
        p = paper.get(a, {})
        rows.append({"axis": a, "mean": _num(e.get("mean")), "std": _num(e.get("std")),
                     "max": _num(e.get("max_abs")), "rms": _num(e.get("rms")),
                     "paper_mean": _num(p["mean"]) if "mean" in p else "",
                     "paper_std": _num(p["std"]) if "std" in p else ""})
    split = fe.get("split_std") if isinstance(fe.get("split_std"), Mapping) else {}
    mechs = list(dict.fromkeys(k for v in split.values() if isinstance(v, Mapping) for k in v))
    split_rows = [[a] + [_num(dig(split, f"{a}.{m}")) for m in mechs] for a in split]

    def text(v):
        if isinstance(v, Mapping):
            return ", ".join(f"{k} = {text(x)}" for k, x in v.items())
        if isinstance(v, (list, tuple)):
            return ", ".join(text(x) for x in v)
        return _num(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else fmt_value(v)

    budget = [[k, text(v)] for k, v in (fe.get("budget") or {}).items()]
    lines = []
    if isinstance(fe.get("summary"), str):
        lines.append(fe["summary"])
    elif fe.get("worst_axis"):
        lines.append(f"worst axis: {fe['worst_axis']}")
    if isinstance(fe.get("load_sets"), Mapping):
        lines.append(", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in fe["load_sets"].items()))
    return {"rows": rows, "has_paper": bool(paper), "paper": _paper_text(fe),
            "mechanisms": [m.replace("_", " ") for m in mechs], "split": split_rows,
            "budget": budget, "lines": lines, "units": str(fe.get("units", "N"))}


def force_error_lines(pred: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(quantity, value) lines of ``force_error_test`` for a terminal summary: the force error
    per axis (mean +- std, max |e|, N) and the comparison with the paper."""
    sec = force_error_section(pred)
    if sec is None:
        return []
    out = [(f"force error {r['axis']} (N, held-out)",
            f"{r['mean']} ± {r['std']} (max |e| {r['max']})"
            + (f"; paper {r['paper_mean']} ± {r['paper_std']}" if r["paper_std"] else ""))
           for r in sec["rows"]]
    out += [("force error", line) for line in sec["lines"][:1]]
    if sec["paper"] and not sec["has_paper"]:
        out.append(("paper", sec["paper"]))
    return out


#: Monte Carlo statistics shown per metric (:func:`designlab.predict.uncertainty.summarize`)
SCATTER_STATS = ("mean", "p5", "p95")


def _drivers_text(drivers: Any, n: int = 3) -> str:
    if not isinstance(drivers, Mapping) or not drivers:
        return ""
    items = list(drivers.items())[:n]
    if isinstance(items[0][1], Mapping):                     # Sobol: S1, ST
        return ", ".join(f"{k} (ST {v.get('ST', float('nan')):.2f})" for k, v in items)
    return ", ".join(f"{k} ({v:+.2f})" for k, v in items)


def scatter_section(summary: Mapping[str, Any], nominal: Mapping[str, Any] | None = None,
                    note: str = "") -> dict[str, Any] | None:
    """The "Scatter (Monte Carlo)" section of a ``predict --samples`` summary
    (``uncertainty.json``): per metric its nominal value, mean, 5 % and 95 % quantiles, the
    inputs that drive it and the number of builds behind it; the sample and failed counts."""
    metrics = summary.get("metrics") or {}
    if not metrics:
        return None
    from designlab.sensors.labels import metric_name_unit

    rows = []
    for m, e in metrics.items():
        name, unit = metric_name_unit(m)
        nom = (nominal or {}).get(m)
        rows.append({"metric": name, "key": m, "unit": unit,
                     "nominal": _num(nom) if nom is not None else "",
                     **{s: _num(e.get(s)) for s in SCATTER_STATS},
                     "drivers": _drivers_text(e.get("drivers")), "n": str(e.get("n", ""))})
    spec = summary.get("spec") or {}
    inputs = [[k, ", ".join(f"{a} = {fmt_value(b)}" for a, b in v.items() if a != "source"),
               str(v.get("source", ""))] for k, v in (spec.get("inputs") or {}).items()]
    errors = [f"{n} builds: {e}" for e, n in (summary.get("failed_errors") or {}).items()]
    return {"rows": rows, "samples": summary.get("builds"), "ok": summary.get("ok"),
            "failed": summary.get("failed", 0), "errors": errors,
            "method": summary.get("sensitivity_method", ""), "seed": spec.get("seed"),
            "inputs": inputs, "note": note, "bands": [],
            "paper": ", ".join(f"{k}: {fmt_value(v)}" for k, v in
                               (summary.get("paper") or {}).items())}


def nominal_build(summary: Mapping[str, Any], params: Mapping[str, Any] | None = None,
                  settings: Mapping[str, Any] | None = None,
                  protocol: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The Monte Carlo metrics of one build with every input at its distribution's centre
    (mean; uniform: the midpoint; fixed: the value) and the readout noise of the run's seed,
    on the run's cached FEM (``summary["fem"]["cache"]``: nothing is solved when it holds the
    design's stage). The reference the bands are read against."""
    from designlab.predict.uncertainty import _fem_stage, build_values, model_of, parse_uncertainty

    spec_doc = summary.get("spec") or {}
    sensor = str(summary.get("sensor") or spec_doc.get("sensor"))
    table = {k: v for k, v in (spec_doc.get("inputs") or {}).items()}
    spec = parse_uncertainty(sensor, {**table, "seed": spec_doc.get("seed", 0)}, samples=2)
    fem_dir = (summary.get("fem") or {}).get("cache")
    from designlab.geometry.parts import make_part
    from designlab.params import as_dict

    full = as_dict(make_part(sensor, dict(params or {})))
    ctx, _ = _fem_stage(sensor, full, dict(settings) if settings else None,
                        dict(protocol) if protocol else None, fem_dir)
    values = build_values(spec, [], np.zeros(0))
    return dict(model_of(sensor).build(ctx, values, int(spec.seed)))


def write_uncertainty_report(out: str | Path, summary: Mapping[str, Any], *,
                             params: Mapping[str, Any] | None = None,
                             settings: Mapping[str, Any] | None = None,
                             protocol: Mapping[str, Any] | None = None, files=None) -> Path:
    """``OUT/report.html`` of ``designlab predict PART --samples N``: the "Scatter (Monte
    Carlo)" section (nominal build, mean, 5-95 % band and drivers of every metric, builds and
    failed builds, the input distributions), the design and settings tables, the files.
    ``files`` (a :class:`~designlab.atomic.FileSet`): the page is staged with it."""
    from designlab.geometry.parts import make_part
    from designlab.params import as_dict
    from designlab.sensors.registry import get_sensor

    out = Path(out)
    sensor = str(summary.get("sensor"))
    rec = get_sensor(sensor)
    try:
        nominal = nominal_build(summary, params, settings, protocol)
        note = ("nominal: one build with every input at its distribution's centre, readout "
                f"noise from seed {(summary.get('spec') or {}).get('seed', 0)}")
    except Exception as exc:     # the bands stand without it; say why it is missing
        nominal, note = None, f"nominal build not evaluated: {type(exc).__name__}: {exc}"
    sec = scatter_section(summary, nominal, note)
    tables = [param_table("Design parameters", rec.part,
                          as_dict(make_part(sensor, dict(params or {}))))]
    if rec.settings is not None:
        tables.append(param_table("Model settings", rec.settings, dict(settings or {})))
    links = [out / "uncertainty.json", out / "run.json"]
    ctx = {"title": f"designlab predict {sensor} --samples {summary.get('builds')}",
           "subtitle": f"Monte Carlo of a {sensor} design ({rec.paper}): "
                       f"{summary.get('ok')} builds, {summary.get('failed', 0)} failed",
           "scatter": sec, "tables": tables, "files": file_links(out, links),
           "warnings": ([f"{summary.get('failed')} of {summary.get('builds')} builds failed "
                         "(Scatter section)"] if summary.get("failed") else [])}
    page = out / "report.html"
    render_report(page if files is None else files.path(page), ctx)
    return page


def param_table(title: str, cls_or_obj: Any, values: Mapping[str, Any] | None = None
                ) -> dict[str, Any]:
    """Parameter table from a dataclass's metadata: name, value, unit, allowed, meaning."""
    rows = []
    for r in field_rows(cls_or_obj):
        v = (values or {}).get(r["name"], r["value"])
        rows.append([r["name"], fmt_value(v), r["unit"], r["allowed"], r["meaning"]])
    return {"title": title, "columns": ["name", "value", "unit", "allowed", "meaning"],
            "rows": rows}


def file_links(root: Path, paths: Iterable[Path]) -> list[dict[str, str]]:
    """Links relative to the report's folder ``root`` (files that exist)."""
    out = []
    for p in sorted({Path(p) for p in paths}):
        if not p.is_file() or p.name == "report.html":
            continue
        try:
            href = p.resolve().relative_to(root.resolve()).as_posix()
        except ValueError:
            href = p.resolve().as_uri()
        out.append({"href": href, "name": href, "what": FILE_KINDS.get(p.suffix.lower(), "")})
    return out


def caption_of(png: Path) -> str:
    """A figure's caption from its file name (``hysteresis_loops.png`` -> hysteresis loops)."""
    return png.stem.replace("_", " ")


def prediction_sections(pred: Mapping[str, Any], pred_dir: Path, *, part_cls: type | None,
                        settings_cls: type | None, protocol_cls: type | None,
                        render_pngs: Iterable[Path] = ()) -> dict[str, Any]:
    """The sections of a design's prediction for the template (see module docstring)."""
    plots = [p for p in sorted(pred_dir.glob("*.png")) if p.name not in ("design.png",)]
    renders = [{"src": data_uri(p), "caption": cap} for p, cap in render_pngs]
    params = (pred.get("design") or {}).get("params", {})
    tables = []
    if part_cls is not None:
        tables.append(param_table("Design parameters", part_cls, params))
    if settings_cls is not None:
        tables.append(param_table("Model settings", settings_cls, pred.get("settings") or {}))
    if protocol_cls is not None:
        tables.append(param_table("Test protocol", protocol_cls, pred.get("protocol") or {}))
    return {
        "renders": renders,
        "results": result_rows(pred),
        "results_title": "Predicted",
        "stress": stress_section(pred.get("stress")),
        "force_error": force_error_section(pred),
        "plots": [{"src": data_uri(p), "caption": caption_of(p)} for p in plots],
        "tables": tables,
        "warnings": list(pred.get("warnings") or []),
    }


def render_report(path: str | Path, context: Mapping[str, Any]) -> Path:
    """Fill the template with ``context`` (missing sections are left out) and write the page
    atomically."""
    from importlib.resources import files

    import jinja2

    from designlab.atomic import atomic_write_bytes

    text = files("designlab").joinpath("templates", "report.html.j2").read_text("utf-8")
    env = jinja2.Environment(autoescape=True, undefined=jinja2.ChainableUndefined,
                             trim_blocks=True, lstrip_blocks=True)
    ctx = {"version": __version__, "date": now(), "command": command_line(), "title": "designlab",
           "subtitle": "", "choice": None, "ties": [], "warnings": [], "renders": [],
           "results": [], "results_title": "Results", "stress": None, "paper": None,
           "plots": [], "designs": None, "tables": [], "files": [], "force_error": None,
           "scatter": None, **context}
    html = env.from_string(text).render(**ctx)
    path = Path(path)
    atomic_write_bytes(path, html.encode("utf-8"))
    return path
