"""Modules that build123d imports at its own import but uses inside a few functions only, put
off until first used (``sympy``: one tangent-arc constructor no designlab part calls). A
stand-in in ``sys.modules`` imports the real module on its first attribute lookup
(docs/models/lazy_imports.md)."""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types

#: what is put off (none of them is imported by designlab itself)
DEFERRED = ("sympy",)


def defer(name: str) -> None:
    """Put ``name``'s import off until an attribute of it is first used (no effect when it is
    imported already or not installed)."""
    if name in sys.modules:
        return
    spec = importlib.util.find_spec(name)
    if spec is None:
        return
    stand_in = types.ModuleType(name, f"stand-in for {name}, imported on first use")
    stand_in.__spec__ = spec
    stand_in.__file__ = spec.origin
    # no __path__: importing a submodule looks it up, which imports the real package first

    def __getattr__(attr: str):
        real = sys.modules.get(name)
        if real is stand_in or real is None:
            sys.modules.pop(name, None)
            try:
                real = importlib.import_module(name)
            except BaseException:
                sys.modules[name] = stand_in
                raise
        return getattr(real, attr)

    stand_in.__getattr__ = __getattr__
    sys.modules[name] = stand_in


for _name in DEFERRED:
    defer(_name)
