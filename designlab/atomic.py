"""Atomic file writes: write to a temporary file beside the target, then ``os.replace``.

A reader (or a resumed sweep) never sees a half-written file; an interrupted write leaves at
most a hidden ``.NAME.RANDOM.tmp[.suffix]`` that is removed on failure, and that
:func:`sweep_temps` removes after a kill -9. Also here: :func:`out_lock` (one writer per output
directory) and :func:`die_with_parent` (child processes end with the process that started them).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import tempfile
from pathlib import Path
from typing import Iterator

from designlab.errors import DesignlabError, OutputError

#: the names :func:`atomic_path` gives its temporary files (``.STEM.PID.RANDOM.tmp[.SUFFIX]``)
TEMP_NAME = re.compile(r"^\.(?P<stem>.+)\.(?P<pid>\d+)\.[A-Za-z0-9_]{8}\.tmp(\.[A-Za-z0-9]+)?$")


def temp_prefix(stem: str) -> str:
    """``mkstemp`` prefix of a temporary file for ``stem`` (names of :data:`TEMP_NAME`)."""
    return f".{stem}.{os.getpid()}."


def pid_alive(pid: int) -> bool:
    """True when a process ``pid`` exists on this machine."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def os_error(path: Path, exc: OSError) -> OutputError:
    """One line for a failed write: the path and the system's reason (never file contents)."""
    reason = {errno.ENOSPC: "no space left on the device", errno.EROFS: "read-only file system",
              errno.EACCES: "permission denied", errno.EPERM: "operation not permitted",
              errno.ENOTDIR: "a parent is a file, not a directory",
              errno.EISDIR: "it is a directory", errno.EDQUOT: "disk quota exceeded",
              errno.ENAMETOOLONG: "file name too long"}.get(exc.errno,
                                                              exc.strerror or type(exc).__name__)
    return OutputError(f"cannot write {path}: {reason}")


def ensure_dir(path: str | Path, what: str = "--out") -> Path:
    """Create the output directory ``path`` (and parents); a file in the way, a read-only or
    full file system or a virtual one (/proc, /sys) is a one-line :class:`OutputError`."""
    path = Path(path)
    real = os.path.realpath(path)
    if real == "/proc" or real.startswith(("/proc/", "/sys/", "/dev/")) or real == "/sys":
        raise OutputError(f"{what}={str(path)!r} is not allowed: a directory on a normal file "
                          "system (not under /proc, /sys or /dev)")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{what}={str(path)!r} is not allowed: a directory (it is a file)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise os_error(path, exc) from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write {path}: permission denied")
    return path


def sweep_temps(folder: str | Path) -> list[Path]:
    """Remove the temporary files that killed writers left in ``folder``: names of
    :data:`TEMP_NAME` whose writer (the PID in the name) no longer runs. Safe beside a live
    writer; returns the removed paths."""
    folder = Path(folder)
    removed = []
    if folder.is_dir():
        for p in folder.iterdir():
            m = TEMP_NAME.match(p.name)
            if m and not pid_alive(int(m["pid"])) and p.is_file():
                p.unlink(missing_ok=True)
                removed.append(p)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | Path, *, keep_suffix: bool = True) -> Iterator[Path]:
    """Yield a temporary path in the target's directory (same suffix, so writers that pick the
    format from it work; ``keep_suffix=False``: the name ends in ``.tmp``, so that a glob for
    the final suffix never matches it); on success it replaces ``path`` with the usual file
    permissions. An empty result is an error (a writer that failed silently); a failed write
    (disk full, read-only) is a one-line :class:`OutputError` and leaves nothing behind."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=temp_prefix(path.stem),
                                   suffix=".tmp" + (path.suffix if keep_suffix else ""))
    except OSError as exc:
        raise os_error(path, exc) from None
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        yield Path(tmp)
        if os.path.getsize(tmp) == 0:
            raise OutputError(f"writing {path} produced an empty file")
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OutputError):
            raise
        raise os_error(path, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes, *, keep_suffix: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (fsynced before the rename)."""
    with atomic_path(path, keep_suffix=keep_suffix) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return Path(path)


