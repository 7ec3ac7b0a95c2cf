"""Prose states what and why, never when: no dates (ISO or day, month name, year), no
slow-phase remarks and no issue numbers in designlab/ (code, templates and data files),
README.md, docs/, examples/, benchmarks/, scripts/ and tests/ (CHANGELOG.md holds the history).

A date that is a whole string literal (``"YYYY-MM-DD"``) is a value, not prose: the "date" field
of the measured-material format, which a record and its tests carry. A bare year, as in a
citation or a DOI, is not a date.

This file builds its own test strings from pieces, so it carries no offence and is checked too."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
_ISO = r"20[0-9]{2}-[01][0-9]-[0-3][0-9]"
_MONTH = r"(?:Jan|Feb|Mar|Apr|May|Jun|Jul|Aug|Sep|Oct|Nov|Dec)[a-z]*\.?"
PATTERN = re.compile(rf"{_ISO}|\b[0-3]?[0-9] {_MONTH},? (?:19|20)[0-9]{{2}}\b"
                     r"|slow[ ]phase|[Ii]ssue [0-9]+")
#: a date that is the whole of a string literal: a data value
VALUE = re.compile(rf"""(["']){_ISO}\1""")
SUFFIXES = {".py", ".html", ".j2", ".jinja", ".md", ".txt", ".css", ".js", ".json", ".toml",
            ".ipynb"}
#: folders checked whole (every file with one of SUFFIXES)
FOLDERS = ("designlab", "examples", "benchmarks", "scripts", "tests")
SKIPPED_DIRS = {"__pycache__", ".pytest_cache", ".ipynb_checkpoints"}


def _files(root: Path):
    for folder in FOLDERS:
        yield from (p for p in sorted((root / folder).rglob("*"))
                    if p.is_file() and p.suffix in SUFFIXES
                    and not SKIPPED_DIRS & set(p.relative_to(root).parts))
    if (root / "README.md").exists():
        yield root / "README.md"
    yield from sorted((root / "docs").rglob("*.md"))


def offences(root: Path) -> list[str]:
    """Every line of the checked files that names a date, a slow-phase remark or an issue number."""
    found = []
    for path in _files(root):
        for i, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if PATTERN.search(VALUE.sub("", line)):
                found.append(f"{path.relative_to(root)}:{i}: {line.strip()[:120]}")
    return found


def test_no_history_in_code_docs_examples_benchmarks_scripts_and_tests():
    assert offences(ROOT) == []


def test_the_check_can_fail(tmp_path):
    iso, dmy = "2026" + "-11-22", "26 Nov" + " 2026"
    issue, slow = "issue" + " 12", "slow" + " phase"
    files = {
        "designlab/m.py": f'"""Fast since {iso}."""\n',
        "docs/guide/a.md": f"See {issue}.\n",
        "docs/b.md": f"Measured in a {slow} of the machine.\n",
        "examples/x.py": f"# the default until {dmy}\n",
        "benchmarks/bench_x.py": f'"""{issue.capitalize()} goal: < 2 s."""\n',
        "scripts/s.py": f"# measured {iso}\n",
        "tests/test_x.py": f'"""The regression of {issue}."""\n',
        "examples/card.toml": f"# {dmy[:2]} November {dmy[-4:]}\n",
        "examples/nb.ipynb": f'{{"cells": [{{"source": ["since {iso}"]}}]}}\n',
        # not offences: CHANGELOG.md, a date as a data value, citations with a bare year
        "CHANGELOG.md": f"## {iso}\n",
        "examples/materials.json": f'{{"date": "{iso}", "source": "Wypych 2018"}}\n',
        "tests/test_y.py": f'MeasuredProperty("PI-ETPU", "rho", 1.0, "x", "{iso}")\n',
        "docs/c.md": "Sensors 17:1190 (2017), doi 10.1177/10519815261458341; Nov. 2018.\n",
        "examples/data/log.csv": f"{iso},1.0\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    assert sorted(o.split(":")[0] for o in offences(tmp_path)) == sorted([
        "designlab/m.py", "docs/guide/a.md", "docs/b.md", "examples/x.py",
        "benchmarks/bench_x.py", "scripts/s.py", "tests/test_x.py", "examples/card.toml",
        "examples/nb.ipynb"])
