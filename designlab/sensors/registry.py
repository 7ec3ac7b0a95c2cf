"""``SENSORS``: every sensor kind designlab knows, by name: the three built in, the definitions
loaded from a file or module (:func:`resolve`), and those that installed packages add through
the ``designlab.sensors`` entry-point group."""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import importlib.util
import re
import sys
from pathlib import Path

from designlab.errors import ParameterError
from designlab.geometry.parts import PARTS
from designlab.params import did_you_mean
from designlab.sensors.fingertip.definition import CantileverFingertip
from designlab.sensors.flexure.definition import SpringFlexure
from designlab.sensors.generic.record import sensor_record
from designlab.sensors.sensor import Sensor
from designlab.sensors.strap.definition import ArchStrap

#: the built-in sensors: definitions like any other, each with its physics plugged in
BUILT_IN_DEFINITIONS = (ArchStrap, CantileverFingertip, SpringFlexure)
SENSORS: dict[str, Sensor] = {cls.name: sensor_record(cls) for cls in BUILT_IN_DEFINITIONS}
PARTS.update({cls.name: cls for cls in BUILT_IN_DEFINITIONS})
BUILT_IN = tuple(SENSORS)
#: the built-in definitions by their names in the Python API (``dl.Fingertip``)
API_CLASSES = {"Fingertip": CantileverFingertip, "Strap": ArchStrap, "Flexure": SpringFlexure}
ENTRY_POINT_GROUP = "designlab.sensors"
#: environment variable carrying {name: spec} of the definitions this process loaded, so that
#: worker processes it starts (sweeps, Monte Carlo) find them by name
ENV = "DESIGNLAB_DEFINITIONS"
#: {spec as given: registered name}
_LOADED: dict[str, str] = {}
_SPEC = re.compile(r"^(?P<target>[^:]+?)(?::(?P<cls>[A-Za-z_]\w*))?$")


def get_sensor(name: str) -> Sensor:
    """The sensor called ``name``, or a one-line error listing the known ones."""
    try:
        return SENSORS[name]
    except (KeyError, TypeError):
        pass
    if isinstance(name, str) and (entry_points().get(name) or looks_like_definition(name)):
        return SENSORS[resolve(name)]
    inherited = _inherited().get(name) if isinstance(name, str) else None
    if inherited:
        return SENSORS[resolve(inherited)]
    raise ParameterError("part", name, "one of " + ", ".join(known_names())
                         + " (or a sensor definition: FILE.py[:Class] or module:Class)"
                         + did_you_mean(str(name), known_names()))


def known_names() -> list[str]:
    return list(dict.fromkeys([*SENSORS, *entry_points()]))


def register(cls: type, spec: str = "") -> str:
    """Add a :class:`~designlab.sensors.definition.SensorDefinition` subclass to ``SENSORS``
    (and its part to ``PARTS``); its name must not be a built-in's. Returns the name."""
    from designlab.sensors.definition import is_definition

    if not is_definition(cls):
        raise ParameterError("part", spec or getattr(cls, "__name__", cls),
                             "a subclass of designlab.SensorDefinition")
    name = cls.name
    if name in BUILT_IN:
        raise ParameterError(f"{cls.__name__}.name", name,
                             "a name that is not a built-in sensor's (" + ", ".join(BUILT_IN) + ")")
    if not re.fullmatch(r"[A-Za-z][\w-]*", name):
        raise ParameterError(f"{cls.__name__}.name", name, "letters, digits, _ or -, "
                                                           "starting with a letter")
    cls._designlab_spec = spec
    SENSORS[name] = sensor_record(cls)
    PARTS[name] = cls
    if spec and not spec.startswith("entry point"):
        os.environ[ENV] = json.dumps({**_inherited(), name: spec})
    return name


def _inherited() -> dict[str, str]:
    try:
        data = json.loads(os.environ.get(ENV, "{}"))
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


