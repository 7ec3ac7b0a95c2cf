"""The ``designlab`` command line (typer + rich).

Every command is a thin wrapper over library functions. A :class:`DesignlabError` becomes one
line on stderr and exit code 2 (no traceback, nothing half-written).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console

from designlab.version import __version__
from designlab.errors import DesignlabError

app = typer.Typer(add_completion=True, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Design, predict and learn 3D-printed force sensors (units: mm, N, MPa, s).")
console = Console()
err_console = Console(stderr=True)

def _print_version(value: bool) -> None:
    if value:
        console.print(f"designlab {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the version and exit.")):
    """designlab: parametric sensors -> mesh -> FEM -> virtual tests -> sweeps -> measured loop."""


def _sensor_names(incomplete: str = "") -> list[str]:
    """Completion choices of a PART argument: the names in ``SENSORS``."""
    from designlab.sensors.registry import SENSORS

    return [n for n in SENSORS if n.startswith(incomplete)]


def _export_names(incomplete: str = "") -> list[str]:
    return [n for n in (*_sensor_names(), "all") if n.startswith(incomplete)]


class Bar:
    """Handle of :func:`progress_bar`: ``bar(description=..., completed=..., total=...,
    advance=...)`` updates it; ``bar.print(...)`` prints above it; ``bar.stop()`` ends it."""

    def __init__(self, prog, task):
        self._prog, self._task = prog, task

    def __call__(self, description: str | None = None, **fields) -> None:
        from rich.markup import escape

        if description is not None:
            fields["description"] = escape(description)
        self._prog.update(self._task, **fields)

    def print(self, *args, **kw) -> None:
        self._prog.console.print(*args, **kw)

    def stop(self) -> None:
        self._prog.stop()


@contextlib.contextmanager
def progress_bar(description: str, total: float | None = None, *, transient: bool = True):
    """The CLI's one progress display: what runs, a bar, done/total, elapsed time and ETA
    (a pulsing bar while the total is unknown). Yields a :class:`Bar`."""
    from rich.markup import escape
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn,
                               TextColumn, TimeElapsedColumn, TimeRemainingColumn)

    prog = Progress(SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
                    MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                    TimeRemainingColumn(), console=console, transient=transient)
    with prog:
        yield Bar(prog, prog.add_task(escape(description), total=total))


def _sweep_callback(bar: Bar):
    """Sweep/optimize progress: designs done of the total, failures printed as they happen."""

    def callback(done: int, total: int | None, row: dict) -> None:
        bar(completed=done, **({"total": total} if total is not None else {}))
        if row.get("status") == "error":
            bar.print(_plain(("design " + row["key"][:8] + " failed:", "yellow"), " ",
                             _one_line(row["error"])), highlight=False)

    return callback


def _executor(scheduler: Optional[str], workers: Optional[int]):
    from designlab.optimize.executors import DaskExecutor, LocalExecutor

    if scheduler:
        if not scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
            from designlab.errors import ParameterError

            raise ParameterError("--scheduler", scheduler, "a Dask address like tcp://HOST:PORT")
        return DaskExecutor(scheduler)
    return LocalExecutor(workers)


def _start_sweep_run(ctx, out: Path, what: str, config: Path, cfg, overwrite: bool,
                     evaluator=None) -> None:
    """Refuse (or, with ``--overwrite``, clear) an ``--out`` holding another config's run, then
    write ``run.json`` first: a killed run's folder still says which config it resumes."""
    from designlab.atomic import out_lock

    identity = _config_identity(cfg, getattr(evaluator, "spec", None))
    if not overwrite:
        _check_reuse(out, what, identity, overwrite=False)
    # the folder's one writer from here to the end of the command (the sweep under it shares
    # the lock): --overwrite never removes the rows of a run still writing them
    ctx.with_resource(out_lock(out, f"designlab {what}"))
    _check_reuse(out, what, identity, overwrite)
    out.mkdir(parents=True, exist_ok=True)
    _write_run(out, what, {"config": str(config), "config_sha256_16": identity,
                           "part": cfg.part, "method": cfg.method,
                           "settings": cfg.settings, "protocol": cfg.protocol}, identity)


def _summary_table(rows, config, pareto_keys, best_key, limit: int = 20, tie_keys=()):
    from rich.table import Table

    from designlab.optimize.sweep import error_bar

    t = Table(title=f"{config.part} sweep: {len(rows)} designs "
                    f"({sum(r.get('status') == 'ok' for r in rows)} ok)")
    dims = [d.name for d in config.dimensions]
    objs = list(config.objectives)
    from rich.markup import escape

    for c in ["", *dims, *(x for o in objs for x in (o, "+-")), "feasible", "s"]:
        t.add_column(escape(c), justify="right")
    def fmt(v):  # user text (choice values) printed literally
        return f"{v:.4g}" if isinstance(v, float) else ("" if v is None else escape(str(v)))
    for r in rows[:limit]:
        mark = ("*" if r["key"] == best_key else "~" if r["key"] in tie_keys
                else "P" if r["key"] in pareto_keys else "")
        if r.get("status") != "ok":
            mark = "x"
        vals = [x for o in objs for x in (fmt(r.get(o)), fmt(error_bar(r, o, config)))]
        t.add_row(mark, *[fmt(r.get(f"param.{d}")) for d in dims], *vals,
                  "yes" if r.get("feasible") else "no", fmt(r.get("elapsed_s")))
    if len(rows) > limit:
        t.caption = f"first {limit} of {len(rows)} designs; all in results.parquet / report.html"
    console.print(t)
    console.print("* chosen design, ~ not distinguishable from it (difference within the mesh "
                  "error bars), P Pareto set, x failed; +- the discretisation error bar (value "
                  "minus the value on one coarser mesh)", highlight=False, markup=False)


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

    _check_out(out)
    _check_options(("--workers", workers, 1, 512))
    cfg, evaluator = load_sweep(config)      # [uncertainty]: robust (Monte Carlo per design)
    executor = _executor(scheduler, workers)
    _start_sweep_run(ctx, out, "sweep", config, cfg, overwrite, evaluator)
    try:
        with progress_bar("designs", len(cfg.designs()), transient=False) as bar:
            res = run_sweep(cfg, out, executor=executor, progress=_sweep_callback(bar),
                            retry_failed=retry_failed, evaluator=evaluator)
    except KeyboardInterrupt:
        err_console.print("interrupted: finished designs are stored; run the same command to resume")
        raise typer.Exit(130)
    write_report(out, res.rows, cfg, res.pareto_keys, res.best_key,
                 title=f"designlab sweep: {config.name}", tie_keys=res.tie_keys, kind="sweep",
                 uncertainty=getattr(evaluator, "spec", None))
    _summary_table(res.rows, cfg, res.pareto_keys, res.best_key, tie_keys=res.tie_keys)
    for line in band_lines(res.rows, cfg, [res.best_key] if res.best_key else None):
        console.print("Monte Carlo band " + line, highlight=False, markup=False)
    if res.tie_keys:
        console.print(f"{len(res.tie_keys) + 1} designs are not distinguishable: their "
                      "differences are within the mesh error bars on every objective",
                      highlight=False, markup=False)
    for w in res.warnings:
        err_console.print(_plain(("warning:", "yellow"), " ", w), highlight=False)
    console.print(f"{res.new} evaluated, {res.reused} from the store, {res.failed} failed -> "
                  f"{res.table_path}, {out / 'report.html'}", markup=False, highlight=False)
    _next(f"open next: {out / 'report.html'} (the report), then designlab optimize "
          f"{config} --out {out} to export the best design")


