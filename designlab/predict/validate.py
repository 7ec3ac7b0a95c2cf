"""Each sensor beside its paper (``designlab validate``): runs the sensors' ``validate`` (their
:class:`~designlab.sensors.sensor.Goal` rows and detailed comparison) and writes
``validation.json`` and the short report ``validation.md`` into the output folder. Nothing
here names a sensor kind: the sensors and their comparisons come from the registry.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable, Sequence

from designlab.sensors.sensor import Goal

#: ``designlab validate``'s word for every sensor that has a comparison
ALL = "all"
#: the report's table: the Goal fields shown, in order
COLUMNS = ("name", "value", "paper", "target", "met", "why")


def validated_sensors() -> list[str]:
    """The registry's sensors that have a paper comparison (``Sensor.validate``)."""
    from designlab.sensors.registry import SENSORS

    return [n for n, s in SENSORS.items() if s.validate is not None]


def sensors_for(which: str) -> list[str]:
    """The sensor names ``which`` stands for (a sensor's name or :data:`ALL`); anything else is
    a one-line error naming ``sensor``."""
    from designlab.errors import ParameterError
    from designlab.params import did_you_mean

    names = validated_sensors()
    if which == ALL:
        return names
    if which not in names:
        choices = [*names, ALL]
        raise ParameterError("sensor", which, "one of " + ", ".join(choices)
                             + did_you_mean(which, choices))
    return [which]


def cell(v: Any) -> str:
    """A value of a goal row as text: numbers to 4 significant digits, yes/no, '-' for none."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def report_markdown(data: dict[str, Any]) -> str:
    """``validation.md``: per sensor its paper and one table row per goal, then its figures."""
    lines = ["# Validation", "",
             "Each sensor beside its paper (`designlab validate`): every goal with the model's "
             "value, the paper's, the target, whether it is met and why. All numbers and the "
             "detailed comparison: `validation.json`.", ""]
    for name, sec in data.items():
        met = [g["met"] for g in sec["goals"] if g["met"] is not None]
        lines += [f"## {name}", "", f"{sec['paper']}: {sum(met)} of {len(met)} goals met.", "",
                  "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        lines += ["| " + " | ".join(cell(g[c]).replace("|", "\\|") for c in COLUMNS) + " |"
                  for g in sec["goals"]]
        lines += [""] + [f"![{f}]({f})" for f in sec["details"].get("figures", [])] + [""]
    return "\n".join(lines)


def validate(which: str | Sequence[str], out: str | Path,
             progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the comparison of each sensor ``which`` names (a name, :data:`ALL`, or a list of
    names), write ``validation.json`` (sensor -> its paper, goal rows and detailed comparison)
    and ``validation.md`` into ``out`` (atomically, each file whole or not at all; a sensor's
    figures beside them) and return that data. The names are checked before anything runs."""
    from designlab.atomic import atomic_write_bytes, atomic_write_json, ensure_dir, jsonable
    from designlab.sensors.registry import get_sensor

    names = [n for w in ([which] if isinstance(which, str) else which) for n in sensors_for(w)]
    names = list(dict.fromkeys(names))
    out = ensure_dir(out)
    data: dict[str, Any] = {}
    for name in names:
        sensor = get_sensor(name)
        say = (lambda s, n=name: progress(f"{n}: {s}")) if progress else None
        details: dict[str, Any] = {}
        goals: list[Goal] = sensor.validate(details, out=out, progress=say)
        data[name] = {"paper": sensor.paper,
                      "goals": [dataclasses.asdict(g) for g in goals],
                      "details": details}
    data = jsonable(data)
    atomic_write_json(out / "validation.json", {"format": "designlab-validation",
                                                "sensors": data})
    atomic_write_bytes(out / "validation.md", report_markdown(data).encode("utf-8"))
    return data
