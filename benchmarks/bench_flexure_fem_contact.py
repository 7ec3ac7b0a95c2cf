"""Solid FEM with contact: convergence in the contact stations and the mesh (docs/flexure.md,
"Solid FEM: contact discretisation").

    .venv/bin/python benchmarks/bench_flexure_fem_contact.py [--stations 18,36,72,144]
                                                             [--spacings 0.5,0.25,0.1]
                                                             [--edges 1.015] [--gaps as_built]

One process, sequential: per tet edge length (mm; the default is the wire radius, as
``designlab flexure --fem``) the Visiflex catalogue helix is meshed once (gmsh, TET10) and
``fem_contact_stiffness`` runs on that mesh for every station density. Per run: the camera-frame
goal metrics at the paper's offset (mean |error| over the measured diagonal, couplings
model / measured), unloaded and at the 10 N working load, the contact counts (node contacts:
``--stations`` per turn, and how many stations have no node on the top contact line; line
contacts: ``--spacings`` mm between points along the wire), the condensed dofs, the spring-centre diagonal at 10 N, wall and CPU s.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from designlab.mesh.meshing import mesh_part
from designlab.sensors.flexure import report as fr
from designlab.sensors.flexure.beam_chain import ChainSettings
from designlab.sensors.flexure.helix_fem import (contact_candidates, fem_contact_stiffness,
                                                 flexure_from_spring)
from designlab.sensors.flexure.spring import VISIFLEX_CATALOG


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stations", default="18,36,72,144",
                    help="contact stations per turn, comma separated")
    ap.add_argument("--spacings", default="0.5,0.25,0.1",
                    help="line contacts: point spacings along the wire, mm, comma separated "
                         "(empty: none)")
    ap.add_argument("--edges", default=str(VISIFLEX_CATALOG.wire_radius),
                    help="tet edge lengths, mm, comma separated")
    ap.add_argument("--gaps", default="as_built", choices=("as_built", "meshed"))
    a = ap.parse_args(argv)
    runs = ([("nodes", int(s)) for s in a.stations.split(",") if s]
            + [("line", float(s)) for s in a.spacings.split(",") if s])
    edges = [float(e) for e in a.edges.split(",")]
    paper = fr.load_paper()
    flex = flexure_from_spring(VISIFLEX_CATALOG)
    print("| edge mm | nodes | contacts | condensed dofs | coil + seat contacts | "
          "closed at 10 N (length) | diag. error 0 / 10 N | couplings 0 N | couplings 10 N | "
          "k_wx / k_wy / k_vx / k_vy / k_vz at 10 N | wall s | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for h in edges:
        w0, c0 = time.perf_counter(), time.process_time()
        mesh = mesh_part(flex, order=2, edge_length=h, quality="default", mesher="gmsh")
        print(f"<!-- mesh edge {h:g} mm: {mesh.n_points} nodes, "
              f"{time.perf_counter() - w0:.1f} s wall, {time.process_time() - c0:.1f} s CPU -->",
              flush=True)
        for kind, n in runs:
            w0, c0 = time.perf_counter(), time.process_time()
            sol = fem_contact_stiffness(VISIFLEX_CATALOG, edge_length=h, gaps=a.gaps,
                                        stations_per_turn=int(n) if kind == "nodes" else 36,
                                        contact_spacing_mm=0.0 if kind == "nodes" else n,
                                        mesh=mesh, settings=ChainSettings(seat="bonded"))
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
            print(f"| {h:g} | {i['n_nodes']} | {where} | {i['condensed_dofs']} | "
                  f"{i['coil_pairs']} + {i['seat_contacts']} | "
                  f"{wl['closed_contacts']} ({wl['closed_length_mm']:.1f} mm) | "
                  f"{g0['diagonal_mean_abs_error_pct']:.1f} / "
                  f"{g1['diagonal_mean_abs_error_pct']:.1f} % | {c0s} | {c1s} | "
                  f"{d[0]:.0f} / {d[1]:.0f} / {d[3]:.2f} / {d[4]:.2f} / {d[5]:.2f} | "
                  f"{wall:.1f} | {cpu:.1f} |", flush=True)


if __name__ == "__main__":
    main()
