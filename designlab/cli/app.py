"""The ``designlab`` typer app, its consoles and progress display, and the entry point: a
:class:`DesignlabError` becomes one line on stderr and exit code 2 (no traceback, nothing
half-written)."""

from __future__ import annotations

import atexit
import contextlib
import datetime
import os
import sys
import tempfile
import traceback
import warnings
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                           TimeElapsedColumn, TimeRemainingColumn)
from rich.text import Text

from designlab.errors import DesignlabError, ParameterError
from designlab.version import __version__

app = typer.Typer(add_completion=True, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Design, predict and learn 3D-printed force sensors (units: mm, N, MPa, s).")
class _Console(Console):
    """A console that shows control characters in printed text as escapes (``\\x1b``): a path
    or name holding an ESC never drives the terminal."""

    def print(self, *objects, **kw) -> None:
        super().print(*(_visible(o) if isinstance(o, str) else o for o in objects), **kw)


def _visible(text: str) -> str:
    return "".join(c.encode("unicode_escape").decode() if (ord(c) < 32 and c not in "\n\t")
                   or 127 <= ord(c) < 160 else c for c in text)


console = _Console()
err_console = _Console(stderr=True)


def _print_version(value: bool) -> None:
    if value:
        console.print(f"designlab {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the version and exit.")):
    """designlab: parametric sensors -> mesh -> FEM -> virtual tests -> sweeps -> measured loop."""


class Bar:
    """Handle of :func:`progress_bar`: ``bar(description=..., completed=..., total=...,
    advance=...)`` updates it; ``bar.print(...)`` prints above it; ``bar.stop()`` ends it."""

    def __init__(self, prog, task):
        self._prog, self._task = prog, task

    def __call__(self, description: str | None = None, **fields) -> None:
        if description is not None:
            fields["description"] = escape(description)
        self._prog.update(self._task, **fields)

    def print(self, *args, **kw) -> None:
        self._prog.console.print(*args, **kw)

    def stop(self) -> None:
        self._prog.stop()


@contextlib.contextmanager
def progress_bar(description: str, total: float | None = None, *, transient: bool = True):
    """The CLI's one progress display: what runs, a bar, done/total, elapsed time and ETA
    (a pulsing bar while the total is unknown). Yields a :class:`Bar`."""
    prog = Progress(SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
                    MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                    TimeRemainingColumn(), console=console, transient=transient)
    with prog:
        yield Bar(prog, prog.add_task(escape(description), total=total))


def plain(*parts):
    """A rich ``Text`` of literal pieces (``str`` or ``(str, style)``): user text such as
    ``[time]`` or ``[/bold]`` is printed as it is, never read as markup."""
    return Text.assemble(*parts)


def warn(message: str, label: str = "warning:") -> None:
    """One yellow-labelled line on stderr, the message printed literally."""
    err_console.print(plain((label, "yellow"), " ", message), highlight=False)


def next_step(text: str) -> None:
    """The last line of a command: what to open next (paths unbroken, printed literally)."""
    console.print(text, markup=False, highlight=False, soft_wrap=True)


def one_line(text: object, limit: int = 2000) -> str:
    """``text`` on one line (newlines and control characters as spaces), at most ``limit``
    characters."""
    s = "".join(c if c.isprintable() else " " for c in str(text).replace("\r\n", "\n")).strip()
    return s if len(s) <= limit else s[:limit - 3] + "..."


def _log_dir() -> Path:
    """Where tracebacks of unexpected errors go: ``$DESIGNLAB_LOG_DIR``, else
    ``$XDG_STATE_HOME/designlab`` (``~/.local/state/designlab``), else the temp directory."""
    env = os.environ.get("DESIGNLAB_LOG_DIR")
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    for d in ([Path(env)] if env else []) + [Path(state) / "designlab",
                                             Path(tempfile.gettempdir()) / "designlab-logs"]:
        try:
            d.mkdir(parents=True, exist_ok=True)
            if os.access(d, os.W_OK):
                return d
        except OSError:
            continue
    return Path(tempfile.gettempdir())


