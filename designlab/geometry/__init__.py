"""Parametric CAD of the sensors (mm): parts as parameter objects, assemblies, printable export (STL/3MF/STEP/glTF), printability checks, tessellation and renders."""

from designlab.geometry import _lazy  # noqa: E402,F401  (before any build123d import)
