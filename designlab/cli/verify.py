"""``designlab verify``: the FEM's verification cases (patch test, symmetry, rigid-body modes,
beam and convergence references, viscoelastic responses, optionally CalculiX)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

from designlab.cli.app import app, console, next_step, progress_bar
from designlab.errors import DesignlabError


def _table(results: list[dict]) -> Table:
    table = Table(title="designlab FEM verification")
    for col in ("case", "quantity", "ours", "reference", "error", "tol", ""):
        table.add_column(col, justify="left" if col in ("case", "quantity") else "right",
                         no_wrap=col not in ("case", "quantity"))
    for c in results:
        table.add_row(c["name"], c["quantity"], f"{c['value']:.4g}", f"{c['reference']:.4g}",
                      f"{c['rel_error']:.1e}", f"{c['tolerance']:.0e}",
                      "[green]pass[/]" if c["passed"] else "[bold red]FAIL[/]")
    return table


@app.command()
def verify(reference: Optional[str] = typer.Option(None, "--reference",
                                                   help="Also compare node by node with a reference solver: calculix (needs ccx)."),
           out: Path = typer.Option(Path("verify-out"), "--out", help="Output directory for verify.json."),
           threads: int = typer.Option(1, "--threads", help="Threads of the reference solver (CalculiX).")):
    """Verify the FEM: patch test, K symmetry, rigid-body modes, cantilever vs Timoshenko,
    convergence orders, viscoelastic creep/relaxation vs exact responses [, CalculiX]."""
    from designlab.fem.verify import default_cases, write_report

    if threads < 1:
        raise DesignlabError(f"--threads={threads} is not allowed: an integer >= 1")
    if reference is not None:
        if reference != "calculix":
            raise DesignlabError(f"--reference={reference!r} is not allowed: calculix")
        from designlab.fem.calculix import ccx_path

        ccx_path()
    groups = default_cases(reference, threads)
    results: list[dict] = []
    with progress_bar("verifying", len(groups)) as bar:
        for title, fn in groups:
            bar(f"verifying: {title}")
            results.extend(fn())
            bar(advance=1)
    console.print(_table(results))
    path = write_report(results, out / "verify.json")
    failed = [c for c in results if not c["passed"]]
    console.print(f"{len(results) - len(failed)}/{len(results)} passed -> {path}", markup=False)
    next_step(f"open next: {path} (every case with its reference and tolerance)")
    if failed:
        raise SystemExit(1)  # (main() drops typer.Exit codes under standalone_mode=False)
