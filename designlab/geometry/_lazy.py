"""Modules that build123d imports at its own import but uses inside a few functions only, put
off until first used. ``sympy``: ``build123d.objects_curve`` imports it for one tangent-arc
constructor, which no designlab part calls (``import build123d`` 3.13 s CPU with it put off, 3.58
s without, ``python benchmarks/bench_imports.py``, 2-core machine, 2026-11-26).

A stand-in module is placed in ``sys.modules`` with the real module's ``__spec__`` (the import
system reads ``__spec__`` on every ``import``, which is why :class:`importlib.util.LazyLoader`
loads at once here); its first attribute lookup imports the real module, which then replaces
it in ``sys.modules``, and the stand-in forwards every later lookup to it."""

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
