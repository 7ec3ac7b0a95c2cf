"""Seed 000: the TPU arch strap with two embedded conductive-TPU strain-gauge meanders.

The strap is printed flat (layer height 0.1 mm: the 0.2 mm gauge is "two layers" thick, which only
makes sense for a flat print), so the *arch* is its planform: a circular-arc band of width
``strap_width`` whose centreline runs through the two arch feet ``(+-arch_width/2, 0)`` and the apex
``(0, arch_height)``, continued by straight end tabs with ``slot_count`` length-adjustment slots
each. Worn, the bottom face (``z = 0``) lies on the finger pad and the tabs hook onto the nail
plate; the gauges sit left and right of the apex and read normal (sum) and shear (difference).

Frame: print bed ``z = 0``, strap top ``z = thickness``; x across the arch, apex on +y; mm.

Bodies: ``strap`` (NinjaFlex, extruder 1) = outline minus slots minus the trace volume,
``trace_left`` / ``trace_right`` (PI-ETPU, extruder 2): meanders of ``legs`` legs running along the
strap (they see its longitudinal strain), ``trace_thickness`` thick, ``trace_cover`` above the
bed, each ending in two connection pads that rise to the top surface (wires are melted into them),
and ``nail_plate`` (NinjaFlex, not meshed) with two lugs that fit the slots, placed beside the strap
on the bed. Strap and traces do not overlap and together fill the slotted outline.

The paper gives only width 15 mm, thickness 0.6 mm, gauge 0.2 mm, layer 0.1 mm and three slots;
the planform, meander and pad sizes are our estimates (meander line 0.8 mm = two 0.4 mm nozzle
lines, far above the 0.4 mm minimum).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from build123d import Plane, Pos, RectangleRounded, Sketch, SlotOverall, extrude, mirror

from designlab.errors import ParameterError
from designlab.geometry.body import Body, FacetSelector
from designlab.geometry.printability import MM_WALL_FACTOR
from designlab.geometry.solids import annular_sector, polygon_face, single_solid
from designlab.params import (above, at_least, at_most, field_range, rng, validate,
                              whole_numbers, within)

#: nozzle diameter (mm): the narrowest printable meander line and gap
NOZZLE = 0.4
#: narrowest embedded trace line (mm): a second-extruder line inside the strap needs
#: ``MM_WALL_FACTOR`` nozzle widths (PrusaSlicer drops a 0.6 mm one; see printability)
MIN_TRACE = MM_WALL_FACTOR * NOZZLE
#: squares of a right-angle bend of a strip of constant width (Hall, "Resistance calculations
#: for thin film patterns", Thin Solid Films 1 (1967) 277-295: 0.559)
CORNER_SQUARES = 0.559


@dataclass(frozen=True)
class ArchStrap:
    """Parameters of the arch strap (mm, counts); defaults: seed 000 where stated, else ours."""

    strap_width: float = field(default=15.0, metadata=rng(8, 30, unit="mm", doc="seed 000: 15"))
    thickness: float = field(default=0.6, metadata=rng(0.3, 3, unit="mm", doc="seed 000: 0.6"))
    layer_height: float = field(default=0.1, metadata=rng(0.05, 0.4, unit="mm",
                                                          doc="seed 000: 0.1"))
    trace_thickness: float = field(default=0.2, metadata=rng(0.05, 1.0, unit="mm",
                                                             doc="seed 000: 0.2 (two layers)"))
    trace_cover: float = field(default=0.2, metadata=rng(0.05, 1.5, unit="mm",
                                                         doc="TPU under the trace (finger side)"))
    arch_width: float = field(default=40.0, metadata=rng(16, 100, unit="mm",
                                                         doc="chord between the arch feet"))
    arch_height: float = field(default=8.0, metadata=rng(1, 50, unit="mm",
                                                         doc="rise of the arch centreline"))
    tab_length: float = field(default=14.0, metadata=rng(
        4, 40, unit="mm", doc="straight end tab beyond each arch foot, holding the slots (ours)"))
    slot_count: int = field(default=3, metadata=rng(1, 6, doc="seed 000: 3 per end"))
    slot_length: float = field(default=9.0, metadata=rng(1, 25, unit="mm", doc="across strap"))
    slot_width: float = field(default=1.6, metadata=rng(0.8, 5, unit="mm",
                                                        doc="along strap; the lug is 0.3 narrower"))
    slot_pitch: float = field(default=3.5, metadata=rng(
        1, 10, unit="mm", doc="centre-to-centre spacing of the length-adjustment slots (ours)"))
    slot_end_margin: float = field(default=2.0, metadata=rng(0.8, 10, unit="mm",
                                                             doc="strap end to last slot"))
    legs: int = field(default=4, metadata=rng(2, 16, doc="meander legs (even)"))
    trace_width: float = field(default=0.8, metadata=rng(MIN_TRACE, 4, unit="mm",
                                                         doc=">= two 0.4 mm nozzle lines"))
    trace_gap: float = field(default=0.8, metadata=rng(
        NOZZLE, 4, unit="mm", doc=("gap between neighbouring meander legs, at least one 0.4 mm "
                                   "nozzle line")))
    gauge_length: float = field(default=8.0, metadata=rng(1, 40, unit="mm",
                                                          doc="leg length along the strap"))
    gauge_offset: float = field(default=7.0, metadata=rng(0.5, 60, unit="mm",
                                                          doc="apex to gauge centre, arc length"))
    lead_length: float = field(default=1.6, metadata=rng(
        0, 15, unit="mm", doc=("trace from the meander to its connection pads, along the arch (0: "
                               "none, with legs = 2 and pad_width = trace_width)")))
    pad_width: float = field(default=2.0, metadata=rng(
        0.8, 8, unit="mm", doc=("connection pad width across the strap (wires are melted into the "
                                "pads)")))
    pad_length: float = field(default=3.0, metadata=rng(
        0.8, 10, unit="mm", doc="connection pad length along the strap"))
    edge_margin: float = field(default=1.0, metadata=rng(0.4, 6, unit="mm",
                                                         doc="TPU beside the traces"))
    contact_length: float = field(default=16.0, metadata=rng(1, 100, unit="mm",
                                                             doc="finger pad contact, arc length"))
    nail_plate_length: float = field(default=16.0, metadata=rng(
        6, 40, unit="mm", doc=("nail plate along the finger; printed beside the strap, its two "
                               "lugs fit the slots")))
    nail_plate_width: float = field(default=12.0, metadata=rng(
        6, 40, unit="mm", doc="nail plate across the finger (at least slot_length)"))
    nail_plate_thickness: float = field(default=1.2, metadata=rng(
        0.4, 5, unit="mm", doc="nail plate thickness"))

    def __post_init__(self):
        whole_numbers(self, ("legs", "slot_count"))
        validate(self)
        self._check()

    # ----------------------------------------------------------------- derived geometry (mm, rad)
    @property
    def radius(self) -> float:
        """Radius of the arch centreline."""
        w, h = self.arch_width, self.arch_height
        return (w * w / 4 + h * h) / (2 * h)

    @property
    def center(self) -> tuple[float, float]:
        """Centre of the arch circle in the bed plane."""
        return (0.0, self.arch_height - self.radius)

    @property
    def half_angle(self) -> float:
        """Half the angle the arch spans (rad)."""
        return math.atan2(self.arch_width / 2, self.radius - self.arch_height)

    @property
    def arc_length(self) -> float:
        """Centreline length of the arch (without tabs)."""
        return 2 * self.half_angle * self.radius

    @property
    def leg_offsets(self) -> np.ndarray:
        """Radial offsets of the meander legs from the centreline (mm, inner to outer)."""
        n, p = self.legs, self.trace_width + self.trace_gap
        return (np.arange(n) - (n - 1) / 2) * p

    @property
    def trace_z(self) -> tuple[float, float]:
        """Bottom and top of the embedded trace layer."""
        return self.trace_cover, self.trace_cover + self.trace_thickness

    def gauge_angles(self) -> dict[str, float]:
        """Angles (rad, right gauge) of the leg ends ``a``/``b``, the turn width ``turn``, and the
        pad ``p0``/``p1`` (left gauge: mirrored)."""
        R = self.radius
        r_min = R + float(self.leg_offsets[0]) - self.trace_width / 2
        a = (self.gauge_offset - self.gauge_length / 2) / R
        b = (self.gauge_offset + self.gauge_length / 2) / R
        turn = self.trace_width / r_min
        p0 = b + self.lead_length / R
        p1 = p0 + self.pad_length / R
        return {"a": a, "b": b, "turn": turn, "p0": p0, "p1": p1}

    # ------------------------------------------------------------- conductor path (electrical)
    def trace_squares(self) -> dict[str, float]:
        """Resistance of one meander in *squares* (path length / width of each segment), at the
        trace thickness: ``R = rho / trace_thickness * squares`` (geometry only, no material).

        The conducting path, pad to pad: lead (outer leg beyond ``b``) -> leg 0 -> turn -> leg 1
        -> ... -> leg n-1 -> lead. ``legs``: the n arcs between the angles ``a`` and ``b`` at
        their radii (their sum is n x gauge_length: the offsets are symmetric); ``turns``: n - 1
        turn blocks, each two right-angle corners (0.559 squares each, the conformal-mapping
        value for a bend of a strip of constant width: Hall, Thin Solid Films 1 (1967) 277) and
        the radial run across the gap (trace_gap / trace_width); ``leads``: the two leads;
        ``pads``: the current enters each pad at its inner end and leaves through the wire
        melted into its top face: half the pad length at the pad's width and full height
        (trace_cover to the top face), converted to squares at the trace thickness (our
        estimate of the spreading path)."""
        R, w = self.radius, self.trace_width
        ang = self.gauge_angles()
        legs = float(sum((ang["b"] - ang["a"]) * (R + y) for y in self.leg_offsets)) / w
        turns = (self.legs - 1) * (2 * CORNER_SQUARES + self.trace_gap / w)
        y0, y1 = float(self.leg_offsets[0]), float(self.leg_offsets[-1])
        leads = self.lead_length * ((R + y0) + (R + y1)) / R / w
        pad_height = self.thickness - self.trace_cover
        pads = 2 * (self.pad_length / 2) / self.pad_width * self.trace_thickness / pad_height
        return {"legs": legs, "turns": turns, "leads": leads, "pads": pads,
                "total": legs + turns + leads + pads}

    @property
    def lug_spacing(self) -> float:
        """Centre distance of the two nail-plate lugs (mm)."""
        return 2 * self.lug_x

    @property
    def lug_x(self) -> float:
        """Lug centre offset from the nail-plate centre (mm): 1.5 mm rim beside the lug."""
        return self.nail_plate_length / 2 - self.slot_width / 2 - 1.5

    def slot_distances(self) -> np.ndarray:
        """Distance (mm, along the tab) from the arch foot to each slot centre, slot 1 = the one
        nearest the strap end (longest strap) ... slot ``slot_count`` (shortest)."""
        k = np.arange(self.slot_count)
        return self.tab_length - self.slot_end_margin - self.slot_width / 2 - k * self.slot_pitch

    def engaged_length(self, slot: int) -> float:
        """Unstretched centreline length between the centres of the two engaged slots (mm):
        the arch plus the tab up to slot ``slot`` (1-based) on both ends."""
        if not 1 <= slot <= self.slot_count:
            raise ParameterError("slot", slot, f"1 <= value <= {self.slot_count} (slot_count)")
        return self.arc_length + 2 * float(self.slot_distances()[slot - 1])

    def gauge_offset_range(self) -> tuple[float, float]:
        """Allowed ``gauge_offset`` given the other parameters: the two meanders keep
        ``trace_gap`` apart at the apex and the pads stay on the arch (mm)."""
        R = self.radius
        lo = self.gauge_length / 2 + self.trace_gap / 2 + self.gauge_angles()["turn"] * R
        hi = self.half_angle * R - self.edge_margin - self.gauge_length / 2 \
            - self.lead_length - self.pad_length
        return lo, hi

    def _arch_width_for(self, short: float) -> float:
        """Smallest arch_width (same arch_height) whose half arc is ``short`` mm longer."""
        def half_arc(aw: float) -> float:
            h = min(self.arch_height, aw / 2)
            R = (aw * aw / 4 + h * h) / (2 * h)
            return math.atan2(aw / 2, R - h) * R
        target = half_arc(self.arch_width) + short
        lo, hi = self.arch_width, field_range(ArchStrap, "arch_width")[1]
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if half_arc(mid) < target else (lo, mid)
        return hi

    def _arch_width_for_radius(self, radius: float) -> float:
        """Smallest arch_width (same arch_height) whose arch radius is at least ``radius``."""
        h = self.arch_height
        return 2 * math.sqrt(max(2 * h * radius - h * h, 0.0))

    def _check_legs_fit(self, avail: float, need: float) -> None:
        """The meanders (``need`` mm across) do not fit in ``avail`` = strap_width - 2 edge
        margins: name the first parameter whose allowed range, given the others, is not empty
        and inside its documented range; when no single parameter can make room, name the
        first one not yet at its most room-giving documented end (with that end as the bound)."""
        n, w, g, pad, em, sw = (self.legs, self.trace_width, self.trace_gap, self.pad_width,
                                self.edge_margin, self.strap_width)

        def lo_of(name):
            return field_range(ArchStrap, name)[0]

        def hi_of(name):
            return field_range(ArchStrap, name)[1]

        w_max = min((avail - (n - 1) * g) / n, (avail - pad) / (n - 1) - g)
        if above(w_max, lo_of("trace_width")):
            at_most("trace_width", w, w_max, f"strap_width - 2 edge margins, {n} legs, gap "
                    f"{g:g}, pad {pad:g}")
        pad_max = avail - (n - 1) * (w + g)
        if above(pad_max, max(w, lo_of("pad_width"))):
            at_most("pad_width", pad, pad_max,
                    f"strap_width - 2 edge margins - {n - 1} x (trace_width + trace_gap)")
        sw_need = 2 * em + need
        arch_sw = 2 * (self.radius - 2)  # the strap must stay inside the arch
        why = f"2 edge margins + {n} legs of {w:g} mm, gaps {g:g}, pad {pad:g}"
        if above(min(hi_of("strap_width"), arch_sw), sw_need):
            at_least("strap_width", sw, sw_need, why)
        fit = [k for k in range(2, n, 2) if above(avail, max(
            k * w + (k - 1) * g, (k - 1) * (w + g) + pad))]
        if fit:
            at_most("legs", n, max(fit), f"legs that fit in strap_width {sw:g}"
                    " - 2 edge margins", unit="")
        em_max = (sw - need) / 2
        if above(em_max, lo_of("edge_margin")):
            at_most("edge_margin", em, em_max, f"room for {n} legs")
        g_max = min((avail - n * w) / (n - 1), (avail - pad) / (n - 1) - w)
        if above(g_max, lo_of("trace_gap")):
            at_most("trace_gap", g, g_max, f"room for {n} legs in strap_width {sw:g} - 2 edge "
                    "margins")
        if above(hi_of("strap_width"), sw_need):  # a wider strap fits, on a larger arch
            aw = self._arch_width_for_radius(sw_need / 2 + 2)
            if above(hi_of("arch_width"), aw):
                at_least("arch_width", self.arch_width, aw,
                         f"an arch (radius >= strap_width / 2 + 2) for strap_width >= "
                         f"{sw_need:.4g}: {why}")
        # no single parameter makes room: move one towards its roomiest documented end
        short = f"the {n} legs need {need:.4g} mm, strap_width - 2 edge margins is {avail:.4g}"
        if n > 2:
            at_most("legs", n, 2, f"{short}; more changes may follow", unit="")
        for name, end in (("edge_margin", lo_of("edge_margin")),
                          ("trace_gap", lo_of("trace_gap")),
                          ("trace_width", lo_of("trace_width")),
                          ("pad_width", max(w, lo_of("pad_width")))):
            at_most(name, getattr(self, name), end, f"{short}; more changes may follow")
        at_least("strap_width", sw, min(hi_of("strap_width"), arch_sw),
                 f"{short}; more changes may follow")
        at_least("arch_width", self.arch_width, hi_of("arch_width"),
                 f"{short}; more changes may follow")
        raise ParameterError("strap_width", sw, f"room for {need:.4g} mm of traces + 2 edge "
                             "margins, which no documented value gives")

    def _check(self) -> None:
        """Constraints between parameters. Each error names a parameter whose allowed range
        (printed as an allowed value) is not empty given the others; where it would be empty,
        the parameter that empties it is named instead."""
        w, n, g, lh = self.trace_width, self.legs, self.trace_gap, self.layer_height
        at_most("arch_height", self.arch_height, self.arch_width / 2,
                "arch_width / 2: at most a semicircle")
        at_most("strap_width", self.strap_width, 2 * (self.radius - 2),
                "2 x (arch radius - 2 mm)")
        at_least("trace_cover", self.trace_cover, lh, f"one layer_height of {lh:g} mm")
        at_least("trace_thickness", self.trace_thickness, lh, f"one layer_height of {lh:g} mm")
        tt_max = self.thickness - self.trace_cover - lh
        if above(tt_max, lh):  # a trace of at least one layer fits: the trace is too thick
            at_most("trace_thickness", self.trace_thickness, tt_max,
                    "thickness - trace_cover - one layer of cover")
        at_least("thickness", self.thickness, self.trace_cover + self.trace_thickness + lh,
                 f"trace_cover {self.trace_cover:g} + trace_thickness {self.trace_thickness:g} "
                 f"+ one {lh:g} mm layer of cover")
        if n % 2:
            raise ParameterError("legs", n, "an even number (both pads at the outer end)")
        avail = self.strap_width - 2 * self.edge_margin
        need = max(n * w + (n - 1) * g, (n - 1) * (w + g) + self.pad_width)
        if not above(avail, need):
            self._check_legs_fit(avail, need)
        within("pad_width", self.pad_width, w,
               min((n - 1) * (w + g) - g, field_range(ArchStrap, "pad_width")[1]),
               f"trace_width to outer leg spacing - trace_gap, with legs = {n}")
        # pad_length is measured on the arch's centreline; the pad is shortest at its inner edge
        r_in = self.radius + float(self.leg_offsets[0]) - self.pad_width / 2
        at_least("pad_length", self.pad_length, MIN_TRACE * self.radius / r_in,
                 f"a {MIN_TRACE:g} mm printed line at the inner pad edge (radius {r_in:.4g} mm; "
                 f"the centreline's is {self.radius:.4g} mm)")
        if 0 < self.lead_length < 0.1:  # a lead shorter than that is a sliver, not a lead
            at_least("lead_length", self.lead_length, 0.1, "or 0: no lead")
        if n > 2:
            at_least("lead_length", self.lead_length, w + g,
                     f"trace_width + trace_gap with legs = {n}: pads clear the outer turns "
                     "(0, no lead, takes legs = 2)")
        lo, hi = self.gauge_offset_range()
        if not above(hi, lo):  # the arch is too short for the gauges: name what to shorten
            short = lo - hi  # each of these lengths counts once in it
            lead_lo = (w + g) if n > 2 else 0.0
            for name, floor in (("gauge_length", 0.0), ("pad_length", 0.0),
                                ("lead_length", lead_lo), ("edge_margin", 0.0)):
                v = getattr(self, name)
                if above(v - short, max(floor, field_range(ArchStrap, name)[0])):
                    at_most(name, v, v - short, "both gauges with their leads and pads fit "
                            f"on the arch of length {self.arc_length:.4g} mm")
            at_least("arch_width", self.arch_width, self._arch_width_for(short),
                     f"an arch long enough for both gauges with arch_height {self.arch_height:g}")
        # lo stays far below the documented maximum (gauge_length/2 + trace_gap/2 + a turn)
        within("gauge_offset", self.gauge_offset, lo,
               min(hi, field_range(ArchStrap, "gauge_offset")[1]),
               "gauges apart at the apex and pads on the arch")
        if not above(avail, self.slot_width + 0.2):
            at_most("slot_width", self.slot_width, avail - 0.2,
                    "slot_length <= strap_width - 2 edge margins must exceed it by 0.2")
        within("slot_length", self.slot_length, self.slot_width + 0.2,
               min(avail, field_range(ArchStrap, "slot_length")[1]),
               "longer than slot_width + 0.2 (the lug), at most strap_width - 2 edge margins")
        at_least("slot_pitch", self.slot_pitch, self.slot_width + 0.8,
                 "slot_width + 0.8 mm web")
        tab_min = self.slot_end_margin + (self.slot_count - 1) * self.slot_pitch \
            + self.slot_width + 1.0
        if not above(field_range(ArchStrap, "tab_length")[1], tab_min):
            k = int((field_range(ArchStrap, "tab_length")[1] - self.slot_end_margin
                     - self.slot_width - 1.0) // self.slot_pitch) + 1
            at_most("slot_count", self.slot_count, k, f"slots at pitch {self.slot_pitch:g} mm "
                    "on the longest tab", unit="")
        at_least("tab_length", self.tab_length, tab_min, f"room for {self.slot_count} slots")
        at_most("contact_length", self.contact_length, self.arc_length, "arch length")
        at_least("nail_plate_length", self.nail_plate_length, 2 * self.slot_width + 4,
                 "two lugs")
        at_least("nail_plate_width", self.nail_plate_width, self.slot_length,
                 f"slot_length = {self.slot_length:g} mm")

    # ------------------------------------------------------------------------------ geometry
    def tab_frames(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """``(foot, tangent, normal)`` in the bed plane for the right and left tab: the arch foot
        point, the outward unit direction along the tab and the in-plane unit normal."""
        phi = self.half_angle
        out = []
        for s in (1.0, -1.0):
            foot = np.array([s * self.arch_width / 2, 0.0])
            t = np.array([s * math.cos(phi), -math.sin(phi)])
            nrm = np.array([s * math.sin(phi), math.cos(phi)])
            out.append((foot, t, nrm))
        return out

    def slot_centers(self) -> np.ndarray:
        """(2 * slot_count, 2) slot centres in the bed plane (right tab first)."""
        pts = []
        for foot, t, _ in self.tab_frames():
            for k in range(self.slot_count):
                d = self.tab_length - self.slot_end_margin - self.slot_width / 2 \
                    - k * self.slot_pitch
                pts.append(foot + d * t)
        return np.array(pts)

    def outline_area(self) -> float:
        """Closed-form area of the slotted outline (arch sector + tabs - slots), mm^2."""
        sw = self.strap_width
        area = 2 * self.half_angle * self.radius * sw + 2 * self.tab_length * sw
        slot = math.pi * (self.slot_width / 2) ** 2 + (self.slot_length - self.slot_width) \
            * self.slot_width
        return area - 2 * self.slot_count * slot

    def build(self) -> dict[str, Body]:
        """Bodies ``strap``, ``trace_left``, ``trace_right``, ``nail_plate`` (cached)."""
        return dict(_build(self))

    def mesh_bodies(self) -> tuple[str, ...]:
        return ("strap", "trace_left", "trace_right")

    def facet_sets(self) -> dict[str, FacetSelector]:
        """``nail_plate``: strap boundary in the end tabs (fixed on the nail plate);
        ``finger_contact``: bottom face within ``contact_length/2`` of the apex (arc length);
        ``pad_left`` / ``pad_right``: the top faces of the connection pads (electrodes)."""
        R, (cx, cy), t = self.radius, self.center, self.thickness
        ztol = self.layer_height / 2
        frames = self.tab_frames()
        half_sw = self.strap_width / 2 + 1e-3

        def polar(c):
            x, y = c[:, 0] - cx, c[:, 1] - cy
            return np.hypot(x, y), np.arctan2(x, y)

        def nail_plate(c, n):
            m = np.zeros(len(c), bool)
            for foot, tan, _ in frames:
                m |= (c[:, :2] - foot) @ tan >= -1e-6
            return m

        def finger_contact(c, n):
            rho, phi = polar(c)
            return (n[:, 2] < -0.9) & (np.abs(c[:, 2]) < ztol) \
                & (np.abs(phi) * R <= self.contact_length / 2) & (np.abs(rho - R) <= half_sw)

        ang = self.gauge_angles()
        y = self.leg_offsets
        pw = self.pad_width / 2 + 1e-3

        def pad(sign):
            def sel(c, n):
                rho, phi = polar(c)
                s = sign * phi
                on_pad = (s >= ang["p0"] - 1e-4) & (s <= ang["p1"] + 1e-4) & (
                    (np.abs(rho - R - y[0]) <= pw) | (np.abs(rho - R - y[-1]) <= pw))
                return (n[:, 2] > 0.9) & (np.abs(c[:, 2] - t) < ztol) & on_pad
            return sel

        return {"nail_plate": nail_plate, "finger_contact": finger_contact,
                "pad_left": pad(-1.0), "pad_right": pad(1.0)}

    def refinement(self) -> list[tuple[np.ndarray, float, float]]:
        """Gauges (edge = trace thickness, so the 2-layer trace is resolved) and pads."""
        R, (cx, cy) = self.radius, self.center
        ang = self.gauge_angles()
        z = sum(self.trace_z) / 2
        span = (self.legs - 1) * (self.trace_width + self.trace_gap) + self.trace_width
        half = math.hypot(self.gauge_length / 2 + self.trace_width, span / 2) + 0.5
        out = []
        for s in (1.0, -1.0):
            phi = s * self.gauge_offset / R
            out.append((np.array([cx + R * math.sin(phi), cy + R * math.cos(phi), z]), half,
                        self.trace_thickness))
            phi = s * (ang["p0"] + ang["p1"]) / 2
            for yo in (self.leg_offsets[0], self.leg_offsets[-1]):
                r = R + yo
                out.append((np.array([cx + r * math.sin(phi), cy + r * math.cos(phi), z]),
                            math.hypot(self.pad_width, self.pad_length) / 2 + 0.5,
                            1.5 * self.trace_thickness))
        return out


def _trace_right(p: ArchStrap):
    """Right meander (x > 0) as one solid: legs, turns, leads, and pads up to the top face."""
    R, c = p.radius, p.center
    ang = p.gauge_angles()
    y = p.leg_offsets
    hw = p.trace_width / 2
    z0, z1 = p.trace_z
    faces = []
    for yi in y:  # legs (the two outer legs run on as leads to their pads)
        faces.append(annular_sector(c, R + yi - hw, R + yi + hw, ang["a"], ang["b"]))
    for i in range(len(y) - 1):  # turns: (0,1), (2,3).. at the apex end, (1,2).. at the outer end
        r0, r1 = R + y[i] - hw, R + y[i + 1] + hw
        if i % 2 == 0:
            faces.append(annular_sector(c, r0, r1, ang["a"] - ang["turn"], ang["a"]))
        else:
            faces.append(annular_sector(c, r0, r1, ang["b"], ang["b"] + ang["turn"]))
    for yi in (y[0], y[-1]):
        if p.lead_length > 0:
            faces.append(annular_sector(c, R + yi - hw, R + yi + hw, ang["b"], ang["p0"]))
    layer = extrude(Pos(0, 0, z0) * _fuse_faces(faces), amount=z1 - z0)
    # a pad as wide as the lead (up to rounding) is built exactly as wide: no sliver faces
    pw = p.trace_width if abs(p.pad_width - p.trace_width) < 1e-3 else p.pad_width
    pads = [annular_sector(c, R + yi - pw / 2, R + yi + pw / 2,
                           ang["p0"], ang["p1"]) for yi in (y[0], y[-1])]
    pad_solid = extrude(Pos(0, 0, z0) * _fuse_faces(pads), amount=p.thickness - z0)
    return single_solid((layer + pad_solid).clean(), "trace_right")


def _fuse_faces(faces):
    """Union of planar faces as one Sketch (so Locations and ``extrude`` apply)."""
    return Sketch() + faces


@functools.lru_cache(maxsize=8)
def _build(p: ArchStrap) -> dict[str, Body]:
    R, c, sw = p.radius, p.center, p.strap_width
    outline = [annular_sector(c, R - sw / 2, R + sw / 2, -p.half_angle, p.half_angle)]
    for foot, t, nrm in p.tab_frames():
        a, b = foot + nrm * sw / 2, foot - nrm * sw / 2
        pts = [a, b, b + t * p.tab_length, a + t * p.tab_length]
        outline.append(polygon_face(pts))
    plate = extrude(_fuse_faces(outline), amount=p.thickness)
    slots = []
    for (foot, t, nrm), centers in zip(p.tab_frames(), np.split(p.slot_centers(), 2)):
        rot = math.degrees(math.atan2(nrm[1], nrm[0]))
        for q in centers:
            slots.append(Pos(q[0], q[1], 0) * SlotOverall(p.slot_length, p.slot_width,
                                                          rotation=rot))
    plate = plate - extrude(_fuse_faces(slots), amount=p.thickness)
    right = _trace_right(p)
    left = single_solid(mirror(right, about=Plane.YZ), "trace_left")
    strap = single_solid((plate - right - left).clean(), "strap")

    # nail plate beside the strap on the bed: a rounded plate with two lugs that fit the slots
    ymin = strap.bounding_box().min.Y
    yc = ymin - 5.0 - p.nail_plate_width / 2
    L, W, T = p.nail_plate_length, p.nail_plate_width, p.nail_plate_thickness
    base = Pos(0, yc, 0) * extrude(RectangleRounded(L, W, min(2.0, W / 4)), amount=T)
    lug_x = p.lug_x
    lugs = [Pos(s * lug_x, yc, T) * SlotOverall(p.slot_length - 0.4, p.slot_width - 0.3,
                                                  rotation=90) for s in (1, -1)]
    nail = single_solid((base + extrude(_fuse_faces(lugs), amount=p.thickness + 0.6)).clean(),
                        "nail_plate")
    blue, black = (0.25, 0.45, 0.85), (0.12, 0.12, 0.12)
    return {
        "strap": Body("strap", strap, "NinjaFlex", blue, extruder=1),
        "trace_left": Body("trace_left", left, "PI-ETPU", black, extruder=2),
        "trace_right": Body("trace_right", right, "PI-ETPU", black, extruder=2),
        "nail_plate": Body("nail_plate", nail, "NinjaFlex", (0.35, 0.55, 0.9), extruder=1),
    }
