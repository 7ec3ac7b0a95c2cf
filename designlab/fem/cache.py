"""One FEM per distinct model: results of an expensive FEM stage (a mesh, unit-load responses)
stored under a key of only what they depend on.

A virtual test splits into what depends on the FEM (mesh, materials, supports, unit-load
responses) and what does not (load points, weights, rotations). The sensor computes the key of
the first part (:func:`fem_key`: a SHA-256 of canonical JSON), and :meth:`FEMCache.get_or_compute`
returns the stored arrays or computes them once. Two layers: a small in-process memory (a
``predict`` that runs the same FEM twice) and, for sweeps, a folder of ``<key>.npz`` files
written atomically (kill -9 safe); a lock file per key makes concurrent workers (local processes
or Dask workers on a shared file system) compute each FEM once and wait for it.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

import numpy as np

from designlab.atomic import atomic_path, jsonable

#: bump when the stored arrays of any sensor change (meaning, or a new array: an older file
#: lacks it). 2: the mesher, its attempts and the solver that ran
FORMAT = 2

_MEMORY: "OrderedDict[str, dict[str, Any]]" = OrderedDict()
_MEMORY_SIZE = 6

#: what this process's caches did (tests and benchmarks read it; :func:`clear_memory` keeps it):
#: ``computed`` stages, ``written`` files, ``file_reads`` (a stage read from its file) and
#: ``memory_hits`` (from the in-process layer)
STATS = {"computed": 0, "written": 0, "file_reads": 0, "memory_hits": 0}


def fem_key(kind: str, **parts: Any) -> str:
    """SHA-256 (hex) of ``kind`` and the keyword values as canonical JSON (sorted keys; numpy
    arrays and non-finite floats via :func:`designlab.atomic.jsonable`)."""
    from designlab.version import __version__

    blob = json.dumps(jsonable({"kind": kind, "format": FORMAT, "designlab": __version__,
                                **parts}), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()


class FEMCache:
    """Arrays by key: memory, then ``directory`` (None: memory only)."""

    def __init__(self, directory: str | Path | None = None):
        self.directory = Path(directory) if directory is not None else None
        self.hits = 0
        self.misses = 0

    def _path(self, key: str) -> Path:
        return self.directory / f"{key}.npz"

    def _load(self, key: str) -> dict[str, Any] | None:
        if key in _MEMORY:
            _MEMORY.move_to_end(key)
            STATS["memory_hits"] += 1
            return _MEMORY[key]
        if self.directory is None or not self._path(key).is_file():
            return None
        try:
            with np.load(self._path(key), allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError):
            return None                        # unreadable: recompute (and overwrite)
        STATS["file_reads"] += 1
        return self._remember(key, data)

    @staticmethod
    def _remember(key: str, data: dict[str, Any]) -> dict[str, Any]:
        _MEMORY[key] = data
        _MEMORY.move_to_end(key)
        while len(_MEMORY) > _MEMORY_SIZE:
            _MEMORY.popitem(last=False)
        return data

    @contextlib.contextmanager
    def _lock(self, key: str):
        if self.directory is None:
            yield
            return
        self.directory.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.directory / f"{key}.lock", os.O_CREAT | os.O_RDWR, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)      # released by the kernel if the holder dies
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def keep(self, key: str, arrays: dict[str, np.ndarray]) -> None:
        """Keep ``arrays`` under ``key`` in this process's memory layer (a stage computed
        elsewhere, e.g. by ``predict``'s side process); the folder is not written."""
        self._remember(key, {k: np.asarray(v) for k, v in arrays.items()})

    def get(self, key: str) -> dict[str, np.ndarray] | None:
        """The arrays stored under ``key`` (memory, then the folder), or None: never computes."""
        return self._load(key)

    def get_or_compute(self, key: str, compute: Callable[[], dict[str, np.ndarray]]
                       ) -> dict[str, np.ndarray]:
        """The arrays stored under ``key``, computing and storing them once if absent.
        ``compute()`` returns plain numpy arrays (no objects: the file is read without pickle)."""
        data = self._load(key)
        if data is not None:
            self.hits += 1
            return data
        with self._lock(key):
            data = self._load(key)              # another worker may have finished meanwhile
            if data is not None:
                self.hits += 1
                return data
            self.misses += 1
            data = {k: np.asarray(v) for k, v in compute().items()}
            STATS["computed"] += 1
            if self.directory is not None:
                with atomic_path(self._path(key)) as tmp:
                    with open(tmp, "wb") as fh:
                        np.savez(fh, **data)
                STATS["written"] += 1
            return self._remember(key, data)


def cached_stage(compute: Callable[[], dict[str, np.ndarray]], key: str | None,
                 cache: FEMCache | None = None) -> tuple[dict[str, np.ndarray], bool]:
    """(arrays, reused): ``compute()`` once per ``key`` in ``cache`` (default: the in-process
    layer only); ``key`` None (a mesh given by the caller) computes without caching."""
    if key is None:
        return compute(), False
    cache = cache if cache is not None else FEMCache()
    hits = cache.hits
    data = cache.get_or_compute(key, compute)
    return data, cache.hits > hits


def timed_stage(compute: Callable[[], dict[str, np.ndarray]], key: str | None,
                cache: FEMCache | None = None) -> tuple[dict[str, np.ndarray], bool, dict]:
    """:func:`cached_stage` with the stage's timings (s): ``mesh``, ``assemble``, ``solve`` from
    the arrays' ``timings`` when computed here, zeros and ``fem_cache`` (the lookup's wall time)
    when reused."""
    import time

    t0 = time.perf_counter()
    data, reused = cached_stage(compute, key, cache)
    wall = time.perf_counter() - t0
    if reused:
        return data, True, {"mesh": 0.0, "assemble": 0.0, "solve": 0.0, "fem_cache": wall}
    mesh_t, assemble_t, solve_t = (float(x) for x in data["timings"])
    return data, False, {"mesh": mesh_t, "assemble": assemble_t, "solve": solve_t}


def clear_memory() -> None:
    """Forget the in-process layer (tests; a changed material library)."""
    _MEMORY.clear()
