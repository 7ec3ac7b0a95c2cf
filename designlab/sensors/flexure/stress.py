"""Wire stress and safety factor of the spring flexure under the virtual test's load cases.
Details: docs/models/flexure_modules.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.sensors.flexure.spring import HelicalSpring

#: below this safety factor the prediction warns (as designlab.fem.stress)
WARN_SAFETY_FACTOR = 2.0
#: Shigley 10th ed. Table 10-4, A313 (302) stainless spring wire: S_ut = A / d^m (MPa, mm)
A313_A_MPA, A313_M = 1867.0, 0.146
#: the wire diameters that table covers, mm
A313_RANGE_MM = (0.3, 2.5)
#: Shigley 10th ed. Table 10-6: S_sy = 0.35 S_ut for austenitic stainless (set not removed)
A313_SSY_OVER_SUT = 0.35
WRENCH = ("m_x", "m_y", "m_z", "f_x", "f_y", "f_z")
#: coil-angle samples per turn of the closed form
PHI_SAMPLES = 720


def factors(C: float) -> dict[str, float]:
    """Wahl ``K_W``, direct shear ``K_s``, curvature ``K_c = K_W / K_s`` and bending ``K_i``
    of spring index ``C = D / d`` (> 1)."""
    if not C > 1:
        raise ParameterError("spring index D/d", C, "> 1 (the mean diameter exceeds the wire)")
    K_W = (4 * C - 1) / (4 * C - 4) + 0.615 / C
    K_s = 1 + 0.5 / C
    return {"K_W": K_W, "K_s": K_s, "K_c": K_W / K_s,
            "K_i": (4 * C ** 2 - C - 1) / (4 * C * (C - 1))}


def wire_strength(material: str, d: float) -> dict[str, Any]:
    """Strength (von Mises equivalent, MPa) of a spring wire of diameter ``d`` (mm), its basis
    and source."""
    if material == "SS302":
        S_ut = A313_A_MPA / d ** A313_M
        lo, hi = A313_RANGE_MM
        note = "" if lo <= d <= hi else (f"; d = {d:.3g} mm lies outside the table's "
                                         f"{lo:g}-{hi:g} mm (extrapolated)")
        return {"strength_MPa": math.sqrt(3) * A313_SSY_OVER_SUT * S_ut,
                "basis": "torsional yield of the wire as a von Mises stress (sqrt(3) S_sy)",
                "source": f"Shigley 10th ed. Table 10-4 (S_ut = {A313_A_MPA:g}/d^{A313_M:g} MPa "
                          f"= {S_ut:.0f} MPa at d = {d:.3g} mm) and Table 10-6 (S_sy = "
                          f"{A313_SSY_OVER_SUT:g} S_ut)" + note}
    from designlab.fem.materials import get_material

    m = get_material(material)
    return {"strength_MPa": m.strength, "basis": m.strength_basis, "source": m.strength_source}


def section_stress(N, V, T, M, d: float, C: float) -> dict[str, np.ndarray]:
    """Normal, shear and von Mises stress (MPa) of round-wire sections with forces N, V (N)
    and moments T, M (N mm) (module docstring)."""
    k = factors(C)
    A = math.pi * d ** 2 / 4
    Z = math.pi * d ** 3 / 32                       # bending section modulus, mm^3
    sigma = k["K_i"] * np.abs(M) / Z + np.abs(N) / A
    tau = k["K_c"] * (np.abs(T) / (2 * Z) + np.abs(V) / A)
    return {"sigma": sigma, "tau": tau, "von_mises": np.sqrt(sigma ** 2 + 3 * tau ** 2)}


def end_height(spring: HelicalSpring) -> float:
    """Height of the outermost free wire section above the spring centre, mm: ``L0/2 - r``
    for ground ends (the wire leaves the seat one radius above it), ``L/2`` for plain ends."""
    if spring.inactive_coils > 0:
        return spring.free_length / 2 - spring.wire_radius
    return spring.active_length / 2


def closed_form_sections(spring: HelicalSpring, wrench, heights: int = 3,
                         phi_samples: int = PHI_SAMPLES) -> dict[str, np.ndarray]:
    """Section forces (N, V, T, M) and points X of the textbook helix under ``wrench``
    (m_x, m_y, m_z [N mm], f_x, f_y, f_z [N]) at the spring centre: one turn of coil angles at
    ``heights`` levels from ``-end_height`` to ``+end_height`` (the moment is affine in the
    height, so the largest stress lies at an end)."""
    W = np.asarray(wrench, float)
    m, f = W[:3], W[3:]
    R, a = spring.mean_radius, spring.pitch_angle
    phi = np.linspace(0.0, 2 * math.pi, phi_samples, endpoint=False)
    zs = np.linspace(-end_height(spring), end_height(spring), heights)
    P, Z = np.meshgrid(phi, zs)
    P, Z = P.ravel(), Z.ravel()
    X = np.column_stack([R * np.cos(P), R * np.sin(P), Z])
    t = np.column_stack([-np.sin(P) * math.cos(a), np.cos(P) * math.cos(a),
                         np.full_like(P, math.sin(a))])
    Mom = m + np.cross(-X, f)                       # centre at the origin: c - p = -X
    n = t @ f
    tq = np.einsum("ij,ij->i", Mom, t)
    return {"X": X, "N": np.abs(n), "V": np.linalg.norm(f - n[:, None] * t, axis=1),
            "T": np.abs(tq), "M": np.linalg.norm(Mom - tq[:, None] * t, axis=1)}


def load_cases(protocol=None) -> list[tuple[str, str, np.ndarray]]:
    """(name, description, wrench at the spring centre) of the virtual test: each axis at the
    protocol's largest force / moment, both signs (seed 002: ~10 N fingertip force)."""
    from designlab.sensors.protocols import FlexureWrenchTest

    protocol = protocol or FlexureWrenchTest()
    amp = [protocol.max_moment_Nmm] * 3 + [protocol.max_force_N] * 3
    out = []
    for i, name in enumerate(WRENCH):
        unit = "N mm" if i < 3 else "N"
        for s in (1.0, -1.0):
            w = np.zeros(6)
            w[i] = s * amp[i]
            what = ("axial " + ("compression" if s < 0 else "tension")) if name == "f_z" else \
                ("moment" if i < 3 else "force")
            out.append((f"{name} {s * amp[i]:+g} {unit}",
                        f"{what} {name} = {s * amp[i]:+g} {unit} at the spring centre", w))
    return out


