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
    {"errors", "params", "atomic", "frames"},
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
    # anything; what the layers import from it is only __version__ (exempt below)
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
            if _top(target) == "__version__" or target == "designlab.__version__":
                continue
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


@pytest.mark.parametrize("layer", ["mesh", "fem", "calibration", "measured", "loop", "optimize"])
def test_no_sensor_named_outside_geometry_and_sensors(layer):
    hits = []
    for path in sorted((PKG / layer).rglob("*.py")):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if SENSOR_NAME.search(line):
                hits.append(f"{path.relative_to(PKG.parent)}:{i}: {line.strip()}")
    assert hits == []


def test_no_product_module_looks_like_a_test():
    assert [p for p in PKG.rglob("*.py") if p.name.endswith("_test.py")
            or p.name.startswith("test_")] == []


def test_calibration_holds_only_metrics():
    assert sorted(p.stem for p in (PKG / "calibration").glob("*.py")) == [
        "__init__", "calibration_matrix", "hysteresis", "metrics", "stiffness_fit"]
