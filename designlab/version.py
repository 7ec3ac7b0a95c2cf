"""The package's version: one place, read by pyproject.toml (``tool.setuptools.dynamic``), the
CLI, the FEM cache keys and the reports."""

__version__ = "0.1.0"
