"""Synthetic measured data for the loop of the fingertip and the flexure: the virtual test of a
design plus planted effects and noise, written as CSV files with their dataset cards.

    python examples/loop_synthetic.py [OUT]      # default OUT: examples/data

* ``fingertip_staircase.csv`` + ``fingertip_card.toml``: seed 001's hanging-weight test (Table
  II weights with the 5 g tray, 4 s per weight at 2 Hz) at the seven heights h1..h7 and three
  rotations of the fingertip, one log; readings = the design's linear FEM gains (wrench at the
  ball -> sensor V) + friction proportional to the moment arm (a Dahl state of the weight times
  the height, per sensor ``FRICTION_PER_ARM`` V/mm) + 0.2 mV noise. Loop:
  ``designlab loop --data examples/data/fingertip_card.toml --base load-arm --out out/ft_loop``
* ``flexure_log.csv`` + ``flexure_card.toml``: a 300 s log of a hand pushing the fingertip of
  the default flexure (random holds and ramps on all six wrench axes, 10 Hz); pose =
  K_f^-1 wrench (the Timoshenko truth of the virtual test) with the printed flexure 10 % softer
  axially (v_z x 1.10) and a tracker zero offset of +0.02 mm on v_x, plus pose noise (2 um,
  20 urad). Rotations are logged in rad (the card says so; the loop reads them in deg). Loop:
  ``designlab predict flexure --out out/flex && designlab loop --data
  examples/data/flexure_card.toml --base out/flex/model.json --out out/flex_loop``

Everything is seeded; the numbers planted are the module constants below.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
#: V per mm of moment arm, per sensor: the planted friction x moment arm of seed 001
FRICTION_PER_ARM = (1.0e-4, -0.6e-4, 0.8e-4)
FRICTION_XC_G = 20.0          #: Dahl characteristic travel of the friction, g of hanging mass
FINGERTIP_NOISE_V = 2e-4
FLEXURE_GAIN_VZ = 0.10        #: relative compliance error along z (printed part softer)
FLEXURE_OFFSET_VX_MM = 0.02   #: tracker zero offset on v_x
FLEXURE_NOISE = (2e-5, 2e-3)  #: pose noise, rad and mm
ROTATIONS = (0.0, 120.0, 240.0)


def fingertip_protocol():
    from designlab.sensors.protocols import HangingWeightTest

    return HangingWeightTest(hold_s=4.0, read_window_s=2.0, dt_s=0.5,
                             g1_locations=tuple(f"h{i}" for i in range(1, 8)), g2_locations=())


def fingertip_measured(part, unit: np.ndarray, seed: int = 1,
                       friction_per_arm=FRICTION_PER_ARM, rotations=ROTATIONS,
                       protocol=None) -> dict[str, np.ndarray]:
    """Columns of one hanging-weight log: ``unit`` (6, 3) sensor force (N) per unit wrench at
    the ball (the virtual test's gains), every load point of ``protocol`` at every rotation
    (load points in a seeded random order), friction x moment arm planted."""
    from designlab.loop.effects.base import dahl
    from designlab.sensors.fingertip.loop import OUTPUTS, linear_readings, load_runs

    rng = np.random.default_rng(seed)
    protocol = protocol or fingertip_protocol()
    t, load, _ = protocol.time_history()
    runs = load_runs(part, protocol, rotations)
    runs = [runs[i] for i in rng.permutation(len(runs))]
    U = np.broadcast_to(unit, (t.size, 6, 3))
    w = np.concatenate([load for _ in runs]) / 9.81 * 1e3
    arm = np.concatenate([np.full(t.size, r.arm_mm) for r in runs])
    rot = np.concatenate([np.full(t.size, r.rotation_deg) for r in runs])
    y = np.concatenate([linear_readings(U, r, load) for r in runs])
    z = dahl(w, np.array([FRICTION_XC_G]), np.zeros(w.size, int))[:, 0]
    y = y + np.outer(arm * z, friction_per_arm) + rng.normal(0, FINGERTIP_NOISE_V, y.shape)
    tt = np.arange(w.size) * protocol.dt_s
    return {"t": tt, "weight_g": w, "height_mm": arm, "rotation_deg": rot,
            **{o: y[:, k] for k, o in enumerate(OUTPUTS)}}


def flexure_drive(rng: np.random.Generator, T: float, dt: float, amp: float) -> np.ndarray:
    """Holds at random levels in [-amp, amp] joined by ramps (1-4 s), 3 s at rest first."""
    t = np.arange(0, T, dt)
    kt, kx = [0.0, 3.0], [0.0, 0.0]
    while kt[-1] < T:
        kt.append(kt[-1] + rng.uniform(1.0, 4.0))
        kx.append(rng.uniform(-amp, amp))
        kt.append(kt[-1] + rng.uniform(1.0, 6.0))
        kx.append(kx[-1])
    return np.interp(t, kt, kx)


def flexure_measured(K_true: np.ndarray, seed: int = 2, T: float = 300.0, dt: float = 0.1,
                     gain_vz: float = FLEXURE_GAIN_VZ, offset_vx: float = FLEXURE_OFFSET_VX_MM
                     ) -> dict[str, np.ndarray]:
    """Columns of one flexure log (wrench N mm / N, pose rad / mm) through ``K_true`` (6x6,
    designlab units) with the planted axial gain and v_x offset."""
    from designlab.sensors.flexure.spring import TWIST, WRENCH

    rng = np.random.default_rng(seed)
    amp = [60.0, 60.0, 60.0, 6.0, 6.0, 6.0]          # within the 100 N mm / 10 N protocol
    W = np.column_stack([flexure_drive(rng, T, dt, a) for a in amp])
    X = W @ np.linalg.inv(K_true).T
    X[:, 5] *= 1.0 + gain_vz
    X[:, 3] += offset_vx
    X = X + rng.normal(size=X.shape) * np.r_[[FLEXURE_NOISE[0]] * 3, [FLEXURE_NOISE[1]] * 3]
    return {"t": np.arange(len(W)) * dt, **{w: W[:, i] for i, w in enumerate(WRENCH)},
            **{o: X[:, i] for i, o in enumerate(TWIST)}}


def write_csv(path: Path, cols: dict[str, np.ndarray]) -> Path:
    from designlab.atomic import atomic_write_bytes

    names = list(cols)
    rows = np.column_stack([cols[n] for n in names])
    lines = [",".join(names)] + [",".join(f"{v:.7g}" for v in r) for r in rows]
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())
    return path


FINGERTIP_CARD = """\
# Synthetic seed 001 hanging-weight log (examples/loop_synthetic.py): Table II weights at h1..h7,
# rotations 0/120/240 deg; readings = FEM gains + friction x moment arm + noise.
# designlab loop --data examples/data/fingertip_card.toml --base load-arm --out out/ft_loop
[[files]]
path = "fingertip_staircase.csv"
[time]
column = "t"
unit = "s"
[inputs]
weight = { column = "weight_g", unit = "g" }
location = { column = "height_mm", unit = "mm", kind = "location" }
rotation = { column = "rotation_deg", unit = "deg", quantity = "angle" }
[outputs]
sensor_1 = { column = "sensor_1", unit = "V" }
sensor_2 = { column = "sensor_2", unit = "V" }
sensor_3 = { column = "sensor_3", unit = "V" }
[split]
train = 0.6
[repair]
dropouts = false
spikes = false
"""

FLEXURE_CARD = """\
# Synthetic seed 002 flexure log (examples/loop_synthetic.py): wrench in, pose out; the printed
# flexure is 10 % softer axially and the tracker's v_x zero is off by 0.02 mm.
# designlab predict flexure --out out/flex
# designlab loop --data examples/data/flexure_card.toml --base out/flex/model.json --out out/flex_loop
[[files]]
path = "flexure_log.csv"
[time]
column = "t"
unit = "s"
[inputs]
m_x = { column = "m_x", unit = "Nmm" }
m_y = { column = "m_y", unit = "Nmm" }
m_z = { column = "m_z", unit = "Nmm" }
f_x = { column = "f_x", unit = "N" }
f_y = { column = "f_y", unit = "N" }
f_z = { column = "f_z", unit = "N" }
[outputs]
w_x = { column = "w_x", unit = "rad" }
w_y = { column = "w_y", unit = "rad" }
w_z = { column = "w_z", unit = "rad" }
v_x = { column = "v_x", unit = "mm" }
v_y = { column = "v_y", unit = "mm" }
v_z = { column = "v_z", unit = "mm" }
[split]
train = 0.6
[repair]
dropouts = false
spikes = false
"""


def fingertip_unit(part, edge_length: float = 4.0) -> np.ndarray:
    """(6, 3) sensor force per unit wrench of ``part`` from its linear virtual test (FEM)."""
    from designlab.sensors.fingertip.model import FingertipModelSettings
    from designlab.sensors.fingertip.virtual import run

    pred = run(part, fingertip_protocol(),
               FingertipModelSettings(edge_length=edge_length, contact=False,
                                      rotations_deg=ROTATIONS))
    return pred.unit_readings[-1]


def write_fingertip(out: Path, part=None, unit=None, seed: int = 1) -> Path:
    from designlab.geometry.fingertip import CantileverFingertip
    from designlab.atomic import atomic_write_bytes

    part = part or CantileverFingertip.tested()
    unit = fingertip_unit(part) if unit is None else unit
    write_csv(out / "fingertip_staircase.csv", fingertip_measured(part, unit, seed))
    atomic_write_bytes(out / "fingertip_card.toml", FINGERTIP_CARD.encode())
    return out / "fingertip_card.toml"


def write_flexure(out: Path, seed: int = 2) -> Path:
    from designlab.atomic import atomic_write_bytes
    from designlab.sensors.flexure.model import run

    write_csv(out / "flexure_log.csv", flexure_measured(run().K_true, seed))
    atomic_write_bytes(out / "flexure_card.toml", FLEXURE_CARD.encode())
    return out / "flexure_card.toml"


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    print(f"wrote {write_flexure(out)}")
    print(f"wrote {write_fingertip(out)}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "data")
