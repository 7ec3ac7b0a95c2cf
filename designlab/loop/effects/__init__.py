"""The effect library: physical mechanisms that can be added to a sensor model.

Each mechanism is one :class:`Effect` subclass in one module of this package (the module's
docstring and the class say what it models and which regressors it adds); defining the class
registers it in :data:`EFFECTS`, and this package imports every module in it, so adding an
effect is adding one file. :mod:`designlab.loop.effects.base` holds what they share: the
signal helpers, the fit (settings by AIC over the effect's grid, coefficients by least squares
with the base's affine part refitted) and the JSON form of a fitted effect.

Candidate order (:func:`library`): for each drive input that varies in the training data, in
the data's order, the ``per_input`` effects by ``rank``; then the other effects by ``rank``
(ties: registration order; the modules are imported by name). The order matters: the greedy
selection takes the first of equally good candidates.

``python -m designlab.loop.effects`` prints the effect table of docs/loop.md
(:func:`effects_table`).
"""

from __future__ import annotations

import importlib
import pkgutil

import numpy as np

from designlab.loop.effects.base import (
    EFFECTS,
    TARE_S,
    Context,
    Effect,
    Fitted,
    contribution,
    dahl,
    describe,
    drive_inputs,
    fit,
    fit_group,
    group_member,
    highpass,
    nuisance_columns,
    ordered,
    play,
    rate,
    regressor,
    robust_range,
    run_paths,
    shift,
    varying_drives,
)
from designlab.measured.dataset import Dataset

for _m in pkgutil.iter_modules(__path__):
    if not _m.name.startswith("_") and _m.name != "base":
        importlib.import_module(f"{__name__}.{_m.name}")

__all__ = ["EFFECTS", "TARE_S", "Context", "Effect", "Fitted", "contribution", "dahl", "describe",
           "drive_inputs", "effects_table", "fit", "fit_group", "group_member", "highpass",
           "library", "nuisance_columns",
           "ordered", "play", "rate", "regressor", "robust_range", "run_paths", "shift",
           "varying_drives"]


def library(train: Dataset, output: str, base_inputs: tuple[str, ...]
            ) -> tuple[list[Effect], dict[str, str]]:
    """The candidate effects that apply to ``output`` of this data, in candidate order (see the
    package docstring), and why others do not (by effect key)."""
    classes = ordered()
    found = {c: c.applies(train, output, base_inputs) for c in classes}
    out: list[Effect] = []
    skipped: dict[str, str] = {}
    for x in drive_inputs(train):
        if np.ptp(train.inputs[x]) == 0:
            skipped[f"*[{x}]"] = "input is constant in the training data"
            continue
        for c in classes:
            if not c.per_input:
                continue
            if isinstance(found[c], str):
                skipped[f"{c.name}[{x}]"] = found[c]
            else:
                out += [e for e in found[c] if e.channel == x]
    for c in classes:
        if c.per_input:
            continue
        if isinstance(found[c], str):
            skipped[c.name] = found[c]
        else:
            out += found[c]
    return out, skipped


def effects_table() -> str:
    """The markdown table of the effects in candidate order (docs/loop.md)."""
    head = ("| effect | regressors added to the prediction | nonlinear settings (grid) "
            "| when it applies |")
    rows = [head, "|---|---|---|---|"]
    rows += [f"| `{c.name}` | {c.regressors_doc} | {c.settings_doc} | {c.applies_doc} |"
             for c in ordered()]
    return "\n".join(rows)
