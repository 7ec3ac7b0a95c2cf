"""Asymmetric ends of the beam chain against seed 002's measured K_c (docs/validation/flexure.md).

    .venv/bin/python benchmarks/bench_flexure_end_seats.py [--discretisation]

Every (base, tip) end condition (bonded, contact, potted), unloaded and at the 10 N working
load, frictionless chain: the camera-frame goal metrics at the paper's offset (11.09 mm), the
zero-coupling point (mm above the spring centre, x / y), the rocking stiffness at the elastic
centre (1 / C_ww, independent of the camera offset) and the lateral stiffness; then the held-out
checks (the end condition chosen on the couplings only, its diagonal error held out, and the
reverse). ``--discretisation``: the default chain per ``elements_per_turn`` with node contacts
(the earlier scheme) and line contacts (default), the line contacts' sensitivities, and the 18
rows at 72 and 144 beams per turn. Prints wall and CPU seconds."""

from __future__ import annotations

import sys
import time

import numpy as np

from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG, stiffness_zero_pitch, to_si


def line(r) -> str:
    c, z = r["coupling_model_over_measured"], r["zero_coupling_mm"]
    kb, kv = r["rocking_at_elastic_centre_si"], r["lateral_si"]
    return (f"| {r['base']} | {r['tip']} | {'10 N' if r['state'] == 'loaded' else '0'} | "
            f"{r['diagonal_mean_abs_error_pct']:.1f} % | {c['k_wx_vy']:.2f} / {c['k_wy_vx']:.2f} | "
            f"{z['x_mm']:+.2f} / {z['y_mm']:+.2f} ({z['mean_mm']:+.2f}) | "
            f"{kb[0]:.3f} / {kb[1]:.3f} | {kv[0]:.0f} / {kv[1]:.0f} | "
            f"{'yes' if fr.meets_goals(r) else 'no'} |")


LEVELS = (24, 36, 48, 72, 108, 144)