class FileSet:
    """Files written as a set: each to a hidden temporary beside its target (a name of
    :data:`TEMP_NAME`, so :func:`sweep_temps` removes a killed writer's), all moved into place
    by :meth:`commit` once every one is written; a failure before that removes every temporary
    (:meth:`abort`), so a full disk leaves the targets as they were. Renames need no space.
    ``with FileSet() as fs: fs.write_bytes(...)`` commits on success and aborts on error."""

    def __init__(self):
        self.temps: list[tuple[Path, Path]] = []
        self.created: list[Path] = []      # folders made for the set, removed by abort if empty

    def make_dir(self, folder: str | Path) -> Path:
        """``folder`` and its missing parents, remembered so :meth:`abort` removes the empty
        ones (a failed set leaves no empty ``--out``)."""
        folder = Path(folder)
        d = folder
        while not d.exists():
            self.created.append(d)
            d = d.parent
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise os_error(folder, exc) from None
        return folder

    def path(self, target: str | Path, *, keep_suffix: bool = True) -> Path:
        """A new temporary path for ``target`` (same suffix unless ``keep_suffix=False``); a
        target staged again replaces its earlier temporary (the last one written commits)."""
        target = Path(target)
        for tmp, final in [t for t in self.temps if t[1] == target]:
            tmp.unlink(missing_ok=True)
            self.temps.remove((tmp, final))
        self.make_dir(target.parent)
        try:
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=temp_prefix(target.stem),
                                       suffix=".tmp" + (target.suffix if keep_suffix else ""))
        except OSError as exc:
            raise os_error(target, exc) from None
        os.close(fd)
        self.temps.append((Path(tmp), target))
        return Path(tmp)

    def targets(self) -> list[Path]:
        """The targets staged so far (not yet in place)."""
        return [final for _, final in self.temps]

    def write_bytes(self, target: str | Path, data: bytes, *, keep_suffix: bool = True) -> Path:
        """``data`` for ``target`` (fsynced); one line on a failed write."""
        tmp = self.path(target, keep_suffix=keep_suffix)
        try:
            with open(tmp, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise os_error(Path(target), exc) from None
        return Path(target)

    def write_json(self, target: str | Path, obj, indent: int = 1) -> Path:
        """``obj`` as JSON for ``target`` (the rules of :func:`atomic_write_json`)."""
        import json

        return self.write_bytes(target, json.dumps(jsonable(obj), indent=indent,
                                                   allow_nan=False).encode())

    def commit(self) -> list[Path]:
        """Move every temporary into place (usual file mode). An empty one or a folder by a
        target's name aborts the set before anything moves."""
        umask = os.umask(0)
        os.umask(umask)
        for tmp, final in self.temps:   # what would stop a rename, before the first one
            problem = ("produced an empty file" if tmp.stat().st_size == 0 else
                       "it is a directory" if final.is_dir() and not final.is_symlink() else "")
            if problem:
                self.abort()
                raise OutputError(f"{'writing ' if 'empty' in problem else 'cannot write '}"
                                  f"{final}{' ' if 'empty' in problem else ': '}{problem}")
        done = []
        for tmp, final in self.temps:
            try:
                os.chmod(tmp, 0o666 & ~umask)
                os.replace(tmp, final)
            except OSError as exc:
                self.abort()
                raise os_error(final, exc) from None
            done.append(final)
        self.temps = []
        return done

    def abort(self) -> None:
        """Remove every temporary not yet moved into place, and the folders made for the set
        that are left empty."""
        for tmp, _ in self.temps:
            tmp.unlink(missing_ok=True)
        self.temps = []
        for d in sorted(set(self.created), key=lambda x: len(x.parts), reverse=True):
            try:
                d.rmdir()
            except OSError:
                pass
        self.created = []

    def __enter__(self) -> "FileSet":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()


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


def atomic_write_json(path: str | Path, obj, indent: int = 1, *,
                      keep_suffix: bool = True) -> Path:
    """``obj`` as JSON, written atomically: the package's one JSON writer and its one rule for
    non-finite numbers (NaN and inf become null, see :func:`jsonable`). ``keep_suffix=False``:
    the temporary name ends in ``.tmp`` (a glob for ``*.json`` never sees it; see
    :func:`atomic_path`)."""
    import json

    return atomic_write_bytes(path, json.dumps(jsonable(obj), indent=indent,
                                               allow_nan=False).encode(),
                              keep_suffix=keep_suffix)


def atomic_savefig(fig, path: str | Path, dpi: int = 120) -> Path:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


# --------------------------------------------------------------------------- processes


def die_with_parent(parent_pid: int | None = None) -> None:
    """Ask Linux to SIGKILL this process when its parent ends (``prctl(PR_SET_PDEATHSIG)``),
    however the parent ends (kill -9 included); when the parent is already gone, exit now.
    Call it first thing in a child (a pool worker's initializer, a ``preexec_fn``).
    A no-op where prctl does not exist (not Linux)."""
    import ctypes
    import signal

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        prctl = libc.prctl
    except (OSError, AttributeError):
        return
    PR_SET_PDEATHSIG = 1
    prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)  # the parent died before the signal was armed


