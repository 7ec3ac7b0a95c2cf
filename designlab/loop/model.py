"""A sensor model: a base plus fitted effects per output, and its JSON file.

Model file (JSON, written by :meth:`SensorModel.save`, read by :func:`load_model`)::

    {"format": "designlab-model", "version": 1,
     "model": {"base": {"kind": "stretch-fem", "inputs": {"force": ["displacement"]},
                        "parameters": {"force": {"E_MPa": 0.25, ...}}},
               "outputs": {"force": {"unit": "N", "effects": [
                   {"name": "relaxation", "channel": "displacement", "theta": {"tau": [8.1]},
                    "beta": [0.03], "alpha": [0.01, -0.002], "nuisance": ["displacement"],
                    "parameters": {...}}]}},
               "inputs": {"displacement": {"unit": "mm", "quantity": "length", "kind": "drive"}}},
     "provenance": {...}}

Effects are applied in order: each adds ``F(data, yhat) @ beta + [1, base inputs] @ alpha`` to
the prediction made before it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from designlab.atomic import atomic_write_json, jsonable
from designlab.errors import DesignlabError, ModelError, ParameterError
from designlab.loop import effects as fx
from designlab.loop.base_models import Base
from designlab.loop.base_models import predict as base_predict
from designlab.measured.card import UNITS
from designlab.measured.dataset import Dataset
from designlab.params import load_json

FORMAT = "designlab-model"
#: largest magnitude of a number in a model file (as data values): a 1e308 gain gives inf results
MAX_ABS_NUMBER = 1e20


@dataclass
class SensorModel:
    """A base plus, per output, an ordered list of fitted effects."""

    base: Base
    effects: dict[str, list[fx.Fitted]] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    inputs: dict[str, dict] = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)

    @property
    def outputs(self) -> list[str]:
        return list(self.base.parameters)

    def predict(self, data: Dataset, output: str, measured: np.ndarray | None = None,
                upto: int | None = None) -> np.ndarray:
        """Prediction of ``output`` on ``data`` (output units) after the first ``upto``
        effects (all by default). ``measured`` lets run offsets tare runs never seen."""
        y = base_predict(self.base, data, output)
        for f in self.effects.get(output, [])[:upto]:
            ctx = fx.Context(data, output, y, f.nuisance, measured)
            try:
                y = y + fx.contribution(f, ctx)
            except (ValueError, IndexError, TypeError) as exc:   # coefficients unlike the effect
                raise ModelError(f"the model's effect {f.effect.name} on '{output}' does not fit "
                                 f"its theta and coefficients (beta: {len(f.beta)}, alpha: {len(f.alpha)}; "
                                 f"{str(exc)[:80]})") from None
        return y

    def to_json(self) -> dict:
        return {"format": FORMAT, "version": 1,
                "model": {"base": self.base.to_json(),
                          "outputs": {o: {"unit": self.units.get(o, ""),
                                          "effects": [f.to_json() for f in
                                                      self.effects.get(o, [])]}
                                      for o in self.outputs},
                          "inputs": self.inputs},
                "provenance": self.provenance}

    def save(self, path: str | Path) -> None:
        """Write the model as JSON, atomically (NaN/inf as null)."""
        atomic_write_json(Path(path), self.to_json())


def load_model(path: str | Path, what: str = "--base") -> SensorModel:
    """Read a model JSON written by :meth:`SensorModel.save` (``loop`` or ``predict``).

    Size, encoding, nesting, finite numbers, ``format``/``version`` and the section types are
    checked; the file is data: nothing in it runs.

    Args:
        path: the model file.
        what: the option that named it, for the messages.

    Returns:
        The model. Anything wrong is a one-line :class:`ModelError`.
    """
    p = Path(path)
    doc = _read_document(p, what)
    m = doc["model"]
    _check_numbers(p, m)
    outs, inputs, prov = m.get("outputs", {}), m.get("inputs", {}), doc.get("provenance", {})
    _check_sections(p, outs, inputs, prov)
    _check_base(p, m["base"])
    try:
        base = Base.from_json(m["base"])
        eff = {o: [fx.Fitted.from_json(e) for e in v.get("effects", [])] for o, v in outs.items()}
    except DesignlabError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        raise ModelError(f"{p}: malformed model section ({type(exc).__name__}: "
                         f"{str(exc)[:80]})") from None
    _check_shapes(p, eff)
    return SensorModel(base, eff, {o: str(v.get("unit", "")) for o, v in outs.items()},
                       inputs, prov)


def _read_document(p: Path, what: str) -> dict:
    """The parsed file with its format, version and a model section holding a base table."""
    try:
        doc = load_json(p, what, max_bytes=64 * 1024 * 1024)
    except ParameterError as exc:
        raise ModelError(f"{p}: {what} needs {exc.allowed}") from None
    if not isinstance(doc, dict):
        raise ModelError(f"{p}: a JSON object is needed; expected a {FORMAT} file")
    if doc.get("format") != FORMAT:
        raise ModelError(f"{p}: format={str(doc.get('format'))[:60]!r} is not allowed: "
                         f"{FORMAT!r}")
    if doc.get("version") != 1 or isinstance(doc.get("version"), bool):
        raise ModelError(f"{p}: version={str(doc.get('version'))[:20]!r} is not allowed: 1 "
                         "(this designlab reads version 1)")
    m = doc.get("model")
    if not isinstance(m, dict) or not isinstance(m.get("base"), dict):
        raise ModelError(f"{p}: no 'model' section with a 'base' table; expected a {FORMAT} file")
    return doc


def _check_numbers(p: Path, model: dict) -> None:
    """Every number of the model section finite and at most :data:`MAX_ABS_NUMBER`."""
    stack = [("model", model)]
    while stack:
        where, v = stack.pop()
        if isinstance(v, dict):
            stack.extend((f"{where}.{k}", x) for k, x in v.items())
        elif isinstance(v, list):
            stack.extend((f"{where}[{i}]", x) for i, x in enumerate(v))
        elif isinstance(v, (int, float)) and not isinstance(v, bool) \
                and not abs(v) <= MAX_ABS_NUMBER:
            raise ModelError(f"{p}: {where[:120]}={str(v)[:30]} is not allowed: a finite "
                             "number with |value| <= 1e+20 (as data values)")


def _check_sections(p: Path, outs, inputs, prov) -> None:
    for name, v in (("model.outputs", outs), ("model.inputs", inputs), ("provenance", prov)):
        if not isinstance(v, dict):
            raise ModelError(f"{p}: {name} is not allowed: a JSON object")
    for o, v in outs.items():
        if not isinstance(v, dict) or not isinstance(v.get("effects", []), list):
            raise ModelError(f"{p}: model.outputs.{o} is not allowed: an object with an "
                             "'effects' list")
        for i, e in enumerate(v.get("effects", [])):
            where = f"model.outputs.{o}.effects[{i}]"
            if not isinstance(e, dict) or not isinstance(e.get("theta"), dict):
                raise ModelError(f"{p}: {where} is not allowed: an object with a 'theta' object")
            for key, ok in (("beta", _is_number), ("alpha", _is_number),
                            ("nuisance", lambda x: isinstance(x, str))):
                x = e.get(key)
                if not isinstance(x, list) or not all(ok(y) for y in x):
                    raise ModelError(f"{p}: {where}.{key}={str(x)[:40]} is not allowed: a list "
                                     f"of {'names' if key == 'nuisance' else 'numbers'}")


def _numbers(n: int) -> str:
    return f"{n} number{'' if n == 1 else 's'}"


def _check_shapes(p: Path, effects: dict[str, list[fx.Fitted]]) -> None:
    """Every effect's settings, ``beta`` and ``alpha`` of the lengths the effect reads: one
    line naming the key, the value with its length and the length allowed (a short ``beta``
    would otherwise fail inside the prediction, after the data are read)."""
    for o, fits in effects.items():
        for i, f in enumerate(fits):
            where, name = f"model.outputs.{o}.effects[{i}]", f.effect.name
            try:
                k = f.effect.width(f.theta)
            except (KeyError, TypeError, ValueError) as exc:
                why = (f"it has no {exc.args[0]!r}" if isinstance(exc, KeyError) else str(exc))
                raise ModelError(f"{p}: {where}.theta={str(jsonable(f.theta))[:60]} is not "
                                 f"allowed: the settings effect {name} reads ({why[:60]})"
                                 ) from None
            if k is not None and len(f.beta) != k:
                raise ModelError(f"{p}: {where}.beta={str(list(f.beta))[:60]} "
                                 f"({_numbers(len(f.beta))}) is not allowed: {_numbers(k)}, one "
                                 f"per regressor of effect {name} at its theta")
            nuis = len(f.nuisance)
            allowed = {int(f.effect.intercept) + nuis: (
                f"{'an intercept and ' if f.effect.intercept else ''}one gain per nuisance "
                f"input ({nuis})")}
            if f.runs and f.effect.intercept:
                allowed.setdefault(len(f.runs) + nuis, f"one offset per run ({len(f.runs)}) "
                                   "and one gain per nuisance input")
            if f.alpha and len(f.alpha) not in allowed:   # none: no affine refit carried
                ok = " or ".join(_numbers(n) for n in sorted(allowed))
                raise ModelError(f"{p}: {where}.alpha={str(list(f.alpha))[:60]} "
                                 f"({_numbers(len(f.alpha))}) is not allowed: {ok} "
                                 f"({'; '.join(allowed.values())})")


#: the numbers each base kind's predict reads per output (``linear``: ``intercept`` and ``gains``)
#: (a stretch base: its force law when it holds E_MPa, else its resistance law)
_BASE_NUMBERS = {"force": ("F0_N", "stiffness_factor", "E_MPa", "area_mm2", "length_mm"),
                 "resistance": ("R0_ohm", "GF", "length_mm")}


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_base(p: Path, base: dict) -> None:
    """The base's inputs (a list of names per output) and the numbers its kind reads: one line
    naming the key and value when one is text, a boolean, a list or missing."""
    inputs, params = base.get("inputs"), base.get("parameters")
    if not isinstance(inputs, dict) or not isinstance(params, dict):
        raise ModelError(f"{p}: model.base needs 'inputs' and 'parameters' objects")
    for o, names in inputs.items():
        if not isinstance(names, list) or not names \
                or not all(isinstance(n, str) for n in names):
            raise ModelError(f"{p}: model.base.inputs.{o}={str(names)[:40]} is not allowed: "
                             "a list of input names")
    for o, v in params.items():
        where = f"model.base.parameters.{o}"
        if o not in inputs or not isinstance(v, dict):
            raise ModelError(f"{p}: {where} is not allowed: an object for an output named in "
                             "model.base.inputs")
        kind = base.get("kind")
        if kind == "linear":
            gains = v.get("gains")
            if not isinstance(gains, dict):
                raise ModelError(f"{p}: {where}.gains is not allowed: an object of input: gain")
            need = [("intercept", v.get("intercept"))] + [(f"gains.{k}", g)
                                                          for k, g in gains.items()]
        elif kind == "load-arm":
            c = v.get("coefficients")
            if not isinstance(c, list) or len(c) != 7:
                raise ModelError(f"{p}: {where}.coefficients={str(c)[:40]} is not allowed: a "
                                 "list of 7 numbers")
            need = [(f"coefficients[{i}]", x) for i, x in enumerate(c)]
        else:
            keys = _BASE_NUMBERS["force" if "E_MPa" in v else "resistance"]
            need = [(k, v.get(k)) for k in keys]
        for k, x in need:
            if not _is_number(x):
                raise ModelError(f"{p}: {where}.{k}={str(x)[:30]} is not allowed: a number")


def convert_units(model: SensorModel, data: Dataset, outs: list[str]) -> None:
    """Rescale a loaded model's outputs to the data's units, in place.

    A model whose output unit differs from the data's (a ``predict`` model gives a flexure's
    rotations in rad, a card's angles are read in deg): a linear base without effects is
    rescaled to the data's unit (recorded in the provenance); anything else is a one-line
    ModelError naming the output and both units.
    """
    for o in outs:
        mu, du = model.units.get(o, ""), data.units.get(o, "")
        if not mu or not du or mu == du:
            continue
        table = next((t for t in UNITS.values() if mu in t and du in t), None)
        factor = (table[mu] / table[du] if table is not None
                  and not isinstance(table[mu], tuple) else None)
        if factor is None or model.base.kind != "linear" or model.effects.get(o):
            raise ModelError(f"the model predicts output '{o}' in {mu}, the data has it in {du}; "
                             "a model with effects or a nonlinear base cannot be rescaled")
        p = model.base.parameters[o]
        p["intercept"] = float(p["intercept"]) * factor
        p["gains"] = {k: float(v) * factor for k, v in p["gains"].items()}
        model.provenance.setdefault("unit_conversions", {})[o] = {
            "from": mu, "to": du, "factor": factor}
        model.units[o] = du
