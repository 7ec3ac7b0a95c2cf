"""Frozen parameter dataclasses: validation, overrides from ``NAME=VALUE`` and TOML.

A part or protocol is a frozen dataclass whose fields carry their allowed range in the field
metadata (``field(default=..., metadata=rng(lo, hi))``). :func:`validate` checks every field, and
:func:`replace_from_strings` builds a new instance from ``--set NAME=VALUE`` pairs, naming the
parameter and its allowed range in a one-line :class:`ParameterError` when something is wrong.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any, Mapping, TypeVar

from designlab.errors import ParameterError

T = TypeVar("T")


def rng(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
        hi_open: bool = False, unit: str = "", choices: tuple | None = None, doc: str = "") -> dict:
    """Field metadata for an allowed range ``[lo, hi]`` (open ends with ``*_open``) or choices."""
    return {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "unit": unit,
            "choices": choices, "doc": doc}


def allowed_text(meta: Mapping[str, Any]) -> str:
    """Human text for a field's allowed values, e.g. ``0 < value <= 9 mm``."""
    if meta.get("choices"):
        return "one of " + ", ".join(map(str, meta["choices"]))
    lo, hi, unit = meta.get("lo"), meta.get("hi"), meta.get("unit", "")
    parts = []
    if lo is not None:
        parts.append(f"{lo:g} {'<' if meta.get('lo_open') else '<='} value")
    if hi is not None:
        parts.append(f"value {'<' if meta.get('hi_open') else '<='} {hi:g}")
    text = " and ".join(parts) if parts else "any value"
    return f"{text}{(' ' + unit) if unit else ''}"


def check_field(name: str, value: Any, meta: Mapping[str, Any]) -> None:
    """Raise :class:`ParameterError` if ``value`` violates the field's metadata."""
    if meta.get("choices"):
        if value not in meta["choices"]:
            raise ParameterError(name, value, allowed_text(meta))
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if meta.get("lo") is None and meta.get("hi") is None:
            return
        raise ParameterError(name, value, "a number, " + allowed_text(meta))
    if not math.isfinite(value):
        raise ParameterError(name, value, "a finite number, " + allowed_text(meta))
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and (value < lo or (meta.get("lo_open") and value == lo)):
        raise ParameterError(name, value, allowed_text(meta))
    if hi is not None and (value > hi or (meta.get("hi_open") and value == hi)):
        raise ParameterError(name, value, allowed_text(meta))


def validate(obj: Any) -> None:
    """Check every field of a parameter dataclass against its declared range."""
    for f in dataclasses.fields(obj):
        if f.metadata:
            check_field(f.name, getattr(obj, f.name), f.metadata)


def _coerce(name: str, text: str, default: Any) -> Any:
    if isinstance(default, bool):
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ParameterError(name, text, "true or false")
    if isinstance(default, int):
        try:
            return int(text)
        except ValueError:
            raise ParameterError(name, text, "an integer") from None
    if isinstance(default, float):
        try:
            return float(text)
        except ValueError:
            raise ParameterError(name, text, "a number") from None
    return text


def parse_sets(pairs: list[str] | None) -> dict[str, str]:
    """``["h=3", "r=9"]`` -> ``{"h": "3", "r": "9"}``; malformed pairs raise ParameterError."""
    out: dict[str, str] = {}
    for p in pairs or []:
        if "=" not in p:
            raise ParameterError("--set", p, "NAME=VALUE")
        k, v = p.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; a missing or malformed file raises a one-line ParameterError."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError("--config", str(p), "an existing TOML file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("--config", str(p), f"valid TOML ({exc})") from None


def with_overrides(cls_or_obj: type[T] | T, values: Mapping[str, Any]) -> T:
    """New validated instance with ``values`` (strings are coerced to the field's type).

    Unknown names raise :class:`ParameterError` listing the known parameters.
    """
    base = cls_or_obj() if isinstance(cls_or_obj, type) else cls_or_obj
    fields = {f.name: f for f in dataclasses.fields(base)}
    kwargs = {}
    for k, v in values.items():
        if k not in fields:
            raise ParameterError(k, v, "a parameter of " + type(base).__name__ + ": "
                                 + ", ".join(sorted(fields)))
        default = getattr(base, k)
        kwargs[k] = _coerce(k, v, default) if isinstance(v, str) else (
            float(v) if isinstance(default, float) and isinstance(v, int)
            and not isinstance(v, bool) else v)
    obj = dataclasses.replace(base, **kwargs)
    validate(obj)
    return obj


def as_dict(obj: Any) -> dict[str, Any]:
    """Parameters as a plain JSON-able dict."""
    return dataclasses.asdict(obj)