def _write_log(argv: Optional[List[str]]) -> Optional[Path]:
    """The current exception's traceback (and the command line) in a new log file."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    try:
        path = _log_dir() / f"designlab-{stamp}-{os.getpid()}.log"
        with open(path, "w", encoding="utf-8", errors="replace") as fh:
            fh.write(f"designlab {__version__}\nargv: {list(sys.argv if argv is None else argv)!r}\n\n")
            fh.write(traceback.format_exc())
        return path
    except OSError:
        return None


_WARNINGS_SHOWN = [0]


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings as one plain line each (at most 5 numeric ones per command)."""
    if issubclass(category, RuntimeWarning):
        _WARNINGS_SHOWN[0] += 1
        if _WARNINGS_SHOWN[0] > 5:
            return
    err_console.print(plain(("warning:", "yellow"), " ", one_line(str(message), 300)),
                      highlight=False, soft_wrap=True)


def _error(exc: BaseException, prefix: str = "error:") -> None:
    err_console.print(plain((prefix, "bold red"), " ", one_line(exc)), highlight=False,
                      soft_wrap=True)


def main(argv: Optional[List[str]] = None) -> None:
    """Console-script entry point: run the app; a user error (:class:`DesignlabError`, a bad
    option) is one line + exit 2 (a lost cluster, :class:`~designlab.errors.ClusterError`: 3); anything else one line naming a log file with the
    traceback + exit 1; Ctrl-C exit 130. Messages are printed literally (no rich markup).
    Called without ``argv`` (the ``designlab`` command itself), the process then ends without
    the interpreter's teardown (:func:`_exit_now`)."""
    if argv is not None:
        return _main(argv)
    try:
        _main(None)
        code = 0
    except SystemExit as exc:
        code = exc.code
    _exit_now(code)


def _exit_now(code) -> None:
    """End the process with ``code`` (a ``SystemExit`` code) after the exit handlers and a
    flush of stdout/stderr, skipping the interpreter's teardown: once OpenCascade is loaded
    its modules' destructors alone take most of a second (every file is written and closed
    by then)."""
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    try:
        atexit._run_exitfuncs()     # what normal exit runs first (X server, pools, logging)
        _stop_resource_tracker()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):   # a closed pipe: nothing more to say
                pass
        os._exit(code)


def _stop_resource_tracker() -> None:
    """Close multiprocessing's resource tracker and wait for it, when this process started one
    (the process pools of a sweep): left alone it outlives the command by the moments it takes
    to notice the closed pipe and clean up."""
    rt = sys.modules.get("multiprocessing.resource_tracker")
    tracker = getattr(rt, "_resource_tracker", None)
    if tracker is not None and getattr(tracker, "_pid", None) is not None:
        stop = getattr(tracker, "_stop", None)
        if stop is not None:
            stop()


def _refuse_empty_out(args: List[str]) -> None:
    """An empty ``--out`` is a path of "." to the parser: the working folder, written silently."""
    for i, a in enumerate(args):
        value = a[len("--out="):] if a.startswith("--out=") else (
            args[i + 1] if a == "--out" and i + 1 < len(args) else None)
        if value is not None and not value.strip():
            raise ParameterError("--out", value, "a folder or file name (. for the working "
                                 "folder)")


def _main(argv: Optional[List[str]]) -> None:
    # numeric warnings (overflow, invalid values) never flood the terminal: a result they
    # spoil is refused by its own check; the first few go to one line each on stderr
    warnings.simplefilter("once", RuntimeWarning)
    warnings.showwarning = _show_warning
    try:
        _refuse_empty_out(sys.argv[1:] if argv is None else list(argv))
        rc = app(args=argv, standalone_mode=False)
        if isinstance(rc, int) and rc:
            sys.exit(rc)
    except DesignlabError as exc:
        _error(exc)
        sys.exit(exc.exit_code)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        err_console.print("interrupted")
        sys.exit(130)
    except typer.TyperException as exc:  # usage errors of the command parser (bad option...)
        # typer carries its own click: these are typer's, not the click package's
        ctx = getattr(exc, "ctx", None)
        hint = f" (see {ctx.command_path} --help)" if ctx is not None else ""
        _error(f"{exc.format_message()}{hint}")
        sys.exit(getattr(exc, "exit_code", 2) or 2)
    except SystemExit:
        raise
    except BrokenPipeError:  # output piped into a reader that quit (head, less)
        sys.exit(1)
    except RecursionError as exc:
        _error(f"input nested too deeply ({type(exc).__name__})")
        sys.exit(2)
    except MemoryError:
        log = _write_log(argv)
        _error(f"out of memory; use smaller inputs (details in {log})")
        sys.exit(1)
    except Exception as exc:
        log = _write_log(argv)
        where = f"; traceback in {log}" if log else ""
        _error(f"internal error {type(exc).__name__}: {one_line(exc, 300)}{where}")
        sys.exit(1)
