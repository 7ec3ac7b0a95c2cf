"""``designlab sweep`` and ``designlab optimize``: a design space evaluated (cached, resumable),
its summary table, and the export of the chosen design."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.table import Table

from designlab.atomic import FileSet, atomic_write_json, jsonable
from designlab.cli.app import (Bar, app, console, err_console, next_step, one_line, plain,
                               progress_bar, warn)
from designlab.cli.options import check_options, make_executor
from designlab.cli.runs import check_out, read_run, start_sweep_run
from designlab.errors import ParameterError
from designlab.params import did_you_mean

#: hand-written methods; the Optuna samplers are designlab.optimize.study.SAMPLERS
METHODS = ("auto", "surrogate", "de", "pareto")


def _sweep_callback(bar: Bar):
    """Sweep/optimize progress: designs done of the total, failures printed as they happen."""

    def callback(done: int, total: int | None, row: dict) -> None:
        bar(completed=done, **({"total": total} if total is not None else {}))
        if row.get("status") == "error":
            bar.print(plain(("design " + row["key"][:8] + " failed:", "yellow"), " ",
                            one_line(row["error"])), highlight=False)

    return callback


def _cell(v) -> str:
    """A table cell; user text (choice values) printed literally."""
    return f"{v:.4g}" if isinstance(v, float) else ("" if v is None else escape(str(v)))


def _mark(row: dict, best_key, pareto_keys, tie_keys) -> str:
    if row.get("status") != "ok":
        return "x"
    key = row["key"]
    return ("*" if key == best_key else "~" if key in tie_keys
            else "P" if key in pareto_keys else "")


def _summary_table(rows, config, pareto_keys, best_key, limit: int = 20, tie_keys=()):
    from designlab.optimize.sweep import error_bar

    t = Table(title=f"{config.part} sweep: {len(rows)} designs "
                    f"({sum(r.get('status') == 'ok' for r in rows)} ok)")
    dims = [d.name for d in config.dimensions]
    objs = list(config.objectives)
    for c in ["", *dims, *(x for o in objs for x in (o, "+-")), "feasible", "s"]:
        t.add_column(escape(c), justify="right")
    for r in rows[:limit]:
        vals = [x for o in objs for x in (_cell(r.get(o)), _cell(error_bar(r, o, config)))]
        t.add_row(_mark(r, best_key, pareto_keys, tie_keys),
                  *[_cell(r.get(f"param.{d}")) for d in dims], *vals,
                  "yes" if r.get("feasible") else "no", _cell(r.get("elapsed_s")))
    if len(rows) > limit:
        t.caption = f"first {limit} of {len(rows)} designs; all in results.parquet / report.html"
    console.print(t)
    console.print("* chosen design, ~ not distinguishable from it (difference within the mesh "
                  "error bars), P Pareto set, x failed; +- the discretisation error bar (value "
                  "minus the value on one coarser mesh)", highlight=False, markup=False)


def _interrupted() -> typer.Exit:
    err_console.print("interrupted: finished designs are stored; run the same command to resume")
    return typer.Exit(130)


@app.command()
def sweep(ctx: typer.Context,
          config: Path = typer.Argument(..., help="Sweep config (TOML): part, parameters, objectives..."),
          out: Path = typer.Option(..., "--out", help="Output directory (reused to resume)."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler",
                                                  help="Dask scheduler tcp://HOST:PORT (default: local processes)."),
          workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes (default: all cores)."),
          retry_failed: bool = typer.Option(False, "--retry-failed", help="Evaluate failed designs again."),
          overwrite: bool = typer.Option(False, "--overwrite", help="Replace another run's "
                                         "results in --out (its design rows; the caches stay).")):
    """Explore a design space: every design -> prediction, cached, resumable; Pareto report."""
    from designlab.optimize.report import write_report
    from designlab.optimize.robust import band_lines, load_sweep
    from designlab.optimize.sweep import run_sweep

    check_out(out)
    check_options(("--workers", workers, 1, 512))
    cfg, evaluator = load_sweep(config)      # [uncertainty]: robust (Monte Carlo per design)
    executor = make_executor(scheduler, workers)
    start_sweep_run(ctx, out, "sweep", config, cfg, overwrite, evaluator)
    try:
        with FileSet() as outputs:      # results.parquet and the report: all or none
            with progress_bar("designs", len(cfg.designs()), transient=False) as bar:
                res = run_sweep(cfg, out, executor=executor, progress=_sweep_callback(bar),
                                retry_failed=retry_failed, evaluator=evaluator, files=outputs)
            write_report(out, res.rows, cfg, res.pareto_keys, res.best_key,
                         title=f"designlab sweep: {config.name}", tie_keys=res.tie_keys,
                         kind="sweep", uncertainty=getattr(evaluator, "spec", None),
                         files=outputs)
    except KeyboardInterrupt:
        raise _interrupted()
    _summary_table(res.rows, cfg, res.pareto_keys, res.best_key, tie_keys=res.tie_keys)
    for line in band_lines(res.rows, cfg, [res.best_key] if res.best_key else None):
        console.print("Monte Carlo band " + line, highlight=False, markup=False)
    if res.tie_keys:
        console.print(f"{len(res.tie_keys) + 1} designs are not distinguishable: their "
                      "differences are within the mesh error bars on every objective",
                      highlight=False, markup=False)
    for w in res.warnings:
        warn(w)
    console.print(f"{res.new} evaluated, {res.reused} from the store, {res.failed} failed -> "
                  f"{res.table_path}, {out / 'report.html'}", markup=False, highlight=False)
    next_step(f"open next: {out / 'report.html'} (the report), then designlab optimize "
              f"{config} --out {out} to export the best design")


def _choose(res, rows: list, cfg) -> tuple:
    """The design optimize exports and why: the optimizer's choice, or, when other designs are
    not distinguishable from it by the mesh error bars, the one of them with the least printed
    volume. Returns ``(chosen row, its parameters, choice text, tied keys, unknown keys)``."""
    from designlab.optimize.report import choice_text
    from designlab.optimize.sweep import compare_to_best

    ties, unknown = (compare_to_best(rows, cfg, res.chosen["key"]) if cfg.objectives
                     else ([], []))
    chosen, chosen_params = res.chosen, res.chosen_params
    choice = choice_text(res.method, rows, cfg, res.sweep.pareto_keys, res.chosen)
    if ties:
        # the prediction cannot rank these: none is chosen on the objective; the exported one
        # is the tied design that needs the least material
        group = [res.chosen] + [r for r in rows if r["key"] in ties]
        chosen = min(group, key=lambda r: (r.get("printed_volume_mm3") or float("inf"), r["key"]))
        chosen_params = {d.name: chosen[f"param.{d.name}"] for d in cfg.dimensions}
        from designlab.sensors.labels import metric_label

        objs = ", ".join(metric_label(o) for o in cfg.objectives)
        choice = (f"{choice} But {len(group)} designs are not distinguishable by {objs} "
                  "(differences within the mesh error bars on every objective): none "
                  "is chosen on them; exported the one with the least printed volume "
                  f"({chosen.get('printed_volume_mm3', float('nan')):.4g} mm^3)")
    if unknown:
        choice = (f"{choice} {len(unknown)} other design(s) have no error bar on an objective "
                  "(unknown, not zero): whether they differ from the chosen one is not known")
    return chosen, chosen_params, choice, ties, unknown


@app.command()
def optimize(ctx: typer.Context,
             config: Path = typer.Argument(..., help="Sweep config (TOML) with objectives."),
             out: Path = typer.Option(..., "--out", help="Output directory."),
             method: str = typer.Option("auto", "--method", help="auto | surrogate | de | pareto, "
                                        "or an Optuna sampler: tpe | nsga2 | gp | grid | random | qmc "
                                        "(the study in OUT/study.log, resumed when run again)"),
             maxiter: int = typer.Option(10, "--maxiter", help="Differential-evolution generations (method de)."),
             trials: Optional[int] = typer.Option(None, "--trials", help="Finished trials of an "
                                                  "Optuna study (default: the config's samples)."),
             scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler tcp://HOST:PORT."),
             workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes."),
             formats: str = typer.Option("stl,3mf,step", "--format", help="Export formats of the chosen design."),
             overwrite: bool = typer.Option(False, "--overwrite", help="Replace another run's "
                                            "results in --out (its design rows; the caches stay).")):
    """Optimise a design (surrogate/DE, or Pareto for several objectives) and export the winner."""
    from designlab.geometry.export import parse_formats
    from designlab.optimize.optimizer import check_method as check_optimize_method
    from designlab.optimize.report import write_report
    from designlab.optimize.robust import band_lines, load_sweep

    from designlab.optimize.study import SAMPLERS, MAX_TRIALS, check_method

    check_out(out)
    check_options(("--workers", workers, 1, 512), ("--maxiter", maxiter, 1, 1000),
                  ("--trials", trials, 1, MAX_TRIALS))
    if method not in METHODS + SAMPLERS:
        raise ParameterError("--method", method, "one of " + ", ".join(METHODS + SAMPLERS)
                             + did_you_mean(method, METHODS + SAMPLERS))
    parse_formats(formats)
    cfg, evaluator = load_sweep(config)      # [uncertainty]: robust (Monte Carlo per design)
    if method in SAMPLERS:
        check_method(method, cfg)
    else:
        check_optimize_method(method, cfg)
    executor = make_executor(scheduler, workers)
    start_sweep_run(ctx, out, "optimize", config, cfg, overwrite, evaluator)
    try:
        # results.parquet, optimize.json and the report: all or none (a failed export of the
        # chosen design or a full disk leaves the previous ones)
        with FileSet() as outputs:
            res = _run_optimize(cfg, out, method, trials, maxiter, executor, evaluator, outputs)
            rows = list({r["key"]: r for r in [*res.sweep.rows, res.chosen]}.values())
            chosen, chosen_params, choice, ties, unknown = _choose(res, rows, cfg)
            _summary_table(res.sweep.rows, cfg, res.sweep.pareto_keys, chosen["key"],
                           tie_keys=ties)
            for line in band_lines(rows, cfg, [chosen["key"]], limit=1):
                console.print("Monte Carlo band of the chosen design " + line,
                              highlight=False, markup=False)
            design_dir = out / "chosen"
            files = _export_chosen(cfg, {**cfg.fixed, **chosen_params}, design_dir, formats,
                                   fem_cache=out / "fem")
            summary = {"method": res.method, "chosen_params": chosen_params, "chosen": chosen,
                       "choice": choice, "not_distinguishable": ties,
                       "error_bar_unknown": unknown, "surrogate": res.surrogate,
                       "files": [str(f) for f in files]}
            outputs.write_json(out / "optimize.json", summary)
            write_report(out, res.sweep.rows, cfg, res.sweep.pareto_keys, chosen["key"],
                         title=f"designlab optimize: {config.name}", tie_keys=ties,
                         choice=choice, chosen_dir=design_dir, kind="optimize",
                         uncertainty=getattr(evaluator, "spec", None), files=outputs)
    except KeyboardInterrupt:
        raise _interrupted()
    console.print(choice, highlight=False, markup=False)
    console.print("exported: " + ", ".join(f"{k}={v:.4g}" for k, v in chosen_params.items()),
                  highlight=False, markup=False)
    console.print(f"exported {len(files)} files to {design_dir}", markup=False, highlight=False)
    next_step(f"open next: {out / 'report.html'} (the report), {design_dir} (files to "
              "print)")


def _run_optimize(cfg, out: Path, method: str, trials, maxiter: int, executor, evaluator, files):
    """The optimizer's result: an Optuna study (``method`` a sampler) or the sweep with the
    optimizer of ``method``; ``results.parquet`` staged in ``files``."""
    from designlab.optimize.optimizer import optimize as run_optimize
    from designlab.optimize.study import SAMPLERS

    if method in SAMPLERS:
        return _run_study(cfg, out, method, trials or cfg.samples, executor, evaluator, files)
    with progress_bar("designs", len(cfg.designs()), transient=False) as bar:
        return run_optimize(cfg, out, method=method, executor=executor,
                            progress=_sweep_callback(bar), maxiter=maxiter,
                            evaluator=evaluator, files=files)


def _run_study(cfg, out: Path, method: str, trials: int, executor, evaluator, files=None):
    """An Optuna study of ``trials`` finished trials in ``out`` (resumed when it exists), as
    the optimizer's result: its designs, their Pareto set and the best one."""
    from designlab.optimize.optimizer import OptimizeResult, _params
    from designlab.optimize.study import run_study

    with progress_bar("trials", trials, transient=False) as bar:
        st = run_study(cfg, out, method, trials=trials, executor=executor,
                       evaluator=evaluator, progress=_sweep_callback(bar), files=files)
    if st.sweep.best_key is None:
        raise ParameterError("constraints", cfg.constraints,
                             "constraints that at least one design of the study satisfies")
    chosen = next(r for r in st.sweep.rows if r["key"] == st.sweep.best_key)
    console.print(f"Optuna study ({method}): {st.trials} trials, {st.sweep.new} designs "
                  f"evaluated in this run, the study in {st.storage} (optuna-dashboard opens it)",
                  highlight=False, markup=False)
    return OptimizeResult(method, st.sweep, chosen, _params(chosen, cfg.dimensions), st.info)