def _force_von_mises(spring: HelicalSpring, forces: np.ndarray, phi_samples: int = PHI_SAMPLES
                     ) -> np.ndarray:
    """Largest closed-form von Mises stress (MPa) of each force (k, 3) at the spring centre
    (``phi_samples`` coil angles per end)."""
    d, C = 2 * spring.wire_radius, spring.mean_diameter / (2 * spring.wire_radius)
    X = closed_form_sections(spring, np.zeros(6), heights=2, phi_samples=phi_samples)["X"]
    P = np.arange(len(X)) % phi_samples * (2 * math.pi / phi_samples)
    a = spring.pitch_angle
    t = np.column_stack([-np.sin(P) * math.cos(a), np.cos(P) * math.cos(a),
                         np.full_like(P, math.sin(a))])
    # a force f alone: N = f.t, V^2 = |f|^2 - N^2, moment -X x f: T = -(t x X).f,
    # M^2 = |X x f|^2 - T^2 = |X|^2 |f|^2 - (X.f)^2 - T^2   (sections x forces)
    f2 = (forces ** 2).sum(1)
    N = t @ forces.T
    T = -np.cross(t, X) @ forces.T
    XF = X @ forces.T
    V = np.sqrt(np.maximum(f2 - N ** 2, 0.0))
    M = np.sqrt(np.maximum((X ** 2).sum(1)[:, None] * f2 - XF ** 2 - T ** 2, 0.0))
    return section_stress(N, V, T, M, d, C)["von_mises"].max(axis=0)


