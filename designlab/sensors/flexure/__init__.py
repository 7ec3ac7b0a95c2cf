"""Seed 002 spring flexure: the closed-form helical-spring 6x6 stiffness, the helix FEM, the virtual wrench test and the paper comparison."""
