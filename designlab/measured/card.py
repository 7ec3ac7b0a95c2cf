"""A dataset card's declarations: units and quantities, channels, and the whole-card check.

The schema is described in :mod:`designlab.measured.dataset`; :func:`parse_card` turns a checked
card into a :class:`Card` that the reader (:func:`designlab.measured.dataset.load_card`) uses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from designlab.errors import DataError
from designlab.params import _short, did_you_mean

MAX_RATE_HZ = 100_000.0
MAX_CHANNELS = 64          #: channels of one card (a 3000-channel card ran past 5 minutes)

# canonical unit first; factor to canonical (temperature: (scale, offset))
UNITS: dict[str, dict[str, float | tuple[float, float]]] = {
    "length": {"mm": 1.0, "m": 1e3, "cm": 10.0, "um": 1e-3, "in": 25.4},
    "force": {"N": 1.0, "kN": 1e3, "mN": 1e-3},
    "resistance": {"ohm": 1.0, "kohm": 1e3, "Mohm": 1e6, "mohm": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3, "uV": 1e-6},
    "current": {"A": 1.0, "mA": 1e-3, "uA": 1e-6},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "temperature": {"C": (1.0, 0.0), "K": (1.0, -273.15)},
    "mass": {"g": 1.0, "kg": 1e3, "mg": 1e-3},
    "angle": {"deg": 1.0, "rad": 180.0 / math.pi},
    "pressure": {"MPa": 1.0, "kPa": 1e-3, "Pa": 1e-6},
    "strain": {"1": 1.0, "%": 1e-2},
    "torque": {"Nmm": 1.0, "Nm": 1e3},
}
CANONICAL = {q: next(iter(u)) for q, u in UNITS.items()}
ELECTRICAL = ("resistance", "voltage", "current")

# channel-name stem -> (quantity, kind); kind says what an input does physically
NAME_QUANTITY: dict[str, tuple[str, str]] = {
    "displacement": ("length", "drive"), "elongation": ("length", "drive"),
    "extension": ("length", "drive"), "deflection": ("length", "drive"),
    "position": ("length", "drive"), "indentation": ("length", "drive"),
    "location": ("length", "location"), "arm": ("length", "location"),
    "force": ("force", "drive"), "load": ("force", "drive"),
    "resistance": ("resistance", "drive"), "voltage": ("voltage", "drive"),
    "current": ("current", "drive"), "temperature": ("temperature", "temperature"),
    "weight": ("mass", "drive"), "mass": ("mass", "drive"), "angle": ("angle", "drive"),
    "pressure": ("pressure", "drive"), "strain": ("strain", "drive"),
    "torque": ("torque", "drive"), "time": ("time", "drive"),
}
KINDS = ("drive", "location", "temperature")


@dataclass(frozen=True)
class Channel:
    """One declared channel of the card (an input or an output)."""

    name: str
    column: str
    unit: str
    quantity: str
    kind: str = "drive"
    sign: float | str = 1.0
    time_column: str | None = None
    scale: float = 1.0
    offset: float = 0.0

    @property
    def canonical_unit(self) -> str:
        return CANONICAL[self.quantity]


def quantity_of(name: str, spec: Mapping[str, Any], where: str) -> tuple[str, str]:
    unit = spec.get("unit")
    q = spec.get("quantity")
    kind = spec.get("kind")
    stem = name.lower().split("_")[0].rstrip("0123456789")
    by_name = NAME_QUANTITY.get(stem)
    if q is None and by_name is not None:
        q = by_name[0]
    if q is None:  # unknown name: the unit decides
        owners = [qq for qq, table in UNITS.items() if unit in table]
        if len(owners) != 1:
            raise DataError(f"{where}: cannot tell the quantity of channel '{name}' from unit "
                            f"{unit!r}; set quantity = one of {', '.join(UNITS)}")
        q = owners[0]
    if q not in UNITS:
        raise DataError(f"{where}: channel '{name}' quantity={q!r} is not allowed: one of "
                        f"{', '.join(UNITS)}")
    if kind is None:
        kind = by_name[1] if by_name is not None and by_name[0] == q else (
            "temperature" if q == "temperature" else "drive")
    if kind not in KINDS:
        raise DataError(f"{where}: channel '{name}' kind={kind!r} is not allowed: one of "
                        f"{', '.join(KINDS)}")
    return q, kind


def make_channel(name: str, spec: Any, where: str, time_spec: Any) -> Channel:
    """A :class:`Channel` from its card entry; bad units raise a one-line DataError."""
    if isinstance(spec, str):
        spec = {"column": spec}
    if not isinstance(spec, Mapping) or "column" not in spec:
        raise DataError(f"{where}: channel '{name}' needs a column, e.g. "
                        f"{name} = {{ column = \"C\", unit = \"...\" }}")
    q, kind = quantity_of(name, spec, where)
    unit = spec.get("unit", CANONICAL[q])
    table = UNITS[q]
    if unit not in table:
        raise DataError(f"{where}: column '{spec['column']}' ({name}) has unit {unit!r}, "
                        f"not a {q} unit; allowed: {', '.join(table)}")
    factor = table[unit]
    scale, offset = factor if isinstance(factor, tuple) else (factor, 0.0)
    sign = spec.get("sign", 1)
    if not (sign == "auto" or sign in (1, -1)):
        raise DataError(f"{where}: channel '{name}' sign={sign!r} is not allowed: 1, -1 or \"auto\"")
    tcol = None
    if isinstance(time_spec, str):
        tcol = time_spec
    elif isinstance(time_spec, Mapping):
        tcol = time_spec.get(spec["column"], time_spec.get(name))
        if tcol is None:
            raise DataError(f"{where}: [time] column gives no clock for column "
                            f"'{spec['column']}' ({name}); add {spec['column']} = \"t...\"")
    return Channel(name=name, column=str(spec["column"]), unit=unit, quantity=q, kind=kind,
                   sign=sign if sign == "auto" else float(sign), time_column=tcol,
                   scale=float(scale), offset=float(offset))


_CARD_KEYS = ("files", "columns", "time", "inputs", "outputs", "split", "repair", "preprocess",
              "allow_outside_paths")
_FILE_KEYS = ("path", "role", "columns", "header", "sign")
_CHANNEL_KEYS = ("column", "unit", "quantity", "kind", "sign")
# key -> (type, lo, hi, lo_open): the numbers a card may hold, and where
_REPAIR = {"dropouts": (bool,), "spikes": (bool,), "spike_k": (float, 0.0, 1e6, True),
           "spike_floor": (float, 0.0, 1.0, False), "window": (int, 3, 100_001, False),
           "max_run": (int, 1, 100_000, False)}
_PREPROCESS = {"rate": (float, 0.0, MAX_RATE_HZ, True), "skip_s": (float, 0.0, 1e9, False),
               "bias_seconds": (float, 0.0, 1e9, True), "bias_channels": (list,),
               "lowpass_hz": (float, 0.0, MAX_RATE_HZ, True), "filter_order": (int, 1, 10, False)}
_SPLIT = {"train": (float, 0.0, 1.0, True)}


def _card_error(where: str, name: str, value: Any, allowed: str) -> DataError:
    return DataError(f"{where}: {name}={_short(value)!r} is not allowed: {allowed}")


def _check_keys(where: str, table: Any, known: tuple, section: str) -> None:
    if not isinstance(table, Mapping):
        raise _card_error(where, section, table, "a table")
    for k in table:
        if k not in known:
            raise DataError(f"{where}: unknown key {section + '.' if section else ''}{k} "
                            f"(allowed: {', '.join(known)}){did_you_mean(k, known)}")


def _check_numbers(where: str, section: str, table: Mapping, spec: dict) -> None:
    _check_keys(where, table, tuple(spec), section)
    for k, v in table.items():
        kind, *rng = spec[k]
        name = f"{section}.{k}"
        if kind is bool:
            if not isinstance(v, bool):
                raise _card_error(where, name, v, "true or false")
        elif kind is list:
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                raise _card_error(where, name, v, "a list of channel names")
        else:
            lo, hi, lo_open = rng
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if kind is int:
                ok = ok and isinstance(v, int)
            ok = ok and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                what = "an integer" if kind is int else "a number"
                raise _card_error(where, name, v, f"{what}, {lo:g} {'<' if lo_open else '<='} "
                                  f"value <= {hi:g}")


def check_card(card: Mapping[str, Any], where: str) -> None:
    """Every key and value of a dataset card before any file is read: unknown keys (with a
    did-you-mean: ``unti`` is never read as millimetres), types, ranges, finite numbers."""
    _check_keys(where, card, _CARD_KEYS, "")
    if not isinstance(card.get("allow_outside_paths", False), bool):
        raise _card_error(where, "allow_outside_paths", card["allow_outside_paths"],
                          "true or false")
    files = card.get("files")
    if not isinstance(files, list) or not files:
        raise DataError(f"{where}: needs at least one [[files]] entry with a path")
    for i, f in enumerate(files):
        _check_file(where, f, f"files[{i + 1}]")
    for sec, cols in [("columns", card.get("columns"))] + [
            (f"files[{i + 1}].columns", f.get("columns")) for i, f in enumerate(files)]:
        _check_columns(where, sec, cols)
    _check_time(where, card.get("time", {}))
    for group in ("inputs", "outputs"):
        _check_channels(where, group, card.get(group, {}))
    _check_numbers(where, "repair", card.get("repair", {}), _REPAIR)
    _check_numbers(where, "preprocess", card.get("preprocess", {}), _PREPROCESS)
    _check_numbers(where, "split", card.get("split", {}), _SPLIT)


def _check_file(where: str, f: Any, sec: str) -> None:
    _check_keys(where, f, _FILE_KEYS, sec)
    if not isinstance(f.get("path"), str) or not f["path"]:
        raise _card_error(where, f"{sec}.path", f.get("path"), "a file name (text)")
    if "header" in f and not isinstance(f["header"], bool):
        raise _card_error(where, f"{sec}.header", f["header"], "true or false")
    if "sign" in f and not isinstance(f["sign"], Mapping):
        raise _card_error(where, f"{sec}.sign", f["sign"], "a table channel = 1 | -1")


def _check_columns(where: str, sec: str, cols: Any) -> None:
    if cols is None:
        return
    if not isinstance(cols, list) or not cols or not all(isinstance(c, str) for c in cols):
        raise _card_error(where, sec, cols, "a list of column names")
    if len(set(cols)) != len(cols):
        raise _card_error(where, sec, cols, "distinct column names")


def _check_time(where: str, time: Any) -> None:
    _check_keys(where, time, ("column", "unit"), "time")
    col = time.get("column")
    if col is not None and not (isinstance(col, str) or (
            isinstance(col, Mapping) and all(isinstance(v, str) for v in col.values()))):
        raise _card_error(where, "time.column", col, 'a column name, or {CHANNEL = "COLUMN"}')
    if "unit" in time and not isinstance(time["unit"], str):
        raise _card_error(where, "time.unit", time["unit"], ", ".join(UNITS["time"]))


def _check_channels(where: str, group: str, chans: Any) -> None:
    if not isinstance(chans, Mapping):
        raise _card_error(where, group, chans, "a table of channels")
    for name, spec in chans.items():
        if isinstance(spec, str):
            continue
        _check_keys(where, spec, _CHANNEL_KEYS, f"{group}.{name}")
        for k in ("column", "unit", "quantity", "kind"):
            if k in spec and not isinstance(spec[k], str):
                raise _card_error(where, f"{group}.{name}.{k}", spec[k], "text")


#: the [repair] defaults
REPAIR_DEFAULTS = {"dropouts": True, "spikes": True, "spike_k": 8.0, "spike_floor": 0.15,
                   "window": 7, "max_run": 3}


@dataclass(frozen=True)
class Card:
    """A checked card's declarations: its files and channels, the time column's scale to s and
    the [repair], [preprocess] and [split] tables."""

    files: list
    channels: dict[str, tuple[str, Channel]]
    t_scale: float
    repair: dict
    preprocess: Mapping
    split: Mapping
    columns: list | None
    allow_outside: bool


def parse_card(card: Mapping[str, Any], path: Path, allow_outside: bool = False) -> Card:
    """The declarations of a card that :func:`check_card` passed; a one-line DataError for a
    missing time column, a unit that is not a time unit, a channel declared twice or with a
    name that is not a file-name part, or no output."""
    files = card.get("files")
    if not files or not isinstance(files, list):
        raise DataError(f"{path}: needs at least one [[files]] entry with a path")
    time_sec = card.get("time", {})
    if "column" not in time_sec:
        raise DataError(f"{path}: [time] needs column = \"t\" (or one per channel)")
    t_unit = time_sec.get("unit", "s")
    if t_unit not in UNITS["time"]:
        raise DataError(f"{path}: [time] unit {t_unit!r} is not a time unit; allowed: "
                        f"{', '.join(UNITS['time'])}")
    channels = _channels(card, str(path), time_sec["column"])
    return Card(files=files, channels=channels, t_scale=float(UNITS["time"][t_unit]),
                repair={**REPAIR_DEFAULTS, **card.get("repair", {})},
                preprocess=card.get("preprocess", {}), split=card.get("split", {}),
                columns=card.get("columns"),
                allow_outside=allow_outside or bool(card.get("allow_outside_paths", False)))


def _channels(card: Mapping[str, Any], where: str, tspec: Any
              ) -> dict[str, tuple[str, Channel]]:
    """Every declared channel by name: (its group, the channel)."""
    channels: dict[str, tuple[str, Channel]] = {}
    for group in ("inputs", "outputs"):
        for name, spec in (card.get(group) or {}).items():
            if name in channels:
                raise DataError(f"{where}: channel '{name}' is declared twice")
            if not name or name in (".", "..") or any(c in name for c in "/\\") or any(
                    ord(c) < 32 or ord(c) == 127 for c in name):
                # the name becomes part of output file names (plots): never a path
                raise DataError(f"{where}: channel name {name!r} is not allowed: a name "
                                "without '/', '\\' or control characters (it names output "
                                "files)")
            channels[name] = (group, make_channel(name, spec, where, tspec))
    if len(channels) > MAX_CHANNELS:   # every input against every output: the work explodes
        raise DataError(f"{where}: {len(channels)} channels are declared; at most "
                        f"{MAX_CHANNELS} in [inputs] and [outputs] together")
    seen: dict[str, str] = {}
    for name, (_, ch) in channels.items():
        if ch.column in seen:       # one signal counted as several: a singular fit
            raise DataError(f"{where}: channels '{seen[ch.column]}' and '{name}' both read "
                            f"column '{ch.column}'; allowed: one channel per column")
        seen[ch.column] = name
    if not any(g == "outputs" for g, _ in channels.values()):
        raise DataError(f"{where}: [outputs] declares no channel")
    return channels

def data_path(card_path: Path, name: str, allow_outside: bool) -> Path:
    """A data file named in a card, confined to the card's folder (symbolic links resolved)
    unless outside paths are allowed (``allow_outside_paths = true`` or the caller's flag)."""
    base = card_path.parent.resolve()
    p = (base / name).resolve()
    if not allow_outside and not p.is_relative_to(base):
        raise DataError(f"{card_path}: file {name!r} is outside the card's folder {base}; "
                        "set allow_outside_paths = true in the card to read it")
    return p