def looks_like_definition(value: str) -> bool:
    """A file (``x.py``, ``x.py:Class``) or ``module:Class`` rather than a sensor name."""
    return isinstance(value, str) and bool(
        value.endswith(".py") or ".py:" in value or re.fullmatch(r"[\w.]+:[A-Za-z_]\w*", value))


def canonical(spec: str, base: str | Path | None = None) -> str:
    """A definition spec that any process resolves the same way: a file's absolute path
    (relative ones taken from ``base``, default the working directory), ``:Class`` kept;
    names and ``module:Class`` unchanged."""
    m = _SPEC.match(spec.strip()) if isinstance(spec, str) else None
    if not m or not m["target"].endswith(".py"):
        return spec
    path = Path(m["target"]).expanduser()
    if not path.is_absolute():
        path = Path(base or Path.cwd()) / path
    return str(path.resolve()) + (f":{m['cls']}" if m["cls"] else "")


def resolve(value: str) -> str:
    """The registered name for a sensor name or a definition spec: ``FILE.py`` (its one
    SensorDefinition subclass), ``FILE.py:Class``, ``module:Class`` or an entry point's name;
    loads and registers it on first use."""
    if not isinstance(value, str):
        raise ParameterError("part", value, "a sensor name or FILE.py[:Class]")
    if value in SENSORS:
        return value
    if looks_like_definition(value):
        value = canonical(value)
    if value in _LOADED:
        return _LOADED[value]
    eps = entry_points()
    if value in eps:
        cls = eps[value].load()
        name = register(cls, f"entry point {value}")
    elif looks_like_definition(value):
        name = register(load_class(value), value)
    else:
        get_sensor(value)   # the one-line error listing the names
        raise AssertionError
    _LOADED[value] = name
    return name


def load_class(spec: str) -> type:
    """The definition class of ``FILE.py[:Class]`` or ``module:Class``."""
    from designlab.sensors.definition import is_definition

    m = _SPEC.match(spec.strip())
    if not m:
        raise ParameterError("part", spec, "FILE.py[:Class] or module:Class")
    target, cls_name = m["target"], m["cls"]
    if target.endswith(".py"):
        module = _load_file(Path(target))
    else:
        if cls_name is None:
            raise ParameterError("part", spec, "module:Class (a module needs the class name)")
        try:
            module = importlib.import_module(target)
        except ImportError as exc:
            raise ParameterError("part", spec, f"an importable module ({exc})") from None
    found = {k: v for k, v in vars(module).items()
             if is_definition(v) and v.__module__ == module.__name__}
    if cls_name is not None:
        if cls_name not in found:
            raise ParameterError("part", spec, "a SensorDefinition subclass of the module: "
                                 + (", ".join(found) or "it defines none"))
        return found[cls_name]
    if len(found) != 1:
        raise ParameterError("part", spec, "a file defining exactly one SensorDefinition "
                             "subclass (it defines " + (", ".join(found) or "none")
                             + "): name one as FILE.py:Class")
    return next(iter(found.values()))


def _load_file(path: Path):
    path = path.expanduser().resolve()
    if not path.is_file():
        raise ParameterError("part", str(path), "an existing Python file defining a sensor")
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    mod_name = f"designlab_user_{re.sub(r'[^0-9A-Za-z_]', '_', path.stem)}_{digest}"
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    spec = importlib.util.spec_from_file_location(mod_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
    except ParameterError:
        del sys.modules[mod_name]
        raise
    except Exception as exc:  # noqa: BLE001 - a user's file: its error named in one line
        del sys.modules[mod_name]
        raise ParameterError("part", str(path), f"a Python file that runs "
                             f"({type(exc).__name__}: {exc})") from None
    return module


_EPS: dict | None = None


def entry_points() -> dict:
    """{name: entry point} of the ``designlab.sensors`` group (read once)."""
    global _EPS
    if _EPS is None:
        from importlib.metadata import entry_points as _group

        _EPS = {ep.name: ep for ep in _group(group=ENTRY_POINT_GROUP)}
    return _EPS