@app.command()
def optimize(ctx: typer.Context,
             config: Path = typer.Argument(..., help="Sweep config (TOML) with objectives."),
             out: Path = typer.Option(..., "--out", help="Output directory."),
             method: str = typer.Option("auto", "--method", help="auto | surrogate | de | pareto"),
             maxiter: int = typer.Option(10, "--maxiter", help="Differential-evolution generations (method de)."),
             scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler tcp://HOST:PORT."),
             workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes."),
             formats: str = typer.Option("stl,3mf,step", "--format", help="Export formats of the chosen design."),
             overwrite: bool = typer.Option(False, "--overwrite", help="Replace another run's "
                                            "results in --out (its design rows; the caches stay).")):
    """Optimise a design (surrogate/DE, or Pareto for several objectives) and export the winner."""
    from designlab.optimize.optimizer import optimize as run_optimize
    from designlab.optimize.report import write_report
    from designlab.optimize.robust import band_lines, load_sweep
    from designlab.atomic import atomic_write_json

    from designlab.errors import ParameterError
    from designlab.geometry.export import parse_formats
    from designlab.params import did_you_mean

    _check_out(out)
    _check_options(("--workers", workers, 1, 512), ("--maxiter", maxiter, 1, 1000))
    if method not in ("auto", "surrogate", "de", "pareto"):
        raise ParameterError("--method", method, "one of auto, surrogate, de, pareto"
                             + did_you_mean(method, ("auto", "surrogate", "de", "pareto")))
    parse_formats(formats)
    cfg, evaluator = load_sweep(config)      # [uncertainty]: robust (Monte Carlo per design)
    executor = _executor(scheduler, workers)
    _start_sweep_run(ctx, out, "optimize", config, cfg, overwrite, evaluator)
    try:
        with progress_bar("designs", len(cfg.designs()), transient=False) as bar:
            res = run_optimize(cfg, out, method=method, executor=executor,
                               progress=_sweep_callback(bar), maxiter=maxiter,
                               evaluator=evaluator)
    except KeyboardInterrupt:
        err_console.print("interrupted: finished designs are stored; run the same command to resume")
        raise typer.Exit(130)
    from designlab.optimize.sweep import compare_to_best

    rows = list({r["key"]: r for r in [*res.sweep.rows, res.chosen]}.values())
    ties, unknown = (compare_to_best(rows, cfg, res.chosen["key"]) if cfg.objectives
                     else ([], []))
    from designlab.optimize.report import choice_text

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
    _summary_table(res.sweep.rows, cfg, res.sweep.pareto_keys, chosen["key"], tie_keys=ties)
    for line in band_lines(rows, cfg, [chosen["key"]], limit=1):
        console.print("Monte Carlo band of the chosen design " + line, highlight=False,
                      markup=False)
    design_dir = out / "chosen"
    files = _export_chosen(cfg, {**cfg.fixed, **chosen_params}, design_dir, formats,
                           fem_cache=out / "fem")
    summary = {"method": res.method, "chosen_params": chosen_params, "chosen": chosen,
               "choice": choice, "not_distinguishable": ties, "error_bar_unknown": unknown,
               "surrogate": res.surrogate, "files": [str(f) for f in files]}
    atomic_write_json(out / "optimize.json", summary)
    write_report(out, res.sweep.rows, cfg, res.sweep.pareto_keys, chosen["key"],
                 title=f"designlab optimize: {config.name}", tie_keys=ties, choice=choice,
                 chosen_dir=design_dir, kind="optimize",
                 uncertainty=getattr(evaluator, "spec", None))
    console.print(choice, highlight=False, markup=False)
    console.print("exported: " + ", ".join(f"{k}={v:.4g}" for k, v in chosen_params.items()),
                  highlight=False, markup=False)
    console.print(f"exported {len(files)} files to {design_dir}", markup=False, highlight=False)
    _next(f"open next: {out / 'report.html'} (the report), {design_dir} (files to "
          "print)")


def _export_chosen(cfg, params: dict, design_dir: Path, formats: str, fem_cache: Path) -> list:
    """Export and predict the chosen design into ``design_dir``, unless its ``run.json`` says it
    already holds this design with these settings, protocol and formats (every file listed
    there still present): a cached optimize does not export and predict again."""
    import json

    from designlab.atomic import jsonable
    from designlab.optimize.evaluate import export_design

    what = {"part": cfg.part, "params": params, "formats": formats,
            "settings": cfg.settings, "protocol": cfg.protocol}
    key = json.loads(json.dumps(jsonable(what), sort_keys=True, default=repr))
    prev = _read_run(design_dir)
    if prev is not None and prev.get("what") == "optimize chosen design" \
            and prev.get("settings") == key:
        files = [design_dir / f for f in prev.get("files", [])]
        if files and all(f.is_file() for f in files):
            console.print(f"the chosen design in {design_dir} is up to date (same design, "
                          "settings and formats): not exported again", markup=False,
                          highlight=False, soft_wrap=True)
            return files
    (design_dir / "run.json").unlink(missing_ok=True)
    with progress_bar(f"exporting the chosen design to {design_dir}"):
        files = export_design(cfg.part, params, design_dir, formats=formats,
                              settings=cfg.settings, protocol=cfg.protocol, fem_cache=fem_cache)
    doc_files = [Path(f).resolve().relative_to(design_dir.resolve()).as_posix() for f in files]
    from designlab.atomic import atomic_write_json
    from designlab.predict.run import run_manifest

    atomic_write_json(design_dir / "run.json",
                      {**run_manifest("optimize chosen design", key), "files": doc_files})
    return files


