"""Run folders: the ``run.json`` a command writes into its ``--out``, the checks before a
folder is (re)used, and the one-writer lock a sweep or optimize holds on its folder."""

from __future__ import annotations

import dataclasses
import errno
import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Optional

from designlab.atomic import atomic_write_json, out_lock
from designlab.cli.app import one_line
from designlab.errors import OutputError

#: commands that may share an output folder: optimize exports what sweep evaluated; exports
#: of different parts go to their own subfolders (PART/)
FAMILIES = {"sweep": "sweep", "optimize": "sweep", "export": "export"}

#: files and folders of a sweep/optimize run that ``--overwrite`` removes (the FEM and design
#: caches stay: they are keyed by what they depend on, so another config can share them)
#: longest name of one folder or file (bytes) on the usual file systems
NAME_MAX = 255

SWEEP_OUTPUTS = ("results", "results.parquet", "optimize.json", "report.html", "pareto.png",
                 "sensitivity.png", "chosen", "run.json")


def family(what: str) -> str:
    """The family of commands a ``run.json``'s ``what`` belongs to (commands of one family
    share a folder)."""
    head = str(what).split(" ", 1)[0]
    return FAMILIES.get(head, str(what))


def read_run(out: Path) -> Optional[dict]:
    """The folder's ``run.json`` (None: none or unreadable)."""
    try:
        doc = json.loads((Path(out) / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and doc.get("format") == "designlab-run" else None


def config_identity(cfg, uncertainty=None) -> str:
    """A sweep config's fingerprint (sha256 of the parsed config: part, swept and fixed
    parameters, settings, protocol, objectives, constraints, and the [uncertainty] spec of a
    robust sweep): a folder resumes only its own."""
    doc = dataclasses.asdict(cfg)
    if uncertainty is not None:
        doc["uncertainty"] = (dataclasses.asdict(uncertainty)
                              if dataclasses.is_dataclass(uncertainty) else repr(uncertainty))
    text = json.dumps(doc, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def write_run(out: Path, what: str, settings: dict, identity: Optional[str] = None) -> Path:
    """``run.json`` of a command's output folder (command, version, date, settings; the
    identity ``--out`` compares before reusing the folder)."""
    from designlab.predict.record import run_manifest

    doc = run_manifest(what, settings)
    if identity is not None:
        doc["identity"] = identity
    atomic_write_json(Path(out) / "run.json", doc)
    return Path(out) / "run.json"


def _clear_sweep(out: Path) -> None:
    """Remove a sweep/optimize run's outputs (:data:`SWEEP_OUTPUTS`) from ``out``."""
    for name in SWEEP_OUTPUTS:
        p = out / name
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        elif p.exists() or p.is_symlink():
            p.unlink()


def check_reuse(out: Path, what: str, identity: Optional[str], overwrite: bool) -> None:
    """A non-empty ``--out`` whose ``run.json`` names another command (or, for a sweep, another
    config) is refused unless ``--overwrite``; with it, a sweep's previous rows are removed so
    the two runs never mix. A folder without ``run.json`` is used as it is."""
    out = Path(out)
    if not out.is_dir() or not any(out.iterdir()):
        return
    prev = read_run(out)
    if prev is None:
        return
    same = family(prev.get("what", "")) == family(what) and (
        identity is None or prev.get("identity") in (None, identity))
    if same:
        return
    if not overwrite:
        was = str(prev.get("command") or prev.get("what") or "another run")
        raise OutputError(
            f"--out={str(out)!r} holds another run ({one_line(was, 200)}, "
            f"{prev.get('date', 'date unknown')}): choose another folder, or add --overwrite "
            f"to replace it")
    if family(prev.get("what", "")) == "sweep":
        _clear_sweep(out)
    else:
        (out / "run.json").unlink(missing_ok=True)


def _writable_folder(out: Path) -> None:
    """``--out`` is (or can become) a folder this process may write: not a file, not under
    /proc, /sys or /dev, the nearest existing folder on its path writable."""
    real = os.path.realpath(out)
    if real in ("/proc", "/sys", "/dev") or real.startswith(("/proc/", "/sys/", "/dev/")):
        raise OutputError(f"--out={str(out)!r} is not allowed: a folder on a normal file system "
                          "(not under /proc, /sys or /dev)")
    p = Path(real)
    try:
        if any(len(os.fsencode(part)) > NAME_MAX for part in p.parts):
            raise OSError(errno.ENAMETOOLONG, "")   # also in folders not made yet
        os.stat(p)
    except FileNotFoundError:
        pass
    except OSError as exc:   # a name longer than the system allows, a loop of links...
        raise OutputError(f"--out={one_line(out, 80)!r} is not allowed: "
                          f"{os.strerror(exc.errno).lower()}") from None
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


def check_out(out: Optional[Path], what: Optional[str] = None, identity: Optional[str] = None,
              overwrite: bool = False) -> None:
    """``--out`` before any work: not a file, not under /proc, /sys or /dev, and the nearest
    existing folder on its path writable (nothing is created yet). With ``what`` (the command
    writing ``run.json``): a folder holding another run is refused unless ``overwrite``
    (:func:`check_reuse`)."""
    if out is None:
        return
    _writable_folder(out)
    if what is not None:
        check_reuse(Path(out), what, identity, overwrite)


def start_sweep_run(ctx, out: Path, what: str, config: Path, cfg, overwrite: bool,
                    evaluator=None) -> None:
    """Refuse (or, with ``--overwrite``, clear) an ``--out`` holding another config's run, then
    write ``run.json`` first: a killed run's folder still says which config it resumes."""
    identity = config_identity(cfg, getattr(evaluator, "spec", None))
    if not overwrite:
        check_reuse(out, what, identity, overwrite=False)
    # the folder's one writer from here to the end of the command (the sweep under it shares
    # the lock): --overwrite never removes the rows of a run still writing them
    ctx.with_resource(out_lock(out, f"designlab {what}"))
    check_reuse(out, what, identity, overwrite)
    out.mkdir(parents=True, exist_ok=True)
    write_run(out, what, {"config": str(config), "config_sha256_16": identity,
                          "part": cfg.part, "method": cfg.method,
                          "settings": cfg.settings, "protocol": cfg.protocol}, identity)