# --------------------------------------------------------------------------- one writer


LOCK_NAME = ".designlab.lock"


class OutLock:
    """An exclusive POSIX lock on ``DIR/.designlab.lock`` naming its holder (pid, host, command,
    start time). The kernel drops the lock when the holder ends, however it ends, so the lock of
    a killed run is stale at once and the next run takes it over. POSIX record locks are not
    inherited by forked children, so a child left running cannot keep it. Nested holders in
    one process (the CLI, then the library under it) share the one lock. Released, the file is
    removed (while still held; a taker checks it locked the file that is there), and a folder
    the lock made is removed again when nothing else was written in it (a refused input)."""

    _held: dict[str, list] = {}  # real path -> [fd, holders] of the locks this process holds

    def __init__(self, folder: str | Path, command: str = ""):
        self.folder, self.command = Path(folder), command
        self.path = self.folder / LOCK_NAME
        self.fd: int | None = None

    def acquire(self) -> "OutLock":
        import datetime
        import fcntl
        import json
        import socket
        import sys

        self.created = not self.folder.exists()
        ensure_dir(self.folder)
        key = os.path.realpath(self.path)
        if key in OutLock._held:
            OutLock._held[key][1] += 1
            self.fd = OutLock._held[key][0]
            return self
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise os_error(self.path, exc) from None
            try:
                fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                self._refuse(fd)
            try:  # a holder removes the file as it releases it: lock the file that is there
                if os.fstat(fd).st_ino == os.stat(self.path).st_ino:
                    break
            except FileNotFoundError:
                pass
            os.close(fd)
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "command": self.command or " ".join(["designlab", *sys.argv[1:]])[:200],
                "started": datetime.datetime.now().isoformat(timespec="seconds")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(info).encode(), 0)
        self.fd = fd
        OutLock._held[key] = [fd, 1]
        return self

    def _refuse(self, fd: int) -> None:
        import json

        try:
            holder = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        except (ValueError, UnicodeDecodeError):
            holder = {}
        os.close(fd)
        who = (f"pid {holder.get('pid')} on {holder.get('host')} ({holder.get('command')}, "
               f"started {holder.get('started')})" if holder else "another process")
        raise DesignlabError(f"--out {self.folder} is in use by {who}; wait for it to "
                             "finish or choose another --out") from None

    def release(self) -> None:
        if self.fd is None:
            return
        import fcntl

        key = os.path.realpath(self.path)
        held = OutLock._held.get(key)
        self.fd, fd = None, self.fd
        if held is not None:
            held[1] -= 1
            if held[1] > 0:
                return
            del OutLock._held[key]
        try:  # removed while still held: the folder keeps no trace of its writer
            os.unlink(self.path)
        except OSError:
            pass
        try:
            fcntl.lockf(fd, fcntl.LOCK_UN)
        except OSError:
            pass
        finally:
            os.close(fd)
        if self.created:  # a folder this lock made and nothing filled (a refused input)
            try:
                self.folder.rmdir()
            except OSError:
                pass

    def __enter__(self) -> "OutLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def out_lock(folder: str | Path, command: str = "") -> OutLock:
    """``with out_lock(out): ...``: hold ``out`` as its one writer (see :class:`OutLock`)."""
    return OutLock(folder, command)
