"""Seed 001 hanging-weight test with contact mechanics at the ball, end to end on the Table II
points of the tall fingertip on the 11 mm base (``CantileverFingertip.tested()``, an earlier
reading of the tested sensor; the tested sensor read from its table is
``CantileverFingertip.table_ii()``: ``examples/fingertip_table_ii_readings.py``): mesh,
condense once, run the full protocol, print the numbers beside the paper's, the effect of the
bolt preload, the friction coefficients at which G1 falls from h1 to h9 (20 and 40 N preload;
with and without Mindlin's partial slip), the partial slip's element count and the readout
seed, the moment sensitivity beside a hand estimate, the sensor's sideways compliance, and a
fine-step check.

    .venv/bin/python examples/fingertip_contact.py [--json out.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import warnings

import numpy as np

from designlab.geometry.fingertip import CantileverFingertip
from designlab.sensors.fingertip.model import FingertipModelSettings, mesh_fingertip
from designlab.sensors.fingertip.contact import condense_fingertip, run_contact_test
from designlab.sensors.fingertip.joint import moment_sensitivity
from designlab.sensors.fingertip.paper_readings import PAPER
from designlab.sensors.fingertip.model import ContactSettings
from designlab.sensors.protocols import HangingWeightTest


def quiet(fn, *a, **k):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        out = fn(*a, **k)
    return out, w


def lowest(rep, key="robust_eq1_span10"):
    g = rep["hysteresis_definitions"][key]["by_group"]
    return g["G1"]["lowest"], g["G2"]["lowest"]


def print_moment_sensitivity(part, cf, s) -> None:
    """The moment sensitivity of the condensed FEM beside the hand estimate
    (:func:`designlab.sensors.fingertip.joint.moment_sensitivity`)."""
    ms = moment_sensitivity(part, cf, s)
    print(f"\nmoment sensitivity (linear, preload {s.bolt_preload_N:g} N: k_n "
          f"{ms['k_n_N_per_mm']:.0f} N/mm Hertz + sensor, Mindlin k_t {ms['k_t_N_per_mm']:.0f} "
          "N/mm); compressed sensor per N f_x, per N mm m_y, rho = ratio per mm of arm, implied "
          "change h9 -> h1 (hand: rigid ball, three springs through its centre, bolt beam "
          "clamped under its head)")
    for label in ("frictionless", "stuck"):
        for name in ("hand", "fem"):
            r = ms[label][name]
            print(f"  {label:12s} {name:4s}: {r['per_N']:.3f} N/N, {r['per_Nmm']:.4f} N/(N mm), "
                  f"rho {r['rho_per_mm']:.4f} /mm, change {r['change_h9_to_h1_pct']:.0f} %")
    k, kb = (ms["rotational_restraint_for_paper_N_mm_per_rad"],
             ms["bolt_rotational_stiffness_at_ball_centre_N_mm_per_rad"])
    print(f"  the paper's change needs rho {ms['paper_rho_per_mm']:.4f} /mm: a rotational "
          f"restraint of the ball of {k:.3g} N mm/rad about x and y (frictionless FEM), "
          f"{k / kb:.1f}x the clamped bolt's own ({kb:.3g} N mm/rad at the ball centre)")
    print(f"  axial share through the sensors (FEM, frictionless): "
          f"{ms['axial_share_through_sensors']:.3f}; bolt + cap axial stiffness at the ball "
          f"{ms['bolt_and_cap_axial_stiffness_N_per_mm']:.0f} N/mm (steel bolt alone EA/L "
          f"{ms['bolt_alone_axial_stiffness_N_per_mm']:.0f}), sensors vertically "
          f"{ms['sensors_vertical_stiffness_N_per_mm']:.0f} N/mm")
    g = ms["gap_closure"]
    print(f"  fingertip touching the base across its {g['gap_mm']:g} mm gap? heaviest weight "
          f"{g['load_N']:.2f} N at h1 ({g['arm_mm']:g} mm): ball turns "
          f"{1e3 * g['frictionless']['ball_rotation_rad']:.2f} mrad frictionless / "
          f"{1e3 * g['stuck']['ball_rotation_rad']:.2f} stuck, the rim (r {g['rim_radius_mm']:g} "
          f"mm) closes {g['frictionless']['closure_mm']:.4f} / {g['stuck']['closure_mm']:.4f} mm "
          f"({100 * g['frictionless']['fraction_of_gap']:.1f} % of the gap): "
          f"{'closes' if g['closes'] else 'does not close'}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", help="write the report here")
    args = ap.parse_args(argv)
    part = CantileverFingertip.tested()
    fs = FingertipModelSettings()
    protocol = HangingWeightTest()
    t0 = time.perf_counter()
    mesh = mesh_fingertip(part, fs)
    t_mesh = time.perf_counter() - t0
    cf = condense_fingertip(part, mesh, fs)
    print(f"mesh {mesh.n_points} points ({t_mesh:.1f} s); condensed FEM "
          f"{cf.n_dofs_fem} dofs -> 24 ({sum(cf.timings_s.values()):.1f} s)")
    s = ContactSettings()
    t0 = time.perf_counter()
    rep, w = quiet(run_contact_test, part, protocol, s, cf)
    print(f"full Table II protocol (14 locations x 6 rotations x 2 loops): "
          f"{time.perf_counter() - t0:.2f} s; warnings: {len(w)}")
    pre = rep["preload"]
    print(f"\npreload: bolt {pre['bolt_tension_N']:.1f} N -> sensors "
          f"{np.round(pre['sensor_preload_N'], 2).tolist()} N; tangential after tightening "
          f"{np.round(np.linalg.norm(pre['tangential_force_after_tightening_N'], axis=1), 2).tolist()} N")
    print(f"friction coefficient {s.friction_coefficient} (chromium on steel, Wypych 2018); "
          f"Mindlin partial slip, {s.microslip_elements} Iwan elements per contact")

    H = rep["hysteresis_definitions"]
    print("\nhysteresis by location, % (eq. 1; mean over 6 rotations)")
    print(f"{'loc':>4} {'robust':>9} {'paper-def':>10} {'robust, no noise':>17} "
          f"{'first loop, no noise':>21}")
    for n in rep["hysteresis_percent"]["by_location"]:
        print(f"{n:>4} {H['robust_eq1_span10']['by_location'][n]:9.3f} "
              f"{H['paper_eq1_all_sensors']['by_location'][n]:10.3f} "
              f"{H['robust_eq1_span10_noise_free']['by_location'][n]:17.4f} "
              f"{H['robust_eq1_span10_noise_free_first_loop']['by_location'][n]:21.3f}")
    pc = rep["paper_comparison"]
    print("\n                                   model      paper")
    for key, lab in (("robust_eq1_span10", "robust"), ("paper_eq1_all_sensors", "paper def"),
                     ("robust_eq1_span10_noise_free", "robust no noise")):
        g1, g2 = lowest(rep, key)
        print(f"lowest mean G1 ({lab:>15})   {g1:8.3f} %  {PAPER['lowest_mean_G1_pct']:6.2f} %")
        print(f"lowest mean G2 ({lab:>15})   {g2:8.3f} %  {PAPER['lowest_mean_G2_pct']:6.2f} %")
    dr = rep["hysteresis_readout_draws"]
    prof = dr["G1_mean_profile"]
    print(f"readout over {dr['draws']} noise draws (robust): G1 h1..h9 mean "
          + " ".join(f"{x:.3g}" for x in prof["mean"])
          + f" (falls: {prof['monotonic']}, smallest step "
          f"{prof['smallest_fall_over_its_standard_error']:.1f} standard errors; single draws "
          f"that fall: {100 * dr['G1_monotonic_share']:.0f} %); "
          f"lowest G1 {dr['G1_lowest']['mean']:.3f} +- {dr['G1_lowest']['sd']:.3f} (sd; standard "
          f"error {dr['G1_lowest']['standard_error']:.3f}), lowest G2 "
          f"{dr['G2_lowest']['mean']:.2f} +- {dr['G2_lowest']['sd']:.2f} %")
    for lab in ("robust", "robust_noise_free"):
        r = pc[lab]
        print(f"G1 falls monotonically h1->h9 ({lab}): {r['G1_monotonic_decrease_h1_to_h9']} "
              f"(paper: decreases exponentially); h1/h9 = {r['G1_ratio_first_to_last']:.3g}")
    print(f"compressed sensor change h9->h1    {pc['compressed_change_G1_pct']:8.1f} %  "
          f"{PAPER['compressed_change_h9_to_h1_pct']:6.1f} %")
    print(f"compressed sensor change r1->r5    {pc['compressed_change_G2_pct']:8.1f} %  "
          f"{PAPER['compressed_change_r1_to_r5_pct']:6.1f} %")
    e = pc["relative_error_per_axis"]
    print(f"rel. error P_x, P_y, P_z           {e['x']:.3f} {e['y']:.3f} {e['z']:.3f}  "
          f"(paper Fig. 9: P_z worst); P_z / max(P_x, P_y) = {pc['Pz_error_over_xy']:.2f}")
    print(f"cond(A), Table II design           {rep['condition_number']:8.2f}   "
          f"(paper, Table III design: {PAPER['condition_number']})")

    print("\nbolt preload (bolt tension N): lowest G1 / G2 robust %, noise free; h1 %")
    for P in (5.0, 10.0, 20.0, 40.0, 60.0):
        rp, _ = quiet(run_contact_test, part, protocol,
                      dataclasses.replace(s, bolt_preload_N=P), cf)
        hn = rp["hysteresis_definitions"]["robust_eq1_span10_noise_free"]
        print(f"  {P:5.1f} N: sensors {np.mean(rp['preload']['sensor_preload_N']):5.2f} N, "
              f"G1 {hn['by_group']['G1']['lowest']:.4f} / G2 {hn['by_group']['G2']['lowest']:.4f}"
              f", h1 {hn['by_location']['h1']:.2f}, lift-offs {len(rp['lift_off_warnings'])}")

    print("\nfriction coefficient scan: G1 / G2 lowest robust % (readout noise included | "
          "noise free), G1 h1 and h9 noise free, G1 falls h1 -> h9 (noise free) with h1 >= 2 h9, "
          "the compressed sensor's change h9 -> h1 (paper 33.9 %)")
    mus = (0.0, 0.002, 0.003, 0.005, 0.01, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5, 0.6,
           0.8, 1.0)
    for P, n_el, scan in ((s.bolt_preload_N, s.microslip_elements, mus),
                          (40.0, s.microslip_elements, (0.05, 0.07, 0.1, 0.15, 0.2, 0.25)),
                          (s.bolt_preload_N, 0, mus)):
        print(f"  bolt preload {P:g} N, microslip_elements {n_el}")
        for mu in scan:
            rm, _ = quiet(run_contact_test, part, protocol,
                          dataclasses.replace(s, friction_coefficient=mu, bolt_preload_N=P,
                                              microslip_elements=n_el), cf)
            g1, g2 = lowest(rm)
            n1, n2 = lowest(rm, "robust_eq1_span10_noise_free")
            hn = rm["hysteresis_definitions"]["robust_eq1_span10_noise_free"]["by_location"]
            v = np.array([hn[f"h{i}"] for i in range(1, 10)])
            # a fall of round-off (mu = 0 leaves ~1e-13 %) is no trend
            trend = bool(np.all(np.diff(v) < 0) and v[0] >= 2 * v[-1] and v[0] > 1e-6)
            d1 = rm["paper_comparison"]["compressed_change_G1_definitions"]
            print(f"  mu {mu:5.3f}: {g1:7.3f} / {g2:7.3f} | {n1:8.4f} / {n2:8.4f}   h1 {v[0]:7.3f}"
                  f"  h9 {v[-1]:7.4f}  trend {'yes' if trend else 'no'}  h9->h1 "
                  f"{d1['relative_to_first_span']:5.1f} % of the h9 span, "
                  f"{d1['percent_of_applied_force']:4.1f} % of the applied force")

    print("\npartial slip (Mindlin; microslip_elements, 0 = the whole contact sticks until it "
          "slides): G1 h1..h9 noise free %; lowest G1 / G2 robust with readout | noise free; "
          "G1 falls h1 -> h9 with readout (h1 >= 2 h9)")
    for n_el in (0, 1, 12, 24, 96):
        rm, _ = quiet(run_contact_test, part, protocol,
                      dataclasses.replace(s, microslip_elements=n_el), cf)
        hn = rm["hysteresis_definitions"]["robust_eq1_span10_noise_free"]["by_location"]
        hr = rm["hysteresis_definitions"]["robust_eq1_span10"]["by_location"]
        v = np.array([hn[f"h{i}"] for i in range(1, 10)])
        vr = np.array([hr[f"h{i}"] for i in range(1, 10)])
        g1, g2 = lowest(rm)
        n1, n2 = lowest(rm, "robust_eq1_span10_noise_free")
        trend = bool(np.all(np.diff(vr) < 0) and vr[0] >= 2 * vr[-1])
        print(f"  {n_el:3d}: " + " ".join(f"{x:.3g}" for x in v)
              + f" | {g1:.3f} / {g2:.3f} | {n1:.4f} / {n2:.4f} | trend {'yes' if trend else 'no'}")
    print("  readout seeds (24 elements): G1 h1..h9 with readout %, lowest G1 / G2, trend")
    for seed in range(5):
        rm, _ = quiet(run_contact_test, part, protocol, dataclasses.replace(s, seed=seed), cf)
        hr = rm["hysteresis_definitions"]["robust_eq1_span10"]["by_location"]
        vr = np.array([hr[f"h{i}"] for i in range(1, 10)])
        g1, g2 = lowest(rm)
        trend = bool(np.all(np.diff(vr) < 0) and vr[0] >= 2 * vr[-1])
        print(f"  seed {seed}: " + " ".join(f"{x:.3g}" for x in vr)
              + f" | {g1:.3f} / {g2:.3f} | trend {'yes' if trend else 'no'}")

    print_moment_sensitivity(part, cf, s)

    print("\nsensor sideways compliance in its well (sensor_lateral_stiffness, N/mm; default "
          "0 = rigid): compressed change h9 -> h1 / r1 -> r5 %, G1 h1 noise free %, cond(A)")
    for kl in (0.0, 5000.0, 1000.0, 300.0, 100.0, 30.0):
        rl, _ = quiet(run_contact_test, part, protocol,
                      dataclasses.replace(s, sensor_lateral_stiffness=kl), cf)
        pl = rl["paper_comparison"]
        h1 = rl["hysteresis_definitions"]["robust_eq1_span10_noise_free"]["by_location"]["h1"]
        print(f"  {kl:6g}: {pl['compressed_change_G1_pct']:6.1f} / "
              f"{pl['compressed_change_G2_pct']:6.1f}   h1 {h1:7.3f}   cond "
              f"{rl['condition_number']:.1f}")

    one = HangingWeightTest(g1_locations=("h1",), g2_locations=(), rotations=1)
    nf = dataclasses.replace(s, repeatability_percent_fs=0.0, daq_bits=32)
    ref, _ = quiet(run_contact_test, part, one, dataclasses.replace(nf, increments_per_step=200), cf)
    got, _ = quiet(run_contact_test, part, one, nf, cf)
    F_ref = np.array(ref["loops"]["h1"]["sensor_force_N"])
    F = np.array(got["loops"]["h1"]["sensor_force_N"])
    print(f"\nfine-step check (h1, rotation 0): {s.increments_per_step} vs 200 increments per "
          f"weight: max force difference {np.abs(F - F_ref).max():.2e} N "
          f"(of {np.abs(F_ref).max():.2f} N); hysteresis "
          f"{got['hysteresis_percent']['by_location']['h1']:.4f} vs "
          f"{ref['hysteresis_percent']['by_location']['h1']:.4f} %")
    if args.json:
        from designlab.atomic import atomic_write_json
        atomic_write_json(args.json, rep)
    return 0


if __name__ == "__main__":
    sys.exit(main())
