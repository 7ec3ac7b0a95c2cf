"""Strap sizes for a population of fingers: N straps (lengths and arches, each cut for the
median finger it serves at a target initial strain) or the fewest that keep the initial-strain
spread within a goal, the fingers each fits, their initial strain and predicted sum-channel
sensitivity, the paper's three slots on the same fingers beside them, and a printable 3MF per
size. Model notes: docs/guide/strap_sizes.md.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from designlab.errors import ParameterError
from designlab.sensors.strap.fit import Finger, check_target, default_target, fit_part
from designlab.sensors.strap.population import Population
from designlab.sensors.strap.prestrain import wrap_path

#: the goal of ``--sizes auto``: initial-strain spread (p5-p95 over a size's fingers, percent
#: of their mean) at most this, for at least GOAL_SHARE of the population
GOAL_SPREAD_PERCENT = 10.0
GOAL_SHARE = 0.90
#: the most sizes a run makes (and ``auto`` tries)
MAX_SIZES = 40
#: the shares of each tail a size range may leave to the end sizes (the best one is kept)
TAIL_SHARES = (0.0, 0.005, 0.01, 0.02, 0.03, 0.05)
#: sizes with their own static FEM (spread evenly over the design perimeters); the other sizes'
#: unstrained sensitivity is interpolated between them
FEM_SIZES = 5
FIT_BY = ("perimeter", "breadth")
#: the gauge's fixed divider resistor (the strap model's default, seed 000 Fig. 3)
DIVIDER_OHM = 2200.0


@dataclass(frozen=True)
class Size:
    """One strap size: the finger range it serves and the strap cut for its median finger."""

    index: int
    lo: float                  #: the range's ends in the fit_by measure (mm)
    hi: float
    members: np.ndarray        #: indices of the population's fingers it serves
    design_perimeter: float
    part: Any


def _edges(values: np.ndarray, n: int, tail: float) -> np.ndarray:
    """The n - 1 inner edges: equal widths between the population's ``tail`` and
    ``1 - tail`` quantiles (the end sizes take the tails)."""
    lo, hi = np.quantile(values, [tail, 1 - tail])
    return np.linspace(lo, hi, n + 1)[1:-1]


def _measure(pop: Population, fit_by: str) -> np.ndarray:
    if fit_by not in FIT_BY:
        raise ParameterError("--fit-by", fit_by, "|".join(FIT_BY))
    return pop.perimeter if fit_by == "perimeter" else pop.width


def strains(part, perimeters: np.ndarray, slot: int | None = 1) -> np.ndarray:
    """Initial strain of ``part`` worn at ``slot`` on each perimeter (rigid finger)."""
    return (np.asarray(perimeters, float) + math.pi * part.thickness + part.lug_spacing) \
        / part.engaged_length(slot) - 1.0


def spread_percent(eps: np.ndarray) -> float:
    """The size's initial-strain spread: p5-p95 over its fingers, percent of their mean."""
    eps = np.asarray(eps, float)
    m = float(np.mean(eps))
    return float(100 * (np.percentile(eps, 95) - np.percentile(eps, 5)) / abs(m)) if m else \
        math.inf


def _cut(pop: Population, members: np.ndarray, target: float, base) -> tuple[float, Any]:
    """The strap of a size: :func:`fit_part` for the median perimeter of its fingers."""
    P = float(np.median(pop.perimeter[members]))
    w = float(np.median(pop.width[members]))
    d = float(np.median(pop.depth[members]))
    from designlab.sensors.strap.fit import ellipse_perimeter

    ratio = P / ellipse_perimeter(w / 2, d / 2)
    finger = Finger(w, d, 25.0, section_perimeter=P if abs(ratio - 1) > 1e-9 else 0.0)
    try:
        return P, fit_part(finger, target, 1, base)
    except ParameterError:
        from designlab.geometry.strap import ArchStrap

        base = base or ArchStrap()
        return P, short_cut(base, wrap_path(base, P) / (1 + target))


def _scaled(base, f: float, tab_distance: float):
    """``base`` with its arch scaled by ``f`` and its one slot ``tab_distance`` from the arch
    foot (fit.fit_part's family)."""
    kw = dict(arch_width=base.arch_width * f, arch_height=base.arch_height * f,
              gauge_offset=base.gauge_offset * f, contact_length=base.contact_length * f,
              tab_length=tab_distance + base.slot_end_margin + base.slot_width / 2,
              slot_count=1, slot_pitch=base.slot_pitch)
    return dataclasses.replace(base, **{k: round(v, 3) if isinstance(v, float) else v
                                        for k, v in kw.items()})


