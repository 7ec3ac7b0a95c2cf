"""The seed 001 fingertip's model below its virtual test: the datasheet and paper constants
(FSS015 stiffness and output, friction, bolt preload, Hertz data, DAQ), the settings
(:class:`ContactSettings`, :class:`FingertipModelSettings`), the mesh and the FEM model with its
six unit-wrench load cases, the wrench of a load about the ball centre, the FEM stage's key and
the protocol's fit to a design. :mod:`designlab.sensors.fingertip.virtual` (the virtual test) and its
helpers (contact, calibration, loads, loop, Monte Carlo) import from here, never the other
way."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from designlab.errors import ParameterError
from designlab.fem.contact import MU_MAX
from designlab.fem.settings import FEMSettings
from designlab.params import rng, validate
from designlab.sensors.protocols import HangingWeightTest

#: Honeywell FSS015WNSX: "low deflection, approximately 30 microns typical at full scale" (FSS
#: series datasheet) over the 15 N range -> about 500 N/mm.
FSS015_STIFFNESS_N_PER_MM = 15.0 / 0.030
#: sensor output, V per N of button force: 2.4 mV/V/N x 5 V supply x amplifier gain 5 (Table I)
FSS015_V_PER_N = 2.4e-3 * 5.0 * 5.0

WRENCH = ("f_x", "f_y", "f_z", "m_x", "m_y", "m_z")


#: Friction of plated steel on steel: chromium on steel, static 0.25 (kinetic 0.21), Wypych,
#: Handbook of Surface Improvement and Modification (ChemTec, 2018), Table 11.1. The paper
#: says only "plated"; chromium is the usual plating of steel balls. One coefficient is used for
#: stick and slip (the micro-slip of the test is slow, the static value applies).
FRICTION_CHROMIUM_ON_STEEL = 0.25
#: Bolt tension after tightening: torque-tension T = K F d (Shigley's Mechanical Engineering
#: Design, 10th ed., eq. 8-27), nut factor K = 0.2 (Shigley Table 8-15, as received steel),
#: d = 2.5 mm (M2.5), finger-tight T = 0.01 N m (about 2 N at the 5 mm radius of a precision
#: screwdriver handle: the screw pulls a ball onto three 15 N sensors, a standard M2.5 torque of
#: ~0.5 N m would give ~1 kN and crush them): F = 0.01 / (0.2 x 0.0025) = 20 N, i.e.
#: 20 / (3 sin 45 deg) = 9.4 N on each sensor, 63 % of its 15 N range.
BOLT_TIGHTENING_TORQUE_NM = 0.01
NUT_FACTOR = 0.2
DEFAULT_BOLT_PRELOAD_N = BOLT_TIGHTENING_TORQUE_NM / (NUT_FACTOR * 2.5e-3)
#: Mindlin's partial slip at each ball/button contact (Cattaneo 1938, Mindlin 1949; Johnson,
#: Contact Mechanics, Sec. 7.2-7.3): the Hertz circle's rim slips before the contact slides, so
#: a tangential load cycle below mu N still dissipates (Johnson eq. 7.53). Discretised as 24
#: Iwan elements (designlab.fem.contact.iwan_elements); on the Table II protocol 12 and 96
#: elements give the same G1 hysteresis to within 1 % of each location's value.
MICROSLIP_ELEMENTS = 24
#: FSS015 sensing ball: the FSS series plunger is a stainless-steel ball; its radius is the
#: part's ``button_radius`` (0.8 mm, approximate outline). Stainless 302/304: E 193 GPa,
#: nu 0.29 (ASM handbook typical); the central ball: steel E 210 GPa, nu 0.30 (materials.py).
BUTTON_E_MPA, BUTTON_NU = 193000.0, 0.29
BALL_E_MPA, BALL_NU = 210000.0, 0.30
#: FSS015 repeatability: +-0.2 % of span (seed 001 Table I)
FSS015_REPEATABILITY_PERCENT_FS = 0.2
#: NI PCI-6229 (the paper's DAQ): 16-bit ADC, widest input range +-10 V (NI datasheet).
DAQ_BITS = 16
DAQ_RANGE_V = 10.0


@dataclass(frozen=True)
class ContactSettings:
    """Contact, preload, readout and solver settings of the contact model (defaults sourced in
    the module constants)."""

    friction_coefficient: float = field(default=FRICTION_CHROMIUM_ON_STEEL, metadata=rng(
        0, MU_MAX, doc="Coulomb coefficient ball/sensor ball (chromium on steel, Wypych 2018)"))
    bolt_preload_N: float = field(default=DEFAULT_BOLT_PRELOAD_N, metadata=rng(
        0, None, unit="N", doc="bolt tension after tightening (T = K F d at 0.01 N m)"))
    hertz: bool = field(default=True, metadata=rng(
        choices=(True, False), doc="Hertz compliance in series with the sensor (False: the "
        "sensor spring alone, the linear model's normal law)"))
    sensor_lateral_stiffness: float = field(default=0.0, metadata=rng(
        0, None, unit="N/mm", doc="tangential stiffness of the sensor in its well in series "
        "with Mindlin's; 0 = rigid"))
    microslip_elements: int = field(default=MICROSLIP_ELEMENTS, metadata=rng(
        0, 1000, doc="Mindlin's partial slip at each contact as this many Iwan elements "
        "(designlab.fem.contact.iwan_elements); 0: the contact sticks whole until it slides "
        "(elastic-perfectly-plastic)"))
    structure_moduli: str = field(default="relaxing", metadata=rng(
        choices=("long_time", "instantaneous", "relaxing"), doc="ABS moduli of the condensed "
        "structure: relaxing between the instantaneous and the relaxed ones through the "
        "protocol's holds (the contact solve follows the time history, ~2.6x the contact "
        "solve of the others), relaxed (long_time) or instantaneous"))
    increments_per_step: int = field(default=4, metadata=rng(1, 10000))
    preconditioning_cycles: int = field(default=1, metadata=rng(
        0, 100, doc="loops run at each location before the measured one: the first loop after "
        "tightening ratchets (the ball settles down the buttons); the paper's sensor had been "
        "through many loops (over 2000 tests)"))
    preload_increments: int = field(default=8, metadata=rng(1, 10000))
    repeatability_percent_fs: float = field(default=FSS015_REPEATABILITY_PERCENT_FS, metadata=rng(
        0, 10, unit="% FS", doc="FSS015 repeatability +-0.2 % span (Table I): the datasheet's "
        "largest difference of two readings at the same force, read as a 2-sigma band on that "
        "difference (sigma band / (2 sqrt 2) on each 3-s reading)"))
    zero_drift_percent_fs: float = field(default=0.0, metadata=rng(
        0, 10, unit="% FS", doc="zero drift over one loop (linear ramp, random sign). The "
        "datasheet's null shift (+-0.5 mV at 5 V, ~0.3 % FS) is over 25 K; a loop lasts "
        "~150 s at room temperature, hence 0"))
    daq_bits: int = field(default=DAQ_BITS, metadata=rng(1, 32))
    daq_range_V: float = field(default=DAQ_RANGE_V, metadata=rng(0, None, lo_open=True,
                                                                unit="V"))
    seed: int = field(default=0, metadata=rng(0, 2 ** 32 - 1))
    readout_draws: int = field(default=200, metadata=rng(
        1, 10000, doc="readout noise draws over which the hysteresis with readout is also "
        "reported as mean and spread (each run's seeded generator continued)"))

    def __post_init__(self):
        validate(self)

    @property
    def daq_lsb_V(self) -> float:
        return 2.0 * self.daq_range_V / 2 ** self.daq_bits


@dataclass(frozen=True)
class FingertipModelSettings(ContactSettings, FEMSettings):
    """Settings of the fingertip test: mesh and solver (:class:`FEMSettings`), the structure
    below, and, with ``contact`` (default), the contact model at the ball
    (:class:`ContactSettings`: friction, bolt preload, Hertz, readout noise; each a
    ``--setting NAME=VALUE`` of its own). ``contact=false``: the linear test (bilateral sensor
    springs, ABS relaxation; its hysteresis is the relaxation alone)."""

    contact: bool = field(default=True, metadata=rng(
        doc="contact model at the ball (Hertz + Mindlin partial slip + Coulomb, bolt preload, "
            "FSS015 readout: designlab.sensors.fingertip.contact); false: bilateral linear "
            "springs"))

    edge_length: float = field(default=2.5, metadata=rng(0.2, 10, unit="mm"))
    cap_support: str = field(default="rim", metadata=rng(
        choices=("rim", "face"), doc="how the bottom cap sits on the robot: on its outer rim "
        "(ring of width cap_rim_width; the cap bends under the bolt) or on its whole bottom face "
        "around the bolt head (the cap is rigid)"))
    cap_rim_width: float = field(default=1.5, metadata=rng(0.2, 10, unit="mm"))
    mesh_fingertip: bool = False
    refine: bool = False
    sensor_stiffness: float = field(default=FSS015_STIFFNESS_N_PER_MM,
                                    metadata=rng(1, 1e7, unit="N/mm"))
    bolt_minor_diameter: float = field(default=2.0, metadata=rng(0.5, 6, unit="mm",
                                       doc="M2.5 coarse thread: minor diameter ~2.0 mm"))
    bolt: bool = True
    rotations_deg: tuple[float, ...] = (0.0, 60.0, 120.0, 180.0, 240.0, 300.0)

    def __post_init__(self):
        validate(self)


def mesh_fingertip(part, settings: FingertipModelSettings, detailed: bool = False):
    """TET10 mesh of the bodies the readings depend on (base, cap; optionally the fingertip),
    with the part's facet sets (and its local refinement when ``settings.refine``);
    ``detailed``: the :class:`~designlab.mesh.meshing.MeshResult` (which mesher made it, the
    attempts)."""
    from designlab.mesh.meshing import mesh_bodies_detailed

    built = part.build()
    names = [n for n in part.mesh_bodies() if settings.mesh_fingertip or n != "fingertip"]
    sets = {k: v for k, v in part.facet_sets().items()
            if settings.mesh_fingertip or not (k == "ball_seat" or k.startswith("load_"))}
    named = {k: [(b, f) for b, f in v if b in names]
             for k, v in part.named_faces(built).items() if k in sets}
    res = mesh_bodies_detailed([built[n] for n in names], sets, order=settings.order,
                               edge_length=settings.edge_length, quality=settings.mesh_quality,
                               mesher=settings.mesher,
                               refinement=part.refinement() if settings.refine else (),
                               named_faces={k: v for k, v in named.items() if v})
    return res if detailed else res.mesh


def wrench_at_ball(point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(f_x, f_y, f_z, m_x, m_y, m_z) at the ball centre (origin) of a unit force ``direction``
    applied at ``point`` (mm): N and N mm."""
    d = np.asarray(direction, float)
    return np.r_[d, np.cross(np.asarray(point, float), d)]


