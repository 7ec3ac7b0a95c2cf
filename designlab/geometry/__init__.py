"""Parametric CAD of the sensors (mm): parts as parameter objects, assemblies, printable export (STL/3MF/STEP/glTF), printability checks, tessellation and renders."""
