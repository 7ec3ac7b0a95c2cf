"""Registry of the parametric parts: ``PARTS[name]`` and :func:`make_part`."""

from __future__ import annotations

from typing import Any, Mapping

from designlab.errors import ParameterError
from designlab.geometry.fingertip import CantileverFingertip
from designlab.geometry.flexure import SpringFlexure
from designlab.geometry.strap import ArchStrap
from designlab.params import did_you_mean, with_overrides

PARTS: dict[str, type] = {"strap": ArchStrap, "fingertip": CantileverFingertip,
                          "flexure": SpringFlexure}


def make_part(name: str, overrides: Mapping[str, str | float] | None = None,
              config: Mapping[str, Any] | None = None):
    """A validated part ``name`` from defaults, then ``config``, then ``overrides``.

    ``config`` is either the part's own table (``{"h": 3}``) or a whole TOML document with a
    table named after the part (``{"fingertip": {"h": 3}, ...}``); ``overrides`` are
    ``--set NAME=VALUE`` pairs (strings are coerced to the field's type). Unknown part names and
    bad values raise a one-line :class:`ParameterError`.
    """
    if name not in PARTS:
        raise ParameterError("part", name, "one of " + ", ".join(PARTS)
                             + did_you_mean(name, PARTS))
    values: dict[str, Any] = {}
    if config:
        table = config.get(name, config)
        if not isinstance(table, Mapping):
            raise ParameterError(name, table, "a table of parameters")
        # parameters are scalars: nested tables belong to other parts or sections
        values.update({k: v for k, v in table.items() if not isinstance(v, Mapping)})
    values.update(overrides or {})
    return with_overrides(PARTS[name], values)


def part_name(part) -> str:
    """Registry name of a part instance (``"strap"``, ``"fingertip"``, ``"flexure"``)."""
    for k, cls in PARTS.items():          # its own class first, then a class it derives from
        if type(part) is cls:
            return k
    for k, cls in PARTS.items():
        if isinstance(part, cls) or issubclass(cls, type(part)):
            return k
    raise ParameterError("part", type(part).__name__, "one of " + ", ".join(PARTS))


def _add_part_api() -> None:
    """Every part class gets :class:`~designlab.geometry.api.PartAPI`'s methods (``params()``,
    ``show()``, ``render()``, ``_repr_png_``) without a change of its dataclass."""
    from designlab.geometry.api import PartAPI

    for cls in PARTS.values():
        for name in ("params", "render", "show", "_repr_png_"):
            if name not in cls.__dict__:
                setattr(cls, name, getattr(PartAPI, name))


_add_part_api()
