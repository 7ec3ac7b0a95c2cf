"""The worn strap's initial strain and a strap sized to one finger (seed 000 Sec. V-E). Details:
docs/models/strap_modules.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from designlab.errors import ParameterError
from designlab.params import rng, validate
from designlab.sensors.strap.prestrain import (
    SPREAD_DEFINITION, initial_strain, neo_hooke, operating_point,
    prestrain_state, spread_percent, wrap_path)

#: accepted finger sizes (mm): the wrap model's range (see the module docstring)
WIDTH_RANGE = (10.0, 26.0)
DEPTH_RANGE = (8.0, 24.0)
LENGTH_RANGE = (15.0, 45.0)
#: reference finger: the strap model's default finger radius, 9 mm ("index: ~9",
#: StrapModelSettings.finger_radius), as a circle
REFERENCE_RADIUS = 9.0
#: the paper's medium slot (seed 000 Fig. 2: three slots; the middle one)
MEDIUM_SLOT = 2
#: a measured section perimeter must lie within these multiples of the width/depth ellipse's
#: (a rounded rectangle of the same extents has up to 4/pi = 1.27 x)
SECTION_PERIMETER_RATIO = (0.9, 1.3)
#: the issue's goal for the personalised strap's initial-strain spread (cv, percent)
GOAL_CV_PERCENT = 10.0


@dataclass(frozen=True)
class Finger:
    """Distal phalanx at the strap position (mm)."""

    width: float = field(metadata=rng(*WIDTH_RANGE, unit="mm",
                                      doc="across the nail (wrap model range)"))
    depth: float = field(metadata=rng(*DEPTH_RANGE, unit="mm", doc="nail to pulp"))
    length: float = field(default=25.0, metadata=rng(*LENGTH_RANGE, unit="mm",
                                                     doc="distal phalanx, tip to DIP crease"))
    #: the measured perimeter of the section at the strap (a scan's cut, convex hull: the band
    #: bridges concavities), 0 = none (the ellipse of width and depth is used)
    section_perimeter: float = 0.0

    def __post_init__(self):
        validate(self)
        if not 0.55 <= self.depth / self.width <= 1.25:
            raise ParameterError("depth", self.depth,
                                 f"{0.55 * self.width:.3g} <= value <= {1.25 * self.width:.3g} "
                                 "mm (0.55-1.25 x width: a fingertip-like section)")
        if self.section_perimeter:
            e = self.ellipse_perimeter
            lo, hi = SECTION_PERIMETER_RATIO
            if not lo * e <= self.section_perimeter <= hi * e:
                raise ParameterError("section_perimeter", round(self.section_perimeter, 3),
                                     f"{lo * e:.4g} <= value <= {hi * e:.4g} mm ({lo:g}-{hi:g} "
                                     "x the ellipse of width and depth: a fingertip-like "
                                     "section)")

    @property
    def ellipse_perimeter(self) -> float:
        return ellipse_perimeter(self.width / 2, self.depth / 2)

    @property
    def perimeter(self) -> float:
        """The measured section perimeter when given, else the ellipse of width and depth."""
        return self.section_perimeter or self.ellipse_perimeter

    @property
    def perimeter_source(self) -> str:
        return ("scan: convex hull of the section at the strap" if self.section_perimeter
                else "ellipse of width and depth (Ramanujan)")

    @property
    def equivalent_radius(self) -> float:
        """Radius of the circle with the same perimeter (the FEM's cone wraps a circle)."""
        return self.perimeter / (2 * math.pi)


def parse_finger(text: str) -> Finger:
    """``"WIDTH,DEPTH,LENGTH"`` (mm) -> Finger; one-line error otherwise."""
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise ParameterError("--finger", text, "WIDTH,DEPTH,LENGTH in mm, e.g. 16,14,25") from None
    if len(vals) != 3:
        raise ParameterError("--finger", text, "three numbers WIDTH,DEPTH,LENGTH in mm")
    return Finger(*vals)


def ellipse_perimeter(a: float, b: float) -> float:
    """Perimeter of an ellipse with semi-axes a, b (Ramanujan's second approximation)."""
    h = ((a - b) / (a + b)) ** 2
    return math.pi * (a + b) * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))




# ------------------------------------------------------------------ the pulp under the band