@functools.lru_cache(maxsize=8)
def min_arch_scale(base) -> float:
    """The smallest arch scale of ``base`` its rules allow (bisection, just above it)."""
    def ok(f):
        try:
            _scaled(base, f, 5.0)
            return True
        except ParameterError:
            return False

    lo, hi = 0.3, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi * 1.001


def short_cut(base, length: float):
    """A strap of engaged ``length`` too short for :func:`fit_part` (whose tab keeps the
    paper's medium-slot distance): the smallest arch scale the part's rules allow (the gauges
    must fit on the arch), the rest taken off the tabs."""
    f = min_arch_scale(base)
    d = (length - f * base.arc_length) / 2
    try:
        return _scaled(base, f, d)
    except ParameterError as exc:
        raise ParameterError("--sizes", f"a strap of engaged length {length:.3g} mm",
                             f"a length this strap family reaches (arch scale {f:.3g}, tab "
                             f"{d:.3g} mm violates {exc.name}: {exc.allowed})") from None


def partition(pop: Population, n: int, target: float, fit_by: str = "perimeter",
              base=None) -> tuple[list[Size], float]:
    """``n`` sizes over the population: equal-width ranges of the ``fit_by`` measure between
    two tail quantiles (of :data:`TAIL_SHARES`, the one giving the largest share within the
    goal, then the smallest mean spread), each strap cut for its median finger. Returns the
    sizes and the tail share used."""
    v = _measure(pop, fit_by)
    best = None
    for tail in TAIL_SHARES if n > 1 else (0.0,):
        e = _edges(v, n, tail)
        idx = np.searchsorted(e, v, side="right")
        groups = [np.flatnonzero(idx == k) for k in range(n)]
        if any(len(g) < 2 for g in groups):
            continue
        sp = [spread_percent(strains_for(pop, g, target, base)) for g in groups]
        within = sum(len(g) for g, s in zip(groups, sp) if s <= GOAL_SPREAD_PERCENT)
        score = (within, -float(np.average(sp, weights=[len(g) for g in groups])))
        if best is None or score > best[0]:
            best = (score, tail, e, groups)
    if best is None:
        raise ParameterError("--sizes", n, f"at most as many sizes as the population holds "
                             f"fingers two by two ({pop.size} fingers)")
    _, tail, e, groups = best
    ends = np.concatenate([[float(v.min())], e, [float(v.max())]])
    sizes = []
    for k, g in enumerate(groups):
        P, part = _cut(pop, g, target, base)
        sizes.append(Size(k + 1, float(ends[k]), float(ends[k + 1]), g, P, part))
    return sizes, tail


def strains_for(pop: Population, members: np.ndarray, target: float, base=None) -> np.ndarray:
    """The initial strain on ``members`` of a strap cut for their median perimeter (the wrap
    path of ``base``: the cut keeps the band's thickness and lugs)."""
    from designlab.geometry.strap import ArchStrap

    base = base or ArchStrap()
    P = pop.perimeter[members]
    L = wrap_path(base, float(np.median(P))) / (1 + target)
    return (P + math.pi * base.thickness + base.lug_spacing) / L - 1.0


def share_within(pop: Population, sizes: list[Size]) -> float:
    """The share of the population in sizes whose strain spread meets the goal."""
    n = sum(len(s.members) for s in sizes
            if spread_percent(strains(s.part, pop.perimeter[s.members])) <= GOAL_SPREAD_PERCENT)
    return n / pop.size


def auto_count(pop: Population, target: float, fit_by: str = "perimeter",
               base=None) -> tuple[int, list[dict[str, float]]]:
    """The fewest sizes (up to :data:`MAX_SIZES`) whose strain spread meets
    :data:`GOAL_SPREAD_PERCENT` for at least :data:`GOAL_SHARE` of the population, and the
    share reached per size count tried. One-line error when no count reaches it."""
    tried = []
    for n in range(1, MAX_SIZES + 1):
        try:
            sizes, _ = partition(pop, n, target, fit_by, base)
        except ParameterError:
            break
        share = share_within(pop, sizes)
        tried.append({"sizes": n, "share_within_goal": share})
        if share >= GOAL_SHARE:
            return n, tried
    best = max(tried, key=lambda r: r["share_within_goal"])
    raise ParameterError("--sizes", "auto", f"a count that keeps the initial-strain spread "
                         f"<= {GOAL_SPREAD_PERCENT:g} % for >= {100 * GOAL_SHARE:g} % of the "
                         f"population: none up to {len(tried)} sizes fitted by {fit_by} (best "
                         f"{100 * best['share_within_goal']:.3g} % at {best['sizes']}); give N, "
                         "or fit by perimeter")