def build_model(part, mesh, settings: FingertipModelSettings, materials=None):
    """The FEM :class:`~designlab.fem.Model` with ball, sensors, bolt, fixed cap, and the six
    unit-wrench load cases ``f_x``..``m_z`` at the ball centre. Returns (model, names)."""
    from designlab.fem.model import Model
    from designlab.fem.beam import beam_stiffness, circular_section
    from designlab.fem.materials import get_material

    model = Model(mesh, materials)
    if "ball_seat" in mesh.facet_sets:
        ball = model.rigid("ball", "ball_seat", ref_point=(0.0, 0.0, 0.0))
    else:
        ball = model.free_body("ball", (0.0, 0.0, 0.0))
    # the cap's bottom sits on the robot around the bolt head (never under it)
    mount = np.setdiff1d(model.nodes("cap_mount"), model.nodes("bolt_head"))
    if settings.cap_support == "rim":
        rho = np.hypot(*mesh.points[mount, :2].T)
        mount = mount[rho >= part.base_radius - settings.cap_rim_width - 1e-9]
    model.fix(mount)
    axes, contacts = part.sensor_axes()
    sensors = []
    for k in range(3):
        well = model.distributing_coupling(f"well_{k + 1}", f"sensor_well_{k + 1}")
        sensors.append(model.spring(f"sensor_{k + 1}", a=(ball, contacts[k]), b=well,
                                    k=settings.sensor_stiffness, axis=-axes[k]))
    if settings.bolt:
        steel = get_material("steel")
        head = model.rigid("bolt_head", "bolt_head",
                           ref_point=(0.0, 0.0, part.cap_z[0]))
        entry = np.array([0.0, 0.0, -part.ball_radius])
        K = beam_stiffness(head.x, entry, steel.E, steel.G,
                           **circular_section(settings.bolt_minor_diameter))
        model.beam("bolt", (head, head.x), (ball, entry), K)
    unit = np.eye(6)
    for i, name in enumerate(WRENCH):
        model.force(ball, force=unit[i, :3], moment=unit[i, 3:], case=name)
    return model, {"ball": ball, "sensors": [s.name for s in sensors]}



