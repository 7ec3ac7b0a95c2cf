"""designlab: design, predict and learn 3D-printed force sensors.

Units everywhere inside the package: mm, N, MPa, s (consistent set; stress in MPa = N/mm^2,
mass density in t/mm^3). Stiffness is reported in SI where a paper does, and says so.
"""

__version__ = "0.1.0"
