"""Sweep reports: Pareto and parameter-sensitivity plots (PNG) and a self-contained HTML page."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import FileSet
from designlab.optimize.space import SweepConfig
from designlab.optimize.sweep import error_bar


def _fig_png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return buf.getvalue()


def _numeric(rows, name):
    return np.array([r.get(name) if isinstance(r.get(name), (int, float)) and r.get("status") == "ok"
                     else np.nan for r in rows], float)


def _bars(rows, name, config=None):
    return np.array([error_bar(r, name, config) if r.get("status") == "ok" else np.nan
                     for r in rows])


def pareto_plot(rows: list[dict], config: SweepConfig, pareto_keys: list[str],
                best_key: str | None, tie_keys: list[str] = ()) -> bytes | None:
    """Scatter of the first two objectives with each design's discretisation error bars (value
    vs one coarser mesh), Pareto set highlighted, designs not distinguishable from the chosen
    one ringed (None with < 2 objectives). Axes: readable names with units."""
    from designlab.sensors.labels import metric_label
    from designlab.sensors.plotstyle import close, figure, legend_outside

    names = list(config.objectives)
    if len(names) < 2:
        return None
    x, y = _numeric(rows, names[0]), _numeric(rows, names[1])
    is_p = np.array([r["key"] in pareto_keys for r in rows])
    fig, ax = figure(width=8.5, height=4.6)
    ex, ey = _bars(rows, names[0], config), _bars(rows, names[1], config)
    ok = np.isfinite(x) & np.isfinite(y)
    ax.errorbar(x[ok], y[ok], xerr=np.nan_to_num(ex[ok]), yerr=np.nan_to_num(ey[ok]), fmt="none",
                ecolor="0.5", elinewidth=0.8, capsize=2, label="mesh error bar", zorder=1)
    ax.scatter(x[~is_p], y[~is_p], c="0.6", marker="o", label="designs", zorder=2)
    order = np.argsort(x[is_p])
    ax.plot(x[is_p][order], y[is_p][order], "s-", c="#d62728", label="Pareto set", zorder=3)
    tie = np.array([r["key"] in tie_keys for r in rows])
    if tie.any():
        ax.scatter(x[tie], y[tie], s=160, facecolors="none", edgecolors="#1f77b4", lw=1.5,
                   zorder=4, label="not distinguishable from the chosen")
    if best_key is not None:
        b = [i for i, r in enumerate(rows) if r["key"] == best_key][0]
        ax.scatter([x[b]], [y[b]], s=220, facecolors="none", edgecolors="k", lw=2,
                   label="chosen", zorder=5)
    ax.set_xlabel(metric_label(names[0], config.objectives[names[0]]))
    ax.set_ylabel(metric_label(names[1], config.objectives[names[1]]))
    legend_outside(ax)
    ax.grid(alpha=0.3)
    data = _fig_png(fig)
    close(fig)
    return data


def sensitivity_plot(rows: list[dict], config: SweepConfig) -> bytes | None:
    """Each objective against each swept parameter (one panel per pair), readable names with
    units on every axis."""
    from designlab.sensors.labels import metric_label, param_label
    from designlab.sensors.plotstyle import close, figure, series_style
    from designlab.sensors.registry import SENSORS

    names = list(config.objectives)
    dims = [d.name for d in config.dimensions]
    if not names:
        return None
    cls = SENSORS[config.part].part if config.part in SENSORS else None
    fig, axes = figure(len(names), len(dims), width=3.6 * len(dims) + 0.8,
                       height=3.0 * len(names), squeeze=False)
    for i, n in enumerate(names):
        y = _numeric(rows, n)
        for j, d in enumerate(dims):
            x = _numeric([{**r, "status": "ok"} for r in rows], f"param.{d}")
            ax = axes[i, j]
            st = series_style(i)
            ax.scatter(x, y, s=20, c=st["color"], marker=st["marker"])
            ok = np.isfinite(x) & np.isfinite(y)
            if ok.sum() >= 3 and np.ptp(x[ok]) > 0:
                rho = np.corrcoef(x[ok], y[ok])[0, 1]
                ax.set_title(f"r = {rho:+.2f}", fontsize=9)
            ax.set_xlabel(param_label(cls, d).split(":")[0])
            ax.set_ylabel(metric_label(n), fontsize=8)
            ax.grid(alpha=0.3)
    data = _fig_png(fig)
    close(fig)
    return data


def _value_text(row: dict, name: str) -> str:
    from designlab.sensors.labels import metric_name_unit

    v, e = row.get(name), error_bar(row, name)
    unit = metric_name_unit(name)[1]
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return f"{metric_name_unit(name)[0]} unknown"
    bar = f" ± {e:.2g}" if np.isfinite(e) else ""
    return f"{metric_name_unit(name)[0]} = {v:.4g}{bar}" + (f" {unit}" if unit else "")


def band_of(row: dict, name: str) -> tuple[float, float] | None:
    """The Monte Carlo 5-95 % band of an objective in a robust sweep's row: of ``M`` for an
    objective ``mc.M.<stat>`` (a quantile or the mean of M), else of the nominal metric's own
    Monte Carlo columns ``mc.<name>.p5`` / ``.p95``; None when the row has none."""
    from designlab.optimize.robust import STATS

    head, _, stat = name.rpartition(".")
    base = head if name.startswith("mc.") and stat in STATS else f"mc.{name}"
    lo, hi = row.get(f"{base}.p5"), row.get(f"{base}.p95")
    ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
             for v in (lo, hi))
    return (float(lo), float(hi)) if ok else None


def _band_text(band: tuple[float, float] | None) -> str:
    return "" if band is None else f"{band[0]:.4g} .. {band[1]:.4g}"


def mc_metrics_of(row: dict) -> list[str]:
    """The Monte Carlo metrics ``M`` a robust sweep's row carries (columns ``mc.M.<stat>``)."""
    from designlab.optimize.robust import STATS

    names = []
    for k in row:
        if k.startswith("mc.") and k.rpartition(".")[2] in STATS:
            m = k[3:].rpartition(".")[0]
            if m not in names:
                names.append(m)
    return names


