"""The ``designlab`` command line (typer + rich).

Every command is a thin wrapper over library functions. A :class:`DesignlabError` becomes one
line on stderr and exit code 2 (no traceback, nothing half-written).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console

from designlab import __version__
from designlab.errors import DesignlabError

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Design, predict and learn 3D-printed force sensors (units: mm, N, MPa, s).")
console = Console()
err_console = Console(stderr=True)

PART_NAMES = ("strap", "fingertip", "flexure")


def _print_version(value: bool) -> None:
    if value:
        console.print(f"designlab {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the version and exit.")):
    """designlab: parametric sensors -> mesh -> FEM -> virtual tests -> sweeps -> measured loop."""


# --- commands (each helper inserts its command above this line) ---


def main(argv: Optional[List[str]] = None) -> None:
    """Console-script entry point: run the app, map user errors to one line + exit 2."""
    try:
        app(args=argv, standalone_mode=False)
    except DesignlabError as exc:
        err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        err_console.print("aborted")
        sys.exit(130)
    except Exception as exc:
        # usage errors of typer's command parser (missing command, bad option...)
        if hasattr(exc, "show") and hasattr(exc, "exit_code"):
            exc.show()
            sys.exit(exc.exit_code or 2)
        raise


if __name__ == "__main__":
    main()
