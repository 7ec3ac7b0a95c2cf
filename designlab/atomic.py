"""Atomic file writes: write to a temporary file beside the target, then ``os.replace``.

A reader (or a resumed sweep) never sees a half-written file; an interrupted write leaves at
most a hidden ``*.tmp`` that is removed on failure.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from designlab.errors import OutputError


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in the target's directory (same suffix, so writers that pick the
    format from it work); on success it replaces ``path`` with the usual file permissions.
    An empty result is an error (a writer that failed silently)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix="." + path.stem + ".",
                               suffix=".tmp" + path.suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        yield Path(tmp)
        if os.path.getsize(tmp) == 0:
            raise OutputError(f"writing {path} produced an empty file")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (fsynced before the rename)."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return Path(path)


def jsonable(x):
    """Plain JSON types from numpy arrays/scalars, tuples and non-finite floats (-> None)."""
    import math

    import numpy as np

    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, Path):
        return str(x)
    return x


def atomic_write_json(path: str | Path, obj, indent: int = 1) -> Path:
    """``obj`` as JSON, written atomically: the package's one JSON writer and its one rule for
    non-finite numbers (NaN and inf become null, see :func:`jsonable`)."""
    import json

    return atomic_write_bytes(path, json.dumps(jsonable(obj), indent=indent,
                                               allow_nan=False).encode())


def atomic_savefig(fig, path: str | Path, dpi: int = 120) -> Path:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return Path(path)
