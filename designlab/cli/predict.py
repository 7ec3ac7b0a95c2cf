"""``designlab predict``: a design's virtual test before printing (or, with ``--samples``, its
Monte Carlo over scattered builds) and the table of what it found."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from rich.table import Table

from designlab.cli.app import app, console, next_step, progress_bar, warn
from designlab.cli.options import check_options, make_executor, part_arg, part_config, sensor_names
from designlab.atomic import FileSet, out_lock
from designlab.cli.runs import check_out
from designlab.errors import ParameterError
from designlab.params import load_toml, parse_sets

Row = tuple[str, str]


def _overrides(part: str, config: Optional[Path], set_: Optional[List[str]]) -> dict:
    """The design's parameters: the part's table of ``--config`` (its [uncertainty] left
    out), then ``--set`` (``NAME=VALUE``, or ``PART.NAME=VALUE`` as export takes it)."""
    overrides = {}
    if config is not None:
        data = part_config(part, load_toml(config))
        data = {k: v for k, v in data.items() if k != "uncertainty"}
        overrides.update(data.get(part, data))
    prefix = f"{part}."
    overrides.update({k.removeprefix(prefix): v for k, v in parse_sets(set_).items()})
    return overrides


def _check_monte_carlo(workers, model, protocol, measured) -> None:
    """Options a Monte Carlo does not take: --model, --protocol, --measured."""
    check_options(("--workers", workers, 1, 512))
    if model is not None or protocol is not None:
        raise ParameterError("--model/--protocol", str(model or protocol),
                             "none with --samples (the Monte Carlo runs the paper's calibration)")
    if measured is not None:
        raise ParameterError("--measured", str(measured), "none with --samples (the Monte "
                             "Carlo scatters the library materials; predict without "
                             "--samples uses measured ones)")


def _monte_carlo(part: str, out: Path, overrides: dict, settings: dict, spec, executor) -> None:
    """Run the Monte Carlo of ``spec``'s virtual builds and print and write its summary."""
    # the summary and its report or neither (the samples stay for a resume)
    with FileSet() as outputs:
        report = _monte_carlo_into(outputs, part, out, overrides, settings, spec, executor)
    console.print(f"wrote {out / 'uncertainty.json'}, {report}", markup=False, highlight=False)


def _monte_carlo_into(outputs, part: str, out: Path, overrides: dict, settings: dict, spec,
                      executor) -> Path:
    from designlab.optimize.montecarlo import monte_carlo
    from designlab.predict.report import write_uncertainty_report
    from designlab.predict.uncertainty import summary_rows

    with progress_bar(f"{part}: virtual builds", spec.samples, transient=False) as bar:
        summary = monte_carlo(part, spec, out, params=overrides, settings=settings or None,
                              executor=executor, progress=lambda d, n: bar(completed=d, total=n),
                              files=outputs)
    t = Table(title=f"{part}: {summary['ok']} builds ({summary['failed']} failed), "
                    f"FEM solves {summary['fem']['solves_this_run']}")
    for col in ("metric", "mean", "5 %", "95 %", "driven by"):
        t.add_column(col, justify="left" if col in ("metric", "driven by") else "right")
    for r in summary_rows(summary):
        t.add_row(*r)
    console.print(t)
    for err, n in summary["failed_errors"].items():
        warn(f"{n} builds: {err}", label="failed:")
    return write_uncertainty_report(out, summary, params=overrides, settings=settings or None,
                                    files=outputs)


def _calibration_rows(prediction) -> list[Row]:
    """Hysteresis, condition numbers, the force errors with the noise budget, K_f."""
    from designlab.predict.report import force_error_lines

    pred = prediction.metrics
    rows = [("hysteresis % (overall)", f"{prediction.hysteresis_percent:.4g}"),
            ("condition number", f"{prediction.condition_number:.4g}")]
    if pred.get("geometric_condition_number") is not None:
        rows.append(("geometric condition number", f"{pred['geometric_condition_number']:.4g}"))
    rows += list(force_error_lines(pred))
    if prediction.K_f is not None:
        import numpy as np

        rows.append(("K_f diagonal (SI)", ", ".join(f"{v:.4g}" for v in np.diag(prediction.K_f))))
    return rows


def _stress_rows(pred: dict) -> list[Row]:
    """The smallest safety factor, the materials without a strength, the wrap prestress."""
    stress = pred.get("stress")
    rows = []
    if stress is None:
        rows.append(("stress, safety factor", "not computed (this model gives stiffness, no "
                     "stress field)"))
    crit = (stress or {}).get("critical")
    if crit:
        rows.append(("smallest safety factor", f"{crit['safety_factor']:.3g} ({crit['body']}, "
                     f"{crit['material']}, {crit['max_von_mises_MPa']:.3g} MPa von Mises, "
                     f"load case {crit['load_case']})"))
    for m, v in ((stress or {}).get("materials") or {}).items():
        if v.get("strength_MPa") is None:
            rows.append((f"safety factor of {m}",
                         f"not computed ({v.get('source') or 'no documented strength'})"))
    wrap = (pred.get("prestrain") or {}).get("stress") or {}
    if wrap.get("critical"):
        w = wrap["critical"]
        rows.append(("wrap prestress safety factor", f"{w['safety_factor']:.3g} ({w['body']}, "
                     f"{w['material']}, {w['max_von_mises_MPa']:.3g} MPa at initial strain "
                     f"{wrap['initial_strain']:.3g})"))
    return rows


