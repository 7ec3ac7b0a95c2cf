"""The public sensor definition: a designer's own sensor in one file.

Subclass :class:`SensorDefinition`, declare its parameters with :func:`param`, and say what the
sensor is made of (:meth:`~SensorDefinition.bodies`), how it is held
(:meth:`~SensorDefinition.supports`), what it reads (:meth:`~SensorDefinition.transducers`) and
how it is loaded (:meth:`~SensorDefinition.loads`, :meth:`~SensorDefinition.protocol`). The generic
virtual test (:mod:`designlab.sensors.generic`) turns the declaration into a FEM, the transducers'
readings and every metric a built-in sensor reports. Units: mm, N, MPa, s; masses in g or kg as
named.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass, field
from typing import Any, ClassVar, Sequence

import numpy as np

from designlab.errors import ParameterError
from designlab.geometry.api import PartAPI
from designlab.geometry.body import Body
from designlab.geometry.step_import import step_solids  # noqa: F401 (public: dl.step_solids)
from designlab.params import rng, validate

G_MM_S2 = 9810.0   # standard gravity, mm/s^2 (9.81 m/s^2: the shared protocols' g)


def param(default: Any, lo: float | None = None, hi: float | None = None, *, unit: str = "",
          doc: str = "", choices: Sequence | None = None, moves_load: bool = False) -> Any:
    """A parameter of a sensor definition: its default, allowed range (or ``choices``), unit and
    meaning. ``moves_load``: the parameter only moves where loads act, so designs that differ
    in it share one FEM."""
    meta = rng(lo, hi, unit=unit, doc=doc, choices=tuple(choices) if choices else None)
    meta = dict(meta, moves_load=bool(moves_load))
    return field(default=default, metadata=meta)


# ----------------------------------------------------------------------------- geometry

@dataclass(frozen=True)
class Solid:
    """One body of the sensor: a build123d solid (mm) and its material.

    material: a name of the material library (``designlab materials`` lists them with sources)
    printed:  False for a bought part (a steel insert, an aluminium plate): not exported to print
    rigid:    the body moves as a rigid body (its nodes follow one 6-dof point)
    """

    shape: Any
    material: str
    color: tuple[float, float, float] | None = None
    printed: bool = True
    rigid: bool = False


def solids_from(built: dict[str, Body], names: Sequence[str] | None = None,
                rigid: Sequence[str] = ()) -> dict[str, Solid]:
    """A CAD part's bodies (its ``build()``) as Solids: the same shapes, materials, colours and
    printed flags; ``names``: only these, in the part's order (default: every one); ``rigid``:
    these move as rigid bodies."""
    return {n: Solid(b.shape, b.material, b.color, b.printed, rigid=n in rigid)
            for n, b in built.items() if names is None or n in names}


@dataclass(frozen=True)
class Face:
    """Boundary facets of one body: those whose outward normal is within ``angle_deg`` of
    ``normal`` and that lie outermost along it (or on the plane ``x . n = at`` when ``at`` is
    given), optionally inside the box ``box = ((x0, y0, z0), (x1, y1, z1))`` (mm)."""

    body: str
    normal: tuple[float, float, float]
    at: float | None = None
    box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    angle_deg: float = 10.0


@dataclass(frozen=True)
class Region:
    """Every node of one body (a probe on a fin, a magnet's carrier)."""

    body: str


# ----------------------------------------------------------------------------- supports

@dataclass(frozen=True)
class Clamped:
    """The face does not move."""

    face: Face


@dataclass(frozen=True)
class ElasticSupport:
    """The face rests on springs to ground: ``stiffness_N_per_mm`` (x, y, z) on its resultant
    (through a distributing coupling at its centroid)."""

    face: Face
    stiffness_N_per_mm: tuple[float, float, float]


@dataclass(frozen=True)
class ElasticInterface:
    """Two faces of bodies that do not touch, joined by a spring of ``stiffness_N_per_mm``
    (x, y, z) between their centroids (bodies that touch are bonded by the mesh itself)."""

    face_a: Face
    face_b: Face
    stiffness_N_per_mm: tuple[float, float, float]


# ----------------------------------------------------------------------------- transducers

@dataclass(frozen=True)
class ForceSensor:
    """A discrete force sensor between two parts (``face_b`` None: between ``face_a`` and
    ground): a spring of ``stiffness_N_per_mm`` along ``axis`` (and ``lateral_N_per_mm``
    across it) whose force is read at ``sensitivity_V_per_N``; ``noise_V`` is the standard
    deviation of one reading (repeatability)."""

    name: str
    face_a: Face
    axis: tuple[float, float, float]
    stiffness_N_per_mm: float
    sensitivity_V_per_N: float
    noise_V: float
    face_b: Face | None = None
    lateral_N_per_mm: float | None = None
    unit: ClassVar[str] = "V"


#: HX711 data sheet (Avia Semiconductor): input-referred noise 50 nV rms at gain 128 and 10 Hz;
#: over a 5 V bridge excitation that is 0.01 uV/V, i.e. 1e-5 mV/V
HX711_NOISE_MV_PER_V = 50e-9 / 5.0 * 1e3


@dataclass(frozen=True)
class StrainGauge:
    """A strain gauge on a face patch: the grid (``length_mm`` along ``direction``, ``width_mm``
    across) centred at ``center`` on ``face``, reading the mean surface strain along
    ``direction`` over the grid.

    kind ``"foil"``: a quarter bridge, reading GF eps / 4 in mV/V; ``noise`` in mV/V (default:
    an HX711 bridge amplifier, see :data:`HX711_NOISE_MV_PER_V`).
    kind ``"printed"``: a conductive printed trace of resistance ``R0_ohm`` read through a
    voltage divider (:func:`designlab.fem.transducers.divider_voltage`), reading in V; ``noise``
    in V (required).
    """

    name: str
    face: Face
    center: tuple[float, float, float]
    direction: tuple[float, float, float]
    length_mm: float
    width_mm: float
    gauge_factor: float = 2.0
    kind: str = "foil"
    noise: float | None = None
    R0_ohm: float = 350.0

    @property
    def unit(self) -> str:
        return "mV/V" if self.kind == "foil" else "V"


@dataclass(frozen=True)
class DisplacementProbe:
    """Motion of ``where`` (a Face or Region; its mean displacement) along ``direction``,
    relative to ``relative_to`` (None: the fixed frame), times ``gain`` (reading per mm):
    a camera, an optical fork or reflective sensor reading an edge. ``noise`` in the reading's
    unit."""

    name: str
    where: Face | Region
    direction: tuple[float, float, float]
    noise: float
    gain: float = 1.0
    unit: str = "mm"
    relative_to: Face | Region | None = None


@dataclass(frozen=True)
class RotationProbe:
    """Rotation of ``where`` (its distributing coupling) about ``axis``, times ``gain``
    (reading per rad); ``noise`` in the reading's unit."""

    name: str
    where: Face | Region
    axis: tuple[float, float, float]
    noise: float
    gain: float = 1.0
    unit: str = "rad"


EPS0_PF_PER_MM = 8.8541878128e-3   # vacuum permittivity, pF/mm


@dataclass(frozen=True)
class CapacitiveGap:
    """A parallel-plate capacitor between ``face_a`` and ``face_b`` (area ``area_mm2``, gap
    ``gap_mm`` at rest, relative permittivity ``eps_r``): reading the change of capacitance in
    pF as the gap closes along ``face_a``'s normal; ``noise_pF`` from the converter's data
    sheet."""

    name: str
    face_a: Face
    face_b: Face
    area_mm2: float
    gap_mm: float
    noise_pF: float
    eps_r: float = 1.0
    unit: ClassVar[str] = "pF"


@dataclass(frozen=True)
class Magnet:
    """A magnet carried by ``carrier`` (its mean motion and rotation), dipole moment
    ``moment_Am2`` at ``position`` (mm), seen by a three-axis magnetometer at ``sensor_at``
    (fixed): three readings (x, y, z) of the change of flux density in uT; ``noise_uT`` from the
    magnetometer's data sheet."""

    name: str
    carrier: Face | Region
    position: tuple[float, float, float]
    moment_Am2: tuple[float, float, float]
    sensor_at: tuple[float, float, float]
    noise_uT: float
    unit: ClassVar[str] = "uT"


TRANSDUCERS = (ForceSensor, StrainGauge, DisplacementProbe, RotationProbe, CapacitiveGap, Magnet)


# ----------------------------------------------------------------------------- loads

@dataclass(frozen=True)
class LoadPoint:
    """Where loads act: a point ``at`` (mm, inside the part's bounding box; default the face's
    centroid) tied to ``face`` by a distributing coupling. A load acting elsewhere (a hanging
    mass's centre of gravity) is given as a wrench about this point. ``direction``: the way a
    weight hung here pulls in the part's frame (a cord over a pulley); None: gravity, as the
    protocol turns the part."""

    name: str
    face: Face
    at: tuple[float, float, float] | None = None
    direction: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class LoadState:
    """One held load: force (N) and moment (N mm, about the load point) at ``load``."""

    load: str
    force_N: tuple[float, float, float]
    moment_Nmm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    label: str = ""


@dataclass(frozen=True)
class Staircase:
    """The papers' hanging-weight staircase: at ``load`` (a load point, or several taken in
    turn), for each gravity direction in ``directions`` (the part turned), weights ``weights_g``
    hung one after another and taken off in reverse, each held ``hold_s`` and read at its end;
    ``cycles`` loops per direction. A load point with its own ``direction`` is pulled along
    it whatever the gravity direction."""

    load: str | tuple[str, ...]
    weights_g: tuple[float, ...]
    directions: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, -1.0),)
    hold_s: float = 10.0
    cycles: int = 1

    def __post_init__(self) -> None:
        w = self.weights_g
        listed = isinstance(w, (Sequence, np.ndarray)) and not isinstance(w, (str, bytes))
        if not listed or not len(w) or not all(isinstance(x, numbers.Real) and not isinstance(
                x, bool) and np.isfinite(x) and x >= 0 for x in w):
            raise ParameterError("weights_g", w, "a non-empty list of finite masses >= 0 (g)")

    @property
    def load_names(self) -> tuple[str, ...]:
        return (self.load,) if isinstance(self.load, str) else tuple(self.load)

    def states(self, pulls: dict | None = None) -> list[LoadState]:
        """The held loads in order; ``pulls``: {load point: its own direction} (the load
        points' ``direction``)."""
        w = [float(x) for x in self.weights_g]
        path = w + w[-2::-1] + [0.0]
        out = []
        for name in self.load_names:
            for k, d in enumerate(self.directions):
                d = (pulls or {}).get(name) or d
                dv = np.asarray(d, float) / np.linalg.norm(d)
                for c in range(self.cycles):
                    for i, m in enumerate(path):
                        f = tuple(float(v) for v in m * 1e-6 * G_MM_S2 * dv)  # g -> t x mm/s^2
                        up = "up" if i < len(w) else "down"
                        tag = f"{name} " if len(self.load_names) > 1 else ""
                        out.append(LoadState(name, f, label=f"{tag}d{k} c{c} {m:g} g {up}"))
        return out

    def loops(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """(loads up, state indices up, loads down, state indices down) of each loop, for the
        hysteresis of seed 001 eq. (1); index -1 is the unloaded state before the first load."""
        w = np.asarray(self.weights_g, float)
        n, per = len(w), 2 * len(w)
        out = []
        for loop in range(len(self.load_names) * len(self.directions) * self.cycles):
            s0 = loop * per
            first = -1 if loop % self.cycles == 0 else s0 - 1
            out.append((np.r_[0.0, w], np.r_[first, s0 + np.arange(n)],
                        np.r_[w[::-1], 0.0], s0 + n - 1 + np.arange(n + 1)))
        return out


@dataclass(frozen=True)
class Wrenches:
    """A set of held wrenches at ``load``, one row (Fx, Fy, Fz N, Mx, My, Mz N mm) each, held
    ``hold_s`` in turn."""

    load: str
    wrenches: tuple[tuple[float, ...], ...]
    labels: tuple[str, ...] = ()
    hold_s: float = 10.0

    def states(self) -> list[LoadState]:
        return [LoadState(self.load, tuple(map(float, w[:3])), tuple(map(float, w[3:6])),
                          self.labels[i] if i < len(self.labels) else f"w{i}")
                for i, w in enumerate(self.wrenches)]

    @classmethod
    def from_masses(cls, load: str, masses_kg: Sequence[float], cogs_mm: Sequence,
                    gravity: Sequence, about_mm=(0.0, 0.0, 0.0), hold_s: float = 10.0,
                    g_m_s2: float = 9.81) -> "Wrenches":
        """Hanging masses in several orientations: every mass (centre of gravity ``cogs_mm``)
        in every gravity direction; F = m g d, M = (cog - about) x F."""
        rows, labels = [], []
        for j, d in enumerate(gravity):
            dv = np.asarray(d, float) / np.linalg.norm(d)
            for i, (m, c) in enumerate(zip(masses_kg, cogs_mm)):
                F = float(m) * g_m_s2 * dv
                M = np.cross(np.asarray(c, float) - np.asarray(about_mm, float), F)
                rows.append(tuple(F) + tuple(M))
                labels.append(f"mass {i} dir {j}")
        return cls(load, tuple(rows), tuple(labels), hold_s)


# ----------------------------------------------------------------------------- plug-in physics

@dataclass(frozen=True)
class Physics:
    """A sensor's own physics, plugged into its definition (``physics = Physics(...)``): a
    virtual test that the declared bodies, supports, transducers and loads alone do not give
    (frictional contact with a bolt preload, a spring's beam chain, a worn strap's electrical
    model). It runs in place of the generic virtual test and names its protocol and settings;
    its hooks are those of :class:`designlab.sensors.sensor.Sensor` (``run``, ``plots`` and
    ``gains`` required; the others optional, as the record documents them). The definition's
    declarations stay what the sensor is: its parameters, bodies and materials, supports,
    transducers, loads and protocol."""

    name: str
    paper: str
    protocol: type
    settings: type
    run: Any
    plots: Any
    gains: Any
    hooks: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------- the definition

class SensorDefinition(PartAPI):
    """Base class of a designer's sensor. A subclass is a frozen dataclass of its parameters
    (declared with :func:`param`) and overrides the methods below.

    name:        the sensor's registry name (``designlab predict NAME``)
    description: one line shown by ``designlab sensors``
    edge_length: the default mesh edge length, mm
    moment_scale_mm: a length (mm) the report divides moments by in ``*_scaled`` condition
                     numbers (None: no scaled figure)
    normalise_rows_by: a load component (``"Fz"``): the report adds each channel's sensitivity
                     row divided by its entry for it, a shape free of the channels' gains
    physics:     a :class:`Physics` plug-in that runs in place of the generic virtual test
                 (None: the generic test)
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    edge_length: ClassVar[float] = 2.0
    source: ClassVar[str] = ""
    moment_scale_mm: ClassVar[float | None] = None
    normalise_rows_by: ClassVar[str | None] = None
    physics: ClassVar[Physics | None] = None

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if "__dataclass_fields__" not in cls.__dict__:
            dataclass(frozen=True)(cls)
        if not cls.name:
            cls.name = cls.__name__.lower()

    def __post_init__(self) -> None:
        validate(self)

    # ---- what a designer overrides ----
    def bodies(self) -> dict[str, Solid]:
        """{body name: Solid}."""
        raise NotImplementedError(f"{type(self).__name__}.bodies() must return its bodies")

    def supports(self) -> list:
        """Clamped / ElasticSupport / ElasticInterface items."""
        return []

    def transducers(self) -> list:
        """ForceSensor / StrainGauge / DisplacementProbe / RotationProbe / CapacitiveGap /
        Magnet items."""
        return []

    def loads(self) -> list[LoadPoint]:
        """The load points."""
        return []

    def protocol(self) -> Staircase | Wrenches:
        """The virtual test's load protocol."""
        raise NotImplementedError(f"{type(self).__name__}.protocol() must return a protocol")

    def refinement(self) -> list:
        """Spheres of finer mesh ``(centre (3,) mm, radius mm, edge mm)``."""
        return []

    # ---- the part interface every command uses ----
    def solids(self) -> dict[str, "Solid"]:
        """:meth:`bodies`, built and checked once per design (each a solid with a library
        material, no two overlapping): copies of a design (a sweep's, the report's) share
        them."""
        key = (type(self), repr(self))
        cached = _SOLIDS.get(key)
        if cached is None:
            cached = self.bodies()
            check_bodies(cached)
            _SOLIDS[key] = cached
            while len(_SOLIDS) > 8:
                _SOLIDS.pop(next(iter(_SOLIDS)))
        return cached

    def build(self) -> dict[str, Body]:
        """The bodies as designlab's parts give them (:meth:`solids`)."""
        bodies = self.solids()
        out = {}
        for k, (name, s) in enumerate(bodies.items()):
            color = s.color or _PALETTE[k % len(_PALETTE)]
            out[name] = Body(name, s.shape, s.material, color=color, printed=s.printed)
        return out

    def mesh_bodies(self) -> tuple[str, ...]:
        return tuple(self.solids())

    def facet_sets(self) -> dict:
        return {}

    def load_only(self) -> tuple[str, ...]:
        """The parameters that only move loads (their designs share one FEM)."""
        return tuple(f.name for f in dataclasses.fields(self) if f.metadata.get("moves_load"))


def same_design(self, other: Any) -> Any:
    """``==`` of a built-in sensor's definition: equal to any design of its CAD part (or of a
    class between) with the same parameters, so a design made either way is the same design."""
    if not (isinstance(other, type(self)) or isinstance(self, type(other))) \
            or not dataclasses.is_dataclass(other):
        return NotImplemented
    names = [f.name for f in dataclasses.fields(self)]
    if names != [f.name for f in dataclasses.fields(other)]:
        return False
    return all(getattr(self, n) == getattr(other, n) for n in names)


#: the last designs' bodies by (class, the design's repr: its parameters)
_SOLIDS: dict = {}

_PALETTE = ((0.85, 0.55, 0.2), (0.3, 0.55, 0.8), (0.5, 0.7, 0.4), (0.75, 0.75, 0.75),
            (0.7, 0.4, 0.6), (0.9, 0.8, 0.3))


def check_bodies(bodies: Any) -> None:
    """Named Solids with library materials and a volume, no two overlapping (bodies may touch:
    the mesh bonds them); else a one-line error naming the body."""
    from designlab.fem.materials import MATERIALS
    from designlab.params import did_you_mean

    if not isinstance(bodies, dict) or not bodies:
        raise ParameterError("bodies", type(bodies).__name__, "a dict {name: Solid} with at "
                             "least one body")
    vols = {}
    for name, s in bodies.items():
        if not isinstance(s, Solid):
            raise ParameterError(f"bodies.{name}", type(s).__name__, "a designlab Solid(shape, "
                                 "material)")
        if s.material not in MATERIALS:
            raise ParameterError(f"bodies.{name}.material", s.material, "a material of the "
                                 "library: " + ", ".join(MATERIALS)
                                 + did_you_mean(str(s.material), MATERIALS))
        try:
            vols[name] = float(s.shape.volume)
        except AttributeError:
            raise ParameterError(f"bodies.{name}.shape", type(s.shape).__name__,
                                 "a build123d solid") from None
        if not vols[name] > 0:
            raise ParameterError(f"bodies.{name}.shape", f"{vols[name]:g} mm^3", "a solid with "
                                 "a volume")
    names = list(bodies)
    boxes = {n: bodies[n].shape.bounding_box() for n in names}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if not _boxes_meet(boxes[a], boxes[b]):
                continue
            shared = bodies[a].shape & bodies[b].shape      # None: nothing in common
            common = 0.0 if shared is None else float(shared.volume)
            if common > 1e-6 * min(vols[a], vols[b]):
                raise ParameterError(f"bodies.{a}", f"overlaps {b} by {common:.3g} mm^3",
                                     "bodies that touch (bonded by the mesh) but do not overlap")


def _boxes_meet(a, b) -> bool:
    """Two bounding boxes overlap in a volume (touching faces do not count)."""
    lo = np.maximum(np.array(tuple(a.min)), np.array(tuple(b.min)))
    hi = np.minimum(np.array(tuple(a.max)), np.array(tuple(b.max)))
    return bool(np.all(hi - lo > 1e-9))


def is_definition(obj: Any) -> bool:
    """A SensorDefinition subclass or instance."""
    cls = obj if isinstance(obj, type) else type(obj)
    return isinstance(cls, type) and issubclass(cls, SensorDefinition) and cls is not SensorDefinition


def check_vector(name: str, v: Any, n: int = 3) -> np.ndarray:
    """``v`` as a finite non-zero n-vector, or a one-line error naming ``name``."""
    try:
        a = np.asarray(v, float).reshape(n)
    except (TypeError, ValueError):
        raise ParameterError(name, v, f"{n} numbers") from None
    if not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 0:
        raise ParameterError(name, v, f"{n} finite numbers, not all zero")
    return a
