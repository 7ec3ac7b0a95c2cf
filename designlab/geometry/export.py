"""Printable export of a part: per-body STL, one 3MF (multi-material where bodies are embedded),
coloured STEP and glTF of the assembly, and a PNG picture. Units mm; build direction +z.

Export runs in two steps so that nothing is half-written:

1. :func:`prepare` tessellates the printed bodies (:func:`tessellate`, 0.01 mm / 0.2 rad) and
   runs the printability checks; :func:`require_printable` raises :class:`PrintabilityError`
   (one line, every body's report attached) when any body of any part fails;
2. :func:`write_all` renders every file of every part into a temporary file beside its target
   and, only when all of them succeeded, moves each into place with ``os.replace``.

The 3MF holds one object per host-material body, with the bodies of other extruders it touches
as volumes of that object (:func:`print_objects`), laid out side by side on the plate. Bought
bodies (``printed=False``) appear in STEP/glTF/PNG only.

Layout: ``OUT/<part>/<part>-<body>.stl``, ``<part>.3mf``, ``<part>.step``, ``<part>.glb``,
``<part>.png``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import trimesh

from designlab.atomic import FileSet
from designlab.errors import OutputError, ParameterError
from designlab.geometry.body import Body
from designlab.geometry.printability import BodyReport, PrintabilityError, check_part
from designlab.geometry.tessellate import tessellate
from designlab.geometry.threemf import Object3MF, Volume3MF, plate_layout, threemf_bytes

FORMATS = ("stl", "3mf", "step", "gltf")
#: print tessellation: chordal 0.01 mm (a tenth of a 0.1 mm layer), 0.2 rad
PRINT_TOLERANCE = 0.01
PRINT_ANGULAR_TOLERANCE = 0.2


def parse_formats(text: str | Iterable[str]) -> tuple[str, ...]:
    """``"stl,3mf"`` -> ``("stl", "3mf")``; unknown names raise ParameterError."""
    items = text.split(",") if isinstance(text, str) else list(text)
    out = []
    for f in (x.strip().lower() for x in items):
        f = {"stp": "step", "glb": "gltf"}.get(f, f)
        if f not in FORMATS:
            raise ParameterError("--format", f, "comma-separated names from " + ",".join(FORMATS))
        if f not in out:
            out.append(f)
    if not out:
        raise ParameterError("--format", text, "at least one of " + ",".join(FORMATS))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class Prepared:
    """A part ready to be written: bodies, print meshes of the printed ones, reports."""

    name: str
    bodies: dict[str, Body]
    meshes: dict[str, trimesh.Trimesh]
    reports: list[BodyReport]
    assembly: Callable[[], Any] | None = None  # -> cadquery.Assembly (coloured)

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.reports)


def prepare(name: str, bodies: Mapping[str, Body], nozzle: float = 0.4, layer: float = 0.1,
            assembly: Callable[[], Any] | None = None, tolerance: float = PRINT_TOLERANCE,
            angular_tolerance: float = PRINT_ANGULAR_TOLERANCE) -> Prepared:
    """Tessellate the printed bodies and check them (nothing is written)."""
    if not any(b.printed for b in bodies.values()):
        raise ParameterError(name, "bodies", "a part with at least one printed body")
    meshes = {k: tessellate(b.shape, tolerance, angular_tolerance, check=False)
              for k, b in bodies.items() if b.printed}
    reports = check_part(name, bodies, nozzle, layer, meshes)
    return Prepared(name, dict(bodies), meshes, reports, assembly)


def prepare_part(part: Any, name: str | None = None, nozzle: float = 0.4,
                 layer: float = 0.1) -> Prepared:
    """:func:`prepare` for a parametric part object (``part.build() -> {name: Body}``); STEP and
    glTF come from :func:`designlab.geometry.assembly.assembly`. A part that declares its own
    ``layer_height`` (the strap: its traces are whole layers) is checked at that layer height,
    not at ``layer``."""
    from designlab.geometry import assembly as asm

    layer = float(getattr(part, "layer_height", layer))

    if name is None:
        from designlab.geometry.parts import part_name

        name = part_name(part)
    return prepare(name, part.build(), nozzle, layer, assembly=lambda: asm.assembly(part))


def require_printable(prepared: Iterable[Prepared]) -> None:
    """Raise :class:`PrintabilityError` with all reports if any body of any part fails."""
    prepared = list(prepared)
    if not all(p.ok for p in prepared):
        raise PrintabilityError([r for p in prepared for r in p.reports])


def bodies_assembly(name: str, bodies: Mapping[str, Body]):
    """Coloured ``cadquery.Assembly`` of bodies (:func:`designlab.geometry.assembly.assembly`
    of a part whose ``build()`` returns ``bodies``)."""
    from types import SimpleNamespace

    from designlab.geometry.assembly import assembly

    return assembly(SimpleNamespace(build=lambda: dict(bodies)), name=f"{name}_assembly")


def print_objects(prepared: Prepared, touch: float = 0.01) -> list[list[str]]:
    """Group the printed bodies into print objects (lists of body names, host first).

    Every body on the host extruder (the lowest one used) is its own object, printed apart; a body
    on another extruder joins the host body it touches (within ``touch`` mm: the traces embedded
    in the strap), so that the slicer keeps it in place; one touching no host stands alone."""
    from designlab.geometry.printability import manifold_of

    bodies = {k: prepared.bodies[k] for k in prepared.meshes}
    host_ext = min(b.extruder for b in bodies.values())
    hosts = [k for k, b in bodies.items() if b.extruder == host_ext]
    groups = {h: [h] for h in hosts}
    alone = []
    mani = {k: manifold_of(m) for k, m in prepared.meshes.items()}
    for k, b in sorted(bodies.items(), key=lambda kv: (kv[1].extruder, kv[0])):
        if b.extruder == host_ext:
            continue
        host = next((h for h in hosts if mani[h].min_gap(mani[k], 10 * touch) <= touch), None)
        if host is None:
            alone.append([k])
        else:
            groups[host].append(k)
    return list(groups.values()) + alone


def threemf_of(prepared: Prepared, layout: bool = True) -> bytes:
    """The part's printed bodies as a 3MF: one object per :func:`print_objects` group (host body
    first, then its embedded bodies as volumes on their own extruders), laid out side by side on
    the plate (``layout``) or at their model coordinates."""
    objects = []
    for group in print_objects(prepared):
        vols = [Volume3MF(k, prepared.meshes[k].vertices, prepared.meshes[k].faces,
                          prepared.bodies[k].extruder, prepared.bodies[k].material,
                          prepared.bodies[k].color) for k in group]
        objects.append(Object3MF(f"{prepared.name}-{group[0]}", vols))
    if layout:
        objects = plate_layout(objects)
    return threemf_bytes(prepared.name, objects)


def _save_step(assy, path: Path) -> None:
    from designlab.geometry.assembly import save_assembly_step

    save_assembly_step(assy, path)


def _save_gltf(assy, path: Path) -> None:
    from designlab.geometry.assembly import save_assembly_gltf

    save_assembly_gltf(assy, path)


def _jobs(prepared: Prepared, formats: tuple[str, ...],
          png: bool) -> list[tuple[str, Callable[[Path], None]]]:
    """(file name, writer(path)) for every output of a part."""
    stem = prepared.name
    jobs: list[tuple[str, Callable[[Path], None]]] = []
    if "stl" in formats:
        for k, mesh in prepared.meshes.items():
            jobs.append((f"{stem}-{k}.stl",
                         lambda p, m=mesh: p.write_bytes(m.export(file_type="stl"))))
    if "3mf" in formats:
        jobs.append((f"{stem}.3mf", lambda p: p.write_bytes(threemf_of(prepared))))
    if "step" in formats or "gltf" in formats:
        assy_cache: list = []

        def assy():
            if not assy_cache:
                assy_cache.append(prepared.assembly() if prepared.assembly
                                  else bodies_assembly(prepared.name, prepared.bodies))
            return assy_cache[0]
        if "step" in formats:
            jobs.append((f"{stem}.step", lambda p: _save_step(assy(), p)))
        if "gltf" in formats:
            jobs.append((f"{stem}.glb", lambda p: _save_gltf(assy(), p)))
    if png:
        from designlab.geometry.render import render_bodies

        jobs.append((f"{stem}.png", lambda p: render_bodies(prepared.bodies, p, title=stem)))
    return jobs


class _Staging(FileSet):
    """A :class:`~designlab.atomic.FileSet` whose :meth:`run` renders jobs into a target
    directory."""

    def run(self, target: Path, jobs) -> None:
        from designlab.atomic import os_error, sweep_temps

        self.make_dir(target)
        sweep_temps(target)  # what a killed export left (its writer is gone)
        for fname, writer in jobs:
            tmp = self.path(target / fname)
            try:
                writer(tmp)
            except OSError as exc:
                if isinstance(exc, OutputError):   # named by the final file, not its temporary
                    raise OutputError(str(exc).replace(str(tmp), str(target / fname))) from None
                raise os_error(target / fname, exc) from None
            if tmp.stat().st_size == 0:
                raise OutputError(f"writing {fname} produced an empty file")


def write_all(prepared: Iterable[Prepared], out_dir: str | Path,
              formats: Iterable[str] = FORMATS, png: bool = True,
              progress: Callable[[str], None] | None = None) -> list[Path]:
    """Write checked parts under ``out_dir/<part>/``, all-or-nothing across every file of every
    part: each file is rendered to a temp file beside its target and only when all succeeded are
    they moved into place (``os.replace``). Returns the paths written."""
    prepared = list(prepared)
    require_printable(prepared)
    formats = parse_formats(formats)
    staging = _Staging()
    try:
        for p in prepared:
            if progress:
                progress(p.name)
            staging.run(Path(out_dir) / p.name, _jobs(p, formats, png))
    except BaseException:
        staging.abort()
        raise
    return staging.commit()


def write(prepared: Prepared, out_dir: str | Path, formats: Iterable[str] = FORMATS,
          png: bool = True) -> list[Path]:
    """Write one checked part under ``out_dir/<part>/`` (see :func:`write_all`)."""
    return write_all([prepared], out_dir, formats, png)


def export_bodies(name: str, bodies: Mapping[str, Body], out_dir: str | Path,
                  formats: Iterable[str] = FORMATS, png: bool = True, nozzle: float = 0.4,
                  layer: float = 0.1) -> list[Path]:
    """Check and write one part given as bodies (convenience for :func:`prepare` + :func:`write`)."""
    return write(prepare(name, bodies, nozzle, layer), out_dir, formats, png)


@dataclass(frozen=True)
class ExportResult:
    """Files written and the printability report of every body."""

    files: list[Path]
    reports: list[BodyReport]


def resolve_parts(target: str, overrides: Mapping[str, str] | None = None,
                  config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Part objects for ``target`` (a part name or ``"all"``) with ``--set`` overrides.

    For ``all``, overrides must name their part: ``strap.width=12``; for one part a bare
    ``width=12`` is allowed too. Unknown parts or parameters raise ParameterError.
    """
    from designlab.geometry.parts import PARTS, make_part
    from designlab.params import did_you_mean

    names = list(PARTS) if target == "all" else [target]
    if target != "all" and target not in PARTS:
        raise ParameterError("part", target, "one of " + ", ".join([*PARTS, "all"])
                             + did_you_mean(target, [*PARTS, "all"]))
    per_part: dict[str, dict[str, str]] = {n: {} for n in names}
    for key, value in (overrides or {}).items():
        part, dot, pname = key.partition(".")
        if dot and part in PARTS:
            if part not in per_part:
                raise ParameterError("--set", f"{key}={value}", f"a parameter of {target}")
            per_part[part][pname] = value
        elif target != "all":
            per_part[target][key] = value
        else:
            raise ParameterError("--set", f"{key}={value}",
                                 "PART.NAME=VALUE with PART one of " + ", ".join(PARTS)
                                 + " when exporting all parts")
    return {n: make_part(n, per_part[n] or None, dict(config) if config else None)
            for n in names}