def scatter_of_row(row: dict, samples: int | None = None, spec: dict | None = None
                   ) -> dict[str, Any] | None:
    """The "Scatter (Monte Carlo)" section of one design of a robust sweep: per Monte Carlo
    metric its nominal value (the row's nominal column of the same name, where there is one),
    mean, 5 % and 95 %; the failed builds (``mc.failed``); the drivers are not kept in a row."""
    from designlab.predict.report import scatter_section

    names = mc_metrics_of(row)
    if not names:
        return None
    summary = {"metrics": {m: {s: row.get(f"mc.{m}.{s}") for s in ("mean", "p5", "p95")}
                           for m in names},
               "failed": int(row.get("mc.failed") or 0), "builds": samples,
               "ok": None if samples is None else samples - int(row.get("mc.failed") or 0),
               "spec": spec or {}}
    nominal = {m: row[m] for m in names
               if isinstance(row.get(m), (int, float)) and not isinstance(row.get(m), bool)}
    sec = scatter_section(summary, nominal, note=(
        f"design {row['key'][:8]}: nominal is the design's prediction (blank where it has no "
        "metric of that name); the drivers are not kept in a sweep row: designlab predict "
        "PART --samples N on the design ranks them"))
    return sec


def choice_text(method: str, rows: list[dict], config: SweepConfig, pareto_keys: list[str],
                chosen: dict) -> str:
    """Why the design was chosen, in words: the objective(s) with readable names, units and
    the chosen design's values and mesh error bars; for the Pareto method the rule (closest to
    the ideal point of the front after scaling each objective to 0..1)."""
    from designlab.sensors.labels import metric_label

    names = list(config.objectives)
    if not names:
        return f"{method}: no objective"
    if len(names) >= 2:        # several objectives: every method picks from the Pareto set
        front = [r for r in rows if r["key"] in pareto_keys and r.get("status") == "ok"]
        ideal = []
        for n in names:
            spec = config.objectives[n]
            vals = [(objective_of(r, n, spec), r.get(n)) for r in front]
            vals = [(o, v) for o, v in vals if o is not None]
            if vals:
                ideal.append(f"{metric_label(n)} {min(vals, key=lambda t: t[0])[1]:.4g}")
        ideal = ", ".join(ideal)
        return (f"Pareto method: of the {len(front)} designs no other design beats in every "
                f"objective (the Pareto set: {', '.join(metric_label(n, config.objectives[n]) for n in names)}), "
                "the chosen one is closest to the ideal point after each objective is scaled "
                f"to 0..1 over the set (ideal point: {ideal}). Chosen design: "
                + "; ".join(_value_text(chosen, n) for n in names) + ".")
    n = names[0]
    how = {"surrogate": "a surrogate model fitted to the sweep, then evaluated at its optimum",
           "de": "differential evolution over the parameter ranges",
           "pareto": "the sweep's best design",
           **{k: f"an Optuna study's best trial, {v} sampler" for k, v in (
               ("tpe", "tree-structured Parzen estimator"), ("nsga2", "NSGA-II"),
               ("gp", "Gaussian-process"), ("grid", "grid"), ("random", "random"),
               ("qmc", "quasi-Monte Carlo"))}}.get(method, method)
    return (f"{method} method ({how}): the best {metric_label(n, config.objectives[n])}: "
            f"{_value_text(chosen, n)}, beyond the mesh error bars of the other designs.")


