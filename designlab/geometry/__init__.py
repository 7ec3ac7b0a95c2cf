"""Parametric CAD of the sensors, assemblies, printable export and tetrahedral meshing (mm)."""
