"""The printed six-axis F/T sensor example: it builds in frame S, its protocol is the 60 hanging-
mass states with S's handedness, and its virtual test gives an 8 x 6 sensitivity with the
design's 4-fold symmetry, whose Fz-normalised rows do not depend on the forks' gains."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[3]
FT = ROOT / "examples" / "sensors" / "printed_ft.py"
#: a coarse mesh for the tests (the default is finer)
COARSE = {"arm_edge": 4.0}
EDGE = 7.0


def _ft(**kw):
    from designlab.geometry.parts import make_part
    from designlab.sensors.registry import resolve

    return make_part(resolve(str(FT)), kw)


def _run(part):
    from designlab.sensors.generic.virtual import run, settings_class

    return run(part, settings=settings_class(type(part))(edge_length=EDGE, viscoelastic=False))


def _K(report, key="sensitivity"):
    rows = report[key]
    return np.array([list(rows[c["name"]].values()) for c in report["channels"]])


@pytest.fixture(scope="module")
def base():
    return _run(_ft(**COARSE))


@pytest.mark.slow
def test_protocol_is_sixty_mass_states_in_frame_s():
    states = _ft().protocol().states()
    assert len(states) == 60
    s = {x.label: x for x in states}["mass 1 dir 0"]    # pocket 1 (+x, +y), gravity -z_S
    F, M = np.array(s.force_N), np.array(s.moment_Nmm)
    assert np.allclose(F, [0, 0, -1.028 * 9.81])
    assert np.allclose(M, [29.37 * F[2], -29.37 * F[2], 0.0])


@pytest.mark.slow
def test_bodies_are_built_in_frame_s():
    bodies = _ft().bodies()
    assert set(bodies) == {"element", "ring", "fins"}
    assert len(bodies["element"].shape.solids()) == 1          # the arms join hub and blocks
    for b in bodies.values():
        bb = b.shape.bounding_box()
        assert bb.max.Z <= 1e-6 and bb.min.Z >= -21.5 - 1e-6      # z_S = -z_T
    # the description's check rays at z_T = 7 (theta_T: material, gap), turned into S
    e, ring = bodies["element"].shape, bodies["ring"].shape

    def solid(theta, r):
        t = np.radians(theta)
        return any(b.is_inside((r * np.cos(t), -r * np.sin(t), -7.0)) for b in (e, ring))

    rays = {-50: ([32.0, 35.9, 39.0], [33.4, 37.9]), 0: ([35.0, 37.9, 42.5], [35.85, 40.5]),
            20: ([36.9], [34.0, 39.5]), 40: ([32.0, 35.9, 39.0], [33.4, 37.9])}
    for theta, (full, empty) in rays.items():
        assert all(solid(theta, r) for r in full), theta
        assert not any(solid(theta, r) for r in empty), theta
    # the spiral's handedness: at theta_T = -20 a second arm reaches r 39, at +20 none does
    assert solid(-20, 39.0) and not solid(20, 39.0)


@pytest.mark.slow
def test_sensitivity_is_8x6_and_four_fold_symmetric(base):
    rep = base.report
    K = _K(rep)
    assert K.shape == (8, 6)
    assert [x["name"].split("_")[-1] for x in rep["loads"]] == ["Fx", "Fy", "Fz", "Mx", "My",
                                                                   "Mz"]
    # fork j + 2 (the next module, same side) under a wrench reads as fork j under the wrench
    # turned back by the module spacing: +90 deg about z_T is -90 deg about z_S
    R = np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]])
    R6 = np.kron(np.eye(2), R)
    assert np.abs(np.roll(K, 2, axis=0) @ R6.T - K).max() < 0.03 * np.abs(K).max()
    # the opposite turn (the wrong handedness) does not hold
    assert np.abs(np.roll(K, 2, axis=0) @ R6 - K).max() > 0.3 * np.abs(K).max()
    # every fork sees Fz alike (pulling the ring away from the robot lowers every edge)
    assert np.all(K[:, 2] < 0) and np.ptp(K[:, 2]) < 0.03 * np.abs(K[:, 2]).max()
    assert 1 < rep["sensitivity_condition_number_scaled"] < rep["sensitivity_condition_number"]
    N = _K(rep, "sensitivity_normalised")
    assert np.allclose(N[:, 2], 1.0) and np.allclose(N, K / K[:, [2]])


@pytest.mark.slow
def test_normalised_rows_do_not_depend_on_the_forks_gains(base):
    gains = np.array([1.0, -0.6, 1.4, 0.8, -1.2, 0.5, 2.0, 0.9])
    Base = type(_ft())

    class Regained(Base):
        name = "printed_ft_regained"

        def transducers(self):
            return [dataclasses.replace(t, gain=t.gain * g)
                    for t, g in zip(super().transducers(), gains)]

    rep = _run(Regained(**COARSE)).report
    K0, K1 = _K(base.report), _K(rep)
    assert np.allclose(K1, gains[:, None] * K0, rtol=1e-6, atol=1e-9)
    assert np.allclose(_K(rep, "sensitivity_normalised"),
                       _K(base.report, "sensitivity_normalised"), rtol=1e-6, atol=1e-9)
    assert not np.isclose(rep["sensitivity_condition_number"],
                          base.report["sensitivity_condition_number"], rtol=1e-3)
