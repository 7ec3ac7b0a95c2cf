"""User-facing errors: one line naming the parameter/column and what is allowed.

The CLI turns any :class:`DesignlabError` into that line on stderr and exit code 2.
"""

from __future__ import annotations


class DesignlabError(Exception):
    """An error the user can fix; its message is a single line."""


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
