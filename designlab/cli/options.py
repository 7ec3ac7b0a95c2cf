"""Option values the commands share, checked before any work: number ranges, part configs,
name lists, the executor of a sweep or Monte Carlo, and the part names for completion."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

from designlab.errors import ParameterError
from designlab.params import _short, did_you_mean, load_toml


def sensor_names(incomplete: str = "") -> list[str]:
    """Completion choices of a PART argument: the names in ``SENSORS``."""
    from designlab.sensors.registry import SENSORS

    return [n for n in SENSORS if n.startswith(incomplete)]


def part_arg(value: str) -> str:
    """A PART argument: a sensor's name, or a sensor definition ``FILE.py[:Class]`` /
    ``module:Class`` (loaded and registered; its name is returned)."""
    from designlab.sensors.registry import looks_like_definition, resolve

    return resolve(value) if looks_like_definition(value) else value


def export_names(incomplete: str = "") -> list[str]:
    return [n for n in (*sensor_names(), "all") if n.startswith(incomplete)]


def check_options(*specs) -> None:
    """Options before any work: ``(name, value, lo, hi)`` -> a finite number in [lo, hi]
    (an integer when ``lo`` is an int); None values (unset options) are skipped."""
    for name, value, lo, hi in specs:
        if value is None:
            continue
        if isinstance(lo, int) and not isinstance(lo, bool):
            if not isinstance(value, int) or not lo <= value <= hi:
                raise ParameterError(name, value, f"an integer, {lo} <= value <= {hi}")
        elif not (math.isfinite(value) and lo <= value <= hi):
            raise ParameterError(name, value, f"a finite number, {lo:g} <= value <= {hi:g}")


def split_names(values: Optional[List[str]]) -> list[str]:
    """Repeated and/or comma-separated option values -> a flat list of names."""
    return [v.strip() for item in values or [] for v in item.split(",") if v.strip()]


def check_scheduler(address: str, timeout_s: float = 10.0) -> None:
    """A Dask scheduler answers at ``address`` (a client connects and closes again), checked
    before a command writes anything into its ``--out``."""
    try:
        from distributed import Client
    except ImportError:
        raise ParameterError("--scheduler", address,
                             "Dask installed: pip install 'designlab[cluster]'") from None
    try:
        client = Client(address, timeout=f"{timeout_s:g}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ParameterError("--scheduler", address,
                             f"the address of a reachable Dask scheduler ({exc})") from None
    client.close()


def make_executor(scheduler: Optional[str], workers: Optional[int]):
    """``--scheduler`` (a Dask address) or local worker processes."""
    from designlab.optimize.executors import DaskExecutor, LocalExecutor

    if scheduler:
        if not scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
            raise ParameterError("--scheduler", scheduler, "a Dask address like tcp://HOST:PORT")
        check_scheduler(scheduler)
        return DaskExecutor(scheduler)
    return LocalExecutor(workers)


def part_config(target: str, cfg: Optional[dict], where: str = "--config") -> Optional[dict]:
    """A part config as ``make_part`` reads it, checked: either the part's own parameters or
    ``[PART]`` tables (required for ``all``); a table inside a part's table, or a top-level
    table that is not a part, is an error (never dropped)."""
    from designlab.geometry.parts import PARTS

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
        if target != "all" and target not in tables:   # else the defaults, silently
            raise ParameterError(where, "[" + "], [".join(tables) + "]",
                                 f"a [{target}] table (or {target}'s parameters at the top "
                                 "level) for this part")
    else:
        tables[target] = cfg
    for part, table in tables.items():
        for k, v in table.items():
            if isinstance(v, (dict, list)):
                raise ParameterError(f"{part}.{k}" if per_part else k, _short(v),
                                     "a single value (a number, text or true/false), not a "
                                     + ("table" if isinstance(v, dict) else "list"))
    return {n: tables.get(n, {}) for n in names} if per_part else cfg


def config_file(part: str, config: Optional[Path]) -> Optional[dict]:
    """``--config FILE`` read and checked by :func:`part_config` (None without the option)."""
    return part_config(part, load_toml(config)) if config is not None else None


def short(v) -> str:
    """A value for a table cell: floats to 3 significant digits, containers element-wise."""
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(short(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {short(x)}" for k, x in v.items()) + "}"
    return str(v)
