"""Finite elements: TET4/TET10 elasticity, viscoelastic Prony materials, solvers, transducers (mm, N, MPa, s)."""
