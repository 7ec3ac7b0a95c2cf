"""The pose is reported about another point than the one the wrench is expressed at."""

from __future__ import annotations

import math

import numpy as np

from designlab.loop.effects.base import Context, Effect, Fitted

#: per-radian factor of an angle unit (the dataset's canonical angle unit is deg)
_PER_RAD = {"rad": 1.0, "deg": math.pi / 180.0}
_AXES = ("x", "y", "z")


def moved_twist(w: np.ndarray, v: np.ndarray, offset: float, axis: str) -> np.ndarray:
    """Translation (n, 3) of a twist ``(w, v)`` (w in rad, (n, 3)) reported about the point
    ``offset * axis`` of its frame instead of the origin: ``v + offset * (w x axis)``, the
    rigid-body rule ``v_q = v + w x q``; equal to :func:`designlab.frames.transform_twist` with
    ``T = transform(translation=-offset * axis)``. Units of ``offset`` and ``v``."""
    a = np.zeros(3)
    a[_AXES.index(axis)] = 1.0
    return np.asarray(v, float) + offset * np.cross(np.asarray(w, float), a)


def _partner(output: str, axis: str) -> tuple[str, float] | None:
    """The rotation whose product with an offset along ``axis`` moves translation ``output``
    (``v_<i>``), and the sign: the ``i``-th component of ``w x axis``. None: no partner
    (the offset is along the translation itself)."""
    i, k = _AXES.index(output[2]), _AXES.index(axis)
    if i == k:
        return None
    j = 3 - i - k                            # the remaining axis
    sign = 1.0 if (j, k) in ((1, 2), (2, 0), (0, 1)) else -1.0   # (e_j x e_k)_i
    return f"w_{_AXES[j]}", sign


def _translation(output: str) -> bool:
    return len(output) == 3 and output[:2] == "v_" and output[2] in _AXES


class PoseReference(Effect):
    """The tracker reports the pose about a point offset by ``e`` along an axis from the frame
    the wrench is expressed in (a camera origin or a fiducial that is not where the model puts
    it): a translation output picks up its partner rotation times ``e``,
    ``v += e (w x axis)`` (for an offset along z: ``v_x += e w_y``, ``v_y -= e w_x``; signs of
    :func:`designlab.frames.adjoint`), rotations are unchanged. Twist outputs are named as
    wrench -> pose cards name them (``w_x, w_y, w_z`` angles, ``v_x, v_y, v_z`` lengths).

    The regressor is the *measured* partner rotation (the data's output; in ``predict``, the
    design's pose): the rule is a rigid-body identity between the two readings of one pose, and
    the framework gives an effect no prediction of another output. ``e`` is fitted alone (no
    refit of the base's input gains beside it: the partner rotation is itself close to a linear
    map of the wrench, so with that refit ``e`` is not identifiable); the zero and gain of a
    loaded base are :class:`GainOffset`'s. Like it, this is an error of a model not fitted on
    the data, which :class:`InputGains` (every input gain refitted) or any effect with a linear
    term in one input would absorb, so it is offered only on a loaded base and taken before
    other passing candidates (``first``; before
    ``gain_offset``: in a pose-driven test the force that drives a translation correlates with
    the partner rotation, so a gain fitted first takes part of the offset: on seed 002's K_c
    in examples/flexure_kc_loop.py, e = -6.58 mm fitted first, -2.95 mm after the gain,
    docs/loop.md). The axis is the
    nonlinear setting (AIC); one ``e`` per output (the loop fits outputs one at a time): for an
    offset along z, ``v_x`` and ``v_y`` each give one, which agree when the data are a pure
    offset. ``e`` in the translation's unit (mm), positive along +axis."""

    name = "pose_reference"
    summary = "the pose is reported about a point offset along an axis (a frame offset)"
    regressors_doc = ("`s w_p` (the measured partner rotation in rad, s = +-1): "
                      "`v += e (w x axis)`")
    settings_doc = ("the axis (x, y or z; not the translation's own) whose partner rotation "
                    "is an output")
    applies_doc = ("a loaded model as the base, on translation outputs `v_x, v_y, v_z` with a "
                   "partner rotation `w_*` among the outputs")
    intercept = False
    rank = 4
    first = True

    @classmethod
    def applies(cls, train, output, base_inputs):
        if not _translation(output):
            return ("not a translation output v_x, v_y, v_z (a rotation is the same about "
                    "every point)")
        if not cls._axes(train, output):
            return (f"no partner rotation of {output} among the outputs (an offset moves it by "
                    "a rotation the data must hold)")
        return [cls()]

    @staticmethod
    def _axes(data, output: str) -> list[dict]:
        out = []
        for axis in _AXES:
            p = _partner(output, axis)
            if p is not None and p[0] in data.outputs \
                    and data.units.get(p[0], "rad") in _PER_RAD:
                out.append({"axis": axis, "partner": p[0], "sign": p[1]})
        return out

    def grid(self, ctx: Context) -> list[dict]:
        return self._axes(ctx.data, ctx.output)

    def features(self, ctx: Context, theta: dict) -> np.ndarray:
        d = ctx.data
        p = theta["partner"]
        return theta["sign"] * _PER_RAD[d.units.get(p, "rad")] * d.outputs[p]

    def solve(self, X: np.ndarray, target: np.ndarray, k: int) -> np.ndarray:
        """``e`` alone: the base's input gains are not refitted beside it."""
        coef = np.zeros(X.shape[1])
        coef[:k] = np.linalg.lstsq(X[:, :k], target, rcond=None)[0]
        return coef

    def width(self, theta: dict) -> int:
        return 1

    def describe(self, f: Fitted) -> dict:
        return {"offset": f.beta[0], "axis": f.theta["axis"], "partner": f.theta["partner"],
                "unit": "offset in the translation's unit (mm) along +axis: the point the "
                        "pose is reported about, seen from the frame of the wrench"}

    def regressor(self, f: Fitted, ctx: Context):
        p = f.theta["partner"]
        return ctx.data.outputs[p], f"{p} ({ctx.data.units.get(p, '')})"
