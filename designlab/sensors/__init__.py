"""The sensors: one module per sensor kind (its virtual test as the paper ran it, plots, paper
comparison, its linear model for the loop) and ``SENSORS``, the registry every command reads::

    from designlab.sensors import SENSORS
    from designlab.predict.run import predict
    pred = predict("fingertip", {"h": 3.0})
    pred.condition_number, pred.hysteresis_percent
"""

from __future__ import annotations

__all__ = ["SENSORS", "get_sensor"]


def __getattr__(name: str):
    # lazy: importing designlab.sensors.flexure.spring must not build every virtual test
    if name in ("SENSORS", "get_sensor"):
        from designlab.sensors import registry

        return getattr(registry, name)
    raise AttributeError(f"module 'designlab.sensors' has no attribute {name!r}")