def objective_of(row: dict, name: str, spec) -> float | None:
    """The objective as minimised (:func:`objective_value`); None when unknown."""
    from designlab.optimize.space import objective_value

    v = row.get(name)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v):
        return None
    return objective_value(v, spec)


def chosen_renders(chosen_dir: Path) -> list[tuple[Path, str]]:
    """Renders of the exported chosen design: the prediction's ``design.png`` (bodies with
    their materials) and ``deformed.png``, else the export's ``PART/PART.png``."""
    chosen_dir = Path(chosen_dir)
    pdir = chosen_dir / "prediction"
    out = []
    if (pdir / "design.png").is_file():
        out.append((pdir / "design.png", "the chosen design (printed bodies opaque, bought "
                    "parts see-through)"))
    else:
        out += [(p, f"the chosen design: {p.parent.name}") for p in
                sorted(chosen_dir.glob("*/*.png")) if p.parent.name != "prediction"]
    if (pdir / "deformed.png").is_file():
        out.append((pdir / "deformed.png", "the chosen design deformed under its first load "
                    "case (warped, coloured by displacement)"))
    return out


#: captions of the sweep's own plots
_CAPTIONS = {"pareto": "the first two objectives of every design with their mesh error bars; "
                       "Pareto set joined, chosen design ringed in black, designs not "
                       "distinguishable from it ringed in blue",
             "sensitivity": "each objective against each swept parameter (r: correlation)"}

#: legend of the designs table; the second line only when a column has Monte Carlo bands
_DESIGNS_LEGEND = ("orange: chosen; blue: not distinguishable from the chosen design "
                   "(difference within the error bar of the difference); pink: Pareto set. "
                   "±: each design's discretisation error bar (metric on the chosen mesh minus "
                   "the same on one coarser mesh). Design: the first 8 characters of its key "
                   "in results.parquet.",
                   " 5-95 %: the objective's Monte Carlo band over the design's virtual builds "
                   "(robust run).")


def _write_plots(out: Path, rows, config, pareto_keys, best_key, tie_keys, files: FileSet):
    """``pareto.png`` and ``sensitivity.png`` where there is something to plot, staged in
    ``files``: (the files by name, the report's plot entries)."""
    from designlab.predict.report import png_uri

    written: dict[str, Path] = {}
    images = []
    for name, data in (("pareto", pareto_plot(rows, config, pareto_keys, best_key, tie_keys)),
                       ("sensitivity", sensitivity_plot(rows, config))):
        if data is not None:
            files.write_bytes(out / f"{name}.png", data)
            written[name] = out / f"{name}.png"
            images.append({"src": png_uri(data), "caption": _CAPTIONS[name]})
    return written, images


def _objective_result(best: dict, n: str, config: SweepConfig) -> dict:
    """One result row of the chosen design: an objective's value, error bar, unit and spec
    (with its Monte Carlo band in a robust run)."""
    from designlab.sensors.labels import fmt_value, metric_name_unit

    name, unit = metric_name_unit(n)
    v, e = best.get(n), error_bar(best, n, config)
    band = band_of(best, n)
    note = f"objective: {config.objectives[n]}" + (
        f"; Monte Carlo 5-95 %: {_band_text(band)}" if band else "")
    return {"name": name, "value": fmt_value(v) if not isinstance(v, float) else f"{v:.4g}",
            "bar": "" if not np.isfinite(e) else f"{e:.2g}", "unit": unit, "note": note}


def _chosen_results(best: dict, config: SweepConfig, part_cls) -> list[dict]:
    """The chosen design's result rows: its objectives, then its swept parameters."""
    from designlab.sensors.labels import fmt_value, param_label

    return ([_objective_result(best, n, config) for n in config.objectives]
            + [{"name": param_label(part_cls, d.name),
                "value": fmt_value(best.get(f"param.{d.name}")),
                "bar": "", "unit": "", "note": "swept parameter"} for d in config.dimensions])


