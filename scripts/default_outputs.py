"""Run the default commands into a folder, or compare two such folders number by number.

    python scripts/default_outputs.py run DIR        # the commands below, outputs under DIR
    python scripts/default_outputs.py diff OLD NEW   # every number of every JSON and table

A refactoring that must change no number is checked by running this before and after and
diffing. Timings, paths and versions are not numbers of the model and are left out of the diff.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

COMMANDS = {
    "optimize_fingertip": ["optimize", "examples/sweep_fingertip_quick.toml"],
    "predict_fingertip": ["predict", "fingertip"],
    "predict_strap": ["predict", "strap"],
    "predict_flexure": ["predict", "flexure"],
    "uncertainty_flexure": ["predict", "flexure", "--samples", "6", "--workers", "2"],
    "sweep_strap": ["sweep", "examples/sweep_strap.toml"],
    "loop_flexure": ["loop", "--data", "examples/data/flexure_card.toml"],
}

# keys whose values are machine-dependent (timings, paths, versions, hosts)
SKIP = ("time", "timing", "elapsed", "path", "version", "host", "pid", "wall", "cpu", "created",
        "started", "finished", "duration", "peak_memory", "memory", "file", "dir", "out", "seconds")


def run(dest: Path) -> None:
    dest.mkdir(parents=True, exist_ok=True)
    # the CLI of the tree this script lives in, whatever its entry point is called
    launch = ("import sys; sys.argv[0] = 'designlab'\n"
              "try:\n    from designlab.cli.app import main\n"
              "except ImportError:\n    from designlab.cli import main\n"
              "sys.exit(main())")
    for name, args in COMMANDS.items():
        print(f"running {name}: designlab {' '.join(args)}", flush=True)
        r = subprocess.run([sys.executable, "-c", launch, *args, "--out", str(dest / name)], cwd=ROOT,
                           env={**os.environ, "PYTHONPATH": str(ROOT)},
                           capture_output=True, text=True)
        (dest / f"{name}.log").write_text(r.stdout + r.stderr)
        if r.returncode != 0:
            raise SystemExit(f"{name} failed ({r.returncode}): see {dest / f'{name}.log'}")


def _skip(key: str) -> bool:
    k = key.lower()
    return any(s in k for s in SKIP) or k.endswith("_s")   # timings in seconds


def _walk(a, b, where: str, out: list) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if _skip(str(k)):
                continue
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only in {'new' if k not in a else 'old'}")
                continue
            _walk(a[k], b[k], f"{where}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: length {len(a)} -> {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            _walk(x, y, f"{where}[{i}]", out)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if not (a == b or (isinstance(a, float) and isinstance(b, float)
                           and math.isnan(a) and math.isnan(b))):
            out.append(f"{where}: {a!r} -> {b!r}")
    elif type(a) is not type(b):
        out.append(f"{where}: {type(a).__name__} -> {type(b).__name__}")


def _table(path: Path) -> list:
    import pandas as pd

    df = pd.read_parquet(path)
    cols = [c for c in df.columns if not _skip(str(c))]
    # rows in the order of their design (a parallel run finishes them in any order)
    keys = sorted(c for c in df.columns if str(c).startswith("param"))
    if keys:
        df = df.sort_values(keys, kind="stable").reset_index(drop=True)
    return json.loads(df[cols].to_json(orient="records"))


def diff(old: Path, new: Path) -> int:
    found = []
    for f in sorted(old.rglob("*")):
        rel = f.relative_to(old)
        if (f.suffix not in (".json", ".parquet") or "cache" in str(rel) or rel.name == "run.json"
                or rel.parent.name == "results"):      # the store's files: named by a key hash
            continue
        g = new / rel
        if not g.is_file():
            found.append(f"{rel}: missing in {new}")
            continue
        if f.suffix == ".json":
            a, b = json.loads(f.read_text()), json.loads(g.read_text())
        else:
            a, b = _table(f), _table(g)
        changes: list = []
        _walk(a, b, str(rel), changes)
        found += changes
    for line in found:
        print(line)
    print(f"{len(found)} differences")
    return 1 if found else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "run":
        run(Path(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "diff":
        raise SystemExit(diff(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        raise SystemExit(__doc__)
