"""The :class:`~designlab.sensors.sensor.Sensor` record of a sensor definition: what ``predict``,
``sweep``, ``optimize`` and the CLI need, from the generic virtual test."""

from __future__ import annotations

from designlab.sensors.generic import virtual as g
from designlab.sensors.generic.loop import apply_model
from designlab.sensors.generic.montecarlo import monte_carlo_model
from designlab.sensors.sensor import Sensor


def _run(part, protocol, settings, progress=None, **_):
    return g.run(part, protocol, settings, progress=progress)


def sensor_record(cls: type) -> Sensor:
    """The record of definition class ``cls``."""
    return Sensor(
        name=cls.name,
        paper=cls.source or "the designer's definition",
        protocol=g.DefinitionProtocol,
        settings=g.settings_class(cls),
        run=_run,
        plots=g.plots,
        gains=g.gains,
        load_cases=g.load_cases,
        convergence=("condition_number", "sensitivity_norm")
        + (("condition_number_scaled",) if getattr(cls, "moment_scale_mm", None) else ()),
        uncertainty=monte_carlo_model(cls),
        apply_model=apply_model,
        row_metrics=("sensitivity_norm", "condition_number_scaled", "force_error", "noise_budget",
                     "cross_talk_percent"),
    )
