"""User-facing errors: one line naming the parameter/column and what is allowed.

The CLI turns any :class:`DesignlabError` into that line on stderr and exit code 2.
"""

from __future__ import annotations


class DesignlabError(Exception):
    """An error the user can fix; its message is a single line."""

    #: the command's exit code when this error ends it
    exit_code = 2


class ParameterError(DesignlabError, ValueError):
    """A parameter value outside its allowed range (or an unknown parameter)."""

    def __init__(self, name: str, value: object, allowed: str):
        self.name, self.value, self.allowed = name, value, allowed
        super().__init__(f"{name}={value!r} is not allowed: {allowed}")


class DataError(DesignlabError, ValueError):
    """Measured data that cannot be used as declared (missing column, NaN, bad unit...)."""


class MeshingError(DesignlabError, RuntimeError):
    """Tetrahedral meshing failed after retries."""


class ModelError(DesignlabError, ValueError):
    """An FEM model that cannot be solved as given (singular, no material, unknown set...)."""


class OutputError(DesignlabError, OSError):
    """A result file could not be written as asked (an exporter produced nothing)."""


class ClusterError(DesignlabError, RuntimeError):
    """The compute cluster failed under a run (its Dask scheduler was lost): the designs it
    finished are stored, the ones it did not are named and run by the same command again.
    Exit code 3: not a bad input, and not a result."""

    exit_code = 3
