"""The part commands: ``export`` (printability check, then STL/3MF/STEP/glTF), ``show`` (a
render), ``mesh`` (the FEM bodies' tetrahedral mesh) and ``params`` (what each parameter
means)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import List, Optional

import typer
from rich.table import Table

from designlab.cli.app import app, console, err_console, next_step, progress_bar
from designlab.cli.options import (check_options, config_file, export_names, part_arg, sensor_names,
                                   short)
from designlab.atomic import out_lock
from designlab.cli.runs import check_out, write_run
from designlab.errors import ParameterError
from designlab.params import parse_sets


def _parts_from_cli(part: str, set_: Optional[List[str]], config: Optional[Path]):
    from designlab.geometry.export import resolve_parts

    overrides = parse_sets(set_)
    return resolve_parts(part, overrides, config_file(part, config))


def _check_ranges(specs, unit: str) -> None:
    """``(name, value, lo, hi)`` -> ``lo <= value <= hi`` (in ``unit``)."""
    for name, v, lo, hi in specs:
        if not lo <= v <= hi:
            raise ParameterError(name, v, f"{lo:g} <= value <= {hi:g} {unit}")


@app.command()
def export(part: str = typer.Argument(..., help="strap | fingertip | flexure | all, or a sensor definition FILE.py[:Class]", autocompletion=export_names, callback=part_arg),
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
    from designlab.geometry.export import export_parts, parse_formats
    from designlab.geometry.printability import PrintabilityError, reports_table

    check_out(out)
    fmts = parse_formats(formats)
    _check_ranges((("--nozzle", nozzle, 0.05, 2.0), ("--layer-height", layer, 0.01, 1.0)), "mm")
    parts = _parts_from_cli(part, set_, config)
    check_out(out, f"export {part}", overwrite=overwrite)
    with out_lock(out, f"designlab export {part}"), \
            progress_bar("export", 2 * len(parts)) as bar:   # one writer: a second is refused
        def step(text: str, done: int, total: int) -> None:
            bar(text, completed=done, total=total)

        try:
            res = export_parts(parts, out, fmts, png=png, nozzle=nozzle, layer=layer, progress=step)
        except PrintabilityError as exc:
            bar.stop()
            err_console.print(reports_table(exc.reports))
            raise
        run = write_run(out, f"export {part}", {
            "formats": formats, "nozzle_mm": nozzle, "layer_height_mm": layer,
            "parts": {n: {f.name: getattr(o, f.name) for f in dataclasses.fields(o)}
                      for n, o in parts.items()}})
    console.print(reports_table(res.reports))
    for f in [*res.files, run]:
        console.print(f"wrote {f}", highlight=False, markup=False)
    next_step(_open_next_export(res.files))


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
def show(part: str = typer.Argument(..., help="strap | fingertip | flexure, or a sensor definition FILE.py[:Class]", autocompletion=sensor_names, callback=part_arg),
         out: Path = typer.Option(..., "--out", help="PNG file to write."),
         set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                  help="Override a part parameter (mm)."),
         config: Optional[Path] = typer.Option(None, "--config", help="Part parameters (TOML)."),
         width: int = typer.Option(1200, "--width", help="Image width, px."),
         height: int = typer.Option(900, "--height", help="Image height, px.")):
    """Render a part (bodies in colour, bought parts see-through) to a PNG."""
    from designlab.geometry.export import write_png

    if part == "all":
        raise ParameterError("part", part, "a single part: " + ", ".join(sensor_names()))
    if out.suffix.lower() != ".png" or out.is_dir():
        raise ParameterError("--out", str(out), "a file name ending in .png"
                             + (" (it is a folder)" if out.is_dir() else ""))
    for name, v in (("--width", width), ("--height", height)):
        if not 64 <= v <= 8000:
            raise ParameterError(name, v, "64 <= value <= 8000 px")
    (name, obj), = _parts_from_cli(part, set_, config).items()
    path = write_png(obj.build(), out, title=name, size=(width, height))
    console.print(f"wrote {path}", highlight=False, markup=False)
    next_step(f"open next: {path} (the render); designlab params {name} (what each "
              f"parameter means), designlab predict {name} --out OUT (its virtual test)")


def _mesh(part: str, set_, config, out: Path, *, order: int, edge_length, quality: str,
          refine: bool, mesher: str):
    """Mesh a part (gmsh from the B-rep) or an STL file (fTetWild) and save it in ``out``:
    ``(mesh result, mesh.vtu, mesh.json)``."""
    from designlab.geometry.parts import make_part
    from designlab.mesh.meshing import mesh_part_detailed, mesh_stl, save_mesh

    if part.lower().endswith(".stl"):
        if set_ or config is not None:
            raise ParameterError("--set/--config", part, "none with an STL (it has no parameters)")
        if not Path(part).is_file():
            raise ParameterError("part", part, "an existing STL file or one of the parts")
        with progress_bar(f"meshing {Path(part).name} (fTetWild)"):
            res = mesh_stl(part, edge_length=edge_length, order=order, quality=quality)
            return (res, *save_mesh(res, out))
    obj = make_part(part, parse_sets(set_), config_file(part, config))
    with progress_bar(f"meshing {part}"):
        res = mesh_part_detailed(obj, refine=refine, order=order, edge_length=edge_length,
                                 quality=quality, mesher=mesher)
        return (res, *save_mesh(res, out))


def _mesh_table(part: str, order: int, rep: dict) -> Table:
    from rich.markup import escape   # a part's name may be a file name: never markup

    table = Table(title=f"{escape(part)}: {rep['n_cells']} TET{4 if order == 1 else 10} cells, "
                        f"{rep['n_points']} nodes, {rep['dof']} DOF, {rep['seconds']:.1f} s "
                        f"({rep['mesher']})")
    for col in ("region", "material", "cells", "volume mm^3", "body mm^3", "error %"):
        table.add_column(col, justify="left" if col in ("region", "material") else "right")
    for name, r in rep["regions"].items():
        table.add_row(escape(name), escape(rep["materials"][name]), str(r["cells"]), f"{r['volume_mm3']:.4g}",
                      f"{r['body_volume_mm3']:.4g}", f"{r['volume_error_percent']:+.2f}")
    return table


@app.command("mesh")
def mesh_cmd(part: str = typer.Argument(..., help="strap | fingertip | flexure, or a closed "
                                                  "surface FILE.stl (a scan, a part from elsewhere), "
                                                  "or a sensor definition FILE.py[:Class]",
                                         autocompletion=sensor_names, callback=part_arg),
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
    check_out(out)
    check_options(("--order", order, 1, 2), ("--edge-length", edge_length, 1e-3, 1e3))
    res, vtu, js = _mesh(part, set_, config, out, order=order, edge_length=edge_length,
                         quality=quality, refine=refine, mesher=mesher)
    rep = res.report()
    console.print(_mesh_table(part, order, rep))
    q = rep["quality"]
    console.print(f"edge {rep['edge_length_mm']:.3g} mm (mean {q['edge_length_mean']:.3g}), "
                  f"min dihedral {q['min_dihedral_deg']:.1f} deg, radius ratio min "
                  f"{q['radius_ratio_min']:.3f} mean {q['radius_ratio_mean']:.3f}, "
                  f"{q['n_poor']} poor cells", highlight=False)
    console.print("facet sets: " + ", ".join(f"{k} ({v})" for k, v in rep["facet_sets"].items()),
                  highlight=False)
    console.print(f"wrote {vtu}\nwrote {js}", highlight=False, markup=False)
    next_step(f"open next: {vtu} (regions as cell data, e.g. in ParaView), {js} (quality "
              "and facet sets)")


@app.command("params")
def params_cmd(part: str = typer.Argument(..., help="strap | fingertip | flexure, or a sensor "
                                          "definition FILE.py[:Class]",
                                          autocompletion=sensor_names, callback=part_arg)):
    """A part's parameters: name, default, allowed range, unit, meaning (from the code)."""
    from designlab.geometry.api import field_rows
    from designlab.sensors.registry import get_sensor

    cls = get_sensor(part).part
    t = Table(title=f"{part} parameters ({cls.__name__}; set with --set NAME=VALUE)")
    for col in ("name", "default", "allowed", "unit", "meaning"):
        t.add_column(col, justify="right" if col == "default" else "left")
    for r in field_rows(cls):
        t.add_row(r["name"], short(r["default"]), r["allowed"], r["unit"], r["meaning"])
    console.print(t)
    console.print(f"next: designlab show {part} --out {part}.png, or designlab predict {part} "
                  f"--set NAME=VALUE --out OUT", markup=False, highlight=False)