def _design_cells(r: dict, config: SweepConfig, banded: set) -> list[str]:
    """One row of the designs table: key, parameters, each objective with its error bar (and
    band), feasibility, status, time, error."""
    from designlab.sensors.labels import fmt_value

    cells = [r["key"][:8]] + [fmt_value(r.get(f"param.{d.name}")) for d in config.dimensions]
    for n in config.objectives:
        v, e = r.get(n), error_bar(r, n, config)
        cells += [f"{v:.4g}" if isinstance(v, float) else fmt_value(v),
                  f"{e:.2g}" if np.isfinite(e) else ""]
        if n in banded:
            cells.append(_band_text(band_of(r, n)))
    return cells + ["yes" if r.get("feasible") else "no", r.get("status", ""),
                    f"{r.get('elapsed_s', float('nan')):.1f}", r.get("error") or ""]


def _designs_table(rows, config: SweepConfig, part_cls, pareto_keys, best_key,
                   tie_keys) -> dict:
    """Every design in a table, the chosen one, its ties and the Pareto set marked; a robust
    run adds each objective's Monte Carlo band beside it."""
    from designlab.sensors.labels import metric_label, param_label

    objs = list(config.objectives)
    banded = {n for n in objs if any(r.get("status") == "ok" and band_of(r, n) for r in rows)}
    cols = (["design"] + [param_label(part_cls, d.name).split(":")[0] for d in config.dimensions]
            + [c for n in objs for c in (metric_label(n), "±")
               + (("5-95 %",) if n in banded else ())]
            + ["feasible", "status", "time (s)", "error"])
    trows = [{"cls": ("best" if r["key"] == best_key else "tie" if r["key"] in tie_keys
                      else "pareto" if r["key"] in pareto_keys else ""),
              "cells": _design_cells(r, config, banded)} for r in rows]
    return {"columns": cols, "rows": trows,
            "legend": _DESIGNS_LEGEND[0] + (_DESIGNS_LEGEND[1] if banded else "")}


def _scatter_of_best(best: dict, config: SweepConfig, uncertainty):
    """The chosen design's Monte Carlo section; the builds per design from ``uncertainty``."""
    samples, spec = None, None
    if uncertainty is not None:
        import dataclasses

        from designlab.predict.uncertainty import draw

        spec_p = dataclasses.replace(uncertainty, sensor=config.part)
        samples, spec = len(draw(spec_p)[1]), spec_p.to_json()      # Sobol: N (2d + 2)
    return scatter_of_row(best, samples, spec)


def _settings_value(v) -> str:
    from designlab.sensors.labels import fmt_value

    if not isinstance(v, dict):
        return fmt_value(v)
    return ", ".join(f"{a} = {fmt_value(b)}" for a, b in v.items())


def _sweep_tables(config: SweepConfig, part_cls) -> list[dict]:
    """The swept parameters (range, levels, unit, meaning) and the sweep's settings."""
    from designlab.geometry.api import field_rows
    from designlab.sensors.labels import fmt_value

    meta = {r["name"]: r for r in field_rows(part_cls)} if part_cls is not None else {}
    sweep_rows = [[d.name, f"{d.lo:g} .. {d.hi:g}" if not d.values else fmt_value(d.values),
                   str(d.levels) if config.method == "grid" and not d.values else "",
                   meta.get(d.name, {}).get("unit", ""), meta.get(d.name, {}).get("meaning", "")]
                  for d in config.dimensions]
    setting_rows = ([["method", config.method]]
                    + [[f"objective {k}", str(v)] for k, v in config.objectives.items()]
                    + [[f"constraint {k}", str(v)] for k, v in config.constraints.items()]
                    + [[f"fixed {k}", fmt_value(v)] for k, v in config.fixed.items()]
                    + [[f"settings {k}", _settings_value(v)] for k, v in config.settings.items()]
                    + [[f"protocol {k}", fmt_value(v)] for k, v in config.protocol.items()])
    return [{"title": "Swept parameters",
             "columns": ["name", "range / values", "levels", "unit", "meaning"],
             "rows": sweep_rows},
            {"title": "Sweep settings", "columns": ["setting", "value"], "rows": setting_rows}]