#: pulp moduli (MPa) of the compliance estimate: strap_pulp's default 0.06 (the Winkler
#: default's equivalent, NOT a literature value) and its sweep's ends; the cited range
#: (:func:`pulp_literature`) is added to them by :func:`pulp_compliance`
PULP_MODULI = (0.02, 0.06, 0.3)
#: the cited fingertip modulus (designlab/data/)
PULP_LITERATURE_JSON = "fingertip_pulp.json"


def pulp_literature() -> dict[str, Any]:
    """The cited modulus of the fingertip (``designlab/data/fingertip_pulp.json``: the
    range with its source, read from an abstract; an effective Hertz modulus of the whole
    fingertip, not the subcutaneous tissue's small-strain modulus)."""
    import json
    from importlib import resources

    return json.loads((resources.files("designlab") / "data" / PULP_LITERATURE_JSON)
                      .read_text())


def cited_pulp_moduli() -> tuple[float, ...]:
    """The ends of the cited fingertip modulus range (MPa)."""
    return tuple(float(e) for e in pulp_literature()["finger_hertz_modulus"]["E_MPa"])


def _pulp_modulus_origin(E: float) -> str:
    if E in cited_pulp_moduli():
        cite = pulp_literature()["finger_hertz_modulus"]["citation"]
        return (f"cited range end: effective Hertz modulus of the index finger, {cite} "
                f"(abstract only; designlab/data/{PULP_LITERATURE_JSON})")
    if E == 0.06:
        return "strap_pulp's default (the Winkler default's equivalent, NOT a literature value)"
    if E in PULP_MODULI:
        return "strap_pulp's sweep end (NOT a literature value)"
    return "given"


def confined_modulus(E: float, nu: float) -> float:
    """Constrained (oedometric) modulus M = E (1 - nu) / ((1 + nu) (1 - 2 nu)): a thin layer
    bonded to a rigid base and loaded by a uniform pressure with no lateral strain."""
    return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def compliant_initial_strain(part, perimeter: float, material, *, slot: int | None = None,
                             length: float | None = None, pulp_E: float = 0.06,
                             pulp_depth: float = 3.0, pulp_nu: float = 0.49) -> dict[str, Any]:
    """Initial strain of the worn strap when the pulp under it gives: the band's tension
    T = sigma0 b t (the neo-Hookean stand-in of :func:`stress_stiffening`) presses the finger
    with p = T / (R b), a pulp layer of ``pulp_depth`` on a rigid bone compresses by
    dr = p d / M (confined: :func:`confined_modulus`), the skin perimeter shrinks by
    2 pi dr and the strain falls; solved for the equilibrium by bisection (the residual is
    monotone in eps). Confined is the stiffest a bonded layer can be under a uniform
    pressure (any axial flow from under the band softens it): for a given E the drop is a
    lower bound."""
    L = part.engaged_length(slot) if length is None else float(length)
    E_t, t = float(material.E), float(part.thickness)
    M = confined_modulus(pulp_E, pulp_nu)
    R = perimeter / (2 * math.pi) + t / 2

    def dr(e):
        lam = 1.0 + e
        sigma = E_t * (lam - lam ** -2) / 3.0 if e > 0 else 0.0
        return sigma * t * pulp_depth / (R * M)

    def resid(e):
        return wrap_path(part, perimeter - 2 * math.pi * dr(e)) / L - 1.0 - e

    rigid = wrap_path(part, perimeter) / L - 1.0
    lo, hi = 0.0, max(rigid, 0.0)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if resid(mid) > 0 else (lo, mid)
    eps = 0.5 * (lo + hi) if rigid > 0 else rigid
    return {"initial_strain": float(eps), "rigid_finger_strain": float(rigid),
            "pulp_compression_mm": float(dr(max(eps, 0.0))), "confined_modulus_MPa": M}


