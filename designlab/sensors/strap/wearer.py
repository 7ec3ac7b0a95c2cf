"""A strap prediction for a wearer: a finger (``W,D,L`` in mm, or a closed STL scan) sets the
strap model's finger radius (the circle of the finger's perimeter, as ``fit-strap`` does) and,
unless a slot or wrap length is given, the slot a wearer would choose: the one whose initial
strain is closest to the paper's medium slot on the reference finger."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.sensors.strap.fit import Finger, default_target, finger_from_scan, parse_finger
from designlab.sensors.strap.prestrain import initial_strain


def read_finger(text: str) -> Finger:
    """``W,D,L`` (mm) or the path of a closed STL scan of the fingertip."""
    p = Path(text)
    if p.suffix.lower() == ".stl":
        if not p.is_file():
            raise ParameterError("--finger", text, "WIDTH,DEPTH,LENGTH in mm or an existing "
                                 "closed STL scan of the fingertip")
        return finger_from_scan(p)
    return parse_finger(text)


def closest_slot(part, perimeter: float, target: float) -> int:
    """The slot of ``part`` whose initial strain on ``perimeter`` is closest to ``target``."""
    eps = [initial_strain(part, perimeter, slot=k) for k in range(1, part.slot_count + 1)]
    return int(np.argmin([abs(e - target) for e in eps])) + 1


def wearer_settings(sensor: str, finger_text: str, overrides: dict[str, Any],
                    settings: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """The model settings for the wearer of ``finger_text`` and a line saying what it set."""
    from designlab.geometry.parts import make_part

    if sensor != "strap":
        raise ParameterError("--finger", finger_text, "only with predict strap (the worn strap "
                             "wraps the finger)")
    for name in ("finger_radius",):
        if name in settings:
            raise ParameterError("--finger", finger_text, f"not with --setting {name} (the "
                                 "finger sets it)")
    finger = read_finger(finger_text)
    out = dict(settings)
    out["finger_radius"] = round(finger.equivalent_radius, 4)
    if "slot" in settings or "wrap_length" in settings:
        how = "slot or wrap length as given"
    else:
        part = make_part("strap", overrides)
        target = default_target()
        out["slot"] = closest_slot(part, finger.perimeter, target)
        eps = initial_strain(part, finger.perimeter, slot=out["slot"])
        how = (f"slot {out['slot']} (initial strain {eps:.3g}, the closest to the paper's "
               f"medium slot on the reference finger, {target:.3g})")
    note = (f"finger {finger.width:g} x {finger.depth:g} x {finger.length:g} mm: perimeter "
            f"{finger.perimeter:.1f} mm ({finger.perimeter_source}), model finger radius "
            f"{out['finger_radius']:g} mm; {how}")
    return out, note