# ------------------------------------------------------------------------------ sensitivity

def sensitivity_factor(eps: np.ndarray, R0: float, material,
                       R_fixed: float = DIVIDER_OHM) -> np.ndarray:
    """The prestrain's factor on the unstrained linear sensitivity per finger (the strap
    model's, :func:`prestrain.operating_point` over :func:`prestrain.neo_hooke`'s tangent,
    vectorised: the gauge's divider slope at its strained resistance over the unstrained one,
    divided by the neo-Hookean tangent over E; 1 when slack)."""
    from designlab.fem.transducers import divider_slope

    e = np.maximum(np.asarray(eps, float), 0.0)
    g, q = material.gauge_factor, material.gauge_quadratic
    R = R0 * (1.0 + g * e + q * e ** 2)
    electrical = (g + 2 * q * e) * divider_slope(R, R_fixed) / (g * divider_slope(R0, R_fixed))
    tangent = (1.0 + 2.0 * (1.0 + e) ** -3) / 3.0
    return np.where(np.asarray(eps, float) > 0, electrical / tangent, 1.0)


def fem_sensitivity(part, perimeter: float, materials) -> float:
    """The strap model's static FEM (elastic materials, stress-free wrap) on a circular
    finger of ``perimeter``: the unstrained sum-channel sensitivity to F_n (V/N)."""
    import designlab.sensors.strap.model as st

    settings = st.StrapModelSettings(finger_radius=round(perimeter / (2 * math.pi), 4))
    rep = st.run(part, settings=settings, materials=materials).report
    return float(rep["sensitivity"]["V_per_N"]["sum"]["F_n"])


def elastic_materials() -> dict[str, Any]:
    """The strap's materials without their Prony stand-ins (the instantaneous response)."""
    from designlab.fem.materials import get_material

    return {b: dataclasses.replace(get_material(m), prony=None) for b, m in
            (("strap", "NinjaFlex"), ("trace_left", "PI-ETPU"), ("trace_right", "PI-ETPU"))}


def unstrained_sensitivities(designs: list[tuple[float, Any]],
                             fem: Callable[[Any, float], float] | None,
                             progress: Callable[[str], None]) -> tuple[list, list[str]]:
    """Per design (perimeter, part): the unstrained sum sensitivity (V/N) and its source. The
    static FEM runs on at most :data:`FEM_SIZES` designs evenly spread over the perimeters;
    the others are interpolated linearly in the design perimeter. ``fem`` None: none
    (sensitivities None)."""
    if fem is None:
        return [None] * len(designs), ["not computed"] * len(designs)
    n = len(designs)
    order = np.argsort([P for P, _ in designs])
    pick = sorted({int(order[round(i)]) for i in np.linspace(0, n - 1, min(n, FEM_SIZES))})
    solved = {}
    for j in pick:
        progress(f"static FEM {len(solved) + 1}/{len(pick)}")
        solved[j] = fem(designs[j][1], designs[j][0])
    xs = np.array([designs[j][0] for j in pick])
    ys = np.array([solved[j] for j in pick])
    srt = np.argsort(xs)
    out, src = [], []
    for j, (P, _) in enumerate(designs):
        if j in solved:
            out.append(solved[j])
            src.append("static FEM of this size on its median finger")
        else:
            out.append(float(np.interp(P, xs[srt], ys[srt])))
            src.append("interpolated between the FEM sizes in design perimeter")
    return out, src


# ------------------------------------------------------------------------------------ tables

def _pct(v: np.ndarray) -> dict[str, float]:
    return {f"p{p}": float(np.percentile(v, p)) for p in (5, 50, 95)}


