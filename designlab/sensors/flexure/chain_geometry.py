"""The beam chain's settings and the spring's centreline as built (mm, MPa).

:class:`ChainSettings` holds the chain's discretisation, end conditions and contact settings;
:class:`Coil` the wire centreline ``z(u)`` and seats, made from a spring (:func:`as_built`) or
from the meshed part (:func:`from_part`). Derivations: docs/models/flexure_beam_chain.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from designlab.errors import ParameterError
from designlab.params import rng, validate
from designlab.sensors.flexure.spring import HelicalSpring


#: turns over which the pitch ramps from the dead pitch d to the active pitch (the solid part's
#: RAMP, designlab.geometry.flexure)
RAMP = 0.25
#: grinding plane above the wire end's centreline, in wire diameters (the solid part's
#: DEAD_GAP-sized grind, designlab.geometry.flexure._cut_planes)
GRIND = 0.1
#: printed seat discs (seed 002: PLA housings): the default ``ChainSettings.seat_material``,
#: E and nu from designlab.fem.materials
SEAT_MATERIAL = "PLA"
#: Coulomb coefficient of the wire's coil contacts (steel on steel, dry, kinetic: the contacts
#: slide under the perturbations): 0.3 in S. A. Hill's table "Coefficients of Friction"
#: (howwhy.nfshost.com/new/book1/motion/coefficients.html, 2023), which gives dry steel on
#: steel static 0.6 / kinetic 0.3 and oiled 0.05 / 0.03. No value is published for the spring.
MU_STEEL = 0.3


def mindlin_ratio(nu: float) -> float:
    """Mindlin's tangential / normal contact stiffness of two like elastic bodies,
    ``2 (1 - nu) / (2 - nu)`` (Johnson, *Contact Mechanics*, 1985, sec. 7.2)."""
    return 2 * (1 - nu) / (2 - nu)


@dataclass(frozen=True)
class ChainSettings:
    """Settings of the beam-chain model (mm, N, rad)."""

    elements_per_turn: int = field(default=36, metadata=rng(8, 400,
                                   doc="straight beams per turn of wire"))
    contact: bool = True
    seat: str = field(default="bonded", metadata=rng(choices=("bonded", "contact", "potted"),
                      doc="ground faces bonded (epoxy), only seated, or the whole dead turn "
                          "set in epoxy"))
    seat_base: str = field(default="", metadata=rng(choices=("", "bonded", "contact", "potted"),
                           doc="end condition of the base end only ('' = seat)"))
    seat_tip: str = field(default="", metadata=rng(choices=("", "bonded", "contact", "potted"),
                          doc="end condition of the tip end only ('' = seat)"))
    working_load_N: float = field(default=10.0, metadata=rng(0, 1000, unit="N", doc=(
        "axial compression of the second reference state (seed 002: maximum fingertip force "
        "10 N)")))
    seat_material: str = field(default=SEAT_MATERIAL, metadata=rng(
        choices=("PLA", "ABS"), doc="material of the printed discs (contact modulus of the seats)"))
    mu: float = field(default=MU_STEEL, metadata=rng(0, 1e6, doc=(
        "Coulomb friction coefficient at the coil and seat contacts (friction_stiffness, "
        "loop_stiffness; chain_stiffness is frictionless). Default 0.3: dry steel on steel, "
        "kinetic (S. A. Hill, 'Coefficients of Friction', howwhy.nfshost.com, 2023: static 0.6, "
        "kinetic 0.3; oiled 0.05 / 0.03)")))
    contact_spacing_mm: float = field(default=0.1, metadata=rng(0, 10, unit="mm", doc=(
        "spacing of the contact points along the wire: a line contact (penalty E* per unit "
        "length, each point E* x its length), the points placed independently of the beam "
        "nodes and moving with the beams' shape functions; 0: one contact per beam node (node "
        "contacts, whose 10 N state depends on elements_per_turn)")))
    contact_mesh_mm: float = field(default=0.25, metadata=rng(0, 10, unit="mm", doc=(
        "beam length (mm of wire) where a contact can close (within 0.1 mm of closing at rest, "
        "plus 3 mm either side; line contacts only): a contact zone shorter than a beam is not "
        "resolved by the beam's shape functions. 0: elements_per_turn everywhere")))
    perturbation_rad: float = field(default=2e-3, metadata=rng(0, 0.1, lo_open=True, unit="rad"))
    perturbation_mm: float = field(default=0.02, metadata=rng(0, 1, lo_open=True, unit="mm"))
    max_iterations: int = field(default=60, metadata=rng(2, 1000))

    def __post_init__(self):
        validate(self)

    @property
    def end_seats(self) -> tuple[str, str]:
        """(base, tip) end conditions: ``seat_base`` / ``seat_tip`` where set, else ``seat``."""
        return self.seat_base or self.seat, self.seat_tip or self.seat


@dataclass(frozen=True)
class Coil:
    """What the chain needs of a spring (mm, MPa): centreline ``z(u)`` at turn count ``u``
    (``0 <= u <= turns``), seat heights in the same frame, ends, wire and moduli."""

    R: float
    r: float
    turns: float
    z_of_u: Callable[[np.ndarray], np.ndarray]
    seat_lo: float
    seat_hi: float
    ends: str
    E: float
    G: float
    label: str

    @property
    def length(self) -> float:
        return self.seat_hi - self.seat_lo


def _ramp_profile(u, turns, p_dead, p_act, start, ramp):
    """Pitch per turn: ``p_dead`` up to ``start``, linear to ``p_act`` over ``ramp``, mirrored."""
    up = np.clip((u - start) / ramp, 0.0, 1.0)
    down = np.clip((u - (turns - start - ramp)) / ramp, 0.0, 1.0)
    return p_dead + (p_act - p_dead) * (up - down)


def _integrate(profile, turns):
    fine = np.linspace(0.0, turns, 20001)
    P = profile(fine)
    z = np.concatenate([[0.0], np.cumsum((P[1:] + P[:-1]) / 2 * np.diff(fine))])
    return lambda u: np.interp(np.asarray(u, float), fine, z)


def as_built(spring: HelicalSpring) -> Coil:
    """The spring as built: ``inactive_coils`` 2 -> closed-and-ground ends (one dead turn each,
    gap closing to zero, ground); 0 -> plain ends clamped at the wire's end points."""
    R, r, d = spring.mean_radius, spring.wire_radius, 2 * spring.wire_radius
    n_a = spring.active_coils
    if spring.inactive_coils == 0:
        p = spring.pitch
        return Coil(R, r, n_a, lambda u: p * np.asarray(u, float), 0.0, p * n_a, "plain",
                    spring.E, spring.G, "plain ends, clamped wire ends")
    if spring.inactive_coils != 2:
        raise ParameterError("inactive_coils", spring.inactive_coils,
                             "0 (plain ends) or 2 (closed and ground ends: one dead turn each)")
    turns = spring.coils                            # >= 2.5 (HelicalSpring checks it)
    L0 = n_a * spring.pitch + 2 * d                 # handbook free length (seed 002: 19.80 mm)
    e = GRIND * d
    # rise: 2 dead turns of d + n_a p_a - RAMP (p_a - d)  =  L0 + 2 e
    p_a = (L0 + 2 * e - 2 * d - RAMP * d) / (n_a - RAMP)
    z = _integrate(lambda u: _ramp_profile(u, turns, d, p_a, 1.0, RAMP), turns)
    return Coil(R, r, turns, z, e, float(z(turns)) - e, "closed_ground", spring.E, spring.G,
                f"as built: closed (gap 0) and ground ends, active pitch {p_a:.3g} mm")


