"""Solid FEM with contact: convergence in the contact stations and the mesh (the model:
docs/models/flexure_contact_fem.md; the results: docs/validation/flexure.md).

    .venv/bin/python benchmarks/bench_flexure_fem_contact.py [--stations 18,36,72,144]
                                                             [--spacings 0.5,0.25,0.1]
                                                             [--edges 1.015] [--gaps as_built]
                                                             [--curved | --straight]
                                                             [--curve-by projection]

One process, sequential: per tet edge length (mm; the default is the wire radius, as
``designlab flexure --fem``) the Visiflex catalogue helix is meshed once (gmsh, TET10) and
``fem_contact_stiffness`` runs on that mesh for every station density. Per run: the camera-frame
goal metrics at the paper's offset (mean |error| over the measured diagonal, couplings
model / measured), unloaded and at the 10 N working load, the contact counts (node contacts:
``--stations`` per turn, and how many stations have no node on the top contact line; line
contacts: ``--spacings`` mm between points along the wire), the condensed dofs, the spring-centre diagonal at 10 N, wall and CPU s.

Mesh convergence: ``--edges`` takes
``default`` (the curvature-sized mesh of ``designlab flexure --fem``) or edge lengths in mm,
honoured (``helix_fem.helix_mesh``); ``--json-out FILE`` appends one JSON line per run (one
process per edge keeps ``/usr/bin/time`` peak memory per mesh), and

    .venv/bin/python benchmarks/bench_flexure_fem_contact.py --richardson FILE

prints, per contact setting, the Richardson extrapolation of the goal metrics and the
spring-centre diagonals over the three finest edges of FILE when their ratios are equal
(within 2 %): observed order ``p = ln((f1 - f2) / (f2 - f3)) / ln(ratio)`` and the limit
``f3 + (f3 - f2) / (ratio^p - 1)`` for a monotone sequence (``f1, f2, f3`` coarse to fine),
"not monotone" otherwise.

``--curved`` (the default, ``helix_fem.CURVED_DEFAULT``) / ``--straight``: TET10
with the wire surface's mid-edge nodes on the wire's surface, or on the chords (``helix_mesh(...,
curved=...)``, the same corners and cells); ``--curve-by projection`` (default: onto the swept
circle) or ``gmsh`` (gmsh's second-order nodes on the B-rep, a second gmsh run); the JSON lines
carry ``curved`` and ``curve_by`` and the extrapolation groups the runs by them.

    .venv/bin/python benchmarks/bench_flexure_fem_contact.py --curving default,0.5

compares the curvings per edge (no contact FEM): the mesh straight, curved by projection (twice:
bit-identical?) and curved by gmsh; per mesh the ``helix_mesh`` wall and CPU s, wire volume
error, smallest Jacobian ratio, cells straightened, the no-contact 6x6 diagonal at the spring
centre (``stiffness_6x6`` on that mesh, as ``fem_stiffness``) and, for the projection, the
distance of its mid-nodes from gmsh's (max / median over the nodes both move; nodes only one
moves: those of cells the other straightened).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.chain_geometry import ChainSettings
from designlab.sensors.flexure.contact_fem import contact_candidates, fem_contact_stiffness
from designlab.sensors.flexure.helix_fem import CURVED_DEFAULT, flexure_from_spring, helix_mesh
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stations", default="18,36,72,144",
                    help="contact stations per turn, comma separated")
    ap.add_argument("--spacings", default="0.5,0.25,0.1",
                    help="line contacts: point spacings along the wire, mm, comma separated "
                         "(empty: none)")
    ap.add_argument("--edges", default="default",
                    help="tet edge lengths, mm, comma separated; 'default': the mesh of "
                         "designlab flexure --fem (sized by the wire's curvature)")
    ap.add_argument("--gaps", default="as_built", choices=("as_built", "meshed"))
    ap.add_argument("--curved", dest="curved", action="store_true", default=CURVED_DEFAULT,
                    help="curved TET10: mid-edge nodes of the wire surface on it (default "
                         f"{'curved' if CURVED_DEFAULT else 'straight'})")
    ap.add_argument("--straight", dest="curved", action="store_false",
                    help="straight-sided TET10: mid-edge nodes on the chords")
    ap.add_argument("--curve-by", default="projection", choices=("projection", "gmsh"),
                    help="curved: projection onto the swept circle, or gmsh's second-order nodes")
    ap.add_argument("--json-out", default=None, help="append one JSON line per run to this file")
    ap.add_argument("--richardson", default=None,
                    help="extrapolate the runs of this JSON-lines file (no FEM run)")
    ap.add_argument("--mesh-survey", default=None,
                    help="edge lengths, mm, comma separated: mesh the helix (TET4) with the "
                         "mesher's own fallbacks, as before helix_mesh, and print what each "
                         "try made (no FEM run)")
    ap.add_argument("--curving", default=None,
                    help="edges ('default' or mm), comma separated: compare straight, projection "
                         "and gmsh curving (no contact FEM)")
    a = ap.parse_args(argv)
    if a.curving:
        curving_table([None if e.strip() == "default" else float(e)
                       for e in a.curving.split(",")])
        return
    if a.richardson:
        richardson_table(a.richardson)
        return
    if a.mesh_survey:
        mesh_survey([float(e) for e in a.mesh_survey.split(",")])
        return
    runs = ([("nodes", int(s)) for s in a.stations.split(",") if s]
            + [("line", float(s)) for s in a.spacings.split(",") if s])
    edges = [None if e.strip() == "default" else float(e) for e in a.edges.split(",")]
    paper = fr.load_paper()
    flex = flexure_from_spring(VISIFLEX_CATALOG)
    print("| edge mm | nodes | contacts | condensed dofs | coil + seat contacts | "
          "closed at 10 N (length) | diag. error 0 / 10 N | couplings 0 N | couplings 10 N | "
          "k_wx / k_wy / k_vx / k_vy / k_vz at 10 N | wall s | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for h in edges:
        w0, c0 = time.perf_counter(), time.process_time()
        mesh, minfo = helix_mesh(flex, h, order=2, curved=a.curved, curve_by=a.curve_by)
        mesh_s = (time.perf_counter() - w0, time.process_time() - c0)
        print(f"<!-- mesh edge {h} mm: {mesh.n_points} nodes, {mesh.n_cells} cells, median "
              f"corner edge {minfo['median_edge_mm']:.3f} mm, curved {a.curved} "
              f"({minfo['curve_by']}), volume "
              f"{100 * minfo['volume_error']:+.2f} % (corners {100 * minfo['volume_error_corners']:+.2f} %), "
              f"min Jacobian / corner {minfo.get('min_jacobian_ratio', float('nan')):.3f} "
              f"({minfo['straightened_cells']} cells straightened), "
              f"{minfo['sized_by']}; {mesh_s[0]:.1f} s wall, {mesh_s[1]:.1f} s CPU -->",
              flush=True)
        for kind, n in runs:
            w0, c0 = time.perf_counter(), time.process_time()
            sol = fem_contact_stiffness(VISIFLEX_CATALOG, edge_length=h, gaps=a.gaps,
                                        stations_per_turn=int(n) if kind == "nodes" else 36,
                                        contact_spacing_mm=0.0 if kind == "nodes" else n,
                                        mesh=mesh, settings=ChainSettings(seat="bonded"),
                                        curved=a.curved)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            rep = fr.flexure_report(VISIFLEX_CATALOG, paper=paper,
                                    K_fem_spring_si=sol.centre_si("unloaded"),
                                    K_fem_loaded_si=sol.centre_si("loaded"))
            g0, g1 = rep["goals"]["fem"], rep["goals"]["fem_loaded"]
            i = sol.info
            if kind == "nodes":
                cand = contact_candidates(mesh, flex, int(n))
                where = (f"{n:g} / turn ({np.count_nonzero(cand['top'] < 0)} of "
                         f"{len(cand['top'])} empty)")
            else:
                where = (f"line, {n:g} mm ({i['line_nodes']} line nodes, "
                         f"{i['line_bins_per_turn']} bins / turn)")
            d = np.diag(sol.at(sol.centre, "loaded"))
            c0s = " / ".join(f"{v:.2f}" for v in g0["coupling_model_over_measured"].values())
            c1s = " / ".join(f"{v:.2f}" for v in g1["coupling_model_over_measured"].values())
            wl = i["working_load"]
            if a.json_out:
                row = {"edge_mm": h, "median_edge_mm": minfo["median_edge_mm"],
                       "curved": a.curved, "curve_by": minfo["curve_by"],
                       "volume_error": minfo["volume_error"],
                       "volume_error_corners": minfo["volume_error_corners"],
                       "min_jacobian_ratio": minfo.get("min_jacobian_ratio"),
                       "straightened_cells": minfo["straightened_cells"], "sized_by": minfo["sized_by"],
                       "n_nodes": i["n_nodes"], "n_cells": i["n_cells"], "dofs": i["dofs"],
                       "contacts": kind, "n": n, "condensed_dofs": i["condensed_dofs"],
                       "closed_10N": wl["closed_contacts"],
                       "closed_length_10N_mm": wl["closed_length_mm"],
                       "diag_error_0N_pct": g0["diagonal_mean_abs_error_pct"],
                       "diag_error_10N_pct": g1["diagonal_mean_abs_error_pct"],
                       "couplings_0N": list(g0["coupling_model_over_measured"].values()),
                       "couplings_10N": list(g1["coupling_model_over_measured"].values()),
                       "diag_centre_10N": d.tolist(),
                       "diag_centre_0N": np.diag(sol.at(sol.centre, "unloaded")).tolist(),
                       "diag_centre_free": np.diag(sol.at(sol.centre, "free")).tolist(),
                       "mesh_s": mesh_s, "wall_s": wall, "cpu_s": cpu,
                       "back_substitution_calls": i["back_substitution_calls"],
                       "timings_s": i["timings_s"]}
                with open(a.json_out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
            print(f"| {h} | {i['n_nodes']} | {where} | {i['condensed_dofs']} | "
                  f"{i['coil_pairs']} + {i['seat_contacts']} | "
                  f"{wl['closed_contacts']} ({wl['closed_length_mm']:.1f} mm) | "
                  f"{g0['diagonal_mean_abs_error_pct']:.1f} / "
                  f"{g1['diagonal_mean_abs_error_pct']:.1f} % | {c0s} | {c1s} | "
                  f"{d[0]:.0f} / {d[1]:.0f} / {d[3]:.2f} / {d[4]:.2f} / {d[5]:.2f} | "
                  f"{wall:.1f} | {cpu:.1f} |", flush=True)


def curving_table(edges) -> None:
    """Straight, projection-curved and gmsh-curved TET10 of the catalogue helix per edge (the
    module docstring's ``--curving``)."""
    from designlab.sensors.flexure.helix_fem import spring_material, stiffness_6x6

    flex = flexure_from_spring(VISIFLEX_CATALOG)
    L = float(flex.length)
    mat = {"spring": spring_material(VISIFLEX_CATALOG)}
    print("| edge | TET10 | mesh wall / CPU s | wire volume | min Jacobian ratio | straightened "
          "| no contact k_wx / k_wy / k_wz, N*mm/rad | k_vx / k_vy / k_vz, N/mm | vs gmsh curved "
          "(largest) | mid-nodes vs gmsh: max / median mm (moved by one only) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for h in edges:
        meshes = {}
        for name, kw in (("straight", {"curved": False}), ("projection", {"curved": True}),
                         ("projection again", {"curved": True}),
                         ("gmsh", {"curved": True, "curve_by": "gmsh"})):
            w0, c0 = time.perf_counter(), time.process_time()
            mesh, info = helix_mesh(flex, h, order=2, **kw)
            meshes[name] = (mesh, info, time.perf_counter() - w0, time.process_time() - c0)
        same = np.array_equal(meshes["projection"][0].points,
                              meshes["projection again"][0].points)
        print(f"<!-- edge {h}: projection twice bit-identical: {same} -->", flush=True)
        del meshes["projection again"]
        diag = {}
        for name, (mesh, info, wall, cpu) in meshes.items():
            fem = stiffness_6x6(mesh, "flexure_base", "flexure_tip", master=(0.0, 0.0, L),
                                centre=(0.0, 0.0, L / 2), materials=mat, solver="direct")
            diag[name] = np.diag(fem.K_centre)
        s = meshes["straight"][0].points
        for name, (mesh, info, wall, cpu) in meshes.items():
            d = diag[name]
            rel = np.abs(d / diag["gmsh"] - 1).max()
            dist = "-"
            if name == "projection":
                g = meshes["gmsh"][0].points
                mp = np.linalg.norm(mesh.points - s, axis=1) > 1e-9
                mg = np.linalg.norm(g - s, axis=1) > 1e-9
                e = np.linalg.norm(mesh.points[mp & mg] - g[mp & mg], axis=1)
                dist = (f"{e.max():.2g} / {np.median(e):.2g} ({np.count_nonzero(mp & ~mg)} "
                        f"projection, {np.count_nonzero(mg & ~mp)} gmsh)")
            print(f"| {h if h is not None else 'default'} {name} | {mesh.n_points} nodes | "
                  f"{wall:.1f} / {cpu:.1f} | {100 * info['volume_error']:+.3f} % | "
                  f"{info['min_jacobian_ratio']:.3f} | {info['straightened_cells']} | "
                  f"{d[0]:.2f} / {d[1]:.2f} / {d[2]:.2f} | {d[3]:.4f} / {d[4]:.4f} / {d[5]:.4f} | "
                  f"{100 * rel:.4f} % | {dist} |", flush=True)


def mesh_survey(edges) -> None:
    """Per edge asked: the mesher's tries (``MeshResult.attempts``: size, curvature sizing, the
    volume check), the mesh kept (corner nodes, cells, median corner edge, wire volume error)."""
    from designlab.mesh.meshing import mesh_part_detailed

    flex = flexure_from_spring(VISIFLEX_CATALOG)
    print("| edge asked mm | corner nodes | cells | median corner edge mm | wire volume | tries |")
    print("|---|---|---|---|---|---|")
    for h in edges:
        res = mesh_part_detailed(flex, order=1, edge_length=h, quality="default", mesher="gmsh")
        m = res.mesh
        pc = m.points[m.cells]
        med = float(np.median(np.linalg.norm(pc[:, 1] - pc[:, 0], axis=1)))
        vol = float(m.corner_volumes.sum()) / sum(res.body_volumes.values()) - 1
        print(f"| {h:g} | {m.n_points} | {m.n_cells} | {med:.3f} | {100 * vol:+.2f} % | "
              f"{'; '.join(res.attempts)} |", flush=True)


def richardson(f1: float, f2: float, f3: float, ratio: float) -> dict:
    """Richardson extrapolation of ``f1, f2, f3`` (coarse to fine, edge ratio ``ratio``): the
    observed order ``p`` and the limit, or ``monotone: False`` when the differences change sign
    (or vanish) and nothing is extrapolated."""
    d1, d2 = f1 - f2, f2 - f3
    if d1 == 0 or d2 == 0 or (d1 > 0) != (d2 > 0):
        return {"monotone": False}
    p = float(np.log(d1 / d2) / np.log(ratio))
    limit = f3 + (f3 - f2) / (ratio ** p - 1.0)
    return {"monotone": True, "p": p, "limit": float(limit), "finest_minus_limit": float(f3 - limit)}


def richardson_table(path: str) -> None:
    """Print the extrapolation of the runs in the JSON-lines file ``path`` (see the module doc)."""
    rows = [json.loads(line) for line in open(path) if line.strip()]
    groups: dict = {}
    for r in rows:
        if r["edge_mm"] is not None:
            curved = bool(r.get("curved", False))
            # a curved run without ``curve_by`` (written before the projection existed) is gmsh's
            by = r.get("curve_by", "gmsh" if curved else None)
            groups.setdefault((curved, by, r["contacts"], r["n"]), {})[r["edge_mm"]] = r
    for (curved, by, kind, n), by_edge in groups.items():
        kind = f"{'curved (' + by + ')' if curved else 'straight'} TET10, {kind}"
        edges = sorted(by_edge, reverse=True)[-3:]
        if len(edges) < 3:
            print(f"{kind} {n}: {len(edges)} edge(s), need 3")
            continue
        r1, r2 = edges[0] / edges[1], edges[1] / edges[2]
        print(f"\n{kind} {n}: edges {edges} mm (ratios {r1:.3f}, {r2:.3f}), nodes "
              f"{[by_edge[e]['n_nodes'] for e in edges]}")
        if abs(r1 / r2 - 1) > 0.02:
            print("  ratios differ by more than 2 %: not extrapolated")
            continue
        ratio = float(np.sqrt(r1 * r2))
        names = {"wire volume error %": lambda r: 100 * r["volume_error"],
                 "diag. error 10 N %": lambda r: r["diag_error_10N_pct"],
                 "diag. error 0 N %": lambda r: r["diag_error_0N_pct"]}
        for k in range(2):
            names[f"coupling {k + 1} at 10 N (x measured)"] = lambda r, k=k: r["couplings_10N"][k]
            names[f"coupling {k + 1} at 0 N (x measured)"] = lambda r, k=k: r["couplings_0N"][k]
        for state in ("free", "0N", "10N"):
            for j, e in enumerate(("k_wx", "k_wy", "k_wz", "k_vx", "k_vy", "k_vz")):
                names[f"{e} {state}"] = lambda r, j=j, s=state: r[f"diag_centre_{s}"][j]
        print("| quantity | " + " | ".join(f"{e:g} mm" for e in edges)
              + " | observed order | extrapolated | finest - extrapolated |")
        print("|---|---|---|---|---|---|---|")
        for name, get in names.items():
            f = [float(get(by_edge[e])) for e in edges]
            x = richardson(*f, ratio)
            tail = (f"{x['p']:.2f} | {x['limit']:.4g} | {x['finest_minus_limit']:+.3g}"
                    if x["monotone"] else "not monotone | - | -")
            print(f"| {name} | " + " | ".join(f"{v:.4g}" for v in f) + f" | {tail} |")


if __name__ == "__main__":
    main()