def _add_chosen_prediction(ctx: dict, images: list, chosen_dir: Path, config: SweepConfig,
                           sensor) -> list[Path]:
    """The exported chosen design's prediction merged into the report (renders, stress,
    paper comparison, plots, results, tables, warnings); returns its files."""
    import json

    from designlab.predict.report import param_table, prediction_sections

    part_cls = sensor.part if sensor is not None else None
    pdir = chosen_dir / "prediction"
    pred = json.loads((pdir / "prediction.json").read_text())
    sec = prediction_sections(pred, pdir, part_cls=part_cls,
                              settings_cls=sensor.settings if sensor else None,
                              protocol_cls=sensor.protocol if sensor else None,
                              render_pngs=chosen_renders(chosen_dir))
    if sensor is not None and sensor.settings is not None:
        # the settings the run used: the prediction's own, over them the sweep's [settings]
        # model table (what the config asked for; defaults only where neither says)
        used = {**(pred.get("settings") or {}), **(config.settings.get("model") or {})}
        sec["tables"] = [param_table("Model settings", sensor.settings, used)
                         if t["title"] == "Model settings" else t for t in sec["tables"]]
    ctx["renders"] = sec["renders"]
    ctx["stress"] = sec["stress"]
    ctx["plots"] = images + [f for f in sec["plots"]
                             if not f["caption"].startswith(("design", "deformed"))]
    ctx["results"] = ctx.get("results", []) + [
        {**r, "note": (r["note"] + " (chosen design's prediction)").strip()}
        for r in sec["results"] if r["name"] not in {x["name"] for x in ctx.get("results", [])}]
    ctx["tables"] = sec["tables"] + ctx["tables"]
    ctx["warnings"] = [f"chosen design: {w}" for w in sec["warnings"]]
    return [p for p in chosen_dir.rglob("*") if p.is_file()]


def write_report(out: Path, rows: list[dict], config: SweepConfig, pareto_keys: list[str],
                 best_key: str | None, title: str = "designlab sweep",
                 tie_keys: list[str] = (), *, choice: str | None = None,
                 chosen_dir: Path | None = None, kind: str = "sweep",
                 uncertainty=None, files: FileSet | None = None) -> dict[str, Path]:
    """Write ``pareto.png``, ``sensitivity.png`` and ``report.html`` as a set (a full disk
    leaves none of them half-written; ``files``: a caller's set they join, committed by the
    caller, e.g. with ``optimize.json``) (the shared template of
    :mod:`designlab.predict.report`, images embedded). ``choice``: why the design was
    chosen (optimize); ``chosen_dir``: the exported chosen design with its ``prediction/``
    (renders, plots, stress, paper comparison, files). A robust run's rows (``mc.*``
    columns): each objective's 5-95 % band beside it and the chosen design's "Scatter (Monte
    Carlo)" section; ``uncertainty`` (its spec) gives the builds per design."""
    from designlab.sensors.registry import SENSORS
    from designlab.predict.report import file_links, render_report

    out = Path(out)
    if files is None:
        with FileSet() as own:
            return write_report(out, rows, config, pareto_keys, best_key, title, tie_keys,
                                choice=choice, chosen_dir=chosen_dir, kind=kind,
                                uncertainty=uncertainty, files=own)
    written, images = _write_plots(out, rows, config, pareto_keys, best_key, tie_keys, files)
    sensor = SENSORS.get(config.part)
    part_cls = sensor.part if sensor is not None else None
    best = next((r for r in rows if r["key"] == best_key), None)
    n_ok = sum(r.get("status") == "ok" for r in rows)
    ctx: dict[str, Any] = {
        "title": title, "choice": choice, "plots": images, "tables": [], "warnings": [],
        "subtitle": (f"{kind} of the {config.part} ({sensor.paper if sensor else ''}): "
                     f"{len(rows)} designs ({n_ok} evaluated without error), method "
                     f"{config.method}")}
    if best is not None:
        ctx["results"] = _chosen_results(best, config, part_cls)
        ctx["results_title"] = "Chosen design: objectives"
    if tie_keys:
        ctx["ties"] = [k[:8] for k in tie_keys]
    ctx["designs"] = _designs_table(rows, config, part_cls, pareto_keys, best_key, tie_keys)
    if best is not None:
        ctx["scatter"] = _scatter_of_best(best, config, uncertainty)
    ctx["tables"] += _sweep_tables(config, part_cls)
    links = [out / "results.parquet", out / "optimize.json", *written.values()]
    if chosen_dir is not None and (Path(chosen_dir) / "prediction" / "prediction.json").is_file():
        links += _add_chosen_prediction(ctx, images, Path(chosen_dir), config, sensor)
    ctx["files"] = file_links(out, [f for f in links if Path(f).exists()
                                    or Path(f) in files.targets()])
    render_report(files.path(out / "report.html"), ctx)
    written["html"] = out / "report.html"
    return written
