"""The Table II goals of seed 001 under the three readings of the tested sensor's geometry
(the paper draws no base; the results: docs/validation/fingertip.md):

- ``tall, on the 11 mm base``: ``CantileverFingertip.tested()``, an earlier reading of the
  tested sensor (h 28.5, r 9 on the optimised sensor's base, 11 mm below the ball centre;
  arms = Table II heights). Its fingertip top, 37.5 mm up, does not carry Table II's load
  points as the dome they lie on (R 6.37 mm centred at h5).
- ``(a) datum at the ball centre``: ``examples/fingertip_table_ii.toml`` (``CantileverFingertip.
  table_ii()``, the model's Table II sensor): the fingertip that the load
  points describe (h 16.70, r 6.37), arms = Table II heights, and the 48.5 mm total height
  leaving 25.43 mm below the ball centre (base 22.43 mm, M2.5 bolt 24.43 mm).
- ``(b) datum 14.43 mm above the ball centre``: the tested fingertip on the optimised base:
  arms = Table II heights + 14.43 mm.

Each runs the paper's Table II protocol (14 locations x 6 rotations, preconditioning loop, 200
readout draws) through the contact model on its own condensed FEM (default mesh and settings:
mu 0.25, preload 20 N, ABS relaxation kept) and prints the goals as ``prediction.json`` states
them, with the moment sensitivity behind the h9 -> h1 change; then reading (a) with one setting
changed at a time (mesh, moduli, friction), and the friction coefficient that would match the
paper's lowest means.

    .venv/bin/python examples/fingertip_table_ii_readings.py
"""

from __future__ import annotations

import dataclasses
import time
import tomllib
import warnings
from pathlib import Path

from designlab.geometry.fingertip import CantileverFingertip
from designlab.geometry.parts import make_part
from designlab.sensors.fingertip.contact import condense_fingertip, run_contact_test
from designlab.sensors.fingertip.paper import paper_comparison, table_ii_dome
from designlab.sensors.fingertip.model import FingertipModelSettings, mesh_fingertip
from designlab.sensors.protocols import HangingWeightTest

CONFIG = Path(__file__).with_name("fingertip_table_ii.toml")


@dataclasses.dataclass(frozen=True)
class Shifted(CantileverFingertip):
    """A design whose Table II heights are measured from ``datum`` mm above the ball centre
    (load points only; the FEM is the same; Table III's keep their datum at the ball)."""

    datum: float = 0.0

    def load_table_values(self):
        hs, rs = super().load_table_values()
        shift = self.datum if self.load_table == "II" else 0.0
        return tuple(h + shift for h in hs), rs


def readings() -> dict[str, CantileverFingertip]:
    tested = CantileverFingertip.tested()
    datum = table_ii_dome(tested)["datum_above_ball_centre_mm"]
    return {"tall, on the 11 mm base (tested())": tested,
            "(a) datum at the ball centre": make_part("fingertip",
                                                      config=tomllib.loads(CONFIG.read_text())),
            f"(b) datum {datum:.2f} mm above the ball centre": Shifted(**dataclasses.asdict(tested),
                                                                        datum=datum)}


def goals(part, fs: FingertipModelSettings, cf=None) -> dict:
    """The Table II goals of ``part`` as ``paper_comparison`` states them (``cf``: its
    condensed structure, when already made at these settings' mesh and moduli)."""
    if cf is None:
        cf = condense_fingertip(part, mesh_fingertip(part, fs), fs, fs.structure_moduli)
    proto = HangingWeightTest()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = run_contact_test(part, proto, fs, cf)
        pc = paper_comparison(part, proto, fs, cf, rep, meshed_fingertip=False)
    g = pc["goals"]
    ms = g["compressed_change_h9_to_h1"]["moment_sensitivity"]   # paper_comparison's diagnosis
    nf = pc["table_II_design"]["hysteresis_percent"]["robust_eq1_span10_noise_free"]
    return {"below_ball_mm": -part.cap_z[0], "G1_noise_free": list(nf["G1_by_location"].values()),
            "trend": g["G1_falls_monotonically_h1_to_h9"], "G1": g["lowest_mean_G1"],
            "G2": g["lowest_mean_G2"], "h9_h1": g["compressed_change_h9_to_h1"],
            "r1_r5": pc["compressed_change_r1_to_r5"],
            "rho": ms["rho_per_mm_fem"]["frictionless"], "rho_stuck": ms["rho_per_mm_fem"]["stuck"],
            "bolt": ms["bolt_rotational_stiffness_at_ball_centre_N_mm_per_rad"]}


