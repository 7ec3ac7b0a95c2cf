"""``designlab validate``: each sensor beside its paper, one row per goal (value, the paper's,
target, met, why), written to ``validation.json`` and ``validation.md`` in ``--out``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

from designlab.cli.app import app, console, next_step, progress_bar
from designlab.cli.runs import check_out, write_run


def validate_names(incomplete: str = "") -> list[str]:
    """Completion choices: the sensors with a paper comparison and ``all``."""
    from designlab.predict.validate import ALL, validated_sensors

    return [n for n in (*validated_sensors(), ALL) if n.startswith(incomplete)]


def goal_table(name: str, section: dict) -> Table:
    """One sensor's goals as a rich table (met: green yes, red no, '-' without a target)."""
    from designlab.predict.validate import COLUMNS, cell

    t = Table(title=f"{name}: {section['paper']}", show_lines=True)
    for c in COLUMNS:
        t.add_column(c, justify="right" if c in ("value", "paper") else "left",
                     ratio=3 if c in ("name", "why") else None)
    style = {True: "[green]yes[/]", False: "[bold red]no[/]", None: "-"}
    for g in section["goals"]:
        t.add_row(*[style[g[c]] if c == "met" else escape(cell(g[c])) for c in COLUMNS])
    return t


@app.command()
def validate(sensor: str = typer.Argument(..., help="strap | fingertip | flexure | all",
                                          autocompletion=validate_names),
             out: Path = typer.Option(..., "--out", help="Output directory (validation.json, "
                                                         "validation.md, figures)."),
             overwrite: bool = typer.Option(False, "--overwrite", help="Write into an --out that "
                                            "holds another command's run (same-named files are "
                                            "replaced).")):
    """Each sensor beside its paper at the paper's design and protocol: every goal with the
    model's value, the paper's, the target, whether it is met and why."""
    from designlab.predict.validate import validate as run_validation, sensors_for

    names = sensors_for(sensor)
    check_out(out, f"validate {sensor}", overwrite=overwrite)
    with progress_bar(f"validate {sensor}") as bar:
        data = run_validation(names, out, progress=lambda s: bar(f"validate {s}"))
    write_run(out, f"validate {sensor}", {"sensors": names})
    for name, section in data.items():
        console.print(goal_table(name, section))
    next_step(f"open next: {out / 'validation.md'} (the goals and figures), "
              f"{out / 'validation.json'} (every number)")