def pulp_compliance(perimeters, target: float, material, R0: float, R_fixed: float,
                    slot_perimeter: float = 2 * math.pi * REFERENCE_RADIUS,
                    moduli=None, pulp_depth: float = 3.0,
                    pulp_nu: float = 0.49) -> dict[str, Any]:
    """What the finger's compliance does to the initial strain (:func:`compliant_initial_
    strain`): per pulp modulus, the personalised strap (cut for the target on a rigid finger)
    over ``perimeters`` -- its strain, their cv and the mean drop -- and the paper's slots on
    the reference finger with the sum-sensitivity cv between them (prestrain factors as in
    :func:`slot_table`). A size-dependent, predictable drop: a fit that knew the pulp could
    cut for it. ``moduli`` default: :data:`PULP_MODULI` (strap_pulp's default and sweep ends,
    not literature values) and the ends of the cited fingertip modulus range
    (:func:`cited_pulp_moduli`), ascending; each row says where its modulus comes from."""
    from designlab.geometry.strap import ArchStrap

    if moduli is None:
        moduli = sorted(set(PULP_MODULI) | set(cited_pulp_moduli()))
    base = ArchStrap()
    out = []
    for E in moduli:
        kw = dict(pulp_E=E, pulp_depth=pulp_depth, pulp_nu=pulp_nu)
        pers = [compliant_initial_strain(base, P, material,
                                         length=wrap_path(base, P) / (1 + target), **kw)
                for P in perimeters]
        eps = [r["initial_strain"] for r in pers]
        slots = []
        for k in range(1, base.slot_count + 1):
            e = compliant_initial_strain(base, slot_perimeter, material, slot=k, **kw)
            e0 = max(e["initial_strain"], 0.0)
            op = operating_point(e0, R0, material.gauge_factor, material.gauge_quadratic,
                                 R_fixed)
            slots.append({"slot": k, "initial_strain": e["initial_strain"],
                          "rigid_finger_strain": e["rigid_finger_strain"],
                          "pulp_compression_mm": e["pulp_compression_mm"],
                          "sensitivity_factor": op["electrical_factor"]
                          / neo_hooke(e0)["tangent_over_E"]})
        out.append({"pulp_E_MPa": E, "pulp_E_origin": _pulp_modulus_origin(E),
                    "personalised_strain": eps,
                    "personalised_strain_cv_percent": spread_percent(eps),
                    "personalised_mean_drop_percent": float(100 * (1 - np.mean(eps) / target)),
                    "pulp_compression_mm": [float(r["pulp_compression_mm"]) for r in pers],
                    "slots": slots,
                    "slots_sum_sensitivity_cv_percent": spread_percent(
                        r["sensitivity_factor"] for r in slots)})
    return {"perimeters_mm": [float(P) for P in perimeters], "target_strain": target,
            "slot_perimeter_mm": slot_perimeter, "pulp_depth_mm": pulp_depth,
            "pulp_nu": pulp_nu, "by_modulus": out,
            "model": "confined linear pulp layer on a rigid bone under the band's pressure "
                     "T / (R b) (T: neo-Hookean stand-in of the TPU), equilibrium eps by "
                     "bisection; the stiffest a bonded layer can be, so the drops are lower "
                     "bounds for each E",
            "pulp_modulus_note": "0.06 MPa is strap_pulp's default, the Winkler default's "
                                 "equivalent, NOT a literature value; 0.02 and 0.3 MPa its "
                                 "sweep's ends; the cited rows (pulp_E_origin) are the ends "
                                 "of an effective Hertz modulus of the whole index fingertip "
                                 "read from an abstract, not a small-strain modulus of the "
                                 "subcutaneous tissue (docs/strap.md)",
            "cited_pulp_modulus": pulp_literature()["finger_hertz_modulus"]}


# ------------------------------------------------------------------------- personalised strap

def fit_part(finger: Finger, target_strain: float, slots: int = 1, base=None):
    """An ArchStrap whose middle slot gives ``target_strain`` on ``finger`` (rigid finger).

    The tab keeps the paper's medium-slot distance from the arch foot (7.7 mm on the default
    strap); the arch (width, height, gauge offset, pad contact) is scaled so that arch + two
    tabs has the engaged length path / (1 + target). ``slots`` = 1 (no adjustment) or an odd
    number of slots at a fine pitch (slot width + 0.85 mm web) centred on the target."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    if slots not in (1, 3, 5):
        raise ParameterError("--slots", slots, "1, 3 or 5")
    pitch = base.slot_width + 0.85             # 0.85 mm web: just above the 0.8 mm minimum
    d0 = float(base.slot_distances()[MEDIUM_SLOT - 1])
    m = (slots - 1) // 2                                    # target = the middle slot
    L = wrap_path(base, finger.perimeter) / (1.0 + target_strain)
    f = (L - 2 * d0) / base.arc_length
    tab = d0 + base.slot_end_margin + base.slot_width / 2 + m * pitch
    kw = dict(arch_width=base.arch_width * f, arch_height=base.arch_height * f,
              gauge_offset=base.gauge_offset * f, contact_length=base.contact_length * f,
              tab_length=tab, slot_count=slots, slot_pitch=pitch if slots > 1 else
              base.slot_pitch)
    try:
        part = dataclasses.replace(base, **{k: round(v, 3) if isinstance(v, float) else v
                                            for k, v in kw.items()})
    except ParameterError as exc:
        raise ParameterError("--finger", f"{finger.width:g},{finger.depth:g},{finger.length:g}",
                             f"a finger this strap family fits at strain {target_strain:.3g} "
                             f"(arch scale {f:.3g} violates {exc.name}: {exc.allowed})") from None
    if finger.length < part.strap_width + 2:
        raise ParameterError("--finger", f"length={finger.length:g}",
                             f">= {part.strap_width + 2:g} mm (strap width + 2 mm)")
    return part


def default_target(base=None) -> float:
    """The paper's medium-slot initial strain on the reference finger (rigid finger)."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    return initial_strain(base, 2 * math.pi * REFERENCE_RADIUS, slot=MEDIUM_SLOT)


