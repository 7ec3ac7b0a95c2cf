"""The seed 001 fingertip declared on the public sensor definition: the CAD part's parameters and
bodies (:class:`designlab.geometry.fingertip.CantileverFingertip`), the cap on the robot, the
three FSS015 force sensors between the ball and their wells, the load points of the paper's
table and its hanging-weight staircase, with its contact physics plugged in
(:data:`~designlab.sensors.fingertip.virtual.BALL_CONTACT`: Hertz and Mindlin contact at the
sensors' buttons, Coulomb friction, the bolt preload, the ABS relaxation, the FSS015/DAQ
readout). The physics runs the virtual test; the declaration states the same sensor in the
vocabulary every definition shares (tests/sensors/test_builtin_definitions.py checks the two
agree)."""

from __future__ import annotations

import numpy as np

from designlab.geometry import fingertip as cad
from designlab.sensors.definition import (
    Clamped,
    Face,
    ForceSensor,
    LoadPoint,
    SensorDefinition,
    Solid,
    Staircase,
    same_design,
    solids_from,
)
from designlab.sensors.fingertip.model import (
    FSS015_REPEATABILITY_PERCENT_FS,
    FSS015_STIFFNESS_N_PER_MM,
    FSS015_V_PER_N,
    LOAD_ONLY_PARAMS,
)
from designlab.sensors.fingertip.readout import repeatability_sigma_V
from designlab.sensors.fingertip.virtual import BALL_CONTACT
from designlab.sensors.protocols import HangingWeightTest

#: the bodies that carry the load (the FSS015 bodies are the force sensors' springs)
LOAD_BODIES = ("fingertip", "skin", "base", "cap", "ball", "bolt")


class CantileverFingertip(cad.CantileverFingertip, SensorDefinition):
    """The seed 001 cantilever fingertip (defaults: the optimised sensor of Table III)."""

    name = "fingertip"
    description = "seed 001: printed fingertip on a steel ball over three FSS015 force sensors"
    source = "seed 001 (cantilever fingertip on a ball and three FSS015 sensors)"
    edge_length = 2.5
    physics = BALL_CONTACT
    __eq__ = same_design

    def bodies(self) -> dict[str, Solid]:
        """The printed fingertip (ABS; its silicone skin when it has one), base and cap (ABS),
        the steel ball (rigid: the fingertip sits on it, the sensors and the bolt hold it) and
        the M2.5 bolt (steel)."""
        return solids_from(self.build(), LOAD_BODIES, rigid=("ball",))

    def supports(self) -> list:
        """The cap's bottom on the robot (the physics sits it on its outer rim:
        ``cap_support``)."""
        return [Clamped(Face("cap", (0.0, 0.0, -1.0)))]

    def transducers(self) -> list:
        """The three FSS015 sensors: each a spring along its axis between the ball (its
        contact patch) and its well's floor, read at 60 mV/N, repeatability 0.2 % of span."""
        axes, _ = self.sensor_axes()
        floors = self.well_floor_centers()
        half = self.sensor_size / 2 + self.well_clearance
        out = []
        for k, (a, f) in enumerate(zip(axes, floors)):
            box = (tuple(f - half * np.sqrt(2)), tuple(f + half * np.sqrt(2)))
            out.append(ForceSensor(
                f"sensor_{k + 1}", face_a=Face("ball", tuple(-a)),
                face_b=Face("base", tuple(a), at=float(f @ a), box=box),
                axis=tuple(-a), stiffness_N_per_mm=FSS015_STIFFNESS_N_PER_MM,
                sensitivity_V_per_N=FSS015_V_PER_N,
                noise_V=repeatability_sigma_V(FSS015_REPEATABILITY_PERCENT_FS)))
        return out

    def loads(self) -> list[LoadPoint]:
        """The paper's load points on the fingertip (lateral ones pulled towards the axis, top
        ones down), at rotation 0."""
        return [LoadPoint(n, Face("fingertip", tuple(-d)), at=tuple(p), direction=tuple(d))
                for n, (p, d) in self.load_points(0.0).items()]

    def protocol(self) -> Staircase:
        """The hanging-weight staircase of the design's load table at each load point (the tray
        included in every weight)."""
        test = HangingWeightTest.preset("optimized") if self.load_table == "III" \
            else HangingWeightTest()
        w = tuple(float(x) + test.tray_g for x in test.weights_g)
        names = tuple(n for n in (*test.g1_locations, *test.g2_locations)
                      if n in self.load_points(0.0))
        return Staircase(names, w, hold_s=test.hold_s)

    def load_only(self) -> tuple[str, ...]:
        return LOAD_ONLY_PARAMS
