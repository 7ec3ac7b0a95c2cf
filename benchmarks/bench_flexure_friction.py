"""Coulomb friction in the beam chain against seed 002's measured K_c (docs/validation/flexure.md).

    .venv/bin/python benchmarks/bench_flexure_friction.py [--quick | --end-conditions] [--line]

Per friction coefficient: the frictional secant 6x6 (perturbations 0.02 mm / 2 mrad, unloaded and
after the 10 N working load, ``friction_stiffness``), its amplitude dependence at the cited mu,
and the paper's own fit (``loop_stiffness``: loops about the relaxed spring, F = K X); each in
the camera frame at the paper's offset (11.09 mm) and with the fitted offset: mean |error| over
the measured diagonal and the coupling ratios model / measured. Prints wall and CPU seconds.

The friction runs use the node contacts (``contact_spacing_mm=0``, the earlier contact scheme);
``--line``: the default line contacts instead,
without mu = 1e4 (its preload does not converge with line contacts)."""

from __future__ import annotations

import sys
import time

import numpy as np

from designlab.sensors.flexure import beam_chain as bc
from designlab.sensors.flexure import chain_friction as cf
from designlab.sensors.flexure import chain_geometry as cg
from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG, to_si
from designlab.frames import transform, transform_stiffness


def goals(K_centre_si, paper):
    rep = fr.flexure_report(VISIFLEX_CATALOG, "camera", paper=paper, K_chain_spring_si=K_centre_si)
    g, f = rep["goals"]["chain"], rep["camera_fit"]["chain"]
    c = g["coupling_model_over_measured"]
    cf = f["coupling_model_over_measured"]
    Kc = fr.to_frame(K_centre_si, "camera", rep["offset_m"])
    return (f"diag {g['diagonal_mean_abs_error_pct']:5.1f} %  couplings {c['k_wx_vy']:.2f} / "
            f"{c['k_wy_vx']:.2f}x | fitted offset {1e3 * f['offset_m']:5.2f} mm: diag "
            f"{f['diagonal_mean_abs_error_pct']:5.1f} %, couplings {cf['k_wx_vy']:.2f} / "
            f"{cf['k_wy_vx']:.2f}x | camera diag " + " ".join(f"{x:.4g}" for x in np.diag(Kc)))


def end_conditions(paper) -> None:
    """Frictionless chain per end condition: lateral stiffness, coupling ratios at the paper's
    offset, the offsets that make each coupling exact (measured coupling / lateral stiffness of
    the model at the spring centre) and the diagonal error at their mean."""
    M = paper["K_c_measured"]
    print("| model | k_vx N/m | ratios at 11.09 mm | diag. | offset for ratio 1 (x / y) | diag. there |")
    for seat in ("bonded", "contact", "potted"):
        r = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(seat=seat))
        for name, K in ((f"chain {seat}", r.K_centre_si), (f"chain {seat} @10 N", r.K_loaded_centre_si)):
            rep = fr.flexure_report(VISIFLEX_CATALOG, "camera", paper=paper, K_chain_spring_si=K)
            g = rep["goals"]["chain"]
            c = g["coupling_model_over_measured"]
            hx, hy = M[1, 3] / K[3, 3], -M[0, 4] / K[4, 4]
            Kc = fr.to_frame(K, "camera", (hx + hy) / 2)
            d = 100 * np.mean([abs(Kc[i, i] / M[i, i] - 1) for i in range(6)])
            print(f"| {name} | {K[3, 3]:.0f} | {c['k_wx_vy']:.2f} / {c['k_wy_vx']:.2f} | "
                  f"{g['diagonal_mean_abs_error_pct']:.1f} % | {1e3 * hx:.2f} / {1e3 * hy:.2f} mm | "
                  f"{d:.1f} % |")


def main(quick: bool = False, line: bool = False) -> None:
    paper = fr.load_paper()
    t0, c0 = time.perf_counter(), time.process_time()
    mus = (0.0, 0.3) if quick else (0.0, 0.05, 0.1, 0.3, 0.6, 0.74) + (() if line else (1e4,))
    S = cg.ChainSettings(contact_spacing_mm=cg.ChainSettings().contact_spacing_mm if line else 0.0)
    print(f"contacts: {'line (default)' if line else 'node (contact_spacing_mm=0)'}")
    print("secant 6x6, perturbations 0.02 mm / 2 mrad (friction_stiffness)")
    for mu in mus:
        r = cf.friction_stiffness(VISIFLEX_CATALOG, S, mu=mu)
        wl = r.info["working_load"]
        print(f"mu {mu:g}: unloaded  {goals(r.K_centre_si, paper)}")
        print(f"mu {mu:g}: @10 N     {goals(r.K_loaded_centre_si, paper)}  "
              f"[{wl['closed_contacts']} closed, {wl['stuck_contacts']} stuck after the preload, "
              f"asymmetry {wl['asymmetry']:.1e}, {r.info['seconds']:.1f} s]")
    mu = cg.MU_STEEL
    print(f"amplitude dependence at mu {mu} (@10 N)")
    for a in ((1.0, 10.0) if quick else (1.0, 10.0, 50.0)):
        r = cf.friction_stiffness(VISIFLEX_CATALOG, S, mu=mu, amplitude=a)
        print(f"  x{a:g} ({0.02 * a:g} mm, {2 * a:g} mrad): {goals(r.K_loaded_centre_si, paper)}")
    print("the paper's fit: loops about the relaxed spring +-1 mm / +-0.05 rad, F = K X (loop_stiffness)")
    for mu, pre in ((0.0, 0.0), (0.3, 0.0), (0.74, 0.0)) if not quick else ((0.3, 0.0),):
        L = cf.loop_stiffness(VISIFLEX_CATALOG, S, mu=mu, points=4, preload_N=pre)
        K = to_si(transform_stiffness(L["K"], transform(translation=L["master"] - L["centre"])))
        hw = L["half_width"]
        print(f"mu {mu:g}, preload {pre:g} N: {goals(K, paper)}")
        rng = {k: np.ptp(L["loops"][i]["F"]) for i, k in enumerate(hw)}
        print("    loop half-widths / full range: " + ", ".join(
            f"{k} {hw[k]:.3g} / {rng[k]:.3g} ({100 * hw[k] / rng[k]:.2f} %)" for k in hw)
            + f" (N, N mm) [{L['seconds']:.1f} s]")
    print(f"total {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU")


if __name__ == "__main__":
    if "--end-conditions" in sys.argv:
        end_conditions(fr.load_paper())
    else:
        main("--quick" in sys.argv, "--line" in sys.argv)
