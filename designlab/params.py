"""Frozen parameter dataclasses: validation, overrides from ``NAME=VALUE`` and TOML.

A part or protocol is a frozen dataclass whose fields carry their allowed range in the field
metadata (``field(default=..., metadata=rng(lo, hi))``). :func:`validate` checks every field, and
:func:`replace_from_strings` builds a new instance from ``--set NAME=VALUE`` pairs, naming the
parameter and its allowed range in a one-line :class:`ParameterError` when something is wrong.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import tomllib
from pathlib import Path
from typing import Any, Iterable, Mapping, TypeVar

from designlab.errors import ParameterError

#: limits of what the input layer reads (a config or card is small; data files are read elsewhere)
MAX_TEXT_BYTES = 8 * 1024 * 1024       # a TOML/JSON document
MAX_DEPTH = 32                         # nesting of tables/arrays in it
REL_TOL = 1e-9                         # boundaries: a value this close to a bound is on it

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
            hint = did_you_mean(value, meta["choices"]) if isinstance(value, str) else ""
            raise ParameterError(name, value, allowed_text(meta) + hint)
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if meta.get("lo") is None and meta.get("hi") is None:
            return
        raise ParameterError(name, value, "a number, " + allowed_text(meta))
    if not math.isfinite(value):
        raise ParameterError(name, value, "a finite number, " + allowed_text(meta))
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and not above(value, lo, open_=bool(meta.get("lo_open"))):
        raise ParameterError(name, value, allowed_text(meta))
    if hi is not None and not above(hi, value, open_=bool(meta.get("hi_open"))):
        raise ParameterError(name, value, allowed_text(meta))


def close(a: float, b: float, rel: float = REL_TOL) -> bool:
    """``a`` and ``b`` equal up to rounding (relative ``rel``, absolute ``rel`` near 0)."""
    return abs(a - b) <= rel * max(1.0, abs(a), abs(b))


def above(value: float, bound: float, *, open_: bool = False, rel: float = REL_TOL) -> bool:
    """``value >= bound`` (``>`` when ``open_``) with rounding tolerance: a value that prints
    as the bound is on the bound, so ``2.4 >= 2.4000000000000004`` holds."""
    if open_:
        return value > bound and not close(value, bound, rel)
    return value >= bound or close(value, bound, rel)


def fmt_bound(x: float) -> str:
    """A bound as the user would type it: 12 significant digits, rounding noise below
    1e-12 shown as 0 (never ``-2.78e-17``)."""
    if abs(x) < 1e-12:
        x = 0.0
    return f"{x:.12g}"


def _fmt_toward(x: float, up: bool, digits: int = 5) -> str:
    """``x`` as short text that is still an allowed value: the shortest decimal (up to 6
    significant digits) equal to ``x`` up to rounding, else ``x`` rounded to ``digits``
    significant digits *inward* (up for a lower bound, down for an upper one), so typing the printed bound
    back is always accepted."""
    if abs(x) < 1e-12:
        return "0"
    for d in range(1, 7):
        s = f"{x:.{d}g}"
        if close(float(s), x):
            return s
    e = math.floor(math.log10(abs(x))) - (digits - 1)
    q = x / 10.0 ** e
    q = math.ceil(q) if up else math.floor(q)
    return f"{q * 10.0 ** e:.{digits + 1}g}"


def fmt_lo(x: float) -> str:
    """A lower bound as an allowed value (rounded up when it is not short)."""
    return _fmt_toward(x, True)


def fmt_hi(x: float) -> str:
    """An upper bound as an allowed value (rounded down when it is not short)."""
    return _fmt_toward(x, False)


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""


def _why(why: str) -> str:
    return f" ({why})" if why else ""


def at_least(name: str, value: float, bound: float, why: str = "", unit: str = "mm") -> None:
    """``value >= bound`` up to rounding, else a one-line :class:`ParameterError` printing the
    bound as an allowed value: ``slot_pitch=2.3 is not allowed: >= 2.4 mm (why)``."""
    if not above(value, bound):
        raise ParameterError(name, value, f">= {fmt_lo(bound)}{_unit(unit)}{_why(why)}")


def at_most(name: str, value: float, bound: float, why: str = "", unit: str = "mm") -> None:
    """``value <= bound`` up to rounding (see :func:`at_least`)."""
    if not above(bound, value):
        raise ParameterError(name, value, f"<= {fmt_hi(bound)}{_unit(unit)}{_why(why)}")


def within(name: str, value: float, lo: float, hi: float, why: str = "",
           unit: str = "mm") -> None:
    """``lo <= value <= hi`` up to rounding. The caller makes sure the range is not empty (an
    empty range is a constraint of other parameters, which the caller names instead)."""
    if not (above(value, lo) and above(hi, value)):
        for digits in range(5, 16):  # a narrow range gets the digits it needs to stay ordered
            a, b = _fmt_toward(lo, True, digits), _fmt_toward(hi, False, digits)
            if float(a) <= float(b):
                break
        if close(lo, hi) or float(a) > float(b):
            text = f"= {fmt_bound((lo + hi) / 2)}"  # a single value (up to rounding)
        else:
            text = f"{a} <= value <= {b}"
        raise ParameterError(name, value, f"{text}{_unit(unit)}{_why(why)}")


def field_range(cls_or_obj: Any, name: str) -> tuple[float, float]:
    """The documented ``(lo, hi)`` of a field (``-inf``/``inf`` where open)."""
    for f in dataclasses.fields(cls_or_obj):
        if f.name == name:
            lo, hi = f.metadata.get("lo"), f.metadata.get("hi")
            return (-math.inf if lo is None else lo, math.inf if hi is None else hi)
    raise KeyError(name)


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` when ``name`` is close to one of ``choices``, else ``""``."""
    m = difflib.get_close_matches(str(name), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {m[0]!r}?)" if m else ""