def worst_force_elevation(spring: HelicalSpring, force_N: float) -> float:
    """Angle (rad) from the coil axis of the force of ``force_N`` at the spring centre with the
    closed form's largest von Mises stress (1 degree steps; seed 002: the fingertip "can
    generate approximately 10 N of force in any direction"). The closed form takes every coil
    angle at both end heights, so it is axisymmetric: any azimuth is as bad."""
    th = np.radians(np.arange(0.0, 180.5, 1.0))
    forces = force_N * np.column_stack([np.sin(th), np.zeros_like(th), np.cos(th)])
    return float(th[int(np.argmax(_force_von_mises(spring, forces)))])


#: azimuths (deg) at which the chain takes the worst-elevation force (the spring as built is
#: not axisymmetric: its wire ends sit at one coil angle)
AZIMUTHS_DEG = tuple(range(0, 360, 15))
#: then these offsets (deg) around the largest of them
AZIMUTH_REFINE_DEG = (-10, -5, 5, 10)


def _chain_wrench(chain, wrench) -> np.ndarray:
    """Wrench at the spring centre -> the chain's master load (f, m at the tip master)."""
    W = np.asarray(wrench, float)
    c = np.array([0.0, 0.0, chain.coil.length / 2])
    return np.r_[W[3:], W[:3] + np.cross(c - chain.master, W[3:])]


def case_sections(spring: HelicalSpring, protocol=None, chain_settings=None, *,
                  chain=True) -> list[dict[str, Any]]:
    """The load cases (:func:`load_cases` plus the protocol's force in the worst direction)
    with their section forces: ``closed_form`` (:func:`closed_form_sections`) and, with
    ``chain``, the beam chain of ``spring`` as built (points about the spring centre, closed
    contacts; ``chain`` may be an assembled :class:`~designlab.sensors.flexure.beam_chain.Chain`
    of the spring to re-use). The section forces of the closed form are statics (no wire
    diameter in them), so a scattered wire re-uses them (:func:`stress_report`)."""
    from designlab.sensors.protocols import FlexureWrenchTest

    protocol = protocol or FlexureWrenchTest()
    cases = load_cases(protocol)
    F = protocol.max_force_N
    th = worst_force_elevation(spring, F)
    worst_name = f"f {F:g} N worst direction"
    cases.append((worst_name, "", np.r_[0.0, 0.0, 0.0, F * math.sin(th), 0.0, F * math.cos(th)]))
    ch = chain if not isinstance(chain, bool) else None
    if chain is True:
        from designlab.sensors.flexure.beam_chain import Chain
        from designlab.sensors.flexure.chain_geometry import ChainSettings, as_built

        ch = Chain(as_built(spring), chain_settings or ChainSettings())
    d, C = 2 * spring.wire_radius, spring.mean_diameter / (2 * spring.wire_radius)

    def chain_sections(w):
        r = ch.solve_force(_chain_wrench(ch, w))
        sf = ch.section_forces(r["q"])
        # chain frame: base seat at z = 0; points about the spring centre like the closed form
        sf["X"] = sf["X"] - np.array([0.0, 0.0, ch.coil.length / 2])
        sf["closed_contacts"] = int(np.count_nonzero(r["closed"]))
        return sf

    out = []
    for name, desc, w in cases:
        entry = {"name": name, "description": desc, "wrench": w,
                 "closed_form": closed_form_sections(spring, w), "chain": None}
        if name == worst_name:
            desc = (f"{F:g} N at the spring centre, {math.degrees(th):.0f} deg from the coil "
                    "axis: the elevation with the largest closed-form stress (axisymmetric: "
                    "any azimuth; seed 002: ~10 N fingertip force in any direction)")
            if ch is not None:
                best = None

                def at(psi_deg, best):
                    psi = math.radians(psi_deg)
                    wp = np.r_[0.0, 0.0, 0.0, F * math.sin(th) * math.cos(psi),
                               F * math.sin(th) * math.sin(psi), F * math.cos(th)]
                    sf = chain_sections(wp)
                    vm = section_stress(sf["N"], sf["V"], sf["T"], sf["M"], d, C)["von_mises"]
                    return (vm.max(), psi_deg, wp, sf) if best is None or vm.max() > best[0] \
                        else best

                for psi_deg in AZIMUTHS_DEG:
                    best = at(psi_deg, best)
                coarse = best[1]
                for step in AZIMUTH_REFINE_DEG:
                    best = at((coarse + step) % 360, best)
                _, psi_deg, w, entry["chain"] = best
                entry["wrench"] = w
                desc += (f"; the chain at azimuths every {AZIMUTHS_DEG[1]} deg and "
                         f"{', '.join(f'{a:+d}' for a in AZIMUTH_REFINE_DEG)} deg around the "
                         f"largest: the largest at {psi_deg:.0f} deg (the wrench given)")
            entry["description"] = desc
        elif ch is not None:
            entry["chain"] = chain_sections(w)
        out.append(entry)
    return out


