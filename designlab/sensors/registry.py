"""``SENSORS``: every sensor kind designlab knows, by name. Adding a sensor: a part module in
``geometry/`` (and its line in ``geometry.parts.PARTS``), a sensor module here ending with
``SENSOR = Sensor(...)``, and one line below."""

from __future__ import annotations

from designlab.errors import ParameterError
from designlab.params import did_you_mean
from designlab.sensors.fingertip import virtual as fingertip
from designlab.sensors.strap import virtual as strap
from designlab.sensors.flexure import virtual as flexure
from designlab.sensors.sensor import Sensor

SENSORS: dict[str, Sensor] = {s.name: s for s in (
    strap.SENSOR,
    fingertip.SENSOR,
    flexure.SENSOR,
)}


def get_sensor(name: str) -> Sensor:
    """The sensor called ``name``, or a one-line error listing the known ones."""
    try:
        return SENSORS[name]
    except (KeyError, TypeError):
        raise ParameterError("part", name, "one of " + ", ".join(SENSORS)
                             + did_you_mean(name, SENSORS)) from None