#: part parameters the FEM does not depend on while the fingertip is not meshed: they only move
#: the load points (h, r, the table) or shape the detachable fingertip, which passes the load to
#: the ball whatever its own compliance (tests/sensors/fingertip/test_fingertip_test.py checks that the meshed
#: bodies' B-rep does not change with them)
LOAD_ONLY_PARAMS = ("h", "r", "fingertip_radius", "load_table", "load_patch_radius",
                    "skin_thickness")


#: settings of the contact model that act after the condensation (friction, preload, readout,
#: increments): a sweep over them reuses one FEM. ``structure_moduli`` chooses the moduli of the
#: condensed structure, so it is part of the FEM key.
CONTACT_ONLY_SETTINGS = tuple(f.name for f in dataclasses.fields(ContactSettings)
                              if f.name != "structure_moduli")


def fem_key(part, protocol: HangingWeightTest, settings: FingertipModelSettings,
            materials=None) -> str:
    """Key of the FEM stage: the part's parameters except :data:`LOAD_ONLY_PARAMS` (all of them
    when the fingertip is meshed), the model settings except the rotations and
    :data:`CONTACT_ONLY_SETTINGS`, the material library, and the time grid of the step
    responses."""
    from designlab.fem.cache import fem_key as key
    from designlab.fem.materials import MATERIALS
    from designlab.params import as_dict

    params = as_dict(part)
    if not settings.mesh_fingertip:
        params = {k: v for k, v in params.items() if k not in LOAD_ONLY_PARAMS}
    skip = {"rotations_deg", "mesh_convergence", "coarse_factor", *CONTACT_ONLY_SETTINGS}
    if not settings.contact:
        skip.add("structure_moduli")
    sett = {k: v for k, v in as_dict(settings).items() if k not in skip}
    t, _, _ = protocol.time_history()
    lib = materials if materials is not None else MATERIALS
    return key("fingertip-unit-wrench", params=params, settings=sett,
               materials=repr(sorted(lib.items())), dt_s=protocol.dt_s, t_end=float(t[-1]))