def wire_stress(spring: HelicalSpring, protocol=None, chain_settings=None, *,
                material: str = "SS302", chain=True) -> dict[str, Any]:
    """The ``stress`` section of the flexure's prediction: per load case (:func:`case_sections`)
    the largest von Mises stress of the closed form and of the beam chain of the spring as
    built, where, the wire's strength and the safety factor (of the larger of the two); the
    smallest safety factor over the cases and the warnings below :data:`WARN_SAFETY_FACTOR`.
    ``spring``: the spring as built (:func:`designlab.sensors.flexure.model.spring_as_built`;
    its moduli only matter to the chain's contact); ``chain``: True (assemble the chain), False
    (closed form only) or an assembled chain of that spring to re-use."""
    return stress_report(case_sections(spring, protocol, chain_settings, chain=chain), spring,
                         material)


def stress_report(cases: list[dict[str, Any]], spring: HelicalSpring, material: str = "SS302"
                  ) -> dict[str, Any]:
    """The report of :func:`wire_stress` from the section forces of :func:`case_sections` and
    the wire of ``spring`` (diameter, index: a scattered wire re-uses nominal sections)."""
    d, C = 2 * spring.wire_radius, spring.mean_diameter / (2 * spring.wire_radius)
    st = wire_strength(material, d)
    out_cases: dict[str, Any] = {}
    worst = None
    for case in cases:
        name, cf = case["name"], case["closed_form"]
        s_cf = section_stress(cf["N"], cf["V"], cf["T"], cf["M"], d, C)
        i = int(np.argmax(s_cf["von_mises"]))
        entry = {"material": material, "closed_form_MPa": float(s_cf["von_mises"][i]),
                 "closed_form_at_mm": cf["X"][i].tolist(),
                 "closed_form_tau_MPa": float(s_cf["tau"][i]),
                 "closed_form_sigma_MPa": float(s_cf["sigma"][i])}
        vm, at, by = entry["closed_form_MPa"], entry["closed_form_at_mm"], "closed_form"
        sf = case["chain"]
        if sf is not None:
            s_ch = section_stress(sf["N"], sf["V"], sf["T"], sf["M"], d, C)
            j = int(np.argmax(s_ch["von_mises"]))
            entry.update({"chain_MPa": float(s_ch["von_mises"][j]), "chain_at_mm": sf["X"][j].tolist(),
                          "chain_closed_contacts": sf["closed_contacts"],
                          "chain_over_closed_form": float(s_ch["von_mises"][j] / vm)})
            if entry["chain_MPa"] > vm:
                vm, at, by = entry["chain_MPa"], entry["chain_at_mm"], "chain"
        strength = st["strength_MPa"]
        sfac = None if strength is None else (strength / vm if vm > 0 else float("inf"))
        entry.update({"max_von_mises_MPa": vm, "at_mm": at, "governed_by": by,
                      "strength_MPa": strength, "safety_factor": sfac})
        out_cases[name] = {"description": case["description"],
                           "wrench_at_centre": np.asarray(case["wrench"]).tolist(),
                           "bodies": {"spring": entry}}
        if sfac is not None and (worst is None or sfac < worst["safety_factor"]):
            worst = {"load_case": name, "body": "spring", **entry}
    report = {
        "method": ("wire section stress of the helical spring: closed form (statics of the "
                   "wrench at every coil section, Wahl's curvature factors) and the beam chain "
                   "of the spring as built (bonded ends, dead-coil and seat contact); von Mises "
                   "of the largest normal and shear stress of a section; safety factor = wire "
                   "strength / the larger of the two"),
        "factors": factors(C), "wire_diameter_mm": d, "spring_index": C,
        "end_height_mm": end_height(spring),
        "load_cases": out_cases,
        "materials": {material: {"strength_MPa": st["strength_MPa"], "basis": st["basis"],
                                 "source": st["source"]}},
        "min_safety_factor": None if worst is None else worst["safety_factor"],
        "critical": worst,
        "max_von_mises_MPa": max(c["bodies"]["spring"]["max_von_mises_MPa"]
                                 for c in out_cases.values()),
        "warn_below": WARN_SAFETY_FACTOR,
        "units": "MPa; at_mm about the spring centre (z on the coil axis)",
    }
    report["warnings"] = warnings_of(report)
    return report


