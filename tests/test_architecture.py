"""The layout of docs/architecture.md: imports go one way, and only geometry/ and sensors/ name a
sensor kind."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "designlab"

#: bottom to top; a module may import from its own layer and the layers below it
LAYERS = [
    {"errors", "params", "atomic", "frames", "version"},
    {"geometry"},
    {"mesh"},
    {"fem"},
    {"calibration"},
    {"measured"},
    {"loop"},
    {"sensors"},
    {"predict"},
    {"optimize"},
    {"cli"},
    # the package root is the Python API's facade (dl.Fingertip, dl.predict): it may import
    # anything, and nothing imports from it
    {"__init__"},
]


def _layer(top: str) -> int:
    for i, names in enumerate(LAYERS):
        if top in names:
            return i
    raise AssertionError(f"designlab.{top} is in no layer of tests/test_architecture.py")


def _top(module: str) -> str:
    return module.split(".")[1] if module.count(".") else "__init__"


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every ``designlab.*`` module imported anywhere in ``path`` (function bodies and
    TYPE_CHECKING blocks included)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "designlab":
                out += [(node.lineno, f"designlab.{a.name}") for a in node.names]
            elif node.module.startswith("designlab."):
                out.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("designlab.")]
    return out


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).with_suffix("")
        yield path, ".".join(rel.parts)


def upward_imports() -> list[str]:
    bad = []
    for path, mod in _modules():
        here = _layer(_top(mod))
        for line, target in _imports(path):
            if _layer(_top(target)) > here:
                bad.append(f"{path.relative_to(PKG.parent)}:{line} imports {target}")
    return bad


def test_imports_go_one_way():
    assert upward_imports() == []


def test_the_checker_sees_an_upward_import(tmp_path, monkeypatch):
    """An upward import (fem -> sensors) in a module is found, also inside a function."""
    fake = tmp_path / "designlab"
    (fake / "fem").mkdir(parents=True)
    (fake / "sensors").mkdir()
    (fake / "fem" / "bad.py").write_text(
        "def f():\n    from designlab.sensors.registry import SENSORS\n    return SENSORS\n")
    (fake / "sensors" / "ok.py").write_text("from designlab.fem import Model\n")
    monkeypatch.setattr(__import__(__name__), "PKG", fake)
    assert upward_imports() == ["designlab/fem/bad.py:2 imports designlab.sensors.registry"]


def import_graph() -> dict[str, set[str]]:
    """module -> the designlab modules it imports anywhere (function bodies included), with
    ``from package import submodule`` resolved to the submodule and relative imports to their
    absolute names. A package's ``__init__`` counts only when a name is taken from it."""
    mods = dict((m.removesuffix(".__init__"), p) for p, m in _modules())
    graph: dict[str, set[str]] = {}
    for mod, path in mods.items():
        pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        out = graph.setdefault(mod, set())
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names if a.name in mods}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = pkg.split(".")[:len(pkg.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    out.add(sub if sub in mods else base)
        out &= set(mods)
        out.discard(mod)
    return graph


def import_cycle() -> list[str]:
    """One circle of imports among designlab's modules (empty when there is none)."""
    import graphlib

    try:
        graphlib.TopologicalSorter(import_graph()).prepare()
    except graphlib.CycleError as exc:
        return list(exc.args[1])
    return []


def test_no_circle_of_imports():
    """Within a layer too, imports go one way: a helper module never imports the module that
    uses it, not even inside a function (a sensor's settings and constants sit below its
    virtual test, the Monte Carlo's input types below the runner, the registry above the
    sensors)."""
    assert import_cycle() == []


def test_the_circle_check_sees_a_circle_through_a_function(tmp_path, monkeypatch):
    fake = tmp_path / "designlab"
    (fake / "sensors").mkdir(parents=True)
    (fake / "sensors" / "__init__.py").write_text("")
    (fake / "sensors" / "a.py").write_text("from designlab.sensors import b\n")
    (fake / "sensors" / "b.py").write_text("def f():\n    from .a import x\n    return x\n")
    (fake / "sensors" / "c.py").write_text("from designlab.sensors import a\n")
    monkeypatch.setattr(__import__(__name__), "PKG", fake)
    assert sorted(set(import_cycle())) == ["designlab.sensors.a", "designlab.sensors.b"]
    (fake / "sensors" / "b.py").write_text("def f():\n    return 1\n")
    assert import_cycle() == []


SENSOR_NAME = re.compile(r"""["'](fingertip|strap|flexure)["']""")

#: everything outside geometry/ and sensors/: the layers' folders, the root modules, the API
#: facade and the CLI (its help examples name sensors in running text, never as a quoted name)
NO_SENSOR_NAMES = ["mesh", "fem", "calibration", "measured", "loop", "predict", "optimize", "errors.py",
                   "params.py", "atomic.py", "frames.py", "version.py", "__init__.py", "cli"]


def sensor_names(where: str) -> list[str]:
    """Lines of ``designlab/<where>`` (a folder or a root module) that name a sensor kind as a
    string."""
    root = PKG / where
    hits = []
    for path in sorted(root.rglob("*.py") if root.is_dir() else [root]):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if SENSOR_NAME.search(line):
                hits.append(f"{path.relative_to(PKG.parent)}:{i}: {line.strip()}")
    return hits


@pytest.mark.parametrize("where", NO_SENSOR_NAMES)
def test_no_sensor_named_outside_geometry_and_sensors(where):
    assert (PKG / where).exists()
    assert sensor_names(where) == []


def test_every_module_outside_geometry_and_sensors_is_checked():
    """A new root module or layer folder is in NO_SENSOR_NAMES (or in geometry/, sensors/)."""
    tops = {p.name for p in PKG.iterdir() if (p.is_dir() and (p / "__init__.py").exists())
            or p.suffix == ".py"}
    assert tops - {"geometry", "sensors"} == set(NO_SENSOR_NAMES)


def test_the_sensor_name_check_sees_a_lookup_by_name(tmp_path, monkeypatch):
    fake = tmp_path / "designlab"
    fake.mkdir()
    (fake / "__init__.py").write_text('Fingertip = PARTS["fingertip"]\nx = "fingertips"\n')
    monkeypatch.setattr(__import__(__name__), "PKG", fake)
    assert sensor_names("__init__.py") == ['designlab/__init__.py:1: Fingertip = PARTS["fingertip"]']


def test_solvers_are_one_table():
    """``solver`` choices and ``factorize``'s dispatch come from ``fem.solvers.KINDS``: each
    entry's class has that kind, and an unknown name is a one-line ParameterError."""
    import numpy as np
    import scipy.sparse as sp

    from designlab.errors import ParameterError
    from designlab.fem.settings import FEMSettings
    from designlab.fem.solvers import KINDS, SOLVERS, LinearSolver, factorize, has_cholmod
    from designlab.fem.solvers import has_pardiso
    import dataclasses

    assert SOLVERS == ("auto", *KINDS)
    solver = next(f for f in dataclasses.fields(FEMSettings) if f.name == "solver")
    assert tuple(solver.metadata["choices"]) == SOLVERS
    n = 40
    K = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tocsr()
    F = np.arange(1.0, n + 1)
    available = {"pardiso": has_pardiso(), "cholmod": has_cholmod()}
    for name, cls in KINDS.items():
        assert issubclass(cls, LinearSolver) and cls.kind == name
        if available.get(name, True):
            s = factorize(K, name)
            assert type(s) is cls
            np.testing.assert_allclose(K @ s.solve(F), F, rtol=1e-8)
    with pytest.raises(ParameterError, match="solver") as e:
        factorize(K, "magic")
    assert "\n" not in str(e.value) and "direct" in str(e.value)
def test_no_product_module_looks_like_a_test():
    assert [p for p in PKG.rglob("*.py") if p.name.endswith("_test.py")
            or p.name.startswith("test_")] == []


def test_calibration_holds_only_metrics():
    assert sorted(p.stem for p in (PKG / "calibration").glob("*.py")) == [
        "__init__", "calibration_matrix", "hysteresis", "metrics", "stiffness_fit"]