def _up_to_date(design_dir: Path, key: dict) -> Optional[list]:
    """The files of ``design_dir`` when its ``run.json`` says it holds the design ``key``
    names and every file listed there is still present (None otherwise)."""
    prev = read_run(design_dir)
    if prev is None or prev.get("what") != "optimize chosen design" \
            or prev.get("settings") != key:
        return None
    files = [design_dir / f for f in prev.get("files", [])]
    return files if files and all(f.is_file() for f in files) else None


def _export_chosen(cfg, params: dict, design_dir: Path, formats: str, fem_cache: Path) -> list:
    """Export and predict the chosen design into ``design_dir``, unless its ``run.json`` says it
    already holds this design with these settings, protocol and formats (every file listed
    there still present): a cached optimize does not export and predict again."""
    from designlab.optimize.evaluate import export_design
    from designlab.predict.record import run_manifest

    what = {"part": cfg.part, "params": params, "formats": formats,
            "settings": cfg.settings, "protocol": cfg.protocol}
    key = json.loads(json.dumps(jsonable(what), sort_keys=True, default=repr))
    files = _up_to_date(design_dir, key)
    if files is not None:
        console.print(f"the chosen design in {design_dir} is up to date (same design, "
                      "settings and formats): not exported again", markup=False,
                      highlight=False, soft_wrap=True)
        return files
    (design_dir / "run.json").unlink(missing_ok=True)
    with progress_bar(f"exporting the chosen design to {design_dir}"):
        files = export_design(cfg.part, params, design_dir, formats=formats,
                              settings=cfg.settings, protocol=cfg.protocol, fem_cache=fem_cache)
    doc_files = [Path(f).resolve().relative_to(design_dir.resolve()).as_posix() for f in files]
    atomic_write_json(design_dir / "run.json",
                      {**run_manifest("optimize chosen design", key), "files": doc_files})
    return files