def warnings_of(report: dict[str, Any]) -> list[str]:
    """One line per load case whose safety factor is below :data:`WARN_SAFETY_FACTOR`."""
    out = []
    for name, case in report["load_cases"].items():
        e = case["bodies"]["spring"]
        if e["safety_factor"] is not None and e["safety_factor"] < WARN_SAFETY_FACTOR:
            out.append(f"safety factor {e['safety_factor']:.2g} < {WARN_SAFETY_FACTOR:g} in the "
                       f"spring wire ({e['material']}) under {name}: von Mises "
                       f"{e['max_von_mises_MPa']:.3g} MPa ({e['governed_by']}) vs strength "
                       f"{e['strength_MPa']:.3g} MPa")
    if report["materials"] and all(m["strength_MPa"] is None for m in report["materials"].values()):
        out.append("spring wire: no documented strength, no safety factor")
    return out


def stress_table(report: dict[str, Any]):
    """A rich Table of the wire stress per load case."""
    from rich.table import Table

    t = Table(title=f"spring wire stress (d = {report['wire_diameter_mm']:.3g} mm, C = "
                    f"{report['spring_index']:.3g}, K_W = {report['factors']['K_W']:.3f}; "
                    "von Mises, MPa)", caption_justify="left")
    for c in ("load case", "closed form", "chain", "chain/closed", "safety factor"):
        t.add_column(c, justify="left" if c == "load case" else "right", no_wrap=True)
    for name, case in report["load_cases"].items():
        e = case["bodies"]["spring"]
        ch = e.get("chain_MPa")
        t.add_row(name, f"{e['closed_form_MPa']:.1f}", "-" if ch is None else f"{ch:.1f}",
                  "-" if ch is None else f"{e['chain_over_closed_form']:.2f}",
                  "-" if e["safety_factor"] is None else f"{e['safety_factor']:.2f}")
    m = next(iter(report["materials"].items()))
    t.caption = (f"strength {m[1]['strength_MPa']:.0f} MPa ({m[0]}: {m[1]['source']}); "
                 f"safety factor against the larger stress; warning below "
                 f"{report['warn_below']:g}")
    return t