def contact_settings(settings: FingertipModelSettings) -> ContactSettings:
    """The :class:`ContactSettings` part of the fingertip's settings."""
    return ContactSettings(**{f.name: getattr(settings, f.name)
                              for f in dataclasses.fields(ContactSettings)})


def check_locations(part, protocol: HangingWeightTest) -> None:
    """Every load point the protocol names must exist on this design (no silent skipping)."""
    known = part.load_points(0.0)
    for field_name, names in (("g1_locations", protocol.g1_locations),
                              ("g2_locations", protocol.g2_locations)):
        for name in names:
            if name not in known:
                raise ParameterError(field_name, name, "a load point of this design: "
                                     + ", ".join(known))



def design_protocol(protocol: HangingWeightTest, design, overrides: dict | None):
    """The default protocol follows the design: Table III for an optimized design, and only the
    table's load points that lie on this design (a short fingertip has no h1; the omitted ones
    are listed in the prediction). Points named explicitly stay an error when missing."""
    if getattr(design, "load_table", "II") == "III":
        protocol = type(protocol).preset("optimized")
    if not (overrides and {"g1_locations", "g2_locations"} & set(overrides)):
        known = design.load_points(0.0)
        protocol = dataclasses.replace(
            protocol, g1_locations=tuple(n for n in protocol.g1_locations if n in known),
            g2_locations=tuple(n for n in protocol.g2_locations if n in known))
    return protocol
