"""Whose failure an exception is: a design's own (stored as its failed row), or the file
system's (a full disk, a quota, a read-only mount: not the design's, so the run stops and
stores nothing for it; a rerun evaluates it).

An executor's worker returns a design's error as one line of text; :func:`error_text` makes
that text an :class:`ErrorText` that carries its kind across processes (a ``str`` subclass:
it pickles with its ``kind``), and :func:`is_write_failure` also reads the kind from the text
alone (a row stored by an older run, an error that crossed as a plain string).
"""

from __future__ import annotations

import errno

#: errno values of a write the file system refused for want of room or permission to write
WRITE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)
#: the reasons :func:`designlab.atomic.os_error` gives for them, and the system's own texts
WRITE_REASONS = ("no space left on the device", "disk quota exceeded", "read-only file system",
                 "no space left on device", "[errno 28]", "[errno 122]", "[errno 30]")
DESIGN, WRITE = "design", "write"


class ErrorText(str):
    """A design's one-line error with its ``kind``: :data:`DESIGN` or :data:`WRITE`."""

    kind: str = DESIGN


def _chain(exc: BaseException | None):
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        yield exc
        exc = exc.__cause__ or exc.__context__


def write_failure(exc: BaseException) -> bool:
    """True when ``exc`` (or an exception it was raised from) is a refused write: ENOSPC,
    EDQUOT or EROFS, or the one-line error :func:`designlab.atomic.os_error` made of one."""
    for e in _chain(exc):
        if isinstance(e, OSError) and e.errno in WRITE_ERRNOS:
            return True
        if isinstance(e, OSError) and _says_write(str(e)):
            return True
    return False


def _says_write(text: str) -> bool:
    low = text.lower()
    return any(r in low for r in WRITE_REASONS)


def one_line(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


def error_text(exc: BaseException) -> ErrorText:
    """``exc`` as one line (``Type: message``) with its kind."""
    out = ErrorText(one_line(exc))
    out.kind = WRITE if write_failure(exc) else DESIGN
    return out


def is_write_failure(error: str | None) -> bool:
    """Whether a design's ``error`` text is a refused write (its kind, or its text: an
    ``OSError``/``OutputError`` naming a full disk, a quota or a read-only file system)."""
    if not error:
        return False
    kind = getattr(error, "kind", None)
    if kind is not None and kind != DESIGN:
        return kind == WRITE
    head = error.split(":", 1)[0]
    return head in ("OSError", "OutputError", "IOError") and _says_write(error)


def write_failure_message(error: str, what: str = "designs") -> str:
    """The run's one line for a design (or a batch of ``what``) that could not write: the file
    and the reason (the exception's type name left out), and what to do."""
    head, _, rest = error.partition(": ")
    text = rest if head in ("OSError", "OutputError", "IOError") and rest else error
    return (f"{text} (free space and run the same command again: the {what} finished are "
            "stored)")
