"""The seed 002 spring flexure declared on the public sensor definition: the CAD part's
parameters and bodies (:class:`designlab.geometry.flexure.SpringFlexure`), the base disc held,
the fingertip disc's pose read by the camera (three translations, three rotations), the wrench
at the fingertip and the paper's wrench set, with its beam-chain physics plugged in
(:data:`~designlab.sensors.flexure.virtual.BEAM_CHAIN`: the spring's closed form, or its beam
chain with coil contact and friction)."""

from __future__ import annotations

from designlab.geometry import flexure as cad
from designlab.sensors.definition import (
    Clamped,
    DisplacementProbe,
    Face,
    LoadPoint,
    Region,
    RotationProbe,
    SensorDefinition,
    Solid,
    Wrenches,
    same_design,
    solids_from,
)
from designlab.sensors.flexure.virtual import BEAM_CHAIN
from designlab.sensors.noise import POSE_NOISE_SIGMA_MM
from designlab.sensors.protocols import FlexureWrenchTest

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


class SpringFlexure(cad.SpringFlexure, SensorDefinition):
    """The seed 002 helical spring flexure (defaults: the paper's spring)."""

    name = "flexure"
    description = "seed 002: fingertip on a helical spring flexure, pose read by a camera"
    source = "seed 002 (fingertip on a helical spring flexure, Visiflex)"
    edge_length = 2.0
    physics = BEAM_CHAIN
    __eq__ = same_design

    def bodies(self) -> dict[str, Solid]:
        """The steel spring (bought) between the printed base and fingertip discs; the discs
        rigid, as the spring's models take its ends (the generic virtual test of this
        declaration meets the flexure's own FEM: tests/sensors/test_builtin_definitions.py)."""
        return solids_from(self.build(), rigid=("base_disc", "tip_disc"))

    def supports(self) -> list:
        """The base disc's bottom on the frame."""
        return [Clamped(Face("base_disc", (0.0, 0.0, -1.0)))]

    def transducers(self) -> list:
        """The fingertip disc's pose from the camera: translations with the paper's pose noise
        (25 um standard deviation from its 20 um mean error), rotations (the paper gives no
        rotation noise: none)."""
        tip = Region("tip_disc")
        return ([DisplacementProbe(f"d_{a}", tip, v, POSE_NOISE_SIGMA_MM)
                 for a, v in _AXES.items()]
                + [RotationProbe(f"theta_{a}", tip, v, 0.0) for a, v in _AXES.items()])

    def loads(self) -> list[LoadPoint]:
        """The wrench at the fingertip disc's face on the spring (its centre)."""
        return [LoadPoint("fingertip", Face("tip_disc", (0.0, 0.0, 1.0)),
                          at=(0.0, 0.0, float(self.length)))]

    def protocol(self) -> Wrenches:
        """The paper's static wrenches: each component alone, up to 10 N and 100 N mm, both
        ways."""
        w = FlexureWrenchTest().wrenches()          # (m_x, m_y, m_z, f_x, f_y, f_z)
        rows = tuple(tuple(float(v) for v in (*r[3:], *r[:3])) for r in w)
        return Wrenches("fingertip", rows)