def check_keys(data: Mapping[str, Any], known: Iterable[str], where: str = "") -> None:
    """Unknown keys of a table -> :class:`ParameterError` naming the key, the allowed keys and
    the closest one (a typo such as ``unti`` must never be ignored)."""
    known = list(known)
    for k, v in data.items():
        if k not in known:
            name = f"{where}.{k}" if where else str(k)
            raise ParameterError(name, _short(v), "a key of " + (where or "the file") + ": "
                                 + ", ".join(sorted(known)) + did_you_mean(k, known))


def _short(v: Any, limit: int = 60) -> Any:
    """A value for an error message: scalars as they are, containers abbreviated."""
    if isinstance(v, (dict, list, tuple)):
        text = repr(v)
        return text if len(text) <= limit else text[:limit - 3] + "..."
    if isinstance(v, str) and len(v) > limit:
        return v[:limit - 3] + "..."
    return v


def check_tree(data: Any, where: str, max_depth: int = MAX_DEPTH) -> None:
    """Nesting at most ``max_depth`` and every float finite (TOML and JSON allow ``inf``/``nan``
    literals; none of the package's inputs means them). Iterative: no recursion limit."""
    stack = [(data, where, 0)]
    while stack:
        v, path, depth = stack.pop()
        if depth > max_depth:
            raise ParameterError(path, "...", f"nesting of at most {max_depth} levels")
        if isinstance(v, float) and not math.isfinite(v):
            raise ParameterError(path, v, "a finite number")
        if isinstance(v, dict):
            stack.extend((w, f"{path}.{k}", depth + 1) for k, w in v.items())
        elif isinstance(v, (list, tuple)):
            stack.extend((w, f"{path}[{i}]", depth + 1) for i, w in enumerate(v))


