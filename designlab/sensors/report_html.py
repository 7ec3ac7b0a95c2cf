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

from designlab import __version__
from designlab.sensors.labels import field_rows, fmt_value, metric_name_unit

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
    """The command as typed (``designlab ...``), quoted for a shell."""
    args = list(sys.argv if argv is None else argv)
    if args and Path(args[0]).name in ("designlab", "__main__.py", "cli.py"):
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


def paper_section(pred: Mapping[str, Any]) -> dict[str, Any] | None:
    """``paper_comparison``: rows of ``*_paper`` / ``*_predicted`` pairs and the explanation."""
    pc = pred.get("paper_comparison")
    if not pc:
        return None
    rows, seen = [], set()
    for k, v in pc.items():
        if not isinstance(k, str):
            continue
        for suf in ("_paper", "_predicted"):
            if k.endswith(suf):
                base = k[: -len(suf)]
                if base in seen:
                    continue
                seen.add(base)
                name, unit = metric_name_unit(base)
                rows.append({"name": name + (f" ({unit})" if unit else ""),
                             "paper": _num(pc.get(base + "_paper")),
                             "predicted": _num(pc.get(base + "_predicted"))})
    for k, v in pc.items():
        if k not in ("explanation",) and not any(k.endswith(s) for s in ("_paper", "_predicted")) \
                and isinstance(v, (int, float)) and not isinstance(v, bool):
            name, unit = metric_name_unit(k)
            rows.append({"name": name + (f" ({unit})" if unit else ""), "paper": "",
                         "predicted": _num(v)})
    return {"rows": rows, "explanation": pc.get("explanation", "")}


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
        "paper": paper_section(pred),
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
           "plots": [], "designs": None, "tables": [], "files": [], **context}
    html = env.from_string(text).render(**ctx)
    path = Path(path)
    atomic_write_bytes(path, html.encode("utf-8"))
    return path