def from_part(part, E: float | None = None, G: float | None = None) -> Coil:
    """The meshed ``SpringFlexure``'s centreline and cut planes (its E, G from its material)."""
    from designlab.fem.materials import get_material

    m = get_material(part.material)
    lo, hi = part._cut_planes()
    return Coil(part.mean_diameter / 2, part.wire_radius, part.total_coils, part.centerline_z,
                lo, hi, part.ends, m.E if E is None else E, m.G if G is None else G,
                f"solid part geometry ({part.ends})")


def wire_contact_points(z_of_u: Callable, R: float, turns: float, spacing: float):
    """Where line contacts sit along a helix of mean radius ``R`` (mm) and centreline height
    ``z_of_u(u)`` over ``turns`` turns: ``(points, coil_spans)``. ``points(lo, hi)`` -> (turn
    counts, lengths of wire in mm): the midpoints of equal steps in turn count over
    [lo, hi], ~``spacing`` mm of wire each. ``coil_spans``: the turn-count ranges of the lower
    wire of each coil-to-coil contact (the dead turn and its pitch ramp at both ends; one range
    for a spring too short to have two). Shared by the beam chain and the solid FEM."""
    fine = np.linspace(0.0, turns, int(turns * 2000) + 1)
    dsdu = np.hypot(2 * np.pi * R, np.gradient(np.asarray(z_of_u(fine), float), fine))

    def points(lo: float, hi: float):
        mid = np.interp((lo + hi) / 2, fine, dsdu)
        n = max(int(math.ceil((hi - lo) * mid / spacing - 1e-9)), 1)
        du = (hi - lo) / n
        us = lo + (np.arange(n) + 0.5) * du
        return us, np.interp(us, fine, dsdu) * du

    span = 1.0 + RAMP
    spans = sorted([(0.0, min(span, turns - 1.0)), (max(turns - 1.0 - span, 0.0), turns - 1.0)])
    if spans[1][0] <= spans[0][1]:                    # short springs: one span
        spans = [(spans[0][0], max(spans[0][1], spans[1][1]))]
    return points, spans


def with_settings(base: ChainSettings | None = None, **kw) -> ChainSettings:
    return replace(base or ChainSettings(), **kw)