def group_row(pop: Population, members: np.ndarray, eps: np.ndarray, s0, factor) -> dict:
    """The fingers of one size or slot: their ranges, share, strain and sensitivity."""
    row = {"fingers": int(len(members)), "share": len(members) / pop.size,
           "breadth_mm": {"min": float(pop.width[members].min()),
                          "max": float(pop.width[members].max()),
                          **_pct(pop.width[members])},
           "perimeter_mm": {"min": float(pop.perimeter[members].min()),
                            "max": float(pop.perimeter[members].max()),
                            **_pct(pop.perimeter[members])},
           "initial_strain": _pct(eps), "initial_strain_mean": float(np.mean(eps)),
           "strain_spread_percent": spread_percent(eps),
           "slack_share": float(np.mean(eps <= 0)),
           "sensitivity_factor": _pct(factor)}
    row["within_goal"] = bool(row["strain_spread_percent"] <= GOAL_SPREAD_PERCENT)
    row["sum_F_n_V_per_N"] = None if s0 is None else _pct(s0 * factor)
    return row


def with_pulp(part, perimeter: float, material, slot: int) -> dict[str, float]:
    """The initial strain on ``perimeter`` when the pulp under the band gives, at both ends of
    the cited fingertip modulus (:func:`fit.compliant_initial_strain`: a confined linear layer
    3 mm deep on a rigid bone, a lower bound on the drop)."""
    from designlab.sensors.strap.fit import cited_pulp_moduli, compliant_initial_strain

    return {f"E_{E:g}_MPa": float(compliant_initial_strain(part, perimeter, material, slot=slot,
                                                           pulp_E=E)["initial_strain"])
            for E in cited_pulp_moduli()}


def paper_slots(pop: Population, target: float, material, s0, base=None) -> dict[str, Any]:
    """The paper's strap on the same fingers: each finger on the slot closest to the target
    (as a wearer would choose), per slot the fingers it takes and their strain and
    sensitivity."""
    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap.electrical import gauge_resistance

    base = base or ArchStrap()
    eps_all = np.column_stack([strains(base, pop.perimeter, k)
                               for k in range(1, base.slot_count + 1)])
    best = np.argmin(np.abs(eps_all - target), axis=1)
    R0 = gauge_resistance(base, 0.0, material)["total"]
    rows, share = [], 0
    for k in range(base.slot_count):
        m = np.flatnonzero(best == k)
        if not len(m):
            rows.append({"slot": k + 1, "fingers": 0, "share": 0.0})
            continue
        eps = eps_all[m, k]
        row = {"slot": k + 1, "engaged_length_mm": float(base.engaged_length(k + 1)),
               **group_row(pop, m, eps, s0, sensitivity_factor(eps, R0, material)),
               "p50_finger_strain_with_pulp": with_pulp(
                   base, float(np.median(pop.perimeter[m])), material, k + 1)}
        share += row["fingers"] * row["within_goal"]
        rows.append(row)
    chosen = eps_all[np.arange(pop.size), best]
    return {"rows": rows, "share_within_goal": share / pop.size,
            "strain_spread_percent_all": spread_percent(chosen),
            "slack_share": float(np.mean(chosen <= 0)),
            "unstrained_sum_F_n_V_per_N": s0,
            "rule": "each finger on the slot whose initial strain is closest to the target"}


def size_rows(pop: Population, sizes: list[Size], s0s: list, sources: list[str],
              material, fit_by: str) -> list[dict[str, Any]]:
    """The size table: per size its strap, the fingers it serves, strain and sensitivity."""
    from designlab.sensors.strap.electrical import gauge_resistance

    rows = []
    for s, s0, src in zip(sizes, s0s, sources):
        eps = strains(s.part, pop.perimeter[s.members])
        R0 = gauge_resistance(s.part, 0.0, material)["total"]
        rows.append({"size": s.index, f"{fit_by}_range_mm": [s.lo, s.hi],
                     "design_perimeter_mm": s.design_perimeter,
                     "engaged_length_mm": float(s.part.engaged_length(1)),
                     "arch_width_mm": s.part.arch_width, "arch_height_mm": s.part.arch_height,
                     "gauge_resistance_ohm": float(R0),
                     **group_row(pop, s.members, eps, s0,
                                 sensitivity_factor(eps, R0, material)),
                     "unstrained_sum_F_n_V_per_N": s0, "sensitivity_source": src,
                     "p50_finger_strain_with_pulp": with_pulp(
                         s.part, float(np.median(pop.perimeter[s.members])), material, 1)})
    return rows


