"""The command line as written: a bracketed word in an option's help (a TOML table such as
``[uncertainty]``, an optional part ``[:Class]``) is not eaten as rich markup; a parameter
named with its part (``--set flexure.active_coils=2``) is taken by predict as by export."""

from __future__ import annotations

import re

import typer.main
from typer.testing import CliRunner

import designlab.cli  # noqa: F401  (registers every command group)
from designlab.cli.app import app


def _commands(group):
    for name, cmd in group.commands.items():
        yield from ([(name, cmd)] if not hasattr(cmd, "commands") else
                    [(f"{name} {n}", c) for n, c in _commands(cmd)])


def test_every_bracketed_word_of_the_help_is_shown():
    group = typer.main.get_command(app)
    runner = CliRunner()
    checked = 0
    for name, cmd in _commands(group):
        words = {w.replace("\\[", "[") for p in cmd.params for w in
                 re.findall(r"\\?\[[^\]\s]+\]", getattr(p, "help", None) or "")}
        if not words:
            continue
        res = runner.invoke(app, [*name.split(), "--help"], env={"COLUMNS": "400"})
        shown = " ".join(res.output.split())
        for w in words:
            assert w in shown, (name, w)
            checked += 1
    assert checked >= 3


def test_predict_takes_a_parameter_named_with_its_part_as_export_does():
    """``--set flexure.active_coils=2`` (export's form) names the part's own parameter."""
    from designlab.cli.predict import _overrides

    assert _overrides("flexure", None, ["flexure.active_coils=2", "wire_radius=0.9"]) == \
        {"active_coils": "2", "wire_radius": "0.9"}
