"""Closed-form 6x6 stiffness of a helical compression spring (seed 002), mm/N/MPa inside. Details:
docs/models/flexure_modules.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from designlab.errors import ParameterError
from designlab.frames import transform, transform_stiffness
from designlab.params import did_you_mean, rng, validate

#: the 6x6's order: twists (rad, mm) in, wrenches (N mm, N) out
TWIST = ("w_x", "w_y", "w_z", "v_x", "v_y", "v_z")
WRENCH = ("m_x", "m_y", "m_z", "f_x", "f_y", "f_z")

#: SS302 (ASTM A313) typical moduli, MPa: E 193 GPa, G 69 GPa (E/G = 2.797; seed 002's K_f has
#: k_x/k_z = E/G = 10913/3911 = 2.790, consistent with these to 0.3 %)
SS302_E_MPA = 193_000.0
SS302_G_MPA = 69_000.0

#: multiply a designlab stiffness (N*mm/rad, N/mm, N) entry-wise by this to get SI (N*m/rad, N/m, N)
#: closed-and-ground ends: one dead turn at each end (inactive_coils = 2)
GROUND_DEAD_COILS = 2.0
#: fewest total turns with ground ends: 2 dead turns plus the two quarter-turn pitch ramps
#: (designlab.geometry.flexure.RAMP) between them and the active pitch
MIN_GROUND_COILS = 2.5

SI_SCALE = np.block([[np.full((3, 3), 1e-3), np.ones((3, 3))],
                     [np.ones((3, 3)), np.full((3, 3), 1e3)]])


@dataclass(frozen=True)
class HelicalSpring:
    """A helical compression spring (mm, rad, MPa).

    ``coils`` is the total number of turns; ``inactive_coils`` of them (closed ends) carry no
    deflection, so the active turns are ``coils - inactive_coils``.
    """

    wire_radius: float = field(default=2.03, metadata=rng(0, 20, lo_open=True, unit="mm"))
    mean_diameter: float = field(default=27.73, metadata=rng(0, 500, lo_open=True, unit="mm"))
    coils: float = field(default=3.75, metadata=rng(0.5, 200, unit="turns"))
    inactive_coils: float = field(default=0.0, metadata=rng(0, 10, unit="turns"))
    pitch_angle: float = field(default=0.1029, metadata=rng(0, 0.5, unit="rad"))
    E: float = field(default=SS302_E_MPA, metadata=rng(0, 1e6, lo_open=True, unit="MPa"))
    G: float = field(default=SS302_G_MPA, metadata=rng(0, 1e6, lo_open=True, unit="MPa"))

    def __post_init__(self):
        validate(self)
        if self.inactive_coils >= GROUND_DEAD_COILS and self.coils < MIN_GROUND_COILS:
            raise ParameterError("coils", self.coils,
                                 f">= {MIN_GROUND_COILS:g} turns for closed and ground ends "
                                 f"({self.inactive_coils:g} dead turns + 0.5 active)")
        if self.active_coils <= 0:
            raise ParameterError("inactive_coils", self.inactive_coils,
                                 f"fewer than coils={self.coils:g}")
        if 2 * self.wire_radius >= self.mean_diameter:
            raise ParameterError("wire_radius", self.wire_radius,
                                 f"< mean_diameter/2 = {self.mean_diameter / 2:g} mm")

    @property
    def active_coils(self) -> float:
        return self.coils - self.inactive_coils

    @property
    def mean_radius(self) -> float:
        """R, mm."""
        return self.mean_diameter / 2.0

    @property
    def pitch(self) -> float:
        """Axial advance per turn, mm (``2 pi R tan(pitch_angle)``)."""
        return 2 * math.pi * self.mean_radius * math.tan(self.pitch_angle)

    @property
    def active_length(self) -> float:
        """Axial length of the active turns, mm (the equivalent column's length)."""
        return self.active_coils * self.pitch

    @property
    def free_length(self) -> float:
        """Active length plus closed end turns touching (one wire diameter per inactive turn), mm."""
        return self.active_length + self.inactive_coils * 2 * self.wire_radius

    @property
    def wire_length(self) -> float:
        """Active wire length in the zero-pitch limit ``2 pi R n_a``, mm."""
        return 2 * math.pi * self.mean_radius * self.active_coils


#: seed 002 as printed: "wire radius of 2.03 mm, mean diameter 27.73 mm, pitch angle 0.1029 rad,
#: 3.75 coils", all taken as active. Its closed form is ~7.47x the paper's K_f (docs/validation/flexure.md).
VISIFLEX_AS_PRINTED = HelicalSpring()
#: the reading that reproduces the paper's numbers: 2.03 mm is the wire *diameter* (0.080 in
#: catalogue wire) and 2 of the 3.75 turns are closed ends (1.75 active). Then the free length is
#: 1.75 * 9.00 + 2 * 2.03 = 19.80 mm, the paper's rest length.
VISIFLEX_CATALOG = HelicalSpring(wire_radius=1.015, inactive_coils=2.0)
PRESETS = {"visiflex": VISIFLEX_AS_PRINTED, "visiflex-catalog": VISIFLEX_CATALOG}


def preset(name: str) -> HelicalSpring:
    """A named spring; unknown names raise ParameterError listing the presets."""
    if name not in PRESETS:
        raise ParameterError("--preset", name, "one of " + ", ".join(PRESETS)
                             + did_you_mean(name, PRESETS))
    return PRESETS[name]


def rigidities(spring: HelicalSpring) -> dict[str, float]:
    """Wire bending ``EI`` and torsion ``GJ`` (N*mm^2), mean radius ``R`` and wire length (mm)."""
    r = spring.wire_radius
    return {"EI": spring.E * math.pi * r**4 / 4, "GJ": spring.G * math.pi * r**4 / 2,
            "R": spring.mean_radius, "wire_length": spring.wire_length}


def centre_terms(spring: HelicalSpring) -> dict[str, float]:
    """Zero-pitch diagonal terms at the centre: k_bx (= k_by), k_tz (N*mm/rad), k_x (= k_y), k_z (N/mm)."""
    q = rigidities(spring)
    EI, GJ, R, Lw = q["EI"], q["GJ"], q["R"], q["wire_length"]
    return {"k_bx": 2.0 / (Lw * (1.0 / EI + 1.0 / GJ)), "k_tz": EI / Lw,
            "k_x": 2.0 * EI / (R**2 * Lw), "k_z": GJ / (R**2 * Lw)}


def stiffness_zero_pitch(spring: HelicalSpring) -> np.ndarray:
    """Seed 002's closed form: diagonal 6x6 K_f at the spring centre (N*mm/rad, N/mm)."""
    t = centre_terms(spring)
    return np.diag([t["k_bx"], t["k_bx"], t["k_tz"], t["k_x"], t["k_x"], t["k_z"]])


def stiffness_timoshenko(spring: HelicalSpring, length: float | None = None,
                         frame: str = "centre") -> np.ndarray:
    """6x6 stiffness of the equivalent Timoshenko column of ``length`` (mm; default the active length).

    ``frame``: ``"centre"`` (diagonal; the lateral term includes column bending), ``"tip"`` (frame
    at the top end, ``+L/2`` along z, rigid with the tip) or ``"base"`` (``-L/2``). Units N*mm/rad,
    N/mm, N.
    """
    L = spring.active_length if length is None else float(length)
    if L < 0 or not math.isfinite(L):
        raise ParameterError("length", length, ">= 0 mm")
    t = centre_terms(spring)
    k_x = 1.0 / (L**2 / (12.0 * t["k_bx"]) + 1.0 / t["k_x"])
    K = np.diag([t["k_bx"], t["k_bx"], t["k_tz"], k_x, k_x, t["k_z"]])
    offsets = {"centre": 0.0, "tip": L / 2.0, "base": -L / 2.0}
    if frame not in offsets:
        raise ParameterError("frame", frame, "one of " + ", ".join(offsets))
    # {a} = the end frame, {f} = centre; T_af puts the centre at -offset along z of {a}
    return transform_stiffness(K, transform(translation=(0.0, 0.0, -offsets[frame])))


def check_working_load(spring: HelicalSpring, force_N: float) -> None:
    """ParameterError when the active coils touch under an axial ``force_N`` (N): the gap
    ``pitch - 2 r`` must exceed the closed-form deflection per active turn ``F / (k_z n_a)``."""
    if force_N <= 0:
        return
    k_z = centre_terms(spring)["k_z"]
    need = 2 * spring.wire_radius + force_N / (k_z * spring.active_coils)
    if spring.pitch <= need:
        a_min = math.atan(need / (2 * math.pi * spring.mean_radius))
        raise ParameterError("pitch_angle", spring.pitch_angle,
                             f"> {a_min:.4g} rad: at the {force_N:g} N working load the active "
                             f"coils touch (pitch {spring.pitch:.3g} mm <= wire diameter + "
                             f"deflection per turn = {need:.3g} mm)")


def to_si(K: np.ndarray) -> np.ndarray:
    """designlab units (N*mm/rad, N/mm, N) -> SI (N*m/rad, N/m, N), entry-wise."""
    return np.asarray(K, float) * SI_SCALE


def from_si(K_si: np.ndarray) -> np.ndarray:
    """SI (N*m/rad, N/m, N) -> designlab units (N*mm/rad, N/mm, N), entry-wise."""
    return np.asarray(K_si, float) / SI_SCALE


def stiffness_ratios(K: np.ndarray) -> dict[str, float]:
    """Unit-free checks of a diagonal-dominant K (any consistent units; k_tz/k_z carries length^2).

    ``k_x/k_z``, ``k_tz/k_z`` and ``k_bx/k_tz`` (x and y averaged).
    """
    K = np.asarray(K, float)
    k_b, k_tz = (K[0, 0] + K[1, 1]) / 2, K[2, 2]
    k_x, k_z = (K[3, 3] + K[4, 4]) / 2, K[5, 5]
    return {"k_x/k_z": k_x / k_z, "k_tz/k_z": k_tz / k_z, "k_bx/k_tz": k_b / k_tz}
