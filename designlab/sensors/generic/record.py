"""The :class:`~designlab.sensors.sensor.Sensor` record of a sensor definition: what ``predict``,
``sweep``, ``optimize`` and the CLI need, from the generic virtual test or from the physics the
definition plugs in (:class:`~designlab.sensors.definition.Physics`)."""

from __future__ import annotations

import dataclasses

from designlab.errors import ParameterError
from designlab.sensors.generic import virtual as g
from designlab.sensors.generic.loop import apply_model
from designlab.sensors.generic.montecarlo import monte_carlo_model
from designlab.sensors.sensor import Sensor

#: the record's fields a Physics may set in its hooks
HOOKS = tuple(f.name for f in dataclasses.fields(Sensor)
              if f.name not in ("name", "paper", "protocol", "settings", "run", "plots", "gains"))


def _run(part, protocol, settings, progress=None, **_):
    return g.run(part, protocol, settings, progress=progress)


def sensor_record(cls: type) -> Sensor:
    """The record of definition class ``cls``."""
    physics = getattr(cls, "physics", None)
    if physics is not None:
        return _physics_record(cls, physics)
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


#: the declarations a physics does not read (it takes the geometry from the part's CAD and the
#: rest from its own protocol and settings): a subclass that changes them needs the generic test
UNREAD_BY_PHYSICS = ("supports", "transducers", "loads", "protocol")


def _physics_record(cls: type, physics) -> Sensor:
    unknown = sorted(set(physics.hooks) - set(HOOKS))
    if unknown:
        raise ParameterError(f"{cls.__name__}.physics.hooks", ", ".join(unknown),
                             "hooks of the sensor record: " + ", ".join(HOOKS))
    _check_declarations_read(cls, physics)
    return Sensor(name=cls.name, paper=physics.paper, protocol=physics.protocol,
                  settings=physics.settings, run=physics.run, plots=physics.plots,
                  gains=physics.gains, **physics.hooks)


def _check_declarations_read(cls: type, physics) -> None:
    """A subclass of a definition with a physics (a built-in with new defaults) may not change
    a declaration the physics does not read: its virtual test would silently ignore it. Refused
    in one line naming the declaration and where the physics takes it from."""
    owner = next(c for c in cls.__mro__ if c.__dict__.get("physics") is physics)
    changed = [m for m in UNREAD_BY_PHYSICS if getattr(cls, m) is not getattr(owner, m)]
    if owner is cls or not changed:
        return
    design = cls()
    for m in changed:
        if getattr(cls, m)(design) != getattr(owner, m)(design):
            raise ParameterError(
                f"{cls.__name__}.{m}()", f"differs from {owner.__name__}.{m}()",
                f"unchanged: the {physics.name} physics runs the virtual test without reading "
                f"{m}() (it takes the geometry from the CAD part and the rest from its "
                "protocol and settings: --setting NAME=VALUE)")
