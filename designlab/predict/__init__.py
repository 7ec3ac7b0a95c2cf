"""The run of a virtual test on one design: the prediction (:mod:`~designlab.predict.run`), its
record and writer (:mod:`~designlab.predict.record`), the forked processes of its side work
(:mod:`~designlab.predict.side`), the Monte Carlo of its uncertainty and the HTML report.

The package is also the Python API's ``dl.predict(part, ...)``: calling it runs
:func:`designlab.predict.run.predict` (so the layer's name and the API's verb stay one word).
``from designlab.predict import Prediction, predict, write_prediction`` loads them on first use
(``import designlab.predict`` stays light)."""

from __future__ import annotations

import sys
from types import ModuleType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from designlab.predict.record import Prediction, write_prediction
    from designlab.predict.run import predict, predict_and_write

__all__ = ["Prediction", "predict", "predict_and_write", "write_prediction"]

#: the API names and the modules that define them
_DEFINED_IN = {"Prediction": "record", "write_prediction": "record", "predict": "run",
               "predict_and_write": "run"}


class _CallablePackage(ModuleType):
    def __call__(self, *args, **kwargs):
        """``designlab.predict(part, params=None, **kw)``: :func:`designlab.predict.run.predict`."""
        from designlab.predict.run import predict

        return predict(*args, **kwargs)


def __getattr__(name: str) -> Any:
    """The API names, imported from their modules when first used."""
    if name not in _DEFINED_IN:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{_DEFINED_IN[name]}"), name)


sys.modules[__name__].__class__ = _CallablePackage
