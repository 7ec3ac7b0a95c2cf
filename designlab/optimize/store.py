"""Result store of a sweep: a per-design prediction cache and a Parquet table that grows as
designs finish.

Layout under the sweep's output directory::

    cache/<key>.json          the full result of one design (atomic write)
    results/<key>.parquet     one row per finished design: a Parquet dataset (atomic write)
    results.parquet           the consolidated table (written at the end of a run)
    fem/<key>.npz             the FEM stages the designs share (:mod:`designlab.fem.cache`)

Every file is written to a temporary name and renamed, so an interrupted sweep (Ctrl-C, kill -9)
leaves only complete files; the key (a hash of part, parameters, settings, protocol and the
designlab version) names both files, so a resumed sweep never duplicates a design. Temporary
names (``.KEY.RANDOM.tmp``) never match the store's own names (``KEY.parquet``, ``KEY.json``),
and :meth:`ResultStore.recover` removes those a killed run left, at the folder's top level and
in ``fem/`` and ``chosen/`` too (under the directory's lock, :func:`designlab.atomic.out_lock`,
so never another live run's). JSON is written by :func:`designlab.atomic.atomic_write_json` (its one NaN rule: null).
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from designlab.version import __version__
from designlab.atomic import atomic_write_bytes, atomic_write_json, jsonable as _jsonable
from designlab.atomic import sweep_temps

KEY = re.compile(r"^[0-9a-f]{20}$")


def design_key(part: str, params: dict[str, Any], settings: dict[str, Any] | None = None,
               protocol: dict[str, Any] | None = None, extra: dict[str, Any] | None = None) -> str:
    """Stable hash of everything that determines a design's prediction (and the version)."""
    blob = json.dumps(_jsonable({"part": part, "params": params, "settings": settings or {},
                                 "protocol": protocol or {}, "extra": extra or {},
                                 "designlab": __version__}), sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def flatten_metrics(result: dict[str, Any]) -> dict[str, Any]:
    """Scalar columns for the table: numbers and strings as they are, ``{"a": {"b": 1}}`` ->
    ``a.b``, lists/matrices as JSON text."""
    out: dict[str, Any] = {}

    def walk(prefix: str, v: Any) -> None:
        if isinstance(v, dict):
            for k, w in v.items():
                walk(f"{prefix}.{k}" if prefix else str(k), w)
        elif isinstance(v, (bool, np.bool_)):
            out[prefix] = bool(v)
        elif isinstance(v, (int, float, np.integer, np.floating)):
            out[prefix] = float(v)
        elif v is None or isinstance(v, str):
            out[prefix] = v
        else:
            out[prefix] = json.dumps(_jsonable(v))

    walk("", result)
    return out


class ResultStore:
    """Cache + Parquet rows of one sweep directory."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.cache_dir = self.root / "cache"
        self.rows_dir = self.root / "results"
        self.fem_dir = self.root / "fem"

    def recover(self) -> dict[str, int]:
        """After a kill: remove temporary files (of the folder's own files: the table, the
        report, ``run.json``; of rows, cache, the FEM stages in ``fem/`` and the chosen design's
        files in ``chosen/``), and row or cache files that cannot be read (a file system that lost a
        write); those designs are evaluated again (an unreadable FEM stage is computed again
        by :class:`~designlab.fem.cache.FEMCache` itself). Returns counts."""
        temps = sum(len(sweep_temps(d)) for d in (self.root, self.rows_dir, self.cache_dir,
                                                  self.fem_dir, self.root / "chosen"))
        temps += len([p.unlink() for p in self.rows_dir.glob(".*.tmp.parquet")])  # old naming
        broken = 0
        for p in self._row_files():
            try:
                pq.read_metadata(p)
            except (pa.ArrowException, OSError):
                p.unlink(missing_ok=True)
                broken += 1
        if self.cache_dir.is_dir():
            for p in self.cache_dir.glob("*.json"):
                if KEY.match(p.stem) and self._read_cache(p) is None:
                    p.unlink(missing_ok=True)
                    broken += 1
        return {"temporary_files": temps, "unreadable_files": broken}

    @staticmethod
    def _read_cache(p: Path) -> dict[str, Any] | None:
        try:
            doc = json.loads(p.read_text())
        except (OSError, ValueError):
            return None
        return doc if isinstance(doc, dict) and "metrics" in doc else None

    def cached(self, key: str) -> dict[str, Any] | None:
        p = self.cache_dir / f"{key}.json"
        if not p.exists():
            return None
        return self._read_cache(p)

    def has_row(self, key: str) -> bool:
        return (self.rows_dir / f"{key}.parquet").exists()

    def put(self, key: str, row: dict[str, Any], result: dict[str, Any] | None) -> None:
        """Store a finished design: its full result in the cache, then its table row."""
        if result is not None:
            atomic_write_json(self.cache_dir / f"{key}.json", result, keep_suffix=False)
        table = pa.Table.from_pylist([row])
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink)
        atomic_write_bytes(self.rows_dir / f"{key}.parquet", sink.getvalue().to_pybytes(),
                           keep_suffix=False)

    def _row_files(self) -> list[Path]:
        """The row files (``KEY.parquet``; temporary and foreign files are not rows)."""
        if not self.rows_dir.is_dir():
            return []
        return sorted(p for p in self.rows_dir.glob("*.parquet") if KEY.match(p.stem))

    def keys(self) -> set[str]:
        return {p.stem for p in self._row_files()}

    def table(self) -> pa.Table:
        """All rows (columns unified across designs; missing values are null)."""
        files = self._row_files()
        if not files:
            return pa.table({})
        return pa.concat_tables([pq.read_table(f) for f in files], promote_options="permissive")

    def rows(self, keys: Iterable[str] | None = None) -> list[dict[str, Any]]:
        rows = self.table().to_pylist()
        if keys is None:
            return rows
        order = {k: i for i, k in enumerate(keys)}
        rows = [r for r in rows if r.get("key") in order]
        return sorted(rows, key=lambda r: order[r["key"]])

    def consolidate(self, path: Path | None = None, files=None) -> Path:
        """Write the whole table to ``results.parquet`` (atomic); ``files`` (a
        :class:`~designlab.atomic.FileSet`): staged with the set, in place when it commits."""
        path = path or self.root / "results.parquet"
        sink = pa.BufferOutputStream()
        pq.write_table(self.table(), sink)
        if files is not None:
            return files.write_bytes(path, sink.getvalue().to_pybytes())
        atomic_write_bytes(path, sink.getvalue().to_pybytes())
        return path
