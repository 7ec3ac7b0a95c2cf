"""docs/parts.md is generated from the part classes (``python scripts/gen_docs.py``): the
committed page equals the generator's output, names every parameter of every part with its
default and range, and every image it links exists."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

from designlab.geometry.api import field_rows
from designlab.geometry.parts import PARTS

ROOT = Path(__file__).resolve().parents[2]


def _gen_docs():
    spec = importlib.util.spec_from_file_location("gen_docs", ROOT / "scripts" / "gen_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_parts_page_is_the_generated_one():
    page = (ROOT / "docs" / "parts.md").read_text(encoding="utf-8")
    assert page == _gen_docs().parts_page(), \
        "docs/parts.md is stale: run python scripts/gen_docs.py"


def test_parts_page_has_every_parameter_with_its_default_and_range():
    page = (ROOT / "docs" / "parts.md").read_text(encoding="utf-8")
    sections = re.split(r"^## ", page, flags=re.M)[1:]
    assert [s.split("\n", 1)[0] for s in sections] == list(PARTS)
    for sec, (name, cls) in zip(sections, PARTS.items()):
        rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `(\w+)` \| (.*) \|$", sec, re.M)}
        fields = [f.name for f in dataclasses.fields(cls) if not f.name.startswith("_")]
        assert list(rows) == fields, name
        for r in field_rows(cls):
            cells = [c.strip() for c in rows[r["name"]].split(" | ")]
            default, allowed, unit = cells[0], cells[1], cells[2]
            if isinstance(r["default"], float):
                assert float(default) == r["default"], (name, r["name"])
            else:
                assert default == str(r["default"]), (name, r["name"])
            assert allowed == r["allowed"] and unit == r["unit"], (name, r["name"])


def test_a_changed_default_makes_the_page_differ(monkeypatch):
    """The check can fail: a part whose default moved gives another page."""
    gen = _gen_docs()
    before = gen.parts_page()
    cls = PARTS["fingertip"]
    f = next(f for f in dataclasses.fields(cls) if f.name == "gap")
    monkeypatch.setattr(f, "default", 0.7)
    after = gen.parts_page()
    assert after != before
    assert "| `gap` | 0.7 |" in after


def test_check_mode_says_stale(tmp_path, monkeypatch, capsys):
    gen = _gen_docs()
    stale = tmp_path / "parts.md"
    stale.write_text("old\n", encoding="utf-8")
    monkeypatch.setattr(gen, "PARTS_MD", stale)
    monkeypatch.setattr(gen, "ROOT", tmp_path)
    assert gen.main(["--check"]) == 1
    assert "stale" in capsys.readouterr().out
    assert stale.read_text() == "old\n"


def test_every_image_the_parts_page_links_exists():
    page = (ROOT / "docs" / "parts.md").read_text(encoding="utf-8")
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page)
    assert len(links) >= len(PARTS)
    for name in PARTS:
        assert f"img/part_{name}.png" in links, name
    for link in links:
        assert (ROOT / "docs" / link).is_file(), link