def discretisation(paper) -> None:
    """The default (bonded / bonded) chain per elements_per_turn, with the node contacts
    (``contact_spacing_mm=0``, the earlier scheme) and the line contacts (default): goal metrics
    unloaded and at 10 N, closed contacts at 10 N, the spread over the six levels; the line
    contacts' sensitivity to their spacing, the refinement mesh, the window rule and the
    penalty; the 18 rows at 72 and 144 beams per turn."""
    from designlab.sensors.flexure import beam_chain as bc
    from designlab.sensors.flexure import chain_geometry as cg

    def levels(label, **kw):
        out = {"loaded": [], "unloaded": []}
        for n in LEVELS:
            rows = fr.end_condition_table(VISIFLEX_CATALOG, paper, seats=("bonded",),
                                          elements_per_turn=n, **kw)
            for r in rows:
                out[r["state"]].append(r)
        for state in ("loaded", "unloaded"):
            e = [r["diagonal_mean_abs_error_pct"] for r in out[state]]
            c = [r["coupling_model_over_measured"] for r in out[state]]
            print(f"{label}, {'10 N' if state == 'loaded' else 'unloaded'}: diag "
                  + " / ".join(f"{x:.2f}" for x in e) + f" % (spread {max(e) - min(e):.2f}); "
                  "couplings " + " / ".join(f"{x['k_wx_vy']:.2f}-{x['k_wy_vx']:.2f}" for x in c)
                  + ("; closed " + " / ".join(str(r["closed_contacts"]) for r in out[state])
                     if state == "loaded" else ""))
        return out

    print("elements_per_turn " + " / ".join(map(str, LEVELS)))
    levels("node contacts (contact_spacing_mm=0)", contact_spacing_mm=0.0)
    levels("line contacts, beams not refined (contact_mesh_mm=0)", contact_mesh_mm=0.0)
    levels("line contacts (default)")
    M, h = paper["K_c_measured"], fr.camera_offset(paper)

    def err(**kw):
        out = []
        for n in (36, 72, 144):
            r = bc.chain_stiffness(VISIFLEX_CATALOG, cg.ChainSettings(elements_per_turn=n, **kw))
            Kc = fr.to_frame(r.K_loaded_centre_si, "camera", h)
            out.append(100 * np.mean([abs(Kc[i, i] / M[i, i] - 1) for i in range(6)]))
        return " / ".join(f"{x:.2f}" for x in out)

    print("line contacts, 10 N diag % at 36 / 72 / 144 beams per turn:")
    for sp_, mesh in ((0.25, 0.25), (0.05, 0.25), (0.05, 0.1)):
        print(f"    contact_spacing_mm {sp_}, contact_mesh_mm {mesh}: "
              + err(contact_spacing_mm=sp_, contact_mesh_mm=mesh))
    rule = (bc.REFINE_GAP_MM, bc.WINDOW_MARGIN_MM)
    for gap, margin in ((0.05, 1.5), (0.3, 6.0)):
        bc.REFINE_GAP_MM, bc.WINDOW_MARGIN_MM = gap, margin
        print(f"    windows where the gap at rest < {gap} mm, +-{margin} mm: " + err())
    bc.REFINE_GAP_MM, bc.WINDOW_MARGIN_MM = rule
    line = bc.Chain._line_contacts
    for f in (0.1, 10.0):
        bc.Chain._line_contacts = lambda self, a, b, s, f=f: line(self, f * a, f * b, s)
        print(f"    penalty x{f:g} (E* per unit length scaled): " + err())
    bc.Chain._line_contacts = line
    ch = bc.Chain(cg.as_built(VISIFLEX_CATALOG), cg.ChainSettings())
    pre = ch.solve(f_master=np.r_[0.0, 0.0, -10.0, 0.0, 0.0, 0.0])
    cl = pre["closed"]
    us = np.array([c.u for c in ch.contacts])
    kind = np.array([c.kind for c in ch.contacts])
    g = ch.g0 + ch.N @ pre["q"]
    for name, sel in (("base", us < ch.coil.turns / 2), ("tip", us >= ch.coil.turns / 2)):
        m = cl & sel & (kind == "coil")
        length = int(m.sum()) * ch.s.contact_spacing_mm
        uc = float(np.sum(us[m] * pre["f_n"][m]) / pre["f_n"][m].sum())
        print(f"10 N, default: {name} coil contact zone u {us[m].min():.4f}-{us[m].max():.4f} "
              f"(lower wire; {int(m.sum())} points, ~{length:.1f} mm), {pre['f_n'][m].sum():.3f} N;"
              f" gap at rest at its centre {1e3 * np.interp(uc, us[m], ch.g0[m]):.1f} um, deepest "
              f"penetration {-1e3 * g[m].min():.2f} um")
    print(f"10 N, default: tip disc tilt {np.degrees(np.abs(pre['q'][ch.m][3:5])).round(3)} deg "
          f"(x, y); chord sagitta at 36 beams per turn "
          f"{ch.coil.R * (1 - np.cos(np.pi / 36)):.3f} mm")
    print(f"10 N, default: seat contacts closed {int(np.count_nonzero(cl & (kind == 'seat')))}, "
          f"{pre['f_n'][cl & (kind == 'seat')].sum():.4f} N; all contacts "
          f"{pre['f_n'].sum():.4f} N against the 10 N load; {len(ch.u) - 1} beams")
    for n in (72, 144):
        rows = fr.end_condition_table(VISIFLEX_CATALOG, paper, elements_per_turn=n)
        zc = [r["zero_coupling_mm"]["mean_mm"] for r in rows]
        kb = [max(r["rocking_at_elastic_centre_si"]) for r in rows]
        print(f"all 18 rows, elements_per_turn {n}: both goals met by "
              f"{sum(fr.meets_goals(r) for r in rows)}; zero-coupling mean {min(zc):+.2f} to "
              f"{max(zc):+.2f} mm; largest rocking at the elastic centre {max(kb):.3f} N*m/rad; "
              f"best diagonal {min(r['diagonal_mean_abs_error_pct'] for r in rows):.1f} %")
        for r in sorted(rows, key=fr.coupling_misfit)[:3]:
            c = r["coupling_model_over_measured"]
            print(f"    coupling misfit {fr.coupling_misfit(r):.3f}: {r['base']}/{r['tip']} "
                  f"{r['state']}, couplings {c['k_wx_vy']:.2f} / {c['k_wy_vx']:.2f}, diagonal "
                  f"{r['diagonal_mean_abs_error_pct']:.1f} %")