def check_target(target: float, material, base=None) -> None:
    """Target strain within (0, elongation at break) and at most the largest strain the paper's
    slots reach on the accepted fingers (the tightest slot on the largest section). There is
    no lower bound but 0: the personalised strap's length is fitted to the finger, and a
    target <= 0 would leave it slack (no prestrain to read from)."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    hi = material.max_elongation if material.max_elongation is not None else 1.0
    if not 0 < target < hi:
        raise ParameterError("--target-strain", target,
                             f"0 < value < {hi:g} ({material.name} elongation at break)")
    p_hi = ellipse_perimeter(WIDTH_RANGE[1] / 2, min(DEPTH_RANGE[1], 1.25 * WIDTH_RANGE[1]) / 2)
    top = initial_strain(base, p_hi, slot=base.slot_count)
    if target > top:
        raise ParameterError("--target-strain", target,
                             f"0 < value <= {top:.3g} (the paper slots' largest strain over the "
                             "accepted fingers)")


def required_measurement_sd(target: float, perimeters, base=None,
                            goal_cv_percent: float = GOAL_CV_PERCENT) -> float:
    """The caliper sd (mm per reading of width and depth) at which the personalised strap's
    initial-strain cv reaches ``goal_cv_percent`` on the smallest of ``perimeters`` (the
    worst: the shortest strap): sd_eps = pi / sqrt(2) sd / L <= goal x target."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    L = min(wrap_path(base, P) for P in perimeters) / (1 + target)
    return goal_cv_percent / 100 * target * L * math.sqrt(2) / math.pi


#: the cited finger-measurement errors (caliper %TEM, scan absolute error)
MEASUREMENT_ERROR_JSON = "finger_measurement_error.json"


def measurement_errors() -> dict[str, Any]:
    """The cited measurement errors of a finger's size (``designlab/data/
    finger_measurement_error.json``: each value with its source, read from an abstract)."""
    import json
    from importlib import resources

    return json.loads((resources.files("designlab") / "data" / MEASUREMENT_ERROR_JSON)
                      .read_text())


def perimeter_sd_caliper(perimeter: float, rel_sd: float) -> float:
    """sd (mm) of the ellipse perimeter of a circular section of ``perimeter`` when width and
    depth are each read with a relative error ``rel_sd`` (independent): dP/dw = dP/dd = pi / 2
    at a circle, so sd_P = pi / 2 x sqrt(2) x rel_sd x P / pi = rel_sd P / sqrt(2)."""
    return rel_sd * perimeter / math.sqrt(2)