@app.command()
def flexure(preset: str = typer.Option("visiflex-catalog", "--preset",
                                       help="Spring preset: visiflex-catalog (default: wire diameter 2.03 mm, "
                                            "1.75 active turns, the spring `predict flexure` builds) or "
                                            "visiflex (seed 002 as printed)."),
            set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                     help="Override a spring parameter (mm, rad, MPa)."),
            frame: str = typer.Option("camera", "--frame", help="spring (centre of the spring) or camera."),
            json_out: Optional[Path] = typer.Option(None, "--json", help="Write all matrices as JSON (SI)."),
            fem: bool = typer.Option(False, "--fem/--no-fem",
                                     help="Also mesh and solve the solid helix with coil and seat "
                                          "contact (minutes; the beam chain always runs)."),
            seat: str = typer.Option("bonded", "--seat",
                                     help="Beam chain ends: bonded (ground faces epoxied), "
                                          "contact (seated, wire end bonded) or potted (dead turn in epoxy)."),
            working_load: float = typer.Option(10.0, "--working-load",
                                               help="Axial load of the second linearisation, N (0: none)."),
            mu: float = typer.Option(0.0, "--mu",
                                     help="Coulomb friction at the beam chain's coil and seat contacts "
                                          "(0: frictionless, the default; 0.3: dry steel on steel). With "
                                          "friction the 6x6 is a secant of +-0.02 mm / 2 mrad perturbations."),
            edge_length: Optional[float] = typer.Option(None, "--edge-length",
                                                        help="FEM tet edge length, mm (default: wire radius)."),
            curved: Optional[bool] = typer.Option(None, "--curved/--straight",
                                                  help="With --fem: TET10 mid-edge nodes on the wire's surface "
                                                       "(the default: the round section not faceted, no-contact "
                                                       "6x6 converged, 6.9 % stiffer than --straight; ~0.5 s of "
                                                       "projection, docs/flexure.md)."),
            paper_json: Optional[Path] = typer.Option(None, "--paper-json",
                                                      help="Seed 002 paper data (JSON; default: the copy packaged with designlab, "
                                                           "designlab/data/papers/visiflex_flexure.json, the same file as "
                                                           "shared/data/papers/, which is read first when present).")):
    """Seed 002 spring flexure 6x6 stiffness: closed form, beam chain, solid FEM (--fem), paper theory and measurement (SI)."""
    from designlab.sensors.flexure import report as fr
    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.spring import preset as spring_preset
    from designlab.params import did_you_mean, parse_sets, with_overrides

    if frame not in fr.FRAMES:
        from designlab.errors import ParameterError
        raise ParameterError("--frame", frame, "one of " + ", ".join(fr.FRAMES)
                             + did_you_mean(frame, fr.FRAMES))
    spring = with_overrides(spring_preset(preset), parse_sets(set_))
    paper = fr.load_paper(paper_json)
    if not 0 <= mu <= 2:
        from designlab.errors import ParameterError
        raise ParameterError("--mu", mu, "a friction coefficient 0 <= mu <= 2")
    if curved is not None and not fem:
        from designlab.errors import ParameterError
        raise ParameterError("--curved" if curved else "--straight", True,
                             "only with --fem (the solid FEM's mesh)")
    if mu > 0:
        from designlab.sensors.flexure.chain_friction import friction_stiffness

        chain = friction_stiffness(spring, ChainSettings(seat=seat, working_load_N=working_load),
                                   mu=mu)
    else:
        chain = chain_stiffness(spring, ChainSettings(seat=seat, working_load_N=working_load))
    K_fem = K_fem_loaded = None
    fem_info = None
    if fem:
        from designlab.sensors.flexure.contact_fem import fem_contact_stiffness
        from designlab.sensors.flexure.helix_fem import CURVED_DEFAULT

        with progress_bar("FEM 6x6") as bar:
            def step(text: str, done: int, total: int) -> None:
                bar(f"FEM: {text}", completed=done, total=total)

            sol = fem_contact_stiffness(spring, edge_length=edge_length, progress=step,
                                        settings=ChainSettings(seat="bonded",
                                                               working_load_N=working_load),
                                        curved=CURVED_DEFAULT if curved is None else curved)
        K_fem = sol.centre_si("unloaded")
        K_fem_loaded = sol.centre_si("loaded") if sol.K_loaded is not None else None
        fem_info = dict(sol.info, K_free_centre_si=sol.centre_si("free").tolist())
    report = fr.flexure_report(spring, frame=frame, K_fem_spring_si=K_fem, paper=paper,
                               K_chain_spring_si=chain.K_centre_si,
                               K_chain_loaded_si=chain.K_loaded_centre_si,
                               K_fem_loaded_si=K_fem_loaded)
    report["fem_info"] = fem_info
    report["chain_info"] = chain.info
    for table in fr.report_tables(report):
        console.print(table)
    r = report["ratios"]
    console.print("ratios (closed form vs paper theory): " + ", ".join(
        f"{k} {r['closed_form'][k]:.4g} vs {r['paper_theory'][k]:.4g} ({v:+.2f} %)"
        for k, v in r["closed_form_vs_paper_pct"].items()), highlight=False)
    ci = chain.info
    if mu > 0:
        console.print(f"chain with friction mu {ci['mu']:g}: {ci['contacts']} contact points, "
                      f"secant of +-{ci['amplitude_mm_rad'][0]:g} mm / "
                      f"{1e3 * ci['amplitude_mm_rad'][1]:g} mrad, asymmetry "
                      f"{ci['asymmetry']:.2e}, {ci['seconds']:.2f} s", highlight=False)
    else:
        console.print(f"chain: {ci['geometry']}; {ci['elements']} beams, {ci['contacts']} "
                      f"contact points, {ci['seconds']:.2f} s", highlight=False)
    if fem_info is not None:
        console.print(f"FEM: {fem_info['n_nodes']} nodes, {fem_info['n_cells']} TET{fem_info['cell_nodes']}"
                      f", {fem_info['coil_pairs']} coil + {fem_info['seat_contacts']} seat contacts "
                      f"(frictionless, {fem_info['gaps']} gaps), condensed "
                      f"asymmetry {fem_info['asymmetry']:.2e}, {fem_info['timings_s']['total']:.0f} s",
                      highlight=False)
    for note in report["notes"]:
        console.print(_plain(("note:", "bold"), " ", note), highlight=False)
    from designlab.sensors.flexure.stress import stress_table, wire_stress

    report["stress"] = wire_stress(spring, chain_settings=ChainSettings(seat=seat))
    console.print(stress_table(report["stress"]))
    for w in report["stress"]["warnings"]:
        err_console.print(_plain(("warning:", "yellow"), " ", w), highlight=False)
    if json_out is not None:
        fr.write_json(json_out, report)
        console.print(f"wrote {json_out}", highlight=False, markup=False)
        _next(f"open next: {json_out} (every matrix, SI units); designlab predict "
              "flexure --out OUT (its virtual test and report)")
    else:
        _next("open next: designlab flexure --json FILE (every matrix, SI units), or "
              "designlab predict flexure --out OUT (its virtual test and report)")


def _parts_from_cli(part: str, set_: Optional[List[str]], config: Optional[Path]):
    from designlab.geometry.export import resolve_parts
    from designlab.params import load_toml, parse_sets

    overrides = parse_sets(set_)
    cfg = _part_config(part, load_toml(config)) if config is not None else None
    return resolve_parts(part, overrides, cfg)


@app.command()
def export(part: str = typer.Argument(..., help="strap | fingertip | flexure | all", autocompletion=_export_names),
           out: Path = typer.Option(..., "--out", help="Output directory (one folder per part)."),
           set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                    help="Override a part parameter (mm); with 'all' "
                                                         "write PART.NAME=VALUE."),
           config: Optional[Path] = typer.Option(None, "--config", help="Part parameters (TOML)."),
           formats: str = typer.Option("stl,3mf,step,gltf", "--format",
                                       help="Comma-separated: stl (per body), 3mf (one object, "
                                            "one volume per body/extruder), step, gltf."),
           png: bool = typer.Option(True, "--png/--no-png", help="Also render <part>.png."),
           nozzle: float = typer.Option(0.4, "--nozzle", help="Nozzle diameter for the wall check, mm."),
           layer: float = typer.Option(0.1, "--layer-height", help="Layer height for the skin check, mm."),
           overwrite: bool = typer.Option(False, "--overwrite", help="Write into an --out that "
                                          "holds another command's run (same-named files are "
                                          "replaced).")):
    """Check printability, then write STL/3MF/STEP/glTF (+PNG) of a part or of all parts."""
    from designlab.errors import ParameterError
    from designlab.geometry.export import export_parts, parse_formats
    from designlab.geometry.printability import PrintabilityError, reports_table

    _check_out(out)
    fmts = parse_formats(formats)
    for name, v, lo, hi in (("--nozzle", nozzle, 0.05, 2.0), ("--layer-height", layer, 0.01, 1.0)):
        if not lo <= v <= hi:
            raise ParameterError(name, v, f"{lo:g} <= value <= {hi:g} mm")
    parts = _parts_from_cli(part, set_, config)
    _check_out(out, f"export {part}", overwrite=overwrite)
    with progress_bar("export", 2 * len(parts)) as bar:
        def step(text: str, done: int, total: int) -> None:
            bar(text, completed=done, total=total)

        try:
            res = export_parts(parts, out, fmts, png=png, nozzle=nozzle, layer=layer, progress=step)
        except PrintabilityError as exc:
            bar.stop()
            err_console.print(reports_table(exc.reports))
            raise
    import dataclasses

    run = _write_run(out, f"export {part}", {
        "formats": formats, "nozzle_mm": nozzle, "layer_height_mm": layer,
        "parts": {n: {f.name: getattr(o, f.name) for f in dataclasses.fields(o)}
                  for n, o in parts.items()}})
    console.print(reports_table(res.reports))
    for f in [*res.files, run]:
        console.print(f"wrote {f}", highlight=False, markup=False)
    _next(_open_next_export(res.files))


def _open_next_export(files) -> str:
    """The export's next step: the 3MF (or the STLs) into the slicer, the render to look at."""
    files = [Path(f) for f in files]
    by = {suf: [f for f in files if f.suffix.lower() == suf] for suf in (".3mf", ".stl", ".png")}
    slicer = by[".3mf"] or by[".stl"]
    what = []
    if slicer:
        what.append(", ".join(map(str, slicer[:3])) + (" ..." if len(slicer) > 3 else "")
                    + " (into the slicer" + (": one object, a volume per body and extruder)"
                                             if by[".3mf"] else ")"))
    if by[".png"]:
        what.append(", ".join(map(str, by[".png"][:3])) + " (renders)")
    return "open next: " + ("; ".join(what) if what else str(files[0].parent if files else ""))


@app.command()
def show(part: str = typer.Argument(..., help="strap | fingertip | flexure", autocompletion=_sensor_names),
         out: Path = typer.Option(..., "--out", help="PNG file to write."),
         set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                  help="Override a part parameter (mm)."),
         config: Optional[Path] = typer.Option(None, "--config", help="Part parameters (TOML)."),
         width: int = typer.Option(1200, "--width", help="Image width, px."),
         height: int = typer.Option(900, "--height", help="Image height, px.")):
    """Render a part (bodies in colour, bought parts see-through) to a PNG."""
    from designlab.errors import ParameterError
    from designlab.geometry.export import write_png

    if part == "all":
        raise ParameterError("part", part, "a single part: " + ", ".join(_sensor_names()))
    if out.suffix.lower() != ".png":
        raise ParameterError("--out", str(out), "a file name ending in .png")
    for name, v in (("--width", width), ("--height", height)):
        if not 64 <= v <= 8000:
            raise ParameterError(name, v, "64 <= value <= 8000 px")
    (name, obj), = _parts_from_cli(part, set_, config).items()
    path = write_png(obj.build(), out, title=name, size=(width, height))
    console.print(f"wrote {path}", highlight=False, markup=False)
    _next(f"open next: {path} (the render); designlab params {name} (what each "
          f"parameter means), designlab predict {name} --out OUT (its virtual test)")


