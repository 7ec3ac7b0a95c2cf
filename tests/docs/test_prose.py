"""Prose stays free of history: no dates, "slow phase" or issue numbers in designlab/ (code,
templates and data files), README.md and docs/ (outside docs/notes/; CHANGELOG.md holds the history)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PATTERN = re.compile(r"20[0-9]{2}-[01][0-9]-[0-3][0-9]|slow phase|[Ii]ssue [0-9]+")
SUFFIXES = {".py", ".html", ".j2", ".jinja", ".md", ".txt", ".css", ".js", ".json"}


def _files(root: Path):
    yield from (p for p in (root / "designlab").rglob("*") if p.is_file() and p.suffix in SUFFIXES)
    if (root / "README.md").exists():
        yield root / "README.md"
    docs = root / "docs"
    if docs.exists():
        yield from (p for p in docs.rglob("*.md") if "notes" not in p.relative_to(docs).parts)


def offences(root: Path) -> list[str]:
    """Every line of the checked files that names a date, a slow phase or an issue number."""
    found = []
    for path in _files(root):
        for i, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if PATTERN.search(line):
                found.append(f"{path.relative_to(root)}:{i}: {line.strip()[:120]}")
    return found


def test_no_history_in_code_readme_and_docs():
    assert offences(ROOT) == []


def test_the_check_can_fail(tmp_path):
    (tmp_path / "designlab").mkdir()
    (tmp_path / "designlab" / "m.py").write_text('"""Fast since 2026-11-22."""\n')
    (tmp_path / "docs" / "notes").mkdir(parents=True)
    (tmp_path / "docs" / "notes" / "diary.md").write_text("issue 12, slow phase\n")
    (tmp_path / "docs" / "a.md").write_text("See issue 7.\n")
    (tmp_path / "CHANGELOG.md").write_text("## 2026-11-28\n")
    assert [o.split(":")[0] for o in offences(tmp_path)] == ["designlab/m.py", "docs/a.md"]