def strain_sd(perimeter: float, target: float, perimeter_sd: float, base=None) -> float:
    """sd of the personalised strap's initial strain from a perimeter error: the strap is cut
    to L = path(P_measured) / (1 + target), so eps = path(P_true) / L - 1 and d eps / dP =
    1 / L."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    return perimeter_sd * (1 + target) / wrap_path(base, perimeter)


def personalised_spread(perimeters, target: float, base=None) -> dict[str, Any]:
    """The personalised strap's initial-strain cv (percent of the target; the largest over
    ``perimeters``, i.e. the smallest finger) for each cited measurement input: caliper width
    and depth at both ends of the cited %TEM range, and a scan's perimeter at its mean
    absolute error and at the largest circumference error the source names. What else moves
    the strain (not in these numbers): the ellipse as the caliper's section model, the
    printed length, the pulp's compression (docs/strap.md)."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    src = measurement_errors()
    cal, scan = src["caliper"], src["scan"]
    k_mad = math.sqrt(math.pi / 2)                 # normal: sd = mean absolute error x this
    inputs = {}
    for tem in cal["rel_tem_percent"]:
        inputs[f"caliper_tem_{tem:g}_percent"] = (
            "caliper", lambda P, r=tem / 100: perimeter_sd_caliper(P, r),
            f"caliper width and depth, relative sd {tem:g} % each (= %TEM, {cal['to_sd']})")
    for name, mae in (("scan_mean_abs_error", scan["mean_absolute_error_mm"]),
                      ("scan_circumference_abs_error", max(
                          scan["circumference_absolute_error_mm"]))):
        inputs[f"{name}_{mae:g}_mm"] = (
            "scan", lambda P, m=mae: k_mad * m,
            f"scan perimeter, mean absolute error {mae:g} mm -> sd {k_mad * mae:.3g} mm "
            "(normal errors)")
    out = {}
    for key, (kind, sd_P, how) in inputs.items():
        cvs = [100 * strain_sd(P, target, sd_P(P), base) / target for P in perimeters]
        cv = float(max(cvs))
        out[key] = {"kind": kind, "how": how, "strain_cv_percent": cv,
                    "strain_cv_percent_per_perimeter": [float(c) for c in cvs],
                    "goal_met": bool(cv < GOAL_CV_PERCENT)}
    # the caliper's relative sd (each reading) at which the goal is just met
    cv_per_rel = max(100 * strain_sd(P, target, perimeter_sd_caliper(P, 1.0), base) / target
                     for P in perimeters)
    # 1 % of the perimeter wrong (e.g. the ellipse model of a caliper's section): its cv
    P0 = float(min(perimeters))
    per_pct = 100 * strain_sd(P0, target, 0.01 * P0, base) / target
    # the printed length: d eps = (1 + eps) dL / L
    L0 = wrap_path(base, P0) / (1 + target)
    per_01mm = 100 * (1 + target) * 0.1 / L0 / target
    return {"inputs": out,
            "caliper_relative_sd_percent_for_goal": 100 * GOAL_CV_PERCENT / cv_per_rel,
            "sources": {"caliper": cal["source"], "scan": scan["source"]},
            "not_included_cv_percent": {
                "per_1_percent_perimeter_model_error": per_pct,
                "per_0.1_mm_printed_length_error": per_01mm,
                "note": "sensitivities on the smallest finger, not errors: no cited value for "
                        "how far a fingertip section's perimeter departs from the ellipse of "
                        "its width and depth, nor for the printed TPU strap's length "
                        "accuracy; the pulp's compression under the band is not modelled "
                        "(rigid finger)"}}


