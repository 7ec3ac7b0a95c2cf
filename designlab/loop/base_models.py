"""BASE models of the loop: what a sensor is believed to do before the residual is analysed.

- ``linear``: a static affine map from the inputs to each output (least squares on training
  data); ``linear:a,b`` restricts it to the inputs ``a`` and ``b``.
- ``stretch-fem`` (alias ``specimen``): the 40 x 10 x 4 mm stretch specimen of
  ../shared/data/stretch (Dragon Skin + 7.5 wt% carbon black), linear-elastic silicone clamped
  at both grips. Force ``F = F0 + k(E) d`` with the axial stiffness ``k`` from a static TET10 FEM
  solution of the box (designlab.fem; linear in E, so solved once at E = 1 MPa) and E fitted on
  the training data; resistance ``R = R0 (1 + GF d / L)`` with R0 and GF fitted.
  ``stretch-closed`` uses the closed form ``k = E A / L`` instead of the FEM.
- ``load-arm`` (``load-arm:LOAD,ARM[,ANGLE]``): a load ``w`` (a drive input: a hanging weight or
  a force) acting at a moment arm ``a`` (the input of kind location) in a direction turned by
  an angle ``phi`` (an input of quantity angle, e.g. the fingertip's rotation; optional). Every
  component of the wrench it makes about a fixed point is ``w`` times a combination of
  ``[1, cos phi, sin phi]`` and ``a [1, cos phi, sin phi]``, so a linear sensor reads
  ``y = y0 + w (g1 + g2 cos phi + g3 sin phi) + w a (g4 + g5 cos phi + g6 sin phi)``; the seven
  coefficients are fitted (least squares). Exact for loads of one kind (seed 001's lateral loads
  at heights, or its axial loads at radii), not for a mix of both in one card.

A base is a :class:`Base`: ``kind``, the ``inputs`` it uses per output and fitted
``parameters`` per output; :func:`predict` evaluates it. Units: mm, N, MPa, ohm, s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from designlab.measured.dataset import Dataset
from designlab.errors import DataError, ModelError, ParameterError
from designlab.params import did_you_mean

SPECIMEN = {"length": 40.0, "width": 10.0, "thickness": 4.0, "nu": 0.49}
BASE_KINDS = ("linear", "stretch-fem", "specimen", "stretch-closed", "load-arm")


@dataclass(frozen=True)
class Base:
    """A fitted base model: ``parameters[output]`` holds what :func:`predict` needs."""

    kind: str
    inputs: dict[str, tuple[str, ...]]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"kind": self.kind, "inputs": {k: list(v) for k, v in self.inputs.items()},
                "parameters": self.parameters}

    @staticmethod
    def from_json(d: dict) -> "Base":
        kind = d.get("kind")
        if kind not in BASE_KINDS:
            raise ModelError(f"model base kind={kind!r} is not known; allowed: "
                             f"{', '.join(BASE_KINDS)}")
        return Base(kind, {k: tuple(v) for k, v in d["inputs"].items()}, d["parameters"])


@lru_cache(maxsize=8)
def specimen_stiffness_factor(length: float = 40.0, width: float = 10.0, thickness: float = 4.0,
                              nu: float = 0.49, divisions: tuple[int, int, int] = (16, 4, 2)
                              ) -> float:
    """Axial stiffness of the box clamped at both ends (one end pulled by 1 mm, lateral motion
    of both grip faces held) over the closed form E A / L: > 1 because the grips stop the
    lateral contraction. Static TET10 FEM at E = 1 MPa (designlab.fem)."""
    from designlab.fem.materials import Material
    from designlab.fem.model import Model
    from designlab.fem.static import solve_static
    from designlab.mesh.tetmesh import box_tet_mesh

    mesh = box_tet_mesh(length, width, thickness, *divisions).quadratic()
    model = Model(mesh, materials={"block": Material("specimen", E=1.0, nu=nu)})
    model.fix("xmin")
    model.prescribe("xmax", displacement=(1.0, 0.0, 0.0))
    res = solve_static(model)
    k = float(res.wrench("xmax")[3])
    return k / (width * thickness / length)


def _choose_input(data: Dataset, kind: str) -> str:
    for name in data.inputs:
        if data.quantities.get(name) == "length" and data.kinds.get(name, "drive") == "drive":
            return name
    raise DataError(f"base {kind} needs a displacement input (a length in [inputs]); the data "
                    f"has {', '.join(data.inputs) or 'none'}")


def fit_base(kind: str, train: Dataset, outputs: list[str]) -> Base:
    """Fit the base ``kind`` (``linear``, ``linear:a,b``, ``stretch-fem``, ``specimen``,
    ``stretch-closed``) to every output of ``train``."""
    name, _, arg = kind.partition(":")
    if name not in BASE_KINDS:
        raise ParameterError("--base", kind, "linear, linear:INPUT[,INPUT..], stretch-fem, "
                             "specimen, stretch-closed, load-arm[:LOAD,ARM[,ANGLE]] or a model "
                             ".json file" + did_you_mean(name, BASE_KINDS))
    if name == "load-arm":
        return _fit_load_arm(kind, arg, train, outputs)
    if name == "linear":
        use = tuple(a.strip() for a in arg.split(",") if a.strip()) or tuple(train.inputs)
        for u in use:
            if u not in train.inputs:
                raise ParameterError("--base", kind, f"inputs among {', '.join(train.inputs)}")
        base = Base("linear", {o: use for o in outputs})
        X = np.column_stack([np.ones(len(train))] + [train.inputs[u] for u in use])
        for o in outputs:
            coef, *_ = np.linalg.lstsq(X, train.outputs[o], rcond=None)
            base.parameters[o] = {"intercept": float(coef[0]),
                                  "gains": {u: float(c) for u, c in zip(use, coef[1:])}}
        return base
    d_name = _choose_input(train, name)
    d = train.inputs[d_name]
    L, W, T = SPECIMEN["length"], SPECIMEN["width"], SPECIMEN["thickness"]
    A = W * T
    factor = 1.0 if name == "stretch-closed" else specimen_stiffness_factor(L, W, T,
                                                                              SPECIMEN["nu"])
    base = Base("stretch-closed" if name == "stretch-closed" else "stretch-fem",
                {o: (d_name,) for o in outputs})
    X = np.column_stack([np.ones(d.size), d])
    for o in outputs:
        q = train.quantities.get(o)
        a, b = np.linalg.lstsq(X, train.outputs[o], rcond=None)[0]
        if q == "force":
            E = float(b) / (factor * A / L)
            base.parameters[o] = {
                "law": "F = F0 + k d, k = factor * E * A / L", "E_MPa": E, "F0_N": float(a),
                "k_N_per_mm": float(b), "stiffness_factor": factor,
                "stiffness_from": ("closed form E A / L" if name == "stretch-closed" else
                                   "static TET10 FEM of the clamped 40x10x4 mm box, nu = 0.49"),
                "length_mm": L, "area_mm2": A}
        elif q == "resistance":
            if a == 0:
                raise ModelError(f"output '{o}': fitted R0 = 0 ohm; the resistance base needs "
                                 "an absolute resistance (no bias removal on it)")
            base.parameters[o] = {"law": "R = R0 (1 + GF d / L)", "R0_ohm": float(a),
                                  "GF": float(b) * L / float(a), "length_mm": L}
        else:
            raise ModelError(f"base {name} models force and resistance outputs; '{o}' is a "
                             f"{q or 'unknown quantity'}; use --base linear")
    return base


def predict(base: Base, data: Dataset, output: str) -> np.ndarray:
    """The base prediction of ``output`` on ``data`` (output units)."""
    if output not in base.parameters:
        raise ModelError(f"the model has no output '{output}'; it has "
                         f"{', '.join(base.parameters)}")
    p = base.parameters[output]
    for n in base.inputs[output]:
        if n not in data.inputs:
            raise DataError(f"the model needs input '{n}', the data has "
                            f"{', '.join(data.inputs) or 'none'}")
    if base.kind == "load-arm":
        return _load_arm_columns(data, base.inputs[output]) @ np.asarray(p["coefficients"])
    if base.kind == "linear":
        y = np.full(len(data), p["intercept"])
        for n, g in p["gains"].items():
            y = y + g * data.inputs[n]
        return y
    d = data.inputs[base.inputs[output][0]]
    if "E_MPa" in p:
        return p["F0_N"] + p["stiffness_factor"] * p["E_MPa"] * p["area_mm2"] / p["length_mm"] * d
    return p["R0_ohm"] * (1.0 + p["GF"] * d / p["length_mm"])


LOAD_ARM_TERMS = ("1", "w", "w cos(phi)", "w sin(phi)", "w a", "w a cos(phi)", "w a sin(phi)")


def _load_arm_inputs(kind: str, arg: str, data: Dataset) -> tuple[str, ...]:
    """(load, arm[, angle]) input names: given after ``load-arm:`` or found by kind/quantity."""
    if arg:
        use = tuple(a.strip() for a in arg.split(",") if a.strip())
        if len(use) not in (2, 3) or any(u not in data.inputs for u in use):
            raise ParameterError("--base", kind, "load-arm:LOAD,ARM[,ANGLE] with inputs among "
                                 + ", ".join(data.inputs))
        return use
    load = [n for n in data.inputs if data.kinds.get(n, "drive") == "drive"
            and data.quantities.get(n) in ("mass", "force")]
    arm = [n for n in data.inputs if data.kinds.get(n) == "location"]
    angle = [n for n in data.inputs if data.quantities.get(n) == "angle"]
    if not load or not arm:
        raise DataError(f"base load-arm needs a load input (a weight or force) and a location "
                        f"input (kind = \"location\"); the data has "
                        f"{', '.join(data.inputs) or 'none'}")
    return (load[0], arm[0], *angle[:1])


def _load_arm_columns(data: Dataset, use: tuple[str, ...]) -> np.ndarray:
    for n in use:
        if n not in data.inputs:
            raise DataError(f"the model needs input '{n}', the data has "
                            f"{', '.join(data.inputs) or 'none'}")
    w, a = data.inputs[use[0]], data.inputs[use[1]]
    phi = np.radians(data.inputs[use[2]]) if len(use) > 2 else np.zeros(len(data))
    c, s = np.cos(phi), np.sin(phi)
    return np.column_stack([np.ones(len(data)), w, w * c, w * s, w * a, w * a * c, w * a * s])


def _fit_load_arm(kind: str, arg: str, train: Dataset, outputs: list[str]) -> Base:
    use = _load_arm_inputs(kind, arg, train)
    X = _load_arm_columns(train, use)
    if len(use) < 3:                     # no angle: the cos/sin columns repeat w and w a
        X[:, [2, 3, 5, 6]] = 0.0
    base = Base("load-arm", {o: use for o in outputs})
    for o in outputs:
        coef, *_ = np.linalg.lstsq(X, train.outputs[o], rcond=None)
        base.parameters[o] = {
            "law": "y = y0 + w (g1 + g2 cos phi + g3 sin phi) + w a (g4 + g5 cos phi + g6 sin phi)",
            "load": use[0], "arm": use[1], "angle": use[2] if len(use) > 2 else None,
            "coefficients": [float(v) for v in coef],
            "terms": dict(zip(LOAD_ARM_TERMS, (float(v) for v in coef)))}
    return base