def main() -> None:
    t0, c0 = time.perf_counter(), time.process_time()
    paper = fr.load_paper()
    M = paper["K_c_measured"]
    h = fr.camera_offset(paper)
    zm = 1e3 * fr.zero_coupling_point(M)
    kb = fr.rocking_at_elastic_centre(M)
    print(f"paper offset {1e3 * h:.2f} mm; measured zero-coupling point {zm:.2f} mm above the "
          f"camera = {zm - 1e3 * h:+.2f} mm from the spring centre; measured rocking at the "
          f"elastic centre {kb[0]:.3f} / {kb[1]:.3f} N*m/rad, lateral {M[3, 3]:.0f} / "
          f"{M[4, 4]:.0f} N/m")
    rows = fr.end_condition_table(VISIFLEX_CATALOG, paper)
    print("| base | tip | load | diag. | couplings / measured | zero-coupling x / y (mean), mm "
          "| rocking at elastic centre, N*m/rad | lateral N/m | both goals |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(line(r))
    for name, pool in (("all 18", rows), ("asymmetric only (12)", [r for r in rows if r["base"] != r["tip"]])):
        a = min(pool, key=fr.coupling_misfit)
        b = min(pool, key=lambda r: r["diagonal_mean_abs_error_pct"])
        ca, cb = a["coupling_model_over_measured"], b["coupling_model_over_measured"]
        print(f"{name}: chosen on the couplings: {a['base']}/{a['tip']} {a['state']} "
              f"(couplings {ca['k_wx_vy']:.2f} / {ca['k_wy_vx']:.2f}) -> held-out diagonal "
              f"{a['diagonal_mean_abs_error_pct']:.1f} %; chosen on the diagonal: "
              f"{b['base']}/{b['tip']} {b['state']} ({b['diagonal_mean_abs_error_pct']:.2f} %) -> "
              f"held-out couplings {cb['k_wx_vy']:.2f} / {cb['k_wy_vx']:.2f}")
    kbs = np.array([r["rocking_at_elastic_centre_si"] for r in rows])
    print(f"rocking at the elastic centre over all rows: {kbs.min():.3f}-{kbs.max():.3f} N*m/rad "
          f"(measured / largest: {min(kb) / kbs.max():.2f}-{max(kb) / kbs.max():.2f}x)")
    ratio = [float(np.mean(r["rocking_at_elastic_centre_si"])) / r["camera_diagonal_si"][5]
             for r in rows]
    cf = to_si(stiffness_zero_pitch(VISIFLEX_CATALOG))
    print(f"rocking at the elastic centre / axial (m^2, both offset-independent): measured "
          f"{np.mean(kb) / M[5, 5]:.3e}, closed form {cf[0, 0] / cf[5, 5]:.3e}, chain rows "
          f"{min(ratio):.3e}-{max(ratio):.3e} (measured / rows {np.mean(kb) / M[5, 5] / max(ratio):.2f}"
          f"-{np.mean(kb) / M[5, 5] / min(ratio):.2f}x)")
    print(f"torsion / axial (m^2): measured {M[2, 2] / M[5, 5]:.3e}, closed form "
          f"{cf[2, 2] / cf[5, 5]:.3e}; measured zero-coupling x / y from the spring centre "
          f"{1e3 * (M[1, 3] / M[3, 3] - h):+.2f} / {1e3 * (-M[0, 4] / M[4, 4] - h):+.2f} mm")
    print(f"rows meeting both goals: {sum(fr.meets_goals(r) for r in rows)} of {len(rows)}")
    print(f"total {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU")


if __name__ == "__main__":
    if "--discretisation" in sys.argv:
        t0, c0 = time.perf_counter(), time.process_time()
        discretisation(fr.load_paper())
        print(f"total {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU")
    else:
        main()
