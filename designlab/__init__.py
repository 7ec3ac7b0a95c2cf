"""designlab: design, predict and learn 3D-printed force sensors.

Units everywhere inside the package: mm, N, MPa, s (consistent set; stress in MPa = N/mm^2,
mass density in t/mm^3). Stiffness is reported in SI where a paper does, and says so.

The Python API (names load on first use)::

    import designlab as dl
    part = dl.Fingertip(h=3, r=9)      # a part: part.params(), part.show(), shown in Jupyter
    pred = dl.predict(part)            # a Prediction: pred.summary(), pred.plot(), pred.save(DIR)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from designlab.version import __version__

#: the public sensor definition (designlab.sensors.definition)
_DEFINITION = ("SensorDefinition", "Physics", "param", "Solid", "Face", "Region", "Clamped", "ElasticSupport",
               "ElasticInterface", "ForceSensor", "StrainGauge", "DisplacementProbe",
               "RotationProbe", "CapacitiveGap", "Magnet", "LoadPoint", "LoadState", "Staircase",
               "Wrenches", "step_solids")

__all__ = ["__version__", "Fingertip", "Strap", "Flexure", "PARTS", "SENSORS", "Prediction",
           "predict", "write_prediction", "get_material", "MATERIALS", *_DEFINITION]

#: the built-in sensors' definitions (designlab.sensors.registry.API_CLASSES)
_BUILT_IN = ("Fingertip", "Strap", "Flexure")

if TYPE_CHECKING:
    from designlab.fem.materials import MATERIALS, get_material
    from designlab.geometry.parts import PARTS
    from designlab.sensors.fingertip.definition import CantileverFingertip as Fingertip
    from designlab.sensors.flexure.definition import SpringFlexure as Flexure
    from designlab.sensors.strap.definition import ArchStrap as Strap
    from designlab.predict.record import Prediction, write_prediction
    from designlab.predict.run import predict
    from designlab.sensors.registry import SENSORS


def __getattr__(name: str) -> Any:
    """The API names, imported when first used (``import designlab`` stays light)."""
    if name in _BUILT_IN:
        # a built-in sensor's definition (its CAD part's parameters, its declarations, its
        # physics): a designer subclasses it to change what it is made of or reads
        from designlab.sensors.registry import API_CLASSES

        return API_CLASSES[name]
    if name == "PARTS":
        from designlab.geometry.parts import PARTS

        return PARTS
    if name == "predict":
        # the package designlab.predict is callable: dl.predict(part) runs the prediction
        import designlab.predict as _pkg

        return _pkg
    if name in ("Prediction", "write_prediction"):
        from designlab.predict import record as _p

        return getattr(_p, name)
    if name == "SENSORS":
        from designlab.sensors.registry import SENSORS

        return SENSORS
    if name in _DEFINITION:
        from designlab.sensors import definition as _d

        return getattr(_d, name)
    if name in ("get_material", "MATERIALS"):
        from designlab.fem import materials as _m

        return getattr(_m, name)
    raise AttributeError(f"module 'designlab' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