def export_parts(parts: Mapping[str, Any], out_dir: str | Path, formats: Iterable[str] = FORMATS,
                 png: bool = True, nozzle: float = 0.4, layer: float = 0.1,
                 progress: Callable[[str, int, int], None] | None = None) -> "ExportResult":
    """Check every part, then (only if all are printable) write them all (``layer``: for parts
    without a ``layer_height`` of their own, see :func:`prepare_part`). ``progress(text, done,
    total)`` is called per step (build/check of each part, then writing of each part).
    Raises :class:`PrintabilityError` (nothing written) when a body fails its checks."""
    formats = parse_formats(formats)
    total, done = 2 * len(parts), 0
    prepared = []
    for name, part in parts.items():
        if progress:
            progress(f"build + check {name}", done, total)
        prepared.append(prepare_part(part, name, nozzle, layer))
        done += 1
    require_printable(prepared)
    counter = iter(range(done, total))

    def step(name: str) -> None:
        if progress:
            progress(f"write {name}", next(counter), total)
    files = write_all(prepared, out_dir, formats, png, step)
    if progress:
        progress("done", total, total)
    return ExportResult(files, [r for p in prepared for r in p.reports])


def write_png(bodies: Mapping[str, Body], path: str | Path, title: str = "",
              size: tuple[int, int] = (1200, 900)) -> Path:
    """Render bodies to ``path`` (PNG) atomically."""
    from designlab.geometry.render import render_bodies

    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ParameterError("--out", str(path), "a file name ending in .png")
    staging = _Staging()
    try:
        staging.run(path.parent, [(path.name, lambda p: render_bodies(
            bodies, p, size=size, title=title))])
    except BaseException:
        staging.abort()
        raise
    return staging.commit()[0]
