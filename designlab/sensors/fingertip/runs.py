"""The hanging-weight test's runs on the fingertip: every load point of the protocol (G1, then
G2) at every rotation of the fingertip. The one location x rotation loop of the contact test,
the calibration test and the loop's readings.
"""

from __future__ import annotations

from collections.abc import Iterator


def location_rotations(part, protocol, rotations_deg) -> Iterator[tuple]:
    """``(group, name, rotation, point, direction)`` of every location of ``protocol`` (G1 then
    G2, each in the protocol's order) at every rotation of ``rotations_deg`` (innermost), the
    rotation as given; the part's load points are computed once per rotation."""
    rotations_deg = list(rotations_deg)
    points = {rot: part.load_points(rot) for rot in rotations_deg}
    for group, names in (("G1", protocol.g1_locations), ("G2", protocol.g2_locations)):
        for name in names:
            for rot in rotations_deg:
                p, d = points[rot][name]
                yield group, name, rot, p, d
