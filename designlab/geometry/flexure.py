"""Seed 002: the Visiflex helical compression-spring flexure between two printed discs.

Frame (mm): the proximal (base) disc's top face is ``z = 0``, the spring runs to ``z = length``
where the distal (fingertip) disc's bottom face sits; the spring centre (the paper's frame {f})
is ``(0, 0, length / 2)``.

The spring is a circle of radius ``wire_radius`` swept (Frenet) along its centreline. ``plain``
ends: a constant-pitch helix of ``active_coils`` turns whose ends are embedded half a wire radius
into the discs (the epoxy bond): the disc planes cut flat footprints off them. ``closed_ground``:
one dead coil at each end (pitch ``(1 + DEAD_GAP) * d`` so the coils clear each other by 10 % of
the wire diameter, ramping to the active pitch over a quarter turn), ground flat so that the free
length is the handbook ``L0 = p * n_a + 2 d``. Either way the spring's flat end faces lie on the
discs (touching, not overlapping): ``flexure_base`` / ``flexure_tip`` are those faces.

The Visiflex numbers (wire "radius" 2.03 mm, mean diameter 27.73 mm, pitch angle 0.1029 rad,
3.75 coils, rest length 19.8 mm) are self-consistent only if 2.03 mm is the wire *diameter* and
the 3.75 coils are total coils of a closed-and-ground spring (1.75 active): then
``L0 = pi D tan(alpha) * 1.75 + 2 * 2.03 = 19.80 mm``, ``k_z = G d^4 / (8 D^3 n_a) = 3.9e3 N/m``
(paper: 3911) and ``k_rot_z = E d^4 / (64 D n_a) = 1.06 N m/rad`` (paper: 1.06) with SS302
(E = 193 GPa, G = 69 GPa). With a 2.03 mm *radius* and 3.75 active coils the spring would be
37.8 mm long and ~16x stiffer. The defaults therefore use ``wire_radius = 1.015``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from build123d import Box, Cylinder, Helix, Plane, Pos, Spline, sweep, Circle

from designlab.errors import ParameterError
from designlab.geometry.body import Body, FacetSelector
from designlab.geometry.solids import single_solid
from designlab.params import at_least, at_most, rng, validate

#: clearance between neighbouring turns, as a fraction of the wire diameter (dead coils and the
#: smallest allowed active pitch), so the swept solid never touches itself
DEAD_GAP = 0.1
#: fraction of a turn over which the pitch ramps from the dead to the active pitch
RAMP = 0.25
#: embedding of plain ends into the discs, as a fraction of the wire radius
PLAIN_EMBED = 0.5
#: centreline samples per turn of the spline (closed_ground)
SAMPLES_PER_TURN = 24


@dataclass(frozen=True)
class SpringFlexure:
    """Parameters of the spring flexure (mm, rad). Defaults: the Visiflex spring (seed 002)."""

    wire_radius: float = field(default=1.015, metadata=rng(0.2, 5, lo_open=False, unit="mm",
                                                           doc="seed 002: d = 2.03 mm"))
    mean_diameter: float = field(default=27.73, metadata=rng(
        3, 80, unit="mm", doc="mean coil diameter D (seed 002: 27.73)"))
    pitch_angle: float = field(default=0.1029, metadata=rng(
        0.005, 0.5, unit="rad", doc="helix pitch angle of the active coils (seed 002: 0.1029)"))
    active_coils: float = field(default=1.75, metadata=rng(0.5, 20, doc="3.75 total - 2 dead"))
    ends: str = field(default="closed_ground", metadata=rng(
        choices=("plain", "closed_ground"),
        doc=("closed_ground: one dead coil per end, ground flat (seed 002 as we read it); "
             "plain: the coil ends embedded in the discs")))
    material: str = field(default="SS302", metadata=rng(
        choices=("SS302", "steel"),
        doc="spring wire: SS302 stainless (seed 002; E 193 GPa, G 69 GPa) or steel"))
    disc_thickness: float = field(default=3.0, metadata=rng(
        0.8, 20, unit="mm", doc="thickness of each printed disc the spring is bonded to"))
    disc_radius: float = field(default=17.0, metadata=rng(
        3, 60, unit="mm", doc="outer radius of the printed discs"))
    disc_bore: float = field(default=8.0, metadata=rng(0, 50, unit="mm",
                                                       doc="radius of the camera opening"))
    disc_material: str = field(default="PLA", metadata=rng(choices=("PLA", "ABS"),
                                                           doc="seed 002: PLA housings"))

    def __post_init__(self):
        validate(self)
        self._check()

    @classmethod
    def with_free_length(cls, free_length: float, **kw) -> "SpringFlexure":
        """The spring whose free length (between the discs) is ``free_length`` mm: solves for
        ``pitch_angle`` given the other parameters (``kw``)."""
        base = cls(**kw)
        d, n = base.wire_diameter, base.active_coils
        if base.ends == "closed_ground":
            p = (free_length - 2 * d) / n
        else:
            p = (free_length - 2 * base.wire_radius * (1 - PLAIN_EMBED)) / n
        if not p > 0:
            raise ParameterError("free_length", free_length,
                                 f"> {free_length - p * n:.3g} mm for these ends and wire")
        return cls(**{**kw, "pitch_angle": math.atan(p / (math.pi * base.mean_diameter))})

    # ------------------------------------------------------------------ derived (mm, rad)
    @property
    def wire_diameter(self) -> float:
        return 2 * self.wire_radius

    @property
    def pitch(self) -> float:
        """Rise per active turn ``p = pi D tan(alpha)``."""
        return math.pi * self.mean_diameter * math.tan(self.pitch_angle)

    @property
    def dead_pitch(self) -> float:
        return (1 + DEAD_GAP) * self.wire_diameter

    @property
    def total_coils(self) -> float:
        return self.active_coils + (2 if self.ends == "closed_ground" else 0)

    @property
    def length(self) -> float:
        """Free length between the disc faces: ``p n_a + 2 d`` (closed_ground), or
        ``p n_a + d - 2 embed`` (plain, ends embedded into the discs)."""
        return self._cut_planes()[1] - self._cut_planes()[0]

    @property
    def spring_center(self) -> np.ndarray:
        """The paper's frame {f}: centre of the spring on its axis."""
        return np.array([0.0, 0.0, self.length / 2])

    def _check(self) -> None:
        """Constraints between parameters (each named range is not empty given the others)."""
        d, D = self.wire_diameter, self.mean_diameter
        at_least("mean_diameter", D, 3 * d, "spring index D/d >= 3")
        p_min = (1 + DEAD_GAP) * d
        a_min = math.atan(p_min / (math.pi * D))
        at_least("pitch_angle", self.pitch_angle, a_min,
                 f"pitch {self.pitch:.3g} mm per coil: coils touch below {p_min:.3g} mm = "
                 "2 x wire radius + 10 %", unit="rad")
        if self.ends == "closed_ground":
            at_least("active_coils", self.active_coils, 2 * RAMP, "closed_ground ends", unit="")
        at_least("disc_radius", self.disc_radius, D / 2 + self.wire_radius + 0.5,
                 "spring outer radius + 0.5")
        at_most("disc_bore", self.disc_bore, D / 2 - self.wire_radius - 0.5,
                "spring inner radius - 0.5")

    # ------------------------------------------------------------------ centreline
    def pitch_profile(self, u: np.ndarray) -> np.ndarray:
        """Rise per turn ``P(u)`` (mm) at turn count ``u`` along the wire."""
        u = np.asarray(u, dtype=float)
        p = self.pitch
        if self.ends == "plain":
            return np.full_like(u, p)
        pd, n = self.dead_pitch, self.total_coils
        up = np.clip((u - (1 - RAMP / 2)) / RAMP, 0, 1)
        down = np.clip((u - (n - 1 - RAMP / 2)) / RAMP, 0, 1)
        return pd + (p - pd) * (up - down)

    def centerline_z(self, u: np.ndarray) -> np.ndarray:
        """Centreline height ``z_c(u) = int_0^u P`` before the shift to the disc frame."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        fine = np.linspace(0, self.total_coils, 20001)
        P = self.pitch_profile(fine)
        z = np.concatenate([[0.0], np.cumsum((P[1:] + P[:-1]) / 2 * np.diff(fine))])
        return np.interp(u, fine, z)

    def _cut_planes(self) -> tuple[float, float]:
        """Heights (centreline frame) of the two disc planes."""
        z_end = float(self.centerline_z(self.total_coils)[0])
        if self.ends == "closed_ground":
            e = DEAD_GAP * self.wire_diameter
            return e, z_end - e
        e = self.wire_radius * (1 - PLAIN_EMBED)
        return -e, z_end + e

    def wire_length(self) -> float:
        """Centreline length ``int sqrt((pi D)^2 + P(u)^2) du``; for plain ends exactly
        ``n_a sqrt((pi D)^2 + p^2)``."""
        if self.ends == "plain":
            return self.active_coils * math.hypot(math.pi * self.mean_diameter, self.pitch)
        u = np.linspace(0, self.total_coils, 20001)
        f = np.hypot(math.pi * self.mean_diameter, self.pitch_profile(u))
        return float(np.sum((f[1:] + f[:-1]) / 2 * np.diff(u)))

    def wire_volume(self) -> float:
        """Closed-form spring volume: ``pi r_w^2 * wire_length`` minus what the two disc planes cut
        off the ends (circular-segment areas integrated along the wire), mm^3."""
        rw, D = self.wire_radius, self.mean_diameter
        z_lo, z_hi = self._cut_planes()
        u = np.linspace(0, self.total_coils, 40001)
        zc = self.centerline_z(u)
        P = self.pitch_profile(u)
        ds = np.hypot(math.pi * D, P)  # d(arc length)/du
        cos_a = math.pi * D / ds

        def segment(c):  # area of the part of the cross-section beyond a chord at distance c
            c = np.clip(c, -rw, rw)
            return rw ** 2 * np.arccos(c / rw) - c * np.sqrt(rw ** 2 - c ** 2)

        cut = segment((zc - z_lo) / cos_a) + segment((z_hi - zc) / cos_a)
        removed = float(np.sum(((cut * ds)[1:] + (cut * ds)[:-1]) / 2 * np.diff(u)))
        return math.pi * rw ** 2 * self.wire_length() - removed

    # ------------------------------------------------------------------ API
    def build(self) -> dict[str, Body]:
        """Bodies ``spring`` (steel), ``base_disc`` and ``tip_disc`` (printed) (cached)."""
        return dict(_build(self))

    def mesh_bodies(self) -> tuple[str, ...]:
        return ("spring",)

    def facet_sets(self) -> dict[str, FacetSelector]:
        """``flexure_base`` / ``flexure_tip``: the spring's flat end faces lying on the base disc
        (``z = 0``, normal -z) and the fingertip disc (``z = length``, normal +z)."""
        L, tol = self.length, 0.02

        def base(c, n):
            return (n[:, 2] < -0.95) & (np.abs(c[:, 2]) < tol)

        def tip(c, n):
            return (n[:, 2] > 0.95) & (np.abs(c[:, 2] - L) < tol)

        return {"flexure_base": base, "flexure_tip": tip}

    def refinement(self) -> list[tuple[np.ndarray, float, float]]:
        """The two wire ends where they meet the discs (edge = wire radius / 2)."""
        R = self.mean_diameter / 2
        z_lo, z_hi = self._cut_planes()
        end_angle = 2 * math.pi * self.total_coils
        pts = [np.array([R, 0.0, 0.0]),
               np.array([R * math.cos(end_angle), R * math.sin(end_angle), z_hi - z_lo])]
        return [(q, 4 * self.wire_radius, self.wire_radius / 2) for q in pts]


def _centerline(p: SpringFlexure):
    R = p.mean_diameter / 2
    if p.ends == "plain":
        return Helix(pitch=p.pitch, height=p.pitch * p.active_coils, radius=R)
    n = max(int(math.ceil(p.total_coils * SAMPLES_PER_TURN)), 8) + 1
    u = np.linspace(0, p.total_coils, n)
    z = p.centerline_z(u)
    pts = [(R * math.cos(2 * math.pi * a), R * math.sin(2 * math.pi * a), b)
           for a, b in zip(u, z)]
    return Spline(*pts)


@functools.lru_cache(maxsize=8)
def _build(p: SpringFlexure) -> dict[str, Body]:
    path = _centerline(p)
    profile = Plane(origin=path @ 0, z_dir=path % 0) * Circle(p.wire_radius)
    wire = sweep(profile, path=path, is_frenet=True)
    z_lo, z_hi = p._cut_planes()
    big = 2 * (p.mean_diameter + 4 * p.wire_radius)
    slab = Pos(0, 0, (z_lo + z_hi) / 2) * Box(big, big, z_hi - z_lo)
    spring = single_solid((Pos(0, 0, -z_lo) * (wire & slab)).clean(), "spring")
    L, t = z_hi - z_lo, p.disc_thickness

    def disc(z0):
        d = Pos(0, 0, z0 + t / 2) * Cylinder(p.disc_radius, t)
        if p.disc_bore > 0:
            d -= Pos(0, 0, z0 + t / 2) * Cylinder(p.disc_bore, t + 1)
        return d

    base = single_solid(disc(-t).clean(), "base_disc")
    tip = single_solid(disc(L).clean(), "tip_disc")
    return {
        "spring": Body("spring", spring, p.material, (0.72, 0.74, 0.78), printed=False),
        "base_disc": Body("base_disc", base, p.disc_material, (0.3, 0.3, 0.33)),
        "tip_disc": Body("tip_disc", tip, p.disc_material, (0.95, 0.8, 0.2)),
    }