def lowest(g: dict, digits: int = 2) -> str:
    """A lowest-mean goal as printed: the draws' mean +- their sd, and friction alone."""
    return (f"{g['value_with_readout_mean_of_draws_pct']:.2f} +- {g['sd_over_draws_pct']:.2f} % "
            f"({g['value_noise_free_pct']:.{digits}f} % friction alone)")


#: how firm reading (a)'s lowest G1 is: one setting changed at a time
VARIANTS = {"coarse mesh (edge 3.75 mm)": {"edge_length": 3.75},
            "relaxed moduli throughout": {"structure_moduli": "long_time"},
            "mu 0.21 (kinetic chromium on steel)": {"friction_coefficient": 0.21},
            "mu 0.3": {"friction_coefficient": 0.3}}


#: friction coefficients tried for the match (the default 0.25 is in the readings above)
MU_SCAN = (0.3, 0.32, 0.35, 0.4, 0.5)


def main() -> int:
    fs = FingertipModelSettings()
    t_all = time.perf_counter()
    for name, part in readings().items():
        t0 = time.perf_counter()
        r = goals(part, fs)
        g1, g2, ch = r["G1"], r["G2"], r["h9_h1"]
        d = ch["by_definition"]
        print(f"\n{name}: base to {r['below_ball_mm']:.2f} mm below the ball centre "
              f"({time.perf_counter() - t0:.1f} s)")
        print("  G1 friction alone h1..h9 %: " + " ".join(f"{v:.3g}" for v in r["G1_noise_free"]))
        print(f"  G1 falls h1 -> h9 (draws' mean): {g1 and r['trend']['met']}; h1/h9 noise free "
              f"{r['G1_noise_free'][0] / r['G1_noise_free'][-1]:.2f}")
        print(f"  lowest mean G1 {lowest(g1)} vs 0.98 %: met {g1['met']}")
        print(f"  lowest mean G2 {lowest(g2, 3)} vs 2.19 %: met {g2['met']}")
        print(f"  h9 -> h1 relative to h9's span {d['relative_to_first_span']['value_pct']:.1f} % "
              f"(met {d['relative_to_first_span']['met']}), to h1's "
              f"{d['relative_to_last_span']['value_pct']:.1f} %, of the applied force "
              f"{d['percent_of_applied_force']['value_pct']:.1f} % (met "
              f"{d['percent_of_applied_force']['met']}); paper 33.9 %")
        rb = r["r1_r5"]["by_definition"]
        print(f"  r1 -> r5 {rb['relative_to_first_span']:.0f} % / {rb['relative_to_last_span']:.1f}"
              f" % / {rb['percent_of_applied_force']:.1f} % of the applied force; paper 9.6 %")
        print(f"  moment sensitivity rho {r['rho']:.3f} per mm frictionless, {r['rho_stuck']:.3f} "
              f"stuck (paper's 33.9 % implies 0.031); bolt at the ball {r['bolt']:.3g} N mm/rad")
    part = readings()["(a) datum at the ball centre"]
    print("\n(a), one setting changed at a time:")
    for name, change in VARIANTS.items():
        r = goals(part, dataclasses.replace(fs, **change))
        g1, d = r["G1"], r["h9_h1"]["by_definition"]
        print(f"  {name}: lowest mean G1 {g1['value_with_readout_mean_of_draws_pct']:.2f} +- "
              f"{g1['sd_over_draws_pct']:.2f} % (met {g1['met']}), G1 falls {r['trend']['met']}, "
              f"h9 -> h1 {d['relative_to_first_span']['value_pct']:.1f} / "
              f"{d['percent_of_applied_force']['value_pct']:.1f} % of the applied force")
    # the coefficient that would match the paper's lowest means (a goal asks for it): the
    # friction coefficient is an interface property, so the structure is condensed once
    print("\n(a), the friction coefficient that would match the paper's lowest means "
          "(0.98 % G1, 2.19 % G2):")
    cf = condense_fingertip(part, mesh_fingertip(part, fs), fs, fs.structure_moduli)
    for mu in MU_SCAN:
        r = goals(part, dataclasses.replace(fs, friction_coefficient=mu), cf)
        g1, g2 = r["G1"], r["G2"]
        print(f"  mu {mu:g}: lowest mean G1 {lowest(g1)}, G1 falls {r['trend']['met']} (h1/h9 "
              f"noise free {r['G1_noise_free'][0] / r['G1_noise_free'][-1]:.2f}); lowest mean "
              f"G2 {lowest(g2, 3)}")
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
