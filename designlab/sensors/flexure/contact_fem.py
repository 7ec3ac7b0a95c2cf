"""Solid FEM 6x6 of a closed-and-ground spring with unilateral coil and seat contact: the
helix meshed as the part builds it, condensed on its contact lines and the tip master, solved by
the beam chain's active set (the chain's reference). Scheme and numbers:
docs/models/flexure_contact_fem.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from designlab.errors import ParameterError
from designlab.fem.materials import get_material
from designlab.fem.model import Model
from designlab.fem.solvers import factorize
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import TetMesh
from designlab.sensors.flexure.active_set import ActiveSet
from designlab.sensors.flexure.chain_geometry import (RAMP, ChainSettings, as_built,
                                                      wire_contact_points)
from designlab.sensors.flexure.helix_fem import (CURVED_DEFAULT, Progress, flexure_from_spring,
                                                 helix_mesh, spring_material, wire_surface)
from designlab.sensors.flexure.spring import HelicalSpring, to_si


@dataclass(frozen=True)
class ContactFEM:
    """Solid FEM 6x6 with unilateral coil and seat contact, unloaded (``K``) and at the axial
    working load (``K_loaded``), at the tip master ``master`` (global axes, N*mm/rad, N/mm, N);
    ``K_free`` the same condensed model with every contact open (no contact)."""

    K: np.ndarray
    K_loaded: np.ndarray | None
    K_free: np.ndarray
    master: np.ndarray
    centre: np.ndarray
    info: dict
    mesh: TetMesh | None = None

    def at(self, point, which: str = "unloaded") -> np.ndarray:
        K = {"unloaded": self.K, "loaded": self.K_loaded, "free": self.K_free}[which]
        return transform_stiffness(K, transform(translation=self.master - np.asarray(point, float)))

    def centre_si(self, which: str = "unloaded") -> np.ndarray:
        return to_si(self.at(self.centre, which))


def _wire_coordinates(mesh: TetMesh, flexure, samples_per_turn: int = 720):
    """Turn count ``u`` of the nearest centreline point and the offset from it for every mesh
    node (the part's centreline in the mesh frame: base seat at z = 0)."""
    from scipy.spatial import cKDTree

    N = flexure.total_coils
    u = np.linspace(0.0, N, int(N * samples_per_turn) + 1)
    c = wire_surface(flexure).centre(u)
    _, k = cKDTree(c).query(mesh.points)
    return u[k], mesh.points - c[k]


def contact_candidates(mesh: TetMesh, flexure, stations_per_turn: int = 36,
                       line_angle: float = np.radians(30.0)) -> dict:
    """Nodes of the solid helix on its top and bottom contact lines, one per station.

    A node is on the top (bottom) line when it lies on the wire surface (``|offset| > 0.9 r``)
    within ``line_angle`` of the section's top (bottom), ``offset`` being its position relative
    to the nearest centreline point; per station (``1 / stations_per_turn`` turn of wire) the
    node closest to the top (bottom) represents it. Returns ``u``, ``top`` and ``bottom`` (node
    per station or -1) and the station turn counts."""
    r = flexure.wire_radius
    u, off = _wire_coordinates(mesh, flexure)
    rad = np.linalg.norm(off, axis=1)
    on = rad > 0.9 * r
    cz = np.where(on, off[:, 2] / np.maximum(rad, 1e-12), 0.0)
    n_st = int(np.ceil(flexure.total_coils * stations_per_turn))
    st = np.minimum((u * stations_per_turn).astype(int), n_st - 1)
    top, bottom = np.full(n_st, -1), np.full(n_st, -1)
    best_t, best_b = np.full(n_st, np.cos(line_angle)), np.full(n_st, np.cos(line_angle))
    for i in np.nonzero(on)[0]:
        if cz[i] > best_t[st[i]]:
            best_t[st[i]], top[st[i]] = cz[i], i
        if -cz[i] > best_b[st[i]]:
            best_b[st[i]], bottom[st[i]] = -cz[i], i
    return {"u": u, "top": top, "bottom": bottom,
            "station_u": (np.arange(n_st) + 0.5) / stations_per_turn}


#: share of the contact FEM's wall time per stage (progress units of 1/1000 of the run), so the
#: progress bar's ETA is a time estimate (the measured split: docs/models/flexure_contact_fem.md)
_STAGES = (("mesh", 80), ("assemble", 30), ("factorise", 30), ("condense", 450),
           ("contact", 410))
_PROGRESS_TOTAL = sum(w for _, w in _STAGES)
#: back-substitution calls of the condensation (progress granularity: every call streams the
#: whole factor once more)
_CHUNKS = 4
#: largest dense right-hand-side block of one back-substitution call, bytes: finer meshes take
#: more calls (docs/models/flexure_contact_fem.md)
_RHS_BYTES = 1 << 30


def _at(stage: str, fraction: float = 0.0) -> tuple[int, int]:
    """(done, total) progress units at ``fraction`` of ``stage``."""
    done = 0
    for name, w in _STAGES:
        if name == stage:
            return int(done + fraction * w), _PROGRESS_TOTAL
        done += w
    raise KeyError(stage)


def _contact_inputs(spring, gaps: str, contact_spacing_mm, cs):
    """The part, its wire material and the contact spacing (mm), checked."""
    if isinstance(spring, HelicalSpring):
        flexure, mat = flexure_from_spring(spring), spring_material(spring)
    else:
        flexure, mat = spring, get_material(spring.material)
    if flexure.ends != "closed_ground":
        raise ParameterError("ends", flexure.ends, "closed_ground for the contact FEM (plain "
                             "ends have no dead turn)")
    if gaps not in ("as_built", "meshed"):
        raise ParameterError("gaps", gaps, "as_built or meshed")
    spacing = cs.contact_spacing_mm if contact_spacing_mm is None else float(contact_spacing_mm)
    if not (np.isfinite(spacing) and spacing >= 0):
        raise ParameterError("contact_spacing_mm", spacing,
                             "a spacing >= 0 mm (0: one node contact per station)")
    return flexure, mat, spacing


def _centreline(flexure, gaps: str) -> Callable:
    """Centreline height above the base seat at turn count(s) u: the spring as built at the
    same turn count (``gaps="as_built"``) or the meshed part's."""
    if gaps == "as_built":
        coil = as_built(HelicalSpring(wire_radius=flexure.wire_radius,
                                      mean_diameter=flexure.mean_diameter,
                                      coils=flexure.total_coils, inactive_coils=2.0,
                                      pitch_angle=flexure.pitch_angle))

        def zc(u):
            """As-built centreline height above the base seat at turn count(s) u."""
            return np.asarray(coil.z_of_u(u), float) - coil.seat_lo
        return zc
    z_lo = flexure._cut_planes()[0]

    def zc(u):
        """Meshed centreline height above the base seat at turn count(s) u."""
        return np.asarray(flexure.centerline_z(np.atleast_1d(u)), float).reshape(
            np.shape(u)) - z_lo
    return zc


def _line_weights(line, us) -> list:
    """{node: weight} per turn count in ``us`` on a contact line ``(nodes, turn counts)``,
    linear in turn count between its two nodes around it (None off the line's ends)."""
    nd, uu = line
    out = []
    for x in us:
        if len(uu) < 2 or x < uu[0] or x > uu[-1]:
            out.append(None)
            continue
        e = min(max(int(np.searchsorted(uu, x, side="right")) - 1, 0), len(uu) - 2)
        du = uu[e + 1] - uu[e]
        xi = 0.0 if du <= 0 else float((x - uu[e]) / du)
        w = {}
        for n, c in ((int(nd[e]), 1.0 - xi), (int(nd[e + 1]), xi)):
            if c:
                w[n] = w.get(n, 0.0) + c
        out.append(w)
    return out


def _contact_lines(mesh: TetMesh, flexure, h_turn: float):
    """The top and bottom contact lines of the wire (one node per half tet edge of the mesh
    made: the median corner edge, gmsh's sweep is not always as fine as ``edge_length``):
    ``({side: (nodes, turn counts)}, line nodes, bins per turn)``."""
    pc = mesh.points[mesh.cells[:, :4]]
    h_made = float(np.median(np.linalg.norm(pc[:, 1] - pc[:, 0], axis=1)))
    n_line = int(np.ceil(2 * h_turn / h_made))
    cand = contact_candidates(mesh, flexure, n_line)
    lines, line_nodes = {}, 0
    for side in ("top", "bottom"):
        nd = cand[side][cand[side] >= 0]
        uu = cand["u"][nd]
        o = np.lexsort((nd, uu))
        lines[side] = (nd[o], uu[o])
        line_nodes += len(nd)
    return lines, line_nodes, n_line


def _line_contacts(mesh: TetMesh, flexure, zc: Callable, spacing: float, h_turn: float):
    """Line contacts: points every ``spacing`` mm of wire, independent of the mesh nodes, each
    point's u_z interpolated between the two nodes of its contact line. Returns (contacts,
    line nodes, bins per turn); a contact is ({node: coefficient of its u_z}, tip seat point or
    None, initial gap mm, length of wire mm, kind, contact line id, turn count)."""
    d, r = flexure.wire_diameter, flexure.wire_radius
    L, N = float(flexure.length), flexure.total_coils
    lines, line_nodes, n_line = _contact_lines(mesh, flexure, h_turn)
    contacts = []
    points, lo_spans = wire_contact_points(zc, flexure.mean_diameter / 2, N, spacing)
    lid = 0
    for lo, hi in lo_spans:
        us, w = points(lo, hi)
        g = np.maximum(zc(us + 1) - zc(us) - d, 0.0)
        for a_, b_, gk, wk, uk in zip(_line_weights(lines["top"], us),
                                      _line_weights(lines["bottom"], us + 1), g, w, us):
            if a_ is None or b_ is None:
                continue
            coef = dict(b_)                               # upper wire bottom - lower top
            for n, c in a_.items():
                coef[n] = coef.get(n, 0.0) - c
            contacts.append((coef, None, float(gk), float(wk), "coil", lid, float(uk)))
        lid += 1
    R = flexure.mean_diameter / 2
    for lo, hi, side in ((0.0, 1.0, 1), (N - 1.0, N, -1)):
        us, w = points(lo, hi)
        z = zc(us)
        if side > 0:                                      # wire bottom above the base
            for a_, gk, wk, uk in zip(_line_weights(lines["bottom"], us),
                                      np.maximum(z - r, 0.0), w, us):
                if a_ is not None:
                    contacts.append((a_, None, float(gk), float(wk), "seat", lid, float(uk)))
        else:                                             # tip seat above the wire top
            pts = np.column_stack([R * np.cos(2 * np.pi * us), R * np.sin(2 * np.pi * us),
                                   z + r])
            for a_, p_, gk, wk, uk in zip(_line_weights(lines["top"], us), pts,
                                          np.maximum(L - z - r, 0.0), w, us):
                if a_ is not None:
                    contacts.append(({n: -c for n, c in a_.items()}, p_, float(gk),
                                     float(wk), "seat", lid, float(uk)))
        lid += 1
    return contacts, line_nodes, n_line


def _node_contacts(mesh: TetMesh, flexure, zc: Callable, stations_per_turn: int,
                   h_turn: float, base_nodes: set, tip_nodes: set) -> list:
    """Node contacts: one node per station, node to node along z (the contacts as
    :func:`_line_contacts` returns them)."""
    d, r = flexure.wire_diameter, flexure.wire_radius
    L, N = float(flexure.length), flexure.total_coils
    cand = contact_candidates(mesh, flexure, stations_per_turn)
    h_st = h_turn / stations_per_turn
    top, bot, su = cand["top"], cand["bottom"], cand["station_u"]
    span = 1.0 + RAMP
    contacts = []
    for k in range(len(su)):
        k_up = k + stations_per_turn
        if k_up >= len(su) or top[k] < 0 or bot[k_up] < 0:
            continue
        if not (su[k] <= span or su[k_up] >= N - span):
            continue
        i, j = int(top[k]), int(bot[k_up])
        # gap between the wire surfaces along z at the two nodes' stations (from the
        # centreline, as the chain: a node a few degrees off the top would add up to 0.27 mm)
        g = float(zc(cand["u"][j]) - zc(cand["u"][i]) - d)
        contacts.append(({j: 1.0, i: -1.0}, None, max(g, 0.0), h_st, "coil", 0,
                         float(cand["u"][i])))
    for k in range(len(su)):
        if su[k] <= 1.0 and bot[k] >= 0 and bot[k] not in base_nodes:
            n = int(bot[k])
            contacts.append(({n: 1.0}, None, max(float(zc(cand["u"][n])) - r, 0.0), h_st,
                             "seat", 1, float(cand["u"][n])))
        if su[k] >= N - 1.0 and top[k] >= 0 and top[k] not in tip_nodes:
            n = int(top[k])
            contacts.append(({n: -1.0}, mesh.points[n].copy(),
                             max(L - float(zc(cand["u"][n])) - r, 0.0), h_st, "seat", 2,
                             float(cand["u"][n])))
    return contacts


def _condense(system, keep: list, solver: str, step, timings: dict, t1: float):
    """The linear model condensed exactly on the kept dofs (one factorisation, the
    back-substitutions in chunks so the progress bar moves): (symmetrised compliance C,
    its asymmetry, reduced dofs, solver name, back-substitution calls)."""
    T = system.T.tocsr()
    Lmap = T[keep]                                 # (n_keep, n_free): q -> kept dofs
    K_full = system.K()
    Kr = system.reduce(K_full)
    timings["assemble"] = time.perf_counter() - t1
    step(f"factorising ({Kr.shape[0]} dofs)", *_at("factorise"))
    t1 = time.perf_counter()
    lin = factorize(Kr, solver, n_rhs=len(keep))
    timings["factorise"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    C = np.empty((len(keep), len(keep)))
    n_calls = max(_CHUNKS, int(np.ceil(8.0 * Kr.shape[0] * len(keep) / _RHS_BYTES)))
    chunks = np.array_split(np.arange(len(keep)), min(n_calls, len(keep)))
    for c, cols in enumerate(chunks):
        step(f"condensing on {len(keep)} dofs ({cols[0]}/{len(keep)})",
             *_at("condense", c / len(chunks)))
        C[:, cols] = np.asarray(Lmap @ lin.solve(np.asarray(Lmap[cols].T.todense())))
    timings["back_substitution"] = time.perf_counter() - t2
    asym = float(np.abs(C - C.T).max() / np.abs(C).max())
    C = (C + C.T) / 2
    timings["condense"] = time.perf_counter() - t1
    return C, asym, int(Kr.shape[0]), type(lin).__name__, len(chunks)


def _contact_moduli(mat, seat_material: str) -> tuple[float, float]:
    """Contact moduli E* (MPa) of wire on wire and of wire on the seat disc."""
    nu = mat.E / (2 * mat.G) - 1 if hasattr(mat, "G") and mat.G else mat.nu
    E_ss = mat.E / (2 * (1 - nu ** 2))
    seat_m = get_material(seat_material)
    E_seat = 1.0 / ((1 - nu ** 2) / mat.E + (1 - seat_m.nu ** 2) / seat_m.E)
    return E_ss, E_seat


def _contact_rows(contacts: list, nodes: list, mesh: TetMesh, tip_nodes: set, held: set,
                  L: float, moduli: tuple[float, float]) -> dict:
    """Each contact's gap opening per kept dof (u_z of its nodes: a kept dof, 0 on the base,
    rigid with the master on the tip), penalty ``E* x length`` (N/mm) and bookkeeping; a
    contact whose nodes are all held (bonded) or that nothing moves is dropped."""
    E_ss, E_seat = moduli
    n_keep = len(nodes) + 6
    pos = {n: a for a, n in enumerate(nodes)}
    m = np.arange(n_keep - 6, n_keep)
    master = np.array([0.0, 0.0, L])

    def uz(n):
        """(n_keep,) u_z of node n: a kept dof, 0 on the base, rigid with the master on the tip."""
        row = np.zeros(n_keep)
        if n in pos:
            row[pos[n]] = 1.0
        elif n in tip_nodes:
            x = mesh.points[n] - master
            row[m] = [0.0, 0.0, 1.0, x[1], -x[0], 0.0]           # u_z = v_z + w_x y - w_y x
        return row

    out = {k: [] for k in ("rows", "kn", "g0", "kinds", "runs", "lens", "us")}
    for coef, p_, g, w, kind, lid, uc in contacts:
        if all(n in held for n in coef):                        # the wire held there (bonded)
            continue
        row = np.zeros(n_keep)
        for n, c in coef.items():
            row += c * uz(n)
        if p_ is not None:                                      # the tip seat at p_
            x = p_ - master
            row[m] += [0.0, 0.0, 1.0, x[1], -x[0], 0.0]
        if not np.any(row):
            continue
        for k, v in (("rows", row), ("g0", g), ("kinds", kind), ("runs", lid), ("lens", w),
                     ("us", uc)):
            out[k].append(v)
        out["kn"].append((E_ss if kind == "coil" else E_seat) * w)
    return out


class _Solid(ActiveSet):
    """The condensed solid FEM as an active-set contact problem."""

    def __init__(self, Kc: np.ndarray, cs, rows: dict, line: bool):
        n_keep = Kc.shape[0]
        self.Kq, self.nq, self.m, self.s = sp.csr_matrix(Kc), n_keep, np.arange(n_keep - 6, n_keep), cs
        self.N = sp.csr_matrix(np.array(rows["rows"]).reshape(-1, n_keep))
        self.kn, self.g0 = np.array(rows["kn"]), np.array(rows["g0"])
        if line:
            self.runs = np.array(rows["runs"])  # line contacts grow from their deepest point


def _loaded_state(prob: _Solid, cs, rows: dict):
    """6x6 about the axial working load (force-controlled preload) and its contact summary;
    (None, None) without a working load."""
    if not cs.working_load_N > 0:
        return None, None
    m = prob.m
    pre = prob.solve(f_master=np.r_[0.0, 0.0, -cs.working_load_N, 0.0, 0.0, 0.0])
    K_loaded, closed_l = prob.stiffness(ref=pre)
    kinds, us_c = rows["kinds"], rows["us"]
    info_l = {"axial_deflection_mm": float(-pre["q"][m][2]),
              "closed_contacts": int(np.count_nonzero(pre["closed"])),
              "closed_length_mm": float(np.sum(np.array(rows["lens"])[pre["closed"]])),
              "closed_turns": [[kinds[c], round(us_c[c], 4)] for c in np.nonzero(pre["closed"])[0]],
              "closed_during_perturbations": [min(closed_l), max(closed_l)]}
    return K_loaded, info_l


def fem_contact_stiffness(spring, edge_length: float | None = None, order: int = 2,
                          quality: str = "default", solver: str = "auto",
                          gaps: str = "as_built", stations_per_turn: int = 36,
                          contact_spacing_mm: float | None = None,
                          settings=None, mesh: TetMesh | None = None,
                          progress: Progress | None = None,
                          curved: bool = CURVED_DEFAULT) -> ContactFEM:
    """Solid FEM 6x6 of a closed-and-ground spring with contact (the reference of the chain).

    The helix is meshed as the part builds it (ground faces bonded to the seats), condensed
    exactly on the contact nodes' z displacements and the master, and the chain's active-set
    iteration runs on that small system, unloaded and at ``settings.working_load_N``.

    Args:
        spring: a :class:`~designlab.sensors.flexure.spring.HelicalSpring` or a ``SpringFlexure``.
        edge_length, order, quality, curved: the mesh (:func:`helix_mesh`); ``mesh`` one made.
        solver: the linear solver of the condensation.
        gaps: ``"as_built"`` (the chain's gaps) or ``"meshed"`` (the part's own gaps).
        stations_per_turn: node contacts per turn (``contact_spacing_mm=0``).
        contact_spacing_mm: line contact spacing, mm (None: ``settings.contact_spacing_mm``).
        settings: a :class:`~designlab.sensors.flexure.chain_geometry.ChainSettings`.

    Returns:
        a :class:`ContactFEM` (N mm/rad, N/mm, N). The contact scheme in full:
        docs/models/flexure_contact_fem.md.
    """
    cs = settings or ChainSettings()
    step = progress or (lambda text, done, total: None)
    t0 = time.perf_counter()
    flexure, mat, spacing = _contact_inputs(spring, gaps, contact_spacing_mm, cs)
    L = float(flexure.length)
    timings = {}
    step("meshing the helix (gmsh)", *_at("mesh"))
    mesh_info = None
    if mesh is None:
        mesh, mesh_info = helix_mesh(flexure, edge_length, order=order, quality=quality,
                                     curved=curved)
    timings["mesh"] = time.perf_counter() - t0
    step("contact lines and assembly", *_at("assemble"))
    t1 = time.perf_counter()
    model = Model(mesh, materials={"spring": mat} if isinstance(spring, HelicalSpring) else None)
    model.fix("flexure_base")
    ref = model.rigid("tip_master", "flexure_tip", ref_point=(0.0, 0.0, L))
    system = model.build()
    base_nodes, tip_nodes = set(model.nodes("flexure_base")), set(model.nodes("flexure_tip"))
    zc = _centreline(flexure, gaps)
    h_turn = np.hypot(np.pi * flexure.mean_diameter, flexure.dead_pitch)
    line_nodes = n_line = 0
    if spacing > 0:
        contacts, line_nodes, n_line = _line_contacts(mesh, flexure, zc, spacing, h_turn)
    else:
        contacts = _node_contacts(mesh, flexure, zc, stations_per_turn, h_turn, base_nodes,
                                  tip_nodes)
    # kept dofs: u_z of every contact node (slaves of the master are expressed through it)
    nodes = sorted({n for c in contacts for n in c[0]})
    nodes = [n for n in nodes if n not in base_nodes and n not in tip_nodes]
    keep = [3 * n + 2 for n in nodes] + list(ref.dofs(mesh.n_points))
    C, asym, n_dofs, solver_name, n_calls = _condense(system, keep, solver, step, timings, t1)
    Kc = np.linalg.inv(C)
    Kc = (Kc + Kc.T) / 2
    step("contact active sets", *_at("contact"))
    t1 = time.perf_counter()
    rows = _contact_rows(contacts, nodes, mesh, tip_nodes, base_nodes | tip_nodes, L,
                         _contact_moduli(mat, cs.seat_material))
    prob = _Solid(Kc, cs, rows, spacing > 0)
    m = prob.m
    perm = np.array([3, 4, 5, 0, 1, 2])
    K_free = np.linalg.inv(C[np.ix_(m, m)])[np.ix_(perm, perm)]
    K_free = (K_free + K_free.T) / 2
    K, closed = prob.stiffness()
    K_loaded, info_l = _loaded_state(prob, cs, rows)
    timings["contact"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    step("done", _PROGRESS_TOTAL, _PROGRESS_TOTAL)
    kinds = rows["kinds"]
    info = {"n_nodes": int(mesh.n_points), "n_cells": int(mesh.n_cells),
            "cell_nodes": int(mesh.cells.shape[1]), "dofs": n_dofs,
            "condensed_dofs": len(keep), "coil_pairs": kinds.count("coil"),
            "seat_contacts": kinds.count("seat"), "gaps": gaps,
            "closed_gaps_at_start": int(np.sum(np.array(rows["g0"]) <= 0)),
            "stations_per_turn": None if spacing > 0 else stations_per_turn,
            "contact_spacing_mm": spacing, "line_nodes": line_nodes,
            "line_bins_per_turn": n_line if spacing > 0 else None, "asymmetry": asym,
            "closed_during_perturbations": [min(closed), max(closed)],
            "working_load": info_l, "solver": solver_name,
            "back_substitution_calls": n_calls, "mesh": mesh_info, "timings_s": timings}
    return ContactFEM(K, K_loaded, K_free, np.array([0.0, 0.0, L]), np.array([0.0, 0.0, L / 2]),
                      info, mesh)