#: ``--pulp-model``: where the hyperelastic pulp model runs (perimeter percentiles)
PULP_MODEL_CHOICES = {"off": (), "p50": (50,), "p5,p50,p95": (5, 50, 95)}
#: the pulp model's mesh edge (mm) in the sizes run (worn_pulp.EDGE_MM's 3 mm differs by
#: <= 4 % in the ratio, docs/guide/strap_sizes.md)
PULP_EDGE_MM = 4.0


def pulp_model(pop: Population, sizes: list[Size], percentiles, progress) -> dict[str, Any]:
    """The hyperelastic pulp model (:func:`worn_pulp.worn_pulp`) at the fingers of the
    population's perimeter ``percentiles``, each on the size that serves it at its initial
    strain: the sum sensitivity with the hyperelastic pulp against the present model's, at
    the ends of the cited pulp modulus (a band)."""
    from designlab.sensors.strap.worn_pulp import ASSUMPTIONS, worn_pulp

    rows = []
    for q in percentiles:
        i = int(np.argmin(np.abs(pop.perimeter - np.percentile(pop.perimeter, q))))
        size = next(s for s in sizes if i in set(s.members.tolist()))
        P = float(pop.perimeter[i])
        eps = float(strains(size.part, np.array([P]))[0])
        progress(f"pulp model at the p{q} finger")
        r = worn_pulp(size.part, P / (2 * math.pi), initial_strain=max(eps, 0.0),
                      edge_length=PULP_EDGE_MM)
        rows.append({"percentile": q, "perimeter_mm": P, "size": size.index,
                     "initial_strain_rigid": eps,
                     "present_sum_F_n_V_per_N": r["present_sum_F_n_V_per_N"],
                     "band": r["band"],
                     "by_modulus": [{k: v for k, v in m.items() if k != "solves"}
                                    for m in r["by_modulus"]],
                     "cells": r["cells"]})
    return {"fingers": rows, "edge_length_mm": PULP_EDGE_MM,
            "what": "the worn strap on a nearly incompressible neo-Hookean pulp: the wrap as a "
                    "geometrically nonlinear prestress step, then a small F_n increment; "
                    "hyperelastic_over_present is the pulp model's factor on the sum "
                    "sensitivity of the tables (the present model: linear Winkler springs "
                    "times the closed-form prestrain factor), nonlinear_over_linear the same "
                    "pulp linear against nonlinear; min / max over the cited pulp moduli",
            "assumptions": list(ASSUMPTIONS) if rows else [],
            "computed": bool(rows)}


@dataclass(frozen=True)
class SizesRequest:
    """What to size: N sizes or ``"auto"``, fitted by perimeter or breadth, at a target
    initial strain (None: the paper's medium slot on the reference finger)."""

    sizes: int | str = 5
    fit_by: str = "perimeter"
    target_strain: float | None = None
    #: the population's perimeter percentiles at which the hyperelastic pulp model runs
    #: (:data:`PULP_MODEL_CHOICES`: "off", "p50" or "p5,p50,p95")
    pulp_model: str = "p50"

    def pulp_percentiles(self) -> tuple[int, ...]:
        """The percentiles of :attr:`pulp_model`; one-line error otherwise."""
        if self.pulp_model not in PULP_MODEL_CHOICES:
            raise ParameterError("--pulp-model", self.pulp_model,
                                 " | ".join(PULP_MODEL_CHOICES))
        return PULP_MODEL_CHOICES[self.pulp_model]

    def count(self) -> int | None:
        """N, or None for auto; one-line error otherwise."""
        if self.sizes == "auto":
            return None
        try:
            n = int(str(self.sizes))
        except ValueError:
            raise ParameterError("--sizes", self.sizes, f"a whole number 1-{MAX_SIZES} or "
                                 "auto") from None
        if not 1 <= n <= MAX_SIZES:
            raise ParameterError("--sizes", self.sizes, f"1 <= N <= {MAX_SIZES}, or auto")
        return n