def _prediction_table(part: str, prediction) -> Table:
    t = Table(title=f"{part}: virtual test")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    rows = [*_calibration_rows(prediction), *_stress_rows(prediction.metrics),
            *((f"time: {k}", f"{v:.2f} s") for k, v in prediction.timings_s.items())]
    for name, value in rows:
        t.add_row(name, value)
    return t


def _predict_once(part: str, out: Path, overrides: dict, settings: dict, protocol, model,
                  measured) -> None:
    """One virtual test: build, predict, write, print its table and where the files are."""
    from designlab.predict.run import predict_and_write
    from designlab.sensors.registry import get_sensor

    records = None
    if measured is not None:
        from designlab.fem.materials import load_measured

        records = load_measured(measured)
    with progress_bar(f"predict {part}: building") as bar:
        prediction, files = predict_and_write(part, overrides, out=out, protocol_path=protocol,
                                              settings=settings, model_path=model,
                                              measured=records,
                                              progress=lambda s: bar(f"predict {part}: {s}"))
    console.print(_prediction_table(part, prediction))
    check = get_sensor(part).validate
    if check is not None:       # a subclass of a built-in names the built-in it derives from
        from designlab.sensors.registry import SENSORS

        paper = next(n for n, s in SENSORS.items() if s.validate is check)
        console.print(f"the paper's own sensor against its tables: designlab validate {paper} "
                      "--out DIR", markup=False, highlight=False)
    for w in prediction.warnings:
        warn(w)
    console.print(f"wrote {len(files)} files to {out}", markup=False, highlight=False)
    vtu = (f", {out / 'deformed.vtu'} (stress and displacement per load case, e.g. in "
           "ParaView)") if (out / "deformed.vtu").is_file() else ""
    next_step(f"open next: {out / 'report.html'} (the report){vtu}")


@app.command()
def predict(part: str = typer.Argument(..., help="strap | fingertip | flexure, or a sensor definition FILE.py[:Class]", autocompletion=sensor_names, callback=part_arg),
            set_: Optional[List[str]] = typer.Option(None, "--set", help="Design parameter NAME=VALUE (repeatable)."),
            config: Optional[Path] = typer.Option(None, "--config", help="TOML with the part's parameters."),
            protocol: Optional[Path] = typer.Option(None, "--protocol", help="Protocol TOML (defaults: the papers')."),
            setting: Optional[List[str]] = typer.Option(None, "--setting", help="Model setting NAME=VALUE, e.g. edge_length=2.5."),
            model: Optional[Path] = typer.Option(None, "--model", help="A loop's model.json: add its learned effects (strap, fingertip, flexure)."),
            measured: Optional[Path] = typer.Option(None, "--measured", help="Measured printed-material data (JSON, docs/formats.md): replaces the stand-ins of the materials it names."),
            out: Path = typer.Option(..., "--out", help="Output directory."),
            samples: Optional[int] = typer.Option(None, "--samples", help="Monte Carlo: N virtual builds with scattered inputs and readout noise (resumable in --out)."),
            uncertainty: Optional[Path] = typer.Option(None, "--uncertainty", help="TOML with an \\[uncertainty] table (default: the documented distributions)."),
            scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Monte Carlo on a Dask scheduler tcp://HOST:PORT."),
            workers: Optional[int] = typer.Option(None, "--workers", help="Monte Carlo: local worker processes (default: all cores)."),
            overwrite: bool = typer.Option(False, "--overwrite", help="Write into an --out that holds another command's run (same-named files are replaced)."),
            finger: Optional[str] = typer.Option(None, "--finger", metavar="W,D,L|SCAN.stl", help="strap: the wearer's finger (mm, or a closed STL scan): sets the finger radius and the closest slot.")):
    """Virtual test of a design before printing: hysteresis, calibration matrix, condition number, K_f."""
    from designlab.sensors.registry import get_sensor

    get_sensor(part)
    check_out(out, f"predict {part}", overwrite=overwrite)
    overrides = _overrides(part, config, set_)
    settings = parse_sets(setting)
    if finger is not None:
        from designlab.sensors.strap.wearer import wearer_settings

        settings, note = wearer_settings(part, finger, overrides, settings)
        console.print(note, highlight=False, markup=False)
    if samples is None and uncertainty is None:
        with out_lock(out, f"designlab predict {part}"):   # one writer: a second run is refused
            _predict_once(part, out, overrides, settings, protocol, model, measured)
        return
    from designlab.predict.uncertainty import load_uncertainty

    _check_monte_carlo(workers, model, protocol, measured)
    spec = load_uncertainty(part, uncertainty if uncertainty is not None else config,
                            samples=samples)
    _monte_carlo(part, out, overrides, settings, spec, make_executor(scheduler, workers))
