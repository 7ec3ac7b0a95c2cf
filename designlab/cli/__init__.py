"""The ``designlab`` command line (typer + rich): every command a thin wrapper over the
library. Importing the package registers each command module's commands on the one app
(:mod:`designlab.cli.app`), listed by ``designlab --help`` in :data:`HELP_ORDER`."""

from designlab.cli import app as _app
from designlab.cli import flexure, measured, parts, predict, sensors, strap, sweep, validate, verify  # commands
from designlab.cli.app import main

#: the order of ``designlab --help``'s command list (a command not named here comes last)
HELP_ORDER = (sweep.sweep, sweep.optimize, flexure.flexure, parts.export, parts.show,
              measured.compensate, measured.loop_cmd, verify.verify, parts.mesh_cmd,
              predict.predict, validate.validate, strap.fit_strap, strap.strap_sizes, parts.params_cmd,
              sensors.new, sensors.sensors_cmd, sensors.materials_cmd)

_app.app.registered_commands.sort(
    key=lambda c: HELP_ORDER.index(c.callback) if c.callback in HELP_ORDER else len(HELP_ORDER))

__all__ = ["main"]
