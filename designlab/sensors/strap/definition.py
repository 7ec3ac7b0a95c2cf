"""The seed 000 arch strap declared on the public sensor definition: the CAD part's parameters
and bodies (:class:`designlab.geometry.strap.ArchStrap`), its tabs held on the nail plate, the
two printed PI-ETPU strain gauges read through voltage dividers, the finger's normal and shear
load at the apex and the staircase of the paper's loads, with its worn-strap physics plugged in
(:data:`~designlab.sensors.strap.virtual.WORN_STRAP`: the wrap around the finger, the finger's
support, the piezoresistive readout). Declared in the strap's as-printed frame; the physics
wraps it around the finger."""

from __future__ import annotations

import math

import numpy as np

from designlab.fem.materials import get_material
from designlab.geometry import strap as cad
from designlab.sensors.definition import (
    Clamped,
    Face,
    LoadPoint,
    SensorDefinition,
    Solid,
    StrainGauge,
    Wrenches,
    same_design,
    solids_from,
)
from designlab.sensors.protocols import StrapLoadTest
from designlab.sensors.strap.electrical import channel_noise, gauge_resistance
from designlab.sensors.strap.model import CHANNELS, LOAD_ONLY_PARAMS
from designlab.sensors.strap.virtual import WORN_STRAP


class ArchStrap(cad.ArchStrap, SensorDefinition):
    """The seed 000 arch strap (defaults: the paper's strap)."""

    name = "strap"
    description = "seed 000: TPU arch strap with two printed conductive-TPU strain gauges"
    source = "seed 000 (TPU arch strap with two printed strain-gauge traces)"
    edge_length = 1.5
    physics = WORN_STRAP
    __eq__ = same_design

    def bodies(self) -> dict[str, Solid]:
        """The NinjaFlex strap and nail plate, the two PI-ETPU traces embedded in it."""
        return solids_from(self.build())

    def _tab_box(self, foot, tangent, normal):
        w = self.strap_width / 2 + 1e-3
        corners = [foot + s * w * normal + a * self.tab_length * tangent
                   for s in (-1, 1) for a in (0, 1)]
        lo, hi = np.min(corners, axis=0), np.max(corners, axis=0)
        return ((float(lo[0]), float(lo[1]), -1.0), (float(hi[0]), float(hi[1]), self.thickness + 1.0))

    def supports(self) -> list:
        """Both end tabs held on the nail plate (their bottom faces)."""
        return [Clamped(Face("strap", (0.0, 0.0, -1.0), box=self._tab_box(*f)))
                for f in self.tab_frames()]

    def transducers(self) -> list:
        """Ch1 (left) and Ch2 (right): each meander a printed gauge along the arch at
        ``gauge_offset`` from the apex, gauge factor of PI-ETPU, read through the divider."""
        R, (cx, cy) = self.radius, self.center
        width = self.legs * self.trace_width + (self.legs - 1) * self.trace_gap
        trace = get_material("PI-ETPU")
        R0 = gauge_resistance(self, 0.0, trace)["total"]
        out = []
        for ch, sign in zip(CHANNELS, (-1.0, 1.0)):
            phi = sign * self.gauge_offset / R
            centre = (cx + R * math.sin(phi), cy + R * math.cos(phi), self.thickness)
            out.append(StrainGauge(ch, Face("strap", (0.0, 0.0, 1.0)), centre,
                                   (math.cos(phi), -math.sin(phi), 0.0), self.gauge_length,
                                   width, gauge_factor=float(trace.gauge_factor), kind="printed",
                                   noise=math.hypot(*channel_noise(R0)), R0_ohm=R0))
        return out

    def loads(self) -> list[LoadPoint]:
        """The finger pad at the apex: the strap's bottom within ``contact_length`` of it."""
        R, cy = self.radius, self.center[1]
        half = self.contact_length / 2
        box = ((-half, cy + R - self.strap_width, -1.0), (half, cy + R + self.strap_width, 1.0))
        return [LoadPoint("pad", Face("strap", (0.0, 0.0, -1.0), box=box),
                          at=(0.0, float(self.arch_height), 0.0))]

    def protocol(self) -> Wrenches:
        """The paper's staircase in normal force (F_n along +z, the shear F_x along +x at its
        ratio), up and down; the grasp cycles that follow are the physics' own."""
        test = StrapLoadTest()
        levels = np.linspace(0.0, 1.0, test.n_steps + 1)
        stair = np.concatenate([levels, levels[-2::-1]])[1:]
        rows = tuple((test.shear_N * s, 0.0, test.normal_N * s, 0.0, 0.0, 0.0) for s in stair)
        return Wrenches("pad", rows, hold_s=test.step_hold_s)

    def load_only(self) -> tuple[str, ...]:
        return LOAD_ONLY_PARAMS