def finger_spread(finger: Finger, target: float, base=None) -> dict[str, Any]:
    """The personalised strap's initial-strain cv (percent of the target) for *this* finger
    from the cited error of the way it was measured: a scan's perimeter (both cited scan
    figures) or a caliper's width and depth (both ends of the cited %TEM range; the
    ellipse's gradient, not the circle's)."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    src = measurement_errors()
    P = finger.perimeter
    out: dict[str, Any] = {"perimeter_mm": P}
    if finger.section_perimeter:
        sc = src["scan"]
        k = math.sqrt(math.pi / 2)
        maes = {"scan_mean_abs_error": sc["mean_absolute_error_mm"],
                "scan_circumference_abs_error": max(sc["circumference_absolute_error_mm"])}
        out["input"] = "scan"
        out["strain_cv_percent"] = {
            f"{n}_{m:g}_mm": 100 * strain_sd(P, target, k * m, base) / target
            for n, m in maes.items()}
    else:
        a, b = finger.width / 2, finger.depth / 2
        h = 1e-4
        da = (ellipse_perimeter(a + h, b) - ellipse_perimeter(a - h, b)) / (2 * h) / 2
        db = (ellipse_perimeter(a, b + h) - ellipse_perimeter(a, b - h)) / (2 * h) / 2
        out["input"] = "caliper"
        out["strain_cv_percent"] = {
            f"caliper_tem_{t:g}_percent": 100 * strain_sd(
                P, target, t / 100 * math.hypot(da * finger.width, db * finger.depth), base)
            / target for t in src["caliper"]["rel_tem_percent"]}
    out["goal_met"] = {k: bool(v < GOAL_CV_PERCENT) for k, v in out["strain_cv_percent"].items()}
    return out


def size_table(perimeters, material, R0: float, R_fixed: float, sens_sum_Fn: float,
               target: float, measurement_sd_mm: float | None = None) -> dict[str, Any]:
    """Initial strain and sum sensitivity over finger perimeters: the paper's three slots (the
    best slot per finger, i.e. the one closest to the target) vs one personalised strap per
    finger. The personalised strap's strain error comes from the finger measurement
    (:func:`personalised_spread`: the cited caliper and scan errors, both reported). The
    headline ``personalised_strain_cv_percent`` / ``goal_met``: the caliper at the upper end
    of its cited %TEM range (the fingertip is one of the "< 25 mm" breadths), or, when
    ``measurement_sd_mm`` is given, that sd per caliper reading (a what-if). Spreads:
    :data:`SPREAD_DEFINITION`."""
    from designlab.geometry.strap import ArchStrap

    if measurement_sd_mm is not None and not measurement_sd_mm > 0:
        raise ParameterError("measurement_sd_mm", measurement_sd_mm, "> 0 mm")
    base = ArchStrap()
    spread = personalised_spread(perimeters, target, base)
    tem_hi = max(measurement_errors()["caliper"]["rel_tem_percent"]) / 100
    rows = []
    for P in perimeters:
        eps = [initial_strain(base, P, slot=k) for k in range(1, base.slot_count + 1)]
        k = int(np.argmin([abs(e - target) for e in eps]))
        st = prestrain_state(base, P, material, R0, R_fixed, slot=k + 1) if eps[k] >= 0 \
            else None
        # personalised: eps = path / L - 1 with L fitted to the *measured* P;
        # d eps / dP = 1 / L, sd_P = pi / sqrt(2) x sd(width) at a circle
        L = wrap_path(base, P) / (1 + target)
        sd_reading = (measurement_sd_mm if measurement_sd_mm is not None
                      else tem_hi * P / math.pi)
        sd_eps = strain_sd(P, target, math.pi / math.sqrt(2) * sd_reading, base)
        fp = prestrain_state(base, P, material, R0, R_fixed, length=L)
        rows.append({"perimeter_mm": float(P), "slot_strains": eps, "best_slot": k + 1,
                     "best_slot_strain": eps[k],
                     "best_slot_sum_F_n_V_per_N": sens_sum_Fn * st["sensitivity_factor"]
                     if st else None,
                     "personalised_strain": target, "personalised_strain_sd": sd_eps,
                     "caliper_sd_mm": float(sd_reading),
                     "personalised_sum_F_n_V_per_N": sens_sum_Fn * fp["sensitivity_factor"]})

    worst = max(rows, key=lambda r: r["personalised_strain_sd"])
    pers_cv = float(100 * worst["personalised_strain_sd"] / target)
    cited = measurement_sd_mm is None
    # the caliper sd (mm per reading) that just meets the goal: an absolute sd binds on the
    # smallest finger; the cited relative error on the finger the headline is taken at
    need = required_measurement_sd(target, [worst["perimeter_mm"]] if cited
                                   else [r["perimeter_mm"] for r in rows], base)
    return {"rows": rows, "target_strain": target,
            "slots_strain_cv_percent": spread_percent(r["best_slot_strain"] for r in rows),
            "personalised_strain_cv_percent": pers_cv,
            "slots_sum_sensitivity_cv_percent":
                spread_percent(r["best_slot_sum_F_n_V_per_N"] for r in rows),
            "personalised_sum_sensitivity_cv_percent":
                spread_percent(r["personalised_sum_F_n_V_per_N"] for r in rows),
            "measurement_sd_mm": float(worst["caliper_sd_mm"]),
            "measurement_sd_note": (
                f"caliper sd per reading of width and depth on the finger with the largest "
                f"strain sd: {100 * tem_hi:g} % of its breadth, the upper end of the cited "
                "%TEM range (measurement_spread.sources.caliper)" if cited else
                "per caliper reading of width and depth: given (a what-if, not a cited "
                "value)"),
            "measurement_sd_cited": cited,
            "measurement_spread": spread,
            "goal_cv_percent": GOAL_CV_PERCENT,
            "required_measurement_sd_mm_for_goal": need,
            "required_measurement_sd_note": (
                f"on the {worst['perimeter_mm']:g} mm finger (the headline's): "
                f"{100 * math.pi * need / worst['perimeter_mm']:.3g} % of its breadth"
                if cited else "an absolute sd per reading: binds on the smallest finger"),
            "goal_met": bool(pers_cv < GOAL_CV_PERCENT),
            "spread_definition": SPREAD_DEFINITION + " (slots: over the perimeters, the slot "
                                 "closest to the target per finger; personalised strain: the "
                                 "strain sd from the finger measurement error over the target, "
                                 "the largest over the perimeters, i.e. the smallest finger)",
            "pulp_compliance": pulp_compliance(perimeters, target, material, R0, R_fixed),
            "population": "a uniform grid of perimeters over the accepted finger range, NOT "
                          "anthropometric percentiles (no fingertip-size survey could be "
                          "checked: docs/strap.md)"}


# ------------------------------------------------------------------------------ finger scans

def finger_from_scan(path, strap_position: float | None = None) -> Finger:
    """Width, depth and length of a fingertip from a closed surface (STL): its long axis by
    PCA, the tip as the end where the sections shrink, the section at ``strap_position`` mm
    from the tip (default: 40 % of the length, the pulp under the strap) fitted with its
    principal extents (width = larger) and its perimeter (convex hull of the cut, recorded
    as ``Finger.section_perimeter`` and used for the wrap instead of the ellipse)."""
    import trimesh

    try:
        mesh = trimesh.load_mesh(str(path), force="mesh")
    except (ValueError, OSError) as exc:
        raise ParameterError("--scan", str(path), f"a readable STL ({exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) < 20:
        raise ParameterError("--scan", str(path), "a triangle surface with >= 20 faces")
    if not mesh.is_watertight:
        raise ParameterError("--scan", str(path), "a closed (watertight) surface")
    v = mesh.vertices - mesh.vertices.mean(0)
    _, _, Vt = np.linalg.svd(v, full_matrices=False)
    axis = Vt[0]
    s = v @ axis
    length = float(s.max() - s.min())
    # the tip: the end whose last 15 % has the smaller cross extent
    cross = np.linalg.norm(v - np.outer(s, axis), axis=1)
    lo = cross[s < s.min() + 0.15 * length].max()
    hi = cross[s > s.max() - 0.15 * length].max()
    if hi < lo:
        axis, s = -axis, -s
    tip = float(s.min())
    pos = 0.4 * length if strap_position is None else float(strap_position)
    if not 0 < pos < length:
        raise ParameterError("strap_position", pos, f"0 < value < {length:.3g} mm")
    sec = mesh.section(plane_origin=mesh.vertices.mean(0) + (tip + pos) * axis,
                       plane_normal=axis)
    if sec is None:
        raise ParameterError("--scan", str(path), "a surface cut by the plane at the strap")
    pts = np.asarray(sec.vertices) - np.asarray(sec.vertices).mean(0)
    pts = pts - np.outer(pts @ axis, axis)
    _, sv, W = np.linalg.svd(pts, full_matrices=False)
    xy = pts @ W[:2].T                                   # the section in its own plane
    ext = [float(np.ptp(xy[:, i])) for i in range(2)]
    width, depth = max(ext), min(ext)
    if not 1.2 <= length / width <= 6:
        raise ParameterError("--scan", str(path),
                             f"a fingertip-like shape (length / width = {length / width:.2g}; "
                             "allowed 1.2-6)")
    return Finger(round(width, 2), round(depth, 2), round(min(length, LENGTH_RANGE[1]), 2),
                  section_perimeter=round(hull_perimeter(xy), 3))


def hull_perimeter(xy: np.ndarray) -> float:
    """Perimeter (mm) of the convex hull of planar points: the length of a taut band around
    the section (it bridges concavities such as the nail fold)."""
    from scipy.spatial import ConvexHull

    h = ConvexHull(np.asarray(xy, float))
    ring = h.points[h.vertices]                       # counter-clockwise in 2-D
    return float(np.linalg.norm(np.diff(np.vstack([ring, ring[:1]]), axis=0), axis=1).sum())


# ------------------------------------------------------------------------------- fit-strap

def fit_strap(finger: Finger, out, *, target_strain: float | None = None, slots: int = 1,
              edge_length: float = 1.5, perimeters=None, measured=None,
              progress=None) -> dict[str, Any]:
    """Personalised strap for ``finger``: the part, its elastic virtual test on the finger
    (static FEM, TPUs without their Prony stand-ins: the instantaneous sensitivity), the
    electrical design, the size table, ``fit.json`` and the printable two-material 3MF
    (``out/strap/strap.3mf``). ``measured``: :class:`~designlab.fem.materials.MeasuredProperty`
    records of the printed TPUs (``load_measured``), applied with ``with_measured`` before
    anything runs. Everything is checked before anything is written."""
    import time
    from pathlib import Path

    from designlab.atomic import atomic_write_json
    from designlab.fem.materials import get_material, with_measured
    from designlab.geometry.export import export_parts, prepare_part, require_printable
    import designlab.sensors.strap.model as st

    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    records = list(measured or ())

    def mat(name):
        return with_measured(get_material(name), records)

    trace = mat("PI-ETPU")
    target = default_target() if target_strain is None else float(target_strain)
    check_target(target, trace)
    part = fit_part(finger, target, slots)
    say("checking printability")
    prepared = prepare_part(part, "strap")
    require_printable([prepared])
    r = finger.equivalent_radius
    settings = st.StrapModelSettings(edge_length=edge_length, finger_radius=round(r, 4),
                                     slot=(slots + 1) // 2)
    mats = {b: dataclasses.replace(mat(m), prony=None) for b, m in
            (("strap", "NinjaFlex"), ("trace_left", "PI-ETPU"), ("trace_right", "PI-ETPU"))}
    say("virtual test (static FEM)")
    pred = st.run(part, settings=settings, materials=mats, progress=say)
    rep = pred.report
    el = rep["electrical"]
    sens = rep["sensitivity"]["V_per_N"]
    # the paper's strap on the same finger, same model, medium slot
    say("paper strap on this finger")
    from designlab.geometry.strap import ArchStrap

    paper = st.run(ArchStrap(), settings=dataclasses.replace(settings, slot=MEDIUM_SLOT),
                   materials=mats).report
    s0 = paper["sensitivity"]["V_per_N"]["sum"]["F_n"] / paper["prestrain"]["sensitivity_factor"]
    d0 = paper["sensitivity"]["V_per_N"]["diff"]["F_x"] / paper["prestrain"]["sensitivity_factor"]
    R0 = el["resistance_ohm"]["total"]
    table = size_table(perimeters if perimeters is not None else np.arange(40.0, 75.0, 5.0),
                       trace, R0, settings.divider_ohm, s0, target)
    result = {
        "finger_mm": dataclasses.asdict(finger) | {"perimeter": finger.perimeter,
                                                   "perimeter_source": finger.perimeter_source,
                                                   "ellipse_perimeter": finger.ellipse_perimeter,
                                                   "equivalent_radius": r},
        "target_initial_strain": target,
        "target_source": "default: the paper's medium slot on the reference finger (radius "
                         f"{REFERENCE_RADIUS:g} mm), rigid finger" if target_strain is None
                         else "given",
        "strap_parameters": dataclasses.asdict(part),
        "prestrain": rep["prestrain"],
        "sensitivity_V_per_N": {"sum_F_n": sens["sum"]["F_n"], "diff_F_x": sens["diff"]["F_x"]},
        "resolution_mN": el["resolution_mN"],
        "electrical": el,
        "paper_slots_on_this_finger": paper["slots"] | {
            "paper_strap_slots_sensitivity_from": "same FEM, the paper's strap"},
        "size_table": table,
        "this_finger_strain_spread": finger_spread(finger, target),
        "material_stand_ins": rep["material_stand_ins"],
        "measured_materials": [dataclasses.asdict(m) for m in records],
        "model": "elastic (no Prony stand-ins), static FEM of the worn strap on a rigid-finger "
                 "prestrain; see strap_fit module notes",
        "paper_medium_slot_sum_F_n_V_per_N_unstrained": s0,
        "paper_medium_slot_diff_F_x_V_per_N_unstrained": d0,
    }
    say("writing")
    out = Path(out)
    files = export_parts({"strap": part}, out, ("3mf",), png=False).files
    result["timings_s"] = {"total": time.perf_counter() - t0}
    files.append(atomic_write_json(out / "fit.json", result))
    result["files"] = [str(f) for f in files]
    return result
