"""``designlab sensors`` (what is installed), ``designlab new`` (a sensor definition to edit) and
``designlab materials`` (the library a definition's bodies choose from)."""

from __future__ import annotations

import keyword
import re
from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

from designlab.cli.app import app, console, next_step
from designlab.errors import ParameterError


@app.command("sensors")
def sensors_cmd():
    """The sensors designlab knows: the built-in three and those installed packages add
    (entry-point group ``designlab.sensors``)."""
    from designlab.sensors.registry import BUILT_IN, SENSORS, entry_points

    table = Table(title="sensors")
    for col in ("name", "kind", "from"):
        table.add_column(col)
    for name, s in SENSORS.items():
        table.add_row(name, "built in" if name in BUILT_IN else "definition", s.paper)
    for name, ep in entry_points().items():
        if name not in SENSORS:
            table.add_row(name, "installed definition", ep.value)
    console.print(table)
    next_step("designlab new NAME writes a sensor definition to edit; designlab predict "
              "FILE.py --out OUT runs it")


@app.command("materials")
def materials_cmd():
    """The material library: modulus, Poisson's ratio, density, strength, relaxation (Prony
    terms or the stand-in used) and the source of each value."""
    from designlab.fem.materials import material_table

    table = Table(title="materials (E MPa, density g/cm^3, strength MPa)")
    for col in ("name", "E", "nu", "density", "strength", "relaxation", "source"):
        table.add_column(col)
    for r in material_table():
        table.add_row(r.name, f"{r.E_MPa:g}", f"{r.nu:g}", f"{r.density_g_cm3:g}",
                      "" if r.strength_MPa is None else f"{r.strength_MPa:g}", r.prony, r.source)
    console.print(table)


def _names(name: str) -> tuple[str, str]:
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name) or keyword.iskeyword(name):
        raise ParameterError("NAME", name, "a Python identifier: a letter, then letters, digits "
                             "or _")
    cls = "".join(p[:1].upper() + p[1:] for p in name.split("_") if p)
    return name.lower(), cls


@app.command("new")
def new(name: str = typer.Argument(..., help="The sensor's name (a Python identifier)."),
        out: Optional[Path] = typer.Option(None, "--out", help="File to write (default NAME.py); "
                                           "an existing file is not replaced.")):
    """Write a commented sensor definition that predicts as it is: a printed beam with a strain
    gauge, to edit into your sensor."""
    from jinja2 import Environment, PackageLoader, StrictUndefined

    from designlab.atomic import atomic_write_bytes

    low, cls = _names(name)
    path = out if out is not None else Path(f"{low}.py")
    if path.suffix != ".py":
        raise ParameterError("--out", str(path), "a file name ending in .py")
    if path.exists():
        raise ParameterError("--out", str(path), "a file that does not exist yet")
    if not path.parent.is_dir():
        raise ParameterError("--out", str(path), "a file in an existing folder")
    env = Environment(loader=PackageLoader("designlab", "templates"), undefined=StrictUndefined,
                      keep_trailing_newline=True)
    text = env.get_template("sensor_definition.py.j2").render(
        name=low, cls=cls, file=path.name, title=cls)
    atomic_write_bytes(path, text.encode("utf-8"))
    console.print(f"wrote {path}")
    next_step(f"designlab predict {path} --out runs/{low}")