def plan_sizes(pop: Population, request: SizesRequest) -> dict[str, Any]:
    """Everything but the FEM and the files: the target, the size count (auto's search), the
    sizes and their straps. Raises a one-line error on bad input before any work is done."""
    from designlab.fem.materials import get_material

    trace = get_material("PI-ETPU")
    n = request.count()
    request.pulp_percentiles()
    _measure(pop, request.fit_by)
    target = default_target() if request.target_strain is None else float(request.target_strain)
    check_target(target, trace)
    tried = None
    if n is None:
        n, tried = auto_count(pop, target, request.fit_by)
    sizes, tail = partition(pop, n, target, request.fit_by)
    hi = trace.max_elongation
    for s in sizes:
        p95 = float(np.percentile(strains(s.part, pop.perimeter[s.members]), 95))
        if hi is not None and p95 >= hi:
            raise ParameterError("--sizes", request.sizes, f"sizes whose p95 initial strain "
                                 f"stays below {hi:g} ({trace.name} elongation at break; size "
                                 f"{s.index}: {p95:.3g})")
    return {"target": target, "n": n, "tried": tried, "sizes": sizes, "tail": tail,
            "material": trace}


def strap_sizes(pop: Population, request: SizesRequest, out=None, *, fem: bool = True,
                progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The size table for ``pop`` with the paper's slots beside it; with ``out``, also
    ``sizes.json``, ``sizes.md`` and ``size_K/size_K.3mf`` per size (all checked before
    anything is written). ``fem`` False: strains and prestrain factors only (no
    sensitivities in V/N)."""
    import time

    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    plan = plan_sizes(pop, request)
    sizes, target, trace = plan["sizes"], plan["target"], plan["material"]
    prepared = _prepare(sizes) if out is not None else None
    mats = elastic_materials() if fem else None
    run_fem = (lambda part, P: fem_sensitivity(part, P, mats)) if fem else None
    s0s, sources = unstrained_sensitivities([(s.design_perimeter, s.part) for s in sizes],
                                            run_fem, say)
    rows = size_rows(pop, sizes, s0s, sources, trace, request.fit_by)
    from designlab.geometry.strap import ArchStrap

    say("paper strap")
    P50 = float(np.median(pop.perimeter))
    s0_paper = fem_sensitivity(ArchStrap(), P50, mats) if fem else None
    slots = paper_slots(pop, target, trace, s0_paper)
    within = sum(r["fingers"] for r in rows if r["within_goal"]) / pop.size
    pulp = pulp_model(pop, sizes, request.pulp_percentiles() if fem else (), say)
    result = {
        "population": pop.describe(), "target_initial_strain": target,
        "target_source": "the paper's medium slot on the reference finger (rigid finger)"
        if request.target_strain is None else "given",
        "fit_by": request.fit_by, "sizes_requested": request.sizes, "sizes": plan["n"],
        "auto_search": plan["tried"], "tail_share_to_end_sizes": plan["tail"],
        "goal": {"strain_spread_percent": GOAL_SPREAD_PERCENT, "share": GOAL_SHARE,
                 "spread": "p5-p95 of the initial strain over a size's fingers, percent of "
                           "their mean"},
        "share_within_goal": within, "size_table": rows, "paper_slots": slots,
        "pulp_model": pulp,
        "model": {"strain": "rigid finger: path around the finger's perimeter over the "
                            "strap's engaged length (prestrain.initial_strain)",
                  "sensitivity": "the strap model's fast path: unstrained sum sensitivity "
                                 "from a static FEM (elastic, stress-free wrap) per size on "
                                 "its median finger (at most 5 FEM sizes, others "
                                 "interpolated), times each finger's prestrain factor "
                                 "(neo-Hookean tangent, gauge operating point); no FEM per "
                                 "finger" if fem else "not computed",
                  "p50_finger_strain_with_pulp": "the median finger's initial strain with "
                                                 "the pulp compressed under the band at the "
                                                 "ends of the cited fingertip modulus "
                                                 "(fit.compliant_initial_strain); the table's "
                                                 "strains are on a rigid finger",
                  "paper_slots_sensitivity": "the paper's strap, static FEM on the "
                                             "population's median finger, times each "
                                             "finger's prestrain factor"},
        "assumptions": pop.describe()["assumptions"],
    }
    if out is not None:
        result["files"] = _write(out, prepared, result, say)
    result["timings_s"] = {"total": time.perf_counter() - t0}
    return result


def _prepare(sizes: list[Size]):
    """Build and check every size's part before any work is written."""
    from designlab.geometry.export import prepare_part, require_printable

    prepared = [prepare_part(s.part, f"size_{s.index}") for s in sizes]
    require_printable(prepared)
    return prepared


def _write(out, prepared, result: dict[str, Any], say) -> list[str]:
    """The 3MF of each size, sizes.json and sizes.md."""
    from pathlib import Path

    from designlab.atomic import atomic_write_bytes, atomic_write_json
    from designlab.geometry.export import write_all

    say("writing")
    out = Path(out)
    files = [str(f) for f in write_all(prepared, out, ("3mf",), False)]
    files.append(str(atomic_write_bytes(out / "sizes.md", markdown(result).encode("utf-8"))))
    result["files"] = files + [str(out / "sizes.json")]
    atomic_write_json(out / "sizes.json", result)
    return result["files"]


def _fmt3(d: dict | None, scale: float = 1.0, f: str = ".3g") -> str:
    if d is None:
        return "-"
    return " / ".join(format(scale * d[k], f) for k in ("p5", "p50", "p95"))


def table_head(key: str) -> list[str]:
    """The markdown header of a size or slot table."""
    return [f"| {key} | breadth p5-p95 (mm) | perimeter range (mm) | share | initial strain "
            "p5 / p50 / p95 | spread % | sum F_n mV/N p5 / p50 / p95 |",
            "|---|---|---|---|---|---|---|"]


def table_lines(rows: list[dict], key: str) -> list[str]:
    """Markdown rows of a size or slot table."""
    lines = []
    for r in rows:
        if not r.get("fingers"):
            lines.append(f"| {key} {r[key]} | - | - | 0 | - | - | - |")
            continue
        b, p = r["breadth_mm"], r["perimeter_mm"]
        lines.append(
            f"| {key} {r[key]} | {b['p5']:.1f}-{b['p95']:.1f} | {p['min']:.1f}-{p['max']:.1f} | "
            f"{100 * r['share']:.1f} % | {_fmt3(r['initial_strain'])} | "
            f"{r['strain_spread_percent']:.3g}{'' if r['within_goal'] else ' (over)'} | "
            f"{_fmt3(r['sum_F_n_V_per_N'], 1e3)} |")
    return lines


def markdown(result: dict[str, Any]) -> str:
    """The size table and the paper's slots on the same fingers, as markdown."""
    pop, sl = result["population"], result["paper_slots"]
    lines = [f"# Strap sizes: {pop['group']}, {pop['fingers']} fingers",
             "", f"Target initial strain {result['target_initial_strain']:.4g} "
             f"({result['target_source']}); sizes fitted by {result['fit_by']}; "
             f"{result['sizes']} sizes; share within the "
             f"{result['goal']['strain_spread_percent']:g} % spread: "
             f"{100 * result['share_within_goal']:.1f} %.", "", *table_head("size"),
             *table_lines(result["size_table"], "size"), "",
             f"The paper's three slots on the same fingers ({sl['rule']}): share within "
             f"the goal {100 * sl['share_within_goal']:.1f} %, slack "
             f"{100 * sl['slack_share']:.1f} %.", "", *table_head("slot"),
             *table_lines(sl["rows"], "slot"), "", "Assumptions:", "",
             *(f"- {a}" for a in result["assumptions"]), "",
             f"Sensitivity: {result['model']['sensitivity']}.", "",
             *pulp_lines(result.get("pulp_model"))]
    return "\n".join(lines)


def pulp_lines(pm: dict | None) -> list[str]:
    """The pulp model's markdown: per finger the band of its factors on the sensitivity."""
    if not pm or not pm["computed"]:
        return []
    lines = ["## The pulp model", "", pm["what"] + ".", "",
             "| finger | size | initial strain (rigid) | gauge strain worn | hyperelastic / "
             "present | linear solid / present | nonlinear / linear |", "|---|---|---|---|---|---|---|"]
    for r in pm["fingers"]:
        b = r["band"]

        def rng(k, f=".3g"):
            return f"{b[k]['min']:{f}}-{b[k]['max']:{f}}"
        lines.append(f"| p{r['percentile']} ({r['perimeter_mm']:.1f} mm) | {r['size']} | "
                     f"{r['initial_strain_rigid']:.3g} | {rng('gauge_strain_worn')} | "
                     f"{rng('hyperelastic_over_present')} | {rng('linear_solid_over_present')} "
                     f"| {rng('nonlinear_over_linear')} |")
    return lines + ["", "Pulp model assumptions:", "", *(f"- {a}" for a in pm["assumptions"]),
                    ""]
