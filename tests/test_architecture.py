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
        "def f():\n    from designlab.sensors.predict import predict\n    return predict\n")
    (fake / "sensors" / "ok.py").write_text("from designlab.fem import Model\n")
    monkeypatch.setattr(__import__(__name__), "PKG", fake)
    assert upward_imports() == ["designlab/fem/bad.py:2 imports designlab.sensors.predict"]


SENSOR_NAME = re.compile(r"""["'](fingertip|strap|flexure)["']""")

#: everything outside geometry/ and sensors/: the layers' folders, the root modules, the API
#: facade and the CLI (its help examples name sensors in running text, never as a quoted name)
NO_SENSOR_NAMES = ["mesh", "fem", "calibration", "measured", "loop", "optimize", "errors.py",
                   "params.py", "atomic.py", "frames.py", "version.py", "__init__.py", "cli.py"]


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