def _names(values: Optional[List[str]]) -> list[str]:
    """Repeated and/or comma-separated option values -> a flat list of names."""
    return [v.strip() for item in values or [] for v in item.split(",") if v.strip()]


@app.command()
def compensate(model: Optional[List[str]] = typer.Option(
                   None, "--model", help="linear, mpl, narx (repeat or comma-separate; default: all)."),
               data: Optional[Path] = typer.Option(None, "--data", help="Dataset card (TOML); its "
                                                   "file roles/split give train and validation."),
               train: Optional[List[Path]] = typer.Option(None, "--train", help="Training CSV/Parquet "
                                                          "with a header (repeat for several)."),
               validate: Optional[List[Path]] = typer.Option(None, "--validate",
                                                             help="Validation CSV/Parquet (repeatable)."),
               input_: List[str] = typer.Option(..., "--input", help="Sensor signal column(s)/channel(s), "
                                                "e.g. Ch1,Ch2 or resistance."),
               output: List[str] = typer.Option(..., "--output", help="Reference column(s)/channel(s), "
                                                "e.g. Fn,Fx or force."),
               time_col: Optional[str] = typer.Option(None, "--time", help="Time column (s) of the "
                                                      "CSV/Parquet files."),
               dt: Optional[float] = typer.Option(None, "--dt", help="Sample period (s) of the files."),
               out: Path = typer.Option(..., "--out", help="Output directory (compensation.json, .png)."),
               cells: int = typer.Option(0, "--cells", help="mPL cells (0: add while held-out error improves)."),
               order: int = typer.Option(5, "--order", help="mPL output polynomial degree."),
               update: str = typer.Option("exact", "--update", help="mPL time update: exact or euler."),
               narx_delays: int = typer.Option(50, "--narx-delays", help="NARX input delays."),
               narx_output_delays: int = typer.Option(0, "--narx-output-delays", help="NARX fed-back "
                                                      "output delays (0: seed 000 input-output net)."),
               mix: str = typer.Option("auto", "--mix", help="Channel per output: auto (sum/diff for 2->2), "
                                       "full, identity, sum-diff."),
               segments: int = typer.Option(10, "--segments", help="Segments per record for Wilcoxon pairs."),
               seed: int = typer.Option(0, "--seed")):
    """Seed 000 compensation: fit linear / mPL / NARX on the training task(s), validate on the others
    (RMSE in the reference unit, NCC at zero lag, Wilcoxon between models and tasks)."""
    from rich.table import Table

    from designlab.measured import compensation as comp
    from designlab.errors import ParameterError

    _check_out(out)
    _check_options(("--dt", dt, 1e-9, 1e6), ("--cells", cells, 0, 1000), ("--order", order, 0, 20),
                   ("--narx-delays", narx_delays, 0, 10000),
                   ("--narx-output-delays", narx_output_delays, 0, 10000),
                   ("--segments", segments, 2, 10000), ("--seed", seed, 0, 2 ** 32 - 1))
    if update not in ("exact", "euler"):
        raise ParameterError("--update", update, "exact or euler")
    models = _names(model) or list(comp.MODELS)
    inputs, outputs = _names(input_), _names(output)
    opts = comp.CompensationOptions(mix=mix, mpl_cells=cells, mpl_order=order, mpl_update=update,
                                    narx_input_delays=narx_delays,
                                    narx_output_delays=narx_output_delays, n_segments=segments,
                                    seed=seed)
    if data is not None:
        if train or validate:
            raise ParameterError("--data", str(data), "either a dataset card or --train/--validate files")
        train_recs, val_recs = comp.records_from_card(data, inputs, outputs)
    else:
        if not train:
            raise ParameterError("--train", None, "at least one training file (or --data CARD)")
        train_recs = [comp.load_record(f, inputs, outputs, time=time_col, dt=dt) for f in train]
        val_recs = [comp.load_record(f, inputs, outputs, time=time_col, dt=dt) for f in validate or []]
    with progress_bar("compensate", len(models) + 1) as bar:
        def step(text: str) -> None:
            bar(text, advance=0 if text.startswith("fitting " + models[0]) else 1)

        result = comp.compare(train_recs, val_recs, models, opts, progress=step)
        bar(completed=len(models) + 1)
    table = Table(title="compensation (RMSE in the reference unit)")
    for col in ("model", "task", "role", "output", "RMSE", "NCC"):
        table.add_column(col, justify="right" if col in ("RMSE", "NCC") else "left")
    from rich.markup import escape

    for m, t, role, o, r, c in result.table():  # task and channel names: user text
        table.add_row(escape(m), escape(t), escape(role), escape(o), f"{r:.4g}", f"{c:.4f}")
    console.print(table)
    for m, f in result.fits.items():
        console.print(f"{m}: fitted in {f['time_s']:.2f} s", highlight=False, markup=False)
    val_names = {r.name for r in val_recs}
    for w in result.between_models:
        if w["task"] in val_names:
            console.print(f"Wilcoxon {w['task']} {w['output']}: {w['a']} vs {w['b']}: p(RMSE) = "
                          f"{w['rmse']['p_value']:.3g}, p(NCC) = {w['ncc']['p_value']:.3g} "
                          f"({segments} segments)", highlight=False, markup=False)
    written = list(comp.write_outputs(result, train_recs + val_recs, out))
    for path in written:
        console.print(f"wrote {path}", markup=False, highlight=False)
    _next("open next: " + ", ".join(
f"{p} ({'validation plots' if Path(p).suffix == '.png' else 'RMSE, NCC, Wilcoxon tables'})"
for p in written))


@app.command("loop")
def loop_cmd(
    data: Path = typer.Option(..., "--data", help="Dataset card (TOML) naming the measured files."),
    base: str = typer.Option("linear", "--base",
                             help="linear | linear:IN1,IN2 | load-arm[:LOAD,ARM[,ANGLE]] | "
                                  "stretch-fem | specimen | stretch-closed | a model .json from "
                                  "predict/loop."),
    out: Path = typer.Option(..., "--out", help="Directory for loop.json, model.json and plots."),
    output: Optional[List[str]] = typer.Option(None, "--output",
                                               help="Output channel(s) to analyse (default: all)."),
    folds: int = typer.Option(10, "--folds", min=3, help="Blocks of the time-series CV."),
    max_effects: int = typer.Option(8, "--max-effects", min=0, help="Stop after this many."),
    n_se: float = typer.Option(2.0, "--n-se", help="Required improvement in standard errors."),
    min_relative: float = typer.Option(0.01, "--min-relative",
                                       help="Required relative improvement (0.01 = 1 %)."),
):
    """Residual -> effect -> better model: add library effects to BASE while they lower the
    cross-validated error; report errors on the validation data."""
    from rich.markup import escape
    from rich.table import Table

    from designlab.measured.dataset import load_card
    from designlab.loop.loop import run_loop
    from designlab.loop.model import load_model
    from designlab.loop.report import write_outputs

    _check_out(out)
    _check_options(("--folds", folds, 3, 1000), ("--max-effects", max_effects, 0, 100),
                   ("--n-se", n_se, 0.0, 100.0), ("--min-relative", min_relative, 0.0, 0.99))
    start = load_model(base) if base.endswith(".json") else base
    ds = load_card(data)
    with progress_bar("loop", 1) as bar:
        def step(o: str, done: int, total: int, what: str) -> None:
            bar(f"{o}: {what}", completed=done, total=max(total, 1))

        result = run_loop(ds, start, outputs=output or None, folds=folds,
                          max_effects=max_effects, n_se=n_se, min_relative=min_relative,
                          progress=step)
    table = Table(title=escape(f"loop on {data.name}: validation RMSE (base {result.report['base']})"))
    for col in ("output", "effect", "parameters", "before", "after"):
        table.add_column(col, justify="right" if col in ("before", "after") else "left")
    for o, rep in result.report["outputs"].items():
        table.add_row(escape(o), "(base)", "", f"{rep['error_before']:.4g}", "",
                      end_section=False)
        for e in rep["effects"]:
            par = ", ".join(f"{k}={_short(v)}" for k, v in e["parameters"].items()
                            if k not in ("base_adjust", "form", "g_unit"))
            table.add_row("", escape(e["key"]), escape(par), f"{e['error_before']:.4g}",
                          f"{e['error_after']:.4g}")
        table.add_row("", "[bold]total", f"unexplained {100 * rep['unexplained_fraction']:.1f} %",
                      f"{rep['error_before']:.4g}", escape(f"{rep['error_after']:.4g} {rep['unit']}"),
                      end_section=True)
    console.print(table)
    for o, rep in result.report["outputs"].items():
        console.print(f"{o}: {rep['verdict']}", highlight=False, markup=False)
    written = list(write_outputs(result, out))
    for path in written:
        console.print(f"wrote {path}", highlight=False, markup=False)
    nxt = [f"{p} (residual plots)" for p in written if Path(p).suffix == ".png"][:2]
    if (out / "model.json").is_file():
        nxt.append(f"designlab predict PART --model {out / 'model.json'} --out OUT (the learned "
                   "effects on a design's prediction)")
    if nxt:
        _next("open next: " + ", ".join(nxt))


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_short(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {_short(x)}" for k, x in v.items()) + "}"
    return str(v)


