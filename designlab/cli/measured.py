"""The commands on measured data: ``compensate`` (linear / mPL / NARX compensation of a
sensor's signal) and ``loop`` (residual -> effect -> better model)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from rich.markup import escape
from rich.table import Table

from designlab.cli.app import app, console, next_step, progress_bar
from designlab.cli.options import check_options, short, split_names
from designlab.cli.runs import check_out
from designlab.errors import ParameterError


def _records(comp, data: Optional[Path], train, validate, inputs, outputs, time_col, dt) -> tuple:
    """Training and validation records from a dataset card or from --train/--validate files."""
    if data is not None:
        if train or validate:
            raise ParameterError("--data", str(data), "either a dataset card or --train/--validate files")
        return comp.records_from_card(data, inputs, outputs)
    if not train:
        raise ParameterError("--train", None, "at least one training file (or --data CARD)")
    train_recs = [comp.load_record(f, inputs, outputs, time=time_col, dt=dt) for f in train]
    val_recs = [comp.load_record(f, inputs, outputs, time=time_col, dt=dt) for f in validate or []]
    return train_recs, val_recs


def _compensation_table(result) -> Table:
    table = Table(title="compensation (RMSE in the reference unit)")
    for col in ("model", "task", "role", "output", "RMSE", "NCC"):
        table.add_column(col, justify="right" if col in ("RMSE", "NCC") else "left")
    for m, t, role, o, r, c in result.table():  # task and channel names: user text
        table.add_row(escape(m), escape(t), escape(role), escape(o), f"{r:.4g}", f"{c:.4f}")
    return table


def _print_wilcoxon(result, val_recs, segments: int) -> None:
    """The Wilcoxon tests between models on the validation tasks, one line each."""
    val_names = {r.name for r in val_recs}
    for w in result.between_models:
        if w["task"] in val_names:
            console.print(f"Wilcoxon {w['task']} {w['output']}: {w['a']} vs {w['b']}: p(RMSE) = "
                          f"{w['rmse']['p_value']:.3g}, p(NCC) = {w['ncc']['p_value']:.3g} "
                          f"({segments} segments)", highlight=False, markup=False)


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
    from designlab.measured import compensation as comp

    check_out(out)
    check_options(("--dt", dt, 1e-9, 1e6), ("--cells", cells, 0, 1000), ("--order", order, 0, 20),
                  ("--narx-delays", narx_delays, 0, 10000),
                  ("--narx-output-delays", narx_output_delays, 0, 10000),
                  ("--segments", segments, 2, 10000), ("--seed", seed, 0, 2 ** 32 - 1))
    if update not in ("exact", "euler"):
        raise ParameterError("--update", update, "exact or euler")
    models = split_names(model) or list(comp.MODELS)
    inputs, outputs = split_names(input_), split_names(output)
    opts = comp.CompensationOptions(mix=mix, mpl_cells=cells, mpl_order=order, mpl_update=update,
                                    narx_input_delays=narx_delays,
                                    narx_output_delays=narx_output_delays, n_segments=segments,
                                    seed=seed)
    train_recs, val_recs = _records(comp, data, train, validate, inputs, outputs, time_col, dt)
    with progress_bar("compensate", len(models) + 1) as bar:
        def step(text: str) -> None:
            bar(text, advance=0 if text.startswith("fitting " + models[0]) else 1)

        result = comp.compare(train_recs, val_recs, models, opts, progress=step)
        bar(completed=len(models) + 1)
    console.print(_compensation_table(result))
    for m, f in result.fits.items():
        console.print(f"{m}: fitted in {f['time_s']:.2f} s", highlight=False, markup=False)
    _print_wilcoxon(result, val_recs, segments)
    written = list(comp.write_outputs(result, train_recs + val_recs, out))
    for path in written:
        console.print(f"wrote {path}", markup=False, highlight=False)
    next_step("open next: " + ", ".join(
        f"{p} ({'validation plots' if Path(p).suffix == '.png' else 'RMSE, NCC, Wilcoxon tables'})"
        for p in written))


def _loop_table(data: Path, report: dict) -> Table:
    """Validation RMSE per output: the base, each effect added, the total."""
    table = Table(title=escape(f"loop on {data.name}: validation RMSE (base {report['base']})"))
    for col in ("output", "effect", "parameters", "before", "after"):
        table.add_column(col, justify="right" if col in ("before", "after") else "left")
    for o, rep in report["outputs"].items():
        table.add_row(escape(o), "(base)", "", f"{rep['error_before']:.4g}", "",
                      end_section=False)
        for e in rep["effects"]:
            par = ", ".join(f"{k}={short(v)}" for k, v in e["parameters"].items()
                            if k not in ("base_adjust", "form", "g_unit"))
            table.add_row("", escape(e["key"]), escape(par), f"{e['error_before']:.4g}",
                          f"{e['error_after']:.4g}")
        nf = rep.get("noise_floor")
        peer = next((p for p in rep.get("peers") or [] if p["kind"] == rep.get("best_peer")),
                    None)
        if nf:
            table.add_row("", "(noise floor)", escape(
                f"{rep['verdict_kind']}; best peer " + (f"{peer['kind']} {peer['error']:.4g}"
                                                        if peer else "none")),
                "", f"{nf['sigma']:.4g}")
        table.add_row("", "[bold]total", f"unexplained {100 * rep['unexplained_fraction']:.1f} %",
                      f"{rep['error_before']:.4g}", escape(f"{rep['error_after']:.4g} {rep['unit']}"),
                      end_section=True)
    return table


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
    from designlab.loop.loop import run_loop
    from designlab.loop.model import load_model
    from designlab.loop.report import write_outputs
    from designlab.measured.dataset import load_card

    check_out(out)
    check_options(("--folds", folds, 3, 1000), ("--max-effects", max_effects, 0, 100),
                  ("--n-se", n_se, 0.0, 100.0), ("--min-relative", min_relative, 0.0, 0.99))
    start = load_model(base) if base.endswith(".json") else base
    ds = load_card(data)
    with progress_bar("loop", 1) as bar:
        def step(o: str, done: int, total: int, what: str) -> None:
            bar(f"{o}: {what}", completed=done, total=max(total, 1))

        result = run_loop(ds, start, outputs=output or None, folds=folds,
                          max_effects=max_effects, n_se=n_se, min_relative=min_relative,
                          progress=step)
    console.print(_loop_table(data, result.report))
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
        next_step("open next: " + ", ".join(nxt))
