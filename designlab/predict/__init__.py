"""The run of a virtual test on one design: the prediction, its record and writer, its side work,
the Monte Carlo of its uncertainty and the HTML report.

The package is also the Python API's ``dl.predict(part, ...)``: calling it runs
:func:`designlab.predict.run.predict` (so the layer's name and the API's verb stay one word)."""

from __future__ import annotations

import sys
from types import ModuleType


class _CallablePackage(ModuleType):
    def __call__(self, *args, **kwargs):
        """``designlab.predict(part, params=None, **kw)``: :func:`designlab.predict.run.predict`."""
        from designlab.predict.run import predict

        return predict(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