@app.command()
def verify(reference: Optional[str] = typer.Option(None, "--reference",
                                                   help="Also compare node by node with a reference solver: calculix (needs ccx)."),
           out: Path = typer.Option(Path("verify-out"), "--out", help="Output directory for verify.json."),
           threads: int = typer.Option(1, "--threads", help="Threads of the reference solver (CalculiX).")):
    """Verify the FEM: patch test, K symmetry, rigid-body modes, cantilever vs Timoshenko,
    convergence orders, viscoelastic creep/relaxation vs exact responses [, CalculiX]."""
    from rich.table import Table

    from designlab.fem.verify import default_cases, write_report

    if threads < 1:
        raise DesignlabError(f"--threads={threads} is not allowed: an integer >= 1")
    if reference is not None:
        if reference != "calculix":
            raise DesignlabError(f"--reference={reference!r} is not allowed: calculix")
        from designlab.fem.calculix import ccx_path

        ccx_path()
    groups = default_cases(reference, threads)
    results: list[dict] = []
    with progress_bar("verifying", len(groups)) as bar:
        for title, fn in groups:
            bar(f"verifying: {title}")
            results.extend(fn())
            bar(advance=1)
    table = Table(title="designlab FEM verification")
    for col in ("case", "quantity", "ours", "reference", "error", "tol", ""):
        table.add_column(col, justify="left" if col in ("case", "quantity") else "right",
                         no_wrap=col not in ("case", "quantity"))
    for c in results:
        table.add_row(c["name"], c["quantity"], f"{c['value']:.4g}", f"{c['reference']:.4g}",
                      f"{c['rel_error']:.1e}", f"{c['tolerance']:.0e}",
                      "[green]pass[/]" if c["passed"] else "[bold red]FAIL[/]")
    console.print(table)
    path = write_report(results, out / "verify.json")
    failed = [c for c in results if not c["passed"]]
    console.print(f"{len(results) - len(failed)}/{len(results)} passed -> {path}", markup=False)
    _next(f"open next: {path} (every case with its reference and tolerance)")
    if failed:
        raise SystemExit(1)  # (main() drops typer.Exit codes under standalone_mode=False)


@app.command("mesh")
def mesh_cmd(part: str = typer.Argument(..., help="strap | fingertip | flexure, or a closed "
                                                  "surface FILE.stl (a scan, a part from elsewhere)",
                                         autocompletion=_sensor_names),
             out: Path = typer.Option(..., "--out", help="Output directory (mesh.vtu, mesh.json)."),
             set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                      help="Override a part parameter (mm)."),
             config: Optional[Path] = typer.Option(None, "--config", help="Part parameters (TOML)."),
             order: int = typer.Option(2, "--order", help="1 = TET4, 2 = TET10."),
             edge_length: Optional[float] = typer.Option(None, "--edge-length",
                                                         help="Ideal edge length, mm."),
             quality: str = typer.Option("default", "--mesh-quality", "--quality",
                                         help="coarse | default | fine (edge length x2/x1/x0.7; "
                                              "the mesh_quality setting of predict/sweeps)."),
             refine: bool = typer.Option(True, "--refine/--no-refine",
                                         help="Use the part's local refinement spheres."),
             mesher: str = typer.Option("auto", "--mesher",
                                        help="auto (gmsh from the B-rep, fTetWild if it fails) | "
                                             "gmsh | tetwild.")):
    """Tetrahedral mesh of a part's FEM bodies (gmsh from the B-rep; fTetWild for an STL):
    writes mesh.vtu and mesh.json."""
    from rich.table import Table

    from designlab.errors import ParameterError
    from designlab.geometry.parts import make_part
    from designlab.mesh.meshing import mesh_part_detailed, mesh_stl, save_mesh
    from designlab.params import load_toml, parse_sets

    _check_out(out)
    _check_options(("--order", order, 1, 2), ("--edge-length", edge_length, 1e-3, 1e3))
    if part.lower().endswith(".stl"):
        if set_ or config is not None:
            raise ParameterError("--set/--config", part, "none with an STL (it has no parameters)")
        if not Path(part).is_file():
            raise ParameterError("part", part, "an existing STL file or one of the parts")
        with progress_bar(f"meshing {Path(part).name} (fTetWild)"):
            res = mesh_stl(part, edge_length=edge_length, order=order, quality=quality)
            vtu, js = save_mesh(res, out)
    else:
        obj = make_part(part, parse_sets(set_),
                        _part_config(part, load_toml(config)) if config is not None else None)
        with progress_bar(f"meshing {part}"):
            res = mesh_part_detailed(obj, refine=refine, order=order, edge_length=edge_length,
                                     quality=quality, mesher=mesher)
            vtu, js = save_mesh(res, out)
    rep = res.report()
    table = Table(title=f"{part}: {rep['n_cells']} TET{4 if order == 1 else 10} cells, "
                        f"{rep['n_points']} nodes, {rep['dof']} DOF, {rep['seconds']:.1f} s "
                        f"({rep['mesher']})")
    for col in ("region", "material", "cells", "volume mm^3", "body mm^3", "error %"):
        table.add_column(col, justify="left" if col in ("region", "material") else "right")
    for name, r in rep["regions"].items():
        table.add_row(name, rep["materials"][name], str(r["cells"]), f"{r['volume_mm3']:.4g}",
                      f"{r['body_volume_mm3']:.4g}", f"{r['volume_error_percent']:+.2f}")
    console.print(table)
    q = rep["quality"]
    console.print(f"edge {rep['edge_length_mm']:.3g} mm (mean {q['edge_length_mean']:.3g}), "
                  f"min dihedral {q['min_dihedral_deg']:.1f} deg, radius ratio min "
                  f"{q['radius_ratio_min']:.3f} mean {q['radius_ratio_mean']:.3f}, "
                  f"{q['n_poor']} poor cells", highlight=False)
    console.print("facet sets: " + ", ".join(f"{k} ({v})" for k, v in rep["facet_sets"].items()),
                  highlight=False)
    console.print(f"wrote {vtu}\nwrote {js}", highlight=False, markup=False)
    _next(f"open next: {vtu} (regions as cell data, e.g. in ParaView), {js} (quality "
          "and facet sets)")