def read_text(path: str | Path, what: str, kind: str, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of a small input file; missing, a directory, unreadable, too big, binary
    or not UTF-8 -> one-line :class:`ParameterError` naming ``what`` (never the contents)."""
    p = Path(path)
    allowed = f"an existing {kind} file"
    try:
        if not p.exists():
            raise ParameterError(what, str(p), allowed)
        if p.is_dir():
            raise ParameterError(what, str(p), f"{allowed} (it is a directory)")
        if not p.is_file():
            raise ParameterError(what, str(p), f"{allowed} (not a regular file)")
        size = p.stat().st_size
        if size > max_bytes:
            raise ParameterError(what, str(p), f"a {kind} file of at most {max_bytes} bytes "
                                 f"(it has {size})")
        raw = p.read_bytes()
    except PermissionError:
        raise ParameterError(what, str(p), f"a readable {kind} file (permission denied)") from None
    except OSError as exc:
        raise ParameterError(what, str(p), f"a readable {kind} file ({exc.strerror})") from None
    if b"\x00" in raw:
        raise ParameterError(what, str(p), f"a {kind} text file (it is binary)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ParameterError(what, str(p), f"a UTF-8 {kind} file (byte {exc.start} is not "
                             "UTF-8)") from None


def check_type(name: str, value: Any, default: Any) -> None:
    """The value's type agrees with the field's default: a bool for a bool, an integer for an
    int, a number for a float, text for a string, a list for a tuple."""
    if isinstance(default, bool):
        ok, want = isinstance(value, bool), "true or false"
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
        want = "an integer"
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        want = "a number"
    elif isinstance(default, str):
        ok, want = isinstance(value, str), "text"
    elif isinstance(default, tuple):
        ok, want = isinstance(value, tuple), "a list"
    else:
        return
    if not ok:
        raise ParameterError(name, _short(value), want)


def _plain(obj: Any, name: str) -> Any:
    """Field ``name`` of ``obj``, a numpy scalar (np.int64(3)) replaced by its Python number."""
    v = getattr(obj, name)
    if type(v).__module__ == "numpy" and getattr(v, "ndim", None) == 0:
        v = v.item()
        object.__setattr__(obj, name, v)
    return v


def whole_numbers(obj: Any, names: Iterable[str]) -> None:
    """Counts of a (frozen) parameter dataclass given as whole floats (4.0 from TOML, JSON or a
    sweep's grid) become ints; 4.5 or a bool is a ParameterError naming the field."""
    for name in names:
        v = _plain(obj, name)
        if isinstance(v, float) and v.is_integer():
            object.__setattr__(obj, name, int(v))
        elif not isinstance(v, int) or isinstance(v, bool):
            raise ParameterError(name, v, "an integer")


def validate(obj: Any) -> None:
    """Check every field of a parameter dataclass: its type (as its default's) and its
    declared range. A numpy scalar becomes the Python number it holds."""
    for f in dataclasses.fields(obj):
        _plain(obj, f.name)
        if f.default is not dataclasses.MISSING:
            check_type(f.name, getattr(obj, f.name), f.default)
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


def load_toml(path: str | Path, what: str = "--config") -> dict[str, Any]:
    """Read a TOML file: missing, binary, not UTF-8, malformed, too deep or with non-finite
    numbers -> a one-line ParameterError naming ``what``."""
    text = read_text(path, what, "TOML")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(what, str(path), f"valid TOML ({_one_line(exc)})") from None
    except RecursionError:
        raise ParameterError(what, str(path), f"TOML nested at most {MAX_DEPTH} levels") from None
    check_tree(data, what)
    return data


def load_json(path: str | Path, what: str, max_bytes: int = MAX_TEXT_BYTES) -> Any:
    """Read a JSON file (same checks as :func:`load_toml`; ``NaN``/``Infinity`` are refused:
    the package writes null)."""
    text = read_text(path, what, "JSON", max_bytes)

    def no_constant(name: str):
        raise ValueError(f"{name} is not a JSON number")

    try:
        data = json.loads(text, parse_constant=no_constant)
    except RecursionError:
        raise ParameterError(what, str(path), f"JSON nested at most {MAX_DEPTH} levels") from None
    except ValueError as exc:
        msg = exc.msg if isinstance(exc, json.JSONDecodeError) else str(exc)
        raise ParameterError(what, str(path), f"valid JSON ({msg})") from None
    check_tree(data, what)
    return data


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200]


def with_overrides(cls_or_obj: type[T] | T, values: Mapping[str, Any]) -> T:
    """New validated instance with ``values`` (strings are coerced to the field's type).

    Unknown names raise :class:`ParameterError` listing the known parameters.
    """
    base = cls_or_obj() if isinstance(cls_or_obj, type) else cls_or_obj
    fields = {f.name: f for f in dataclasses.fields(base)}
    kwargs = {}
    for k, v in values.items():
        if k not in fields:
            raise ParameterError(k, _short(v), "a parameter of " + type(base).__name__ + ": "
                                 + ", ".join(sorted(fields)) + did_you_mean(k, fields))
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
