"""The seed papers' tables ship inside the package (the tool works outside this workspace) and
stay equal to ../shared/data/papers."""

from pathlib import Path

import pytest

from designlab.sensors.flexure import report as fr

PKG = Path(fr.__file__).resolve().parents[2] / "data" / "papers"


def test_shipped_tables_equal_the_shared_ones(shared):
    names = sorted(p.name for p in (shared / "data" / "papers").glob("*.json"))
    assert names and names == sorted(p.name for p in PKG.glob("*.json"))
    for n in names:
        assert (PKG / n).read_bytes() == (shared / "data" / "papers" / n).read_bytes(), n


def test_paper_json_found_without_the_workspace(monkeypatch, tmp_path):
    monkeypatch.setattr(fr, "PAPER_JSON", Path("no/such/visiflex_flexure.json"))
    p = fr.find_paper_json(tmp_path)
    assert p == PKG / "visiflex_flexure.json"
    assert fr.load_paper(p)["K_c_measured"].shape == (6, 6)
    monkeypatch.setattr(fr, "PAPER_JSON", Path("no/such/missing.json"))
    with pytest.raises(fr.DataError, match="not found"):
        fr.find_paper_json(tmp_path)