@app.command()
def predict(part: str = typer.Argument(..., help="strap | fingertip | flexure", autocompletion=_sensor_names),
            set_: Optional[List[str]] = typer.Option(None, "--set", help="Design parameter NAME=VALUE (repeatable)."),
            config: Optional[Path] = typer.Option(None, "--config", help="TOML with the part's parameters."),
            protocol: Optional[Path] = typer.Option(None, "--protocol", help="Protocol TOML (defaults: the papers')."),
            setting: Optional[List[str]] = typer.Option(None, "--setting", help="Model setting NAME=VALUE, e.g. edge_length=2.5."),
            model: Optional[Path] = typer.Option(None, "--model", help="A loop's model.json: add its learned effects (strap, fingertip, flexure)."),
            measured: Optional[Path] = typer.Option(None, "--measured", help="Measured printed-material data (JSON, docs/formats.md): replaces the stand-ins of the materials it names."),
            out: Path = typer.Option(..., "--out", help="Output directory."),
            samples: Optional[int] = typer.Option(None, "--samples", help="Monte Carlo: N virtual builds with scattered inputs and readout noise (resumable in --out)."),
            uncertainty: Optional[Path] = typer.Option(None, "--uncertainty", help="TOML with an [uncertainty] table (default: the documented distributions)."),
            scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Monte Carlo on a Dask scheduler tcp://HOST:PORT."),
            workers: Optional[int] = typer.Option(None, "--workers", help="Monte Carlo: local worker processes (default: all cores)."),
            overwrite: bool = typer.Option(False, "--overwrite", help="Write into an --out that holds another command's run (same-named files are replaced).")):
    """Virtual test of a design before printing: hysteresis, calibration matrix, condition number, K_f."""
    from rich.table import Table

    from designlab.predict.run import predict_and_write
    from designlab.params import load_toml, parse_sets

    from designlab.sensors.registry import get_sensor

    get_sensor(part)
    _check_out(out, f"predict {part}", overwrite=overwrite)
    overrides = {}
    if config is not None:
        data = _part_config(part, load_toml(config))
        data = {k: v for k, v in data.items() if k != "uncertainty"}
        overrides.update(data.get(part, data))
    overrides.update(parse_sets(set_))
    settings = parse_sets(setting)
    if samples is not None or uncertainty is not None:
        from designlab.errors import ParameterError
        from designlab.optimize.montecarlo import monte_carlo
        from designlab.predict.uncertainty import load_uncertainty, summary_rows

        _check_options(("--workers", workers, 1, 512))
        if model is not None or protocol is not None:
            raise ParameterError("--model/--protocol", str(model or protocol),
                                 "none with --samples (the Monte Carlo runs the paper's calibration)")
        if measured is not None:
            raise ParameterError("--measured", str(measured), "none with --samples (the Monte "
                                 "Carlo scatters the library materials; predict without "
                                 "--samples uses measured ones)")
        spec = load_uncertainty(part, uncertainty if uncertainty is not None else config,
                                samples=samples)
        executor = _executor(scheduler, workers)
        with progress_bar(f"{part}: virtual builds", spec.samples, transient=False) as bar:
            summary = monte_carlo(part, spec, out, params=overrides, settings=settings or None,
                                  executor=executor, progress=lambda d, n: bar(completed=d, total=n))
        t = Table(title=f"{part}: {summary['ok']} builds ({summary['failed']} failed), "
                        f"FEM solves {summary['fem']['solves_this_run']}")
        for col in ("metric", "mean", "5 %", "95 %", "driven by"):
            t.add_column(col, justify="left" if col in ("metric", "driven by") else "right")
        for r in summary_rows(summary):
            t.add_row(*r)
        console.print(t)
        for err, n in summary["failed_errors"].items():
            err_console.print(_plain(("failed:", "yellow"), " ", f"{n} builds: {err}"), highlight=False)
        from designlab.predict.report import write_uncertainty_report

        report = write_uncertainty_report(out, summary, params=overrides, settings=settings or None)
        console.print(f"wrote {out / 'uncertainty.json'}, {report}", markup=False, highlight=False)
        return
    records = None
    if measured is not None:
        from designlab.fem.materials import load_measured

        records = load_measured(measured)
    with progress_bar(f"predict {part}: building") as bar:
        prediction, files = predict_and_write(part, overrides, out=out, protocol_path=protocol,
                                              settings=settings, model_path=model,
                                              measured=records,
                                              progress=lambda s: bar(f"predict {part}: {s}"))
    pred = prediction.metrics
    t = Table(title=f"{part}: virtual test")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    t.add_row("hysteresis % (overall)", f"{prediction.hysteresis_percent:.4g}")
    t.add_row("condition number", f"{prediction.condition_number:.4g}")
    if pred.get("geometric_condition_number") is not None:
        t.add_row("geometric condition number", f"{pred['geometric_condition_number']:.4g}")
    if pred.get("paper_comparison"):
        t.add_row("paper condition number", f"{pred['paper_comparison']['condition_number_paper']:.4g}")
    from designlab.predict.report import force_error_lines

    for name, value in force_error_lines(pred):    # the calibration with the noise budget
        t.add_row(name, value)
    if prediction.K_f is not None:
        import numpy as np

        t.add_row("K_f diagonal (SI)", ", ".join(f"{v:.4g}" for v in np.diag(prediction.K_f)))
    crit = (pred.get("stress") or {}).get("critical")
    if pred.get("stress") is None:
        t.add_row("stress, safety factor", "not computed (this model gives stiffness, no "
                  "stress field)")
    if crit:
        t.add_row("smallest safety factor", f"{crit['safety_factor']:.3g} ({crit['body']}, "
                  f"{crit['material']}, {crit['max_von_mises_MPa']:.3g} MPa von Mises, "
                  f"load case {crit['load_case']})")
    for m, v in ((pred.get("stress") or {}).get("materials") or {}).items():
        if v.get("strength_MPa") is None:
            t.add_row(f"safety factor of {m}", f"not computed ({v.get('source') or 'no documented strength'})")
    wrap = (pred.get("prestrain") or {}).get("stress") or {}
    if wrap.get("critical"):
        w = wrap["critical"]
        t.add_row("wrap prestress safety factor", f"{w['safety_factor']:.3g} ({w['body']}, "
                  f"{w['material']}, {w['max_von_mises_MPa']:.3g} MPa at initial strain "
                  f"{wrap['initial_strain']:.3g})")
    for k, v in prediction.timings_s.items():
        t.add_row(f"time: {k}", f"{v:.2f} s")
    console.print(t)
    if pred.get("paper_comparison"):
        console.print(pred["paper_comparison"]["explanation"], highlight=False)
    for w in prediction.warnings:
        err_console.print(_plain(("warning:", "yellow"), " ", w), highlight=False)
    console.print(f"wrote {len(files)} files to {out}", markup=False, highlight=False)
    vtu = (f", {out / 'deformed.vtu'} (stress and displacement per load case, e.g. in "
           "ParaView)") if (out / "deformed.vtu").is_file() else ""
    _next(f"open next: {out / 'report.html'} (the report){vtu}")


@app.command("fit-strap")
def fit_strap(finger: Optional[str] = typer.Option(None, "--finger", metavar="WIDTH,DEPTH,LENGTH",
                                                   help="Distal phalanx at the strap, mm."),
              scan: Optional[Path] = typer.Option(None, "--scan", help="Fingertip surface (closed STL)."),
              target_strain: Optional[float] = typer.Option(None, "--target-strain",
                                                            help="Initial strain (default: the paper's medium slot on the reference finger)."),
              slots: int = typer.Option(1, "--slots", help="1 (no adjustment), 3 or 5 fine slots."),
              measured: Optional[Path] = typer.Option(None, "--measured", help="Measured printed-material data (JSON, docs/strap.md): replaces the stand-ins it names."),
              out: Path = typer.Option(..., "--out", help="Output directory (fit.json, strap/strap.3mf).")):
    """A strap sized to one finger: parameters for a target initial strain, its predicted
    sensitivity and resolution, the size table vs the paper's three slots, the printable 3MF."""
    from rich.table import Table

    from designlab.errors import ParameterError
    from designlab.sensors.strap import fit as sf
    if (finger is None) == (scan is None):
        raise ParameterError("--finger/--scan", finger or scan, "exactly one of the two")
    fg = sf.parse_finger(finger) if finger is not None else sf.finger_from_scan(scan)
    records = None
    if measured is not None:
        from designlab.fem.materials import load_measured

        records = load_measured(measured)
    with progress_bar("fit-strap") as bar:
        res = sf.fit_strap(fg, out, target_strain=target_strain, slots=slots, measured=records,
                           progress=lambda s: bar(f"fit-strap: {s}"))
    t = Table(title=f"strap for finger {fg.width:g} x {fg.depth:g} x {fg.length:g} mm "
                    f"(perimeter {fg.perimeter:.1f} mm, {fg.perimeter_source})")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    p, pre, el = res["strap_parameters"], res["prestrain"], res["electrical"]
    t.add_row("arch width x height (mm)", f"{p['arch_width']:.4g} x {p['arch_height']:.4g}")
    t.add_row("tab length (mm), slots", f"{p['tab_length']:.4g}, {p['slot_count']}")
    t.add_row("initial strain (target)", f"{pre['initial_strain']:.4g} ({res['target_initial_strain']:.4g})")
    t.add_row("gauge resistance (ohm)", f"{el['resistance_ohm']['total']:.4g}")
    t.add_row("sum F_n sensitivity (mV/N)", f"{1e3 * res['sensitivity_V_per_N']['sum_F_n']:.4g}")
    t.add_row("diff F_x sensitivity (mV/N)", f"{1e3 * res['sensitivity_V_per_N']['diff_F_x']:.4g}")
    t.add_row("resolution F_n / F_x (mN)", f"{res['resolution_mN']['F_n']:.3g} / {res['resolution_mN']['F_x']:.3g}")
    sl = res["paper_slots_on_this_finger"]
    t.add_row("paper slots: strains", ", ".join(f"{r['initial_strain']:.3g}" for r in sl["slots"]))
    t.add_row("paper slots: sum sensitivity cv %", f"{sl['sum_sensitivity_cv_percent']:.3g}")
    st = res["size_table"]
    t.add_row("size grid: strain cv % (best paper slot / personalised, caliper sd "
              f"{st['measurement_sd_mm']:.2g} mm, "
              f"{'cited %TEM' if st['measurement_sd_cited'] else 'given'})",
              f"{st['slots_strain_cv_percent']:.3g} / {st['personalised_strain_cv_percent']:.3g}")
    t.add_row("personalised strain cv % by measurement input",
              ", ".join(f"{k} {v['strain_cv_percent']:.2g}"
                        for k, v in st["measurement_spread"]["inputs"].items()))
    t.add_row(f"personalised cv < {st['goal_cv_percent']:g} %: caliper sd needed (mm), goal met",
              f"<= {st['required_measurement_sd_mm_for_goal']:.2g}, "
              f"{'yes' if st['goal_met'] else 'no'}")
    t.add_row("time (s)", f"{res['timings_s']['total']:.1f}")
    console.print(t)
    for note in res["material_stand_ins"]:
        console.print(_plain(("note:", "bold"), " ", note), highlight=False)
    for f in res["files"]:
        console.print(f"wrote {f}", highlight=False, markup=False)
    threemf = [f for f in res["files"] if str(f).endswith(".3mf")]
    _next("open next: " + ", ".join([f"{f} (into the slicer)" for f in threemf]
                                    + [f"{out / 'fit.json'} (the fit and size table)"]))


@app.command("params")
def params_cmd(part: str = typer.Argument(..., help="strap | fingertip | flexure",
                                          autocompletion=_sensor_names)):
    """A part's parameters: name, default, allowed range, unit, meaning (from the code)."""
    from rich.table import Table

    from designlab.geometry.api import field_rows
    from designlab.sensors.registry import get_sensor

    cls = get_sensor(part).part
    t = Table(title=f"{part} parameters ({cls.__name__}; set with --set NAME=VALUE)")
    for col in ("name", "default", "allowed", "unit", "meaning"):
        t.add_column(col, justify="right" if col == "default" else "left")
    for r in field_rows(cls):
        t.add_row(r["name"], _short(r["default"]), r["allowed"], r["unit"], r["meaning"])
    console.print(t)
    console.print(f"next: designlab show {part} --out {part}.png, or designlab predict {part} "
                  f"--set NAME=VALUE --out OUT", markup=False, highlight=False)


# --- commands (each helper inserts its command above this line) ---


def _check_options(*specs) -> None:
    """Options before any work: ``(name, value, lo, hi)`` -> a finite number in [lo, hi]
    (an integer when ``lo`` is an int); None values (unset options) are skipped."""
    import math

    from designlab.errors import ParameterError

    for name, value, lo, hi in specs:
        if value is None:
            continue
        if isinstance(lo, int) and not isinstance(lo, bool):
            if not isinstance(value, int) or not lo <= value <= hi:
                raise ParameterError(name, value, f"an integer, {lo} <= value <= {hi}")
        elif not (math.isfinite(value) and lo <= value <= hi):
            raise ParameterError(name, value, f"a finite number, {lo:g} <= value <= {hi:g}")


#: commands that may share an output folder: optimize exports what sweep evaluated; exports
#: of different parts go to their own subfolders (PART/)
_FAMILIES = {"sweep": "sweep", "optimize": "sweep", "export": "export"}


def _family(what: str) -> str:
    head = str(what).split(" ", 1)[0]
    return _FAMILIES.get(head, str(what))


def _read_run(out: Path) -> Optional[dict]:
    """The folder's ``run.json`` (None: none or unreadable)."""
    import json

    try:
        doc = json.loads((Path(out) / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and doc.get("format") == "designlab-run" else None


def _config_identity(cfg, uncertainty=None) -> str:
    """A sweep config's fingerprint (sha256 of the parsed config: part, swept and fixed
    parameters, settings, protocol, objectives, constraints, and the [uncertainty] spec of a
    robust sweep): a folder resumes only its own."""
    import dataclasses
    import hashlib
    import json

    doc = dataclasses.asdict(cfg)
    if uncertainty is not None:
        doc["uncertainty"] = (dataclasses.asdict(uncertainty)
                              if dataclasses.is_dataclass(uncertainty) else repr(uncertainty))
    text = json.dumps(doc, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _write_run(out: Path, what: str, settings: dict, identity: Optional[str] = None) -> Path:
    """``run.json`` of a command's output folder (command, version, date, settings; the
    identity ``--out`` compares before reusing the folder)."""
    from designlab.atomic import atomic_write_json
    from designlab.predict.run import run_manifest

    doc = run_manifest(what, settings)
    if identity is not None:
        doc["identity"] = identity
    atomic_write_json(Path(out) / "run.json", doc)
    return Path(out) / "run.json"


#: files and folders of a sweep/optimize run that ``--overwrite`` removes (the FEM and design
#: caches stay: they are keyed by what they depend on, so another config can share them)
_SWEEP_OUTPUTS = ("results", "results.parquet", "optimize.json", "report.html", "pareto.png",
                  "sensitivity.png", "chosen", "run.json")


def _check_reuse(out: Path, what: str, identity: Optional[str], overwrite: bool) -> None:
    """A non-empty ``--out`` whose ``run.json`` names another command (or, for a sweep, another
    config) is refused unless ``--overwrite``; with it, a sweep's previous rows are removed so
    the two runs never mix. A folder without ``run.json`` is used as it is."""
    import shutil

    from designlab.errors import OutputError

    out = Path(out)
    if not out.is_dir() or not any(out.iterdir()):
        return
    prev = _read_run(out)
    if prev is None:
        return
    same = _family(prev.get("what", "")) == _family(what) and (
        identity is None or prev.get("identity") in (None, identity))
    if same:
        return
    if not overwrite:
        was = str(prev.get("command") or prev.get("what") or "another run")
        raise OutputError(
            f"--out={str(out)!r} holds another run ({_one_line(was, 200)}, "
            f"{prev.get('date', 'date unknown')}): choose another folder, or add --overwrite "
            f"to replace it")
    if _family(prev.get("what", "")) == "sweep":
        for name in _SWEEP_OUTPUTS:
            p = out / name
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            elif p.exists() or p.is_symlink():
                p.unlink()
    else:
        (out / "run.json").unlink(missing_ok=True)


def _check_out(out: Optional[Path], what: Optional[str] = None, identity: Optional[str] = None,
               overwrite: bool = False) -> None:
    """``--out`` before any work: not a file, not under /proc, /sys or /dev, and the nearest
    existing folder on its path writable (nothing is created yet). With ``what`` (the command
    writing ``run.json``): a folder holding another run is refused unless ``overwrite``
    (:func:`_check_reuse`)."""
    import os

    from designlab.errors import OutputError

    if out is None:
        return
    real = os.path.realpath(out)
    if real in ("/proc", "/sys", "/dev") or real.startswith(("/proc/", "/sys/", "/dev/")):
        raise OutputError(f"--out={str(out)!r} is not allowed: a folder on a normal file system "
                          "(not under /proc, /sys or /dev)")
    p = Path(real)
    if p.exists() and not p.is_dir():
        raise OutputError(f"--out={str(out)!r} is not allowed: a folder (it is a file)")
    while not p.exists():
        p = p.parent
    if not p.is_dir():
        raise OutputError(f"--out={str(out)!r} is not allowed: {p} is a file, not a folder")
    if not os.access(p, os.W_OK | os.X_OK):
        try:
            ro = bool(os.statvfs(p).f_flag & os.ST_RDONLY)
        except OSError:
            ro = False
        raise OutputError(f"cannot write --out={str(out)!r}: {p} is "
                          + ("on a read-only file system" if ro else "not writable"))
    if what is not None:
        _check_reuse(Path(out), what, identity, overwrite)


def _part_config(target: str, cfg: Optional[dict], where: str = "--config") -> Optional[dict]:
    """A part config as ``make_part`` reads it, checked: either the part's own parameters or
    ``[PART]`` tables (required for ``all``); a table inside a part's table, or a top-level
    table that is not a part, is an error (never dropped)."""
    from designlab.errors import ParameterError
    from designlab.geometry.parts import PARTS
    from designlab.params import _short, did_you_mean

    if cfg is None:
        return None
    names = list(PARTS) if target == "all" else [target]
    per_part = any(k in PARTS for k in cfg) or target == "all"
    tables = {}
    if per_part:
        for k, v in cfg.items():
            if k not in PARTS or not isinstance(v, dict):
                raise ParameterError(f"{where}: {k}", _short(v), "a [PART] table with PART one "
                                     "of " + ", ".join(PARTS) + did_you_mean(k, PARTS))
            tables[k] = v
    else:
        tables[target] = cfg
    for part, table in tables.items():
        for k, v in table.items():
            if isinstance(v, (dict, list)):
                raise ParameterError(f"{part}.{k}" if per_part else k, _short(v),
                                     "a single value (a number, text or true/false), not a "
                                     + ("table" if isinstance(v, dict) else "list"))
    return {n: tables.get(n, {}) for n in names} if per_part else cfg


def _plain(*parts):
    """A rich ``Text`` of literal pieces (``str`` or ``(str, style)``): user text such as
    ``[time]`` or ``[/bold]`` is printed as it is, never read as markup."""
    from rich.text import Text

    return Text.assemble(*parts)


def _next(text: str) -> None:
    """The last line of a command: what to open next (paths unbroken, printed literally)."""
    console.print(text, markup=False, highlight=False, soft_wrap=True)


def _one_line(text: object, limit: int = 2000) -> str:
    """``text`` on one line (newlines and control characters as spaces), at most ``limit``
    characters."""
    s = "".join(c if c.isprintable() else " " for c in str(text).replace("\r\n", "\n")).strip()
    return s if len(s) <= limit else s[:limit - 3] + "..."


def _log_dir() -> Path:
    """Where tracebacks of unexpected errors go: ``$DESIGNLAB_LOG_DIR``, else
    ``$XDG_STATE_HOME/designlab`` (``~/.local/state/designlab``), else the temp directory."""
    import os
    import tempfile

    env = os.environ.get("DESIGNLAB_LOG_DIR")
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    for d in ([Path(env)] if env else []) + [Path(state) / "designlab",
                                             Path(tempfile.gettempdir()) / "designlab-logs"]:
        try:
            d.mkdir(parents=True, exist_ok=True)
            if os.access(d, os.W_OK):
                return d
        except OSError:
            continue
    return Path(tempfile.gettempdir())


def _write_log(argv: Optional[List[str]]) -> Optional[Path]:
    """The current exception's traceback (and the command line) in a new log file."""
    import datetime
    import os
    import traceback

    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    try:
        path = _log_dir() / f"designlab-{stamp}-{os.getpid()}.log"
        with open(path, "w", encoding="utf-8", errors="replace") as fh:
            fh.write(f"designlab {__version__}\nargv: {list(sys.argv if argv is None else argv)!r}\n\n")
            fh.write(traceback.format_exc())
        return path
    except OSError:
        return None


_WARNINGS_SHOWN = [0]


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings as one plain line each (at most 5 numeric ones per command)."""
    if issubclass(category, RuntimeWarning):
        _WARNINGS_SHOWN[0] += 1
        if _WARNINGS_SHOWN[0] > 5:
            return
    err_console.print(_plain(("warning:", "yellow"), " ", _one_line(str(message), 300)),
                      highlight=False, soft_wrap=True)


def _error(exc: BaseException, prefix: str = "error:") -> None:
    err_console.print(_plain((prefix, "bold red"), " ", _one_line(exc)), highlight=False,
                      soft_wrap=True)


def main(argv: Optional[List[str]] = None) -> None:
    """Console-script entry point: run the app; a user error (:class:`DesignlabError`, a bad
    option) is one line + exit 2; anything else one line naming a log file with the
    traceback + exit 1; Ctrl-C exit 130. Messages are printed literally (no rich markup).
    Called without ``argv`` (the ``designlab`` command itself), the process then ends without
    the interpreter's teardown (:func:`_exit_now`)."""
    if argv is not None:
        return _main(argv)
    try:
        _main(None)
        code = 0
    except SystemExit as exc:
        code = exc.code
    _exit_now(code)


def _exit_now(code) -> None:
    """End the process with ``code`` (a ``SystemExit`` code) after the exit handlers and a
    flush of stdout/stderr, skipping the interpreter's teardown: once OpenCascade is loaded
    its modules' destructors alone take 0.6-1 s (every file is written and closed by then)."""
    import atexit
    import os

    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    try:
        atexit._run_exitfuncs()     # what normal exit runs first (X server, pools, logging)
        _stop_resource_tracker()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):   # a closed pipe: nothing more to say
                pass
        os._exit(code)


def _stop_resource_tracker() -> None:
    """Close multiprocessing's resource tracker and wait for it, when this process started one
    (the process pools of a sweep): left alone it outlives the command by the moments it takes
    to notice the closed pipe and clean up."""
    rt = sys.modules.get("multiprocessing.resource_tracker")
    tracker = getattr(rt, "_resource_tracker", None)
    if tracker is not None and getattr(tracker, "_pid", None) is not None:
        stop = getattr(tracker, "_stop", None)
        if stop is not None:
            stop()


def _main(argv: Optional[List[str]]) -> None:
    import warnings

    # numeric warnings (overflow, invalid values) never flood the terminal: a result they
    # spoil is refused by its own check; the first few go to one line each on stderr
    warnings.simplefilter("once", RuntimeWarning)
    warnings.showwarning = _show_warning
    try:
        rc = app(args=argv, standalone_mode=False)
        if isinstance(rc, int) and rc:
            sys.exit(rc)
    except DesignlabError as exc:
        _error(exc)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        err_console.print("interrupted")
        sys.exit(130)
    except typer.TyperException as exc:  # usage errors of the command parser (bad option...)
        # typer >= 0.29 carries its own click: these are typer's, not the click package's
        ctx = getattr(exc, "ctx", None)
        hint = f" (see {ctx.command_path} --help)" if ctx is not None else ""
        _error(f"{exc.format_message()}{hint}")
        sys.exit(getattr(exc, "exit_code", 2) or 2)
    except SystemExit:
        raise
    except BrokenPipeError:  # output piped into a reader that quit (head, less)
        sys.exit(1)
    except RecursionError as exc:
        _error(f"input nested too deeply ({type(exc).__name__})")
        sys.exit(2)
    except MemoryError:
        log = _write_log(argv)
        _error(f"out of memory; use smaller inputs (details in {log})")
        sys.exit(1)
    except Exception as exc:
        log = _write_log(argv)
        where = f"; traceback in {log}" if log else ""
        _error(f"internal error {type(exc).__name__}: {_one_line(exc, 300)}{where}")
        sys.exit(1)


if __name__ == "__main__":
    main()
