"""FEM 6x6 stiffness of a flexure: base clamped, tip coupled to a rigid 6-dof master (mm, N, MPa).

Six unit load cases at the master (three moments, three forces) give the columns of the
compliance ``C`` (twist (w, v) per wrench (m, f)); ``K = C^-1``. The compliance of a symmetric
linear model is symmetric, so ``||C - C^T|| / ||C||`` measures round-off and solver error only;
``K`` is returned symmetrised. :func:`stiffness_6x6` works on any mesh with a base and a tip set;
:func:`fem_stiffness` meshes a helical spring flexure (the parts helper's ``SpringFlexure``) and
expresses the result at the spring centre, as the closed form (:mod:`designlab.sensors.flexure.spring`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from designlab.errors import ModelError, ParameterError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.sensors.flexure.spring import HelicalSpring, to_si
from designlab.fem.static import solve_static
from designlab.frames import transform, transform_stiffness
from designlab.mesh.tetmesh import TetMesh

Progress = Callable[[str, int, int], None]
_CASES = (("m_x", (0, 0, 0), (1, 0, 0)), ("m_y", (0, 0, 0), (0, 1, 0)), ("m_z", (0, 0, 0), (0, 0, 1)),
          ("f_x", (1, 0, 0), (0, 0, 0)), ("f_y", (0, 1, 0), (0, 0, 0)), ("f_z", (0, 0, 1), (0, 0, 0)))


@dataclass(frozen=True)
class FlexureFEM:
    """FEM 6x6 of a flexure. ``K`` (N*mm/rad, N/mm, N) in a frame at ``master`` (global axes);
    ``C_raw`` the unsymmetrised compliance; ``centre`` the point where :attr:`K_centre` sits."""

    K: np.ndarray
    C_raw: np.ndarray
    master: np.ndarray
    centre: np.ndarray
    asymmetry: float
    n_nodes: int
    n_cells: int
    cell_nodes: int
    solver: str

    def at(self, point) -> np.ndarray:
        """K expressed in a frame at ``point`` (mm, global axes)."""
        return transform_stiffness(self.K, transform(translation=self.master - np.asarray(point, float)))

    @property
    def K_centre(self) -> np.ndarray:
        """K at the spring centre, designlab units."""
        return self.at(self.centre)

    @property
    def K_centre_si(self) -> np.ndarray:
        """K at the spring centre, SI (N*m/rad, N/m, N)."""
        return to_si(self.K_centre)

    def summary(self) -> dict:
        return {"n_nodes": self.n_nodes, "n_cells": self.n_cells, "cell_nodes": self.cell_nodes,
                "asymmetry": self.asymmetry, "master_mm": self.master.tolist(),
                "centre_mm": self.centre.tolist(), "solver": self.solver,
                "K_master": self.K.tolist(), "K_centre_si": self.K_centre_si.tolist()}


def stiffness_6x6(mesh: TetMesh, base: str, tip: str, master=None, centre=None,
                  materials: dict | None = None, solver: str = "auto",
                  progress: Progress | None = None) -> FlexureFEM:
    """6x6 stiffness of ``mesh`` with the set ``base`` clamped and ``tip`` rigid to a master.

    master: point of the 6-dof master (mm; default the centroid of the tip nodes).
    centre: reference point reported as :attr:`FlexureFEM.K_centre` (default midway between the
            base and tip centroids).
    """
    step = progress or (lambda text, done, total: None)
    step("assembling", 0, 3)
    model = Model(mesh, materials=materials)
    model.fix(base)
    ref = model.rigid("tip_master", tip, ref_point=master)
    for name, f, m in _CASES:
        model.force(ref, force=f, moment=m, case=name)
    step("solving 6 load cases", 1, 3)
    res = solve_static(model, solver=solver)
    step("compliance", 2, 3)
    C = np.column_stack([res.twist(ref, name) for name, _, _ in _CASES])
    asym = float(np.linalg.norm(C - C.T) / np.linalg.norm(C))
    Cs = (C + C.T) / 2
    try:
        K = np.linalg.inv(Cs)
    except np.linalg.LinAlgError:
        raise ModelError("FEM compliance of the flexure is singular: check the base/tip sets") from None
    K = (K + K.T) / 2
    base_c = mesh.points[model.nodes(base)].mean(axis=0)
    tip_c = mesh.points[model.nodes(tip)].mean(axis=0)
    cen = (base_c + tip_c) / 2 if centre is None else np.asarray(centre, float)
    step("done", 3, 3)
    return FlexureFEM(K=K, C_raw=C, master=np.asarray(ref.x, float), centre=cen, asymmetry=asym,
                      n_nodes=mesh.n_points, n_cells=mesh.n_cells, cell_nodes=mesh.cells.shape[1],
                      solver=type(res.solver).__name__)


def flexure_from_spring(spring: HelicalSpring, **kw):
    """The parts helper's ``SpringFlexure`` with this spring's wire, diameter, pitch and coils.

    ``inactive_coils`` 0 -> plain ends, 2 -> closed-and-ground ends (one dead coil each end);
    other values have no geometry and raise ParameterError. ``kw`` sets disc parameters (by
    default the part's, widened/narrowed to clear the coil; the discs are not meshed).
    """
    from designlab.geometry.flexure import SpringFlexure

    ends = {0.0: "plain", 2.0: "closed_ground"}.get(float(spring.inactive_coils))
    if ends is None:
        raise ParameterError("inactive_coils", spring.inactive_coils,
                             "0 (plain ends) or 2 (closed and ground ends) for the FEM geometry")
    R, r = spring.mean_radius, spring.wire_radius
    defaults = {f.name: f.default for f in dataclasses.fields(SpringFlexure)}
    kw.setdefault("disc_radius", max(defaults["disc_radius"], R + r + 1.0))
    kw.setdefault("disc_bore", max(0.0, min(defaults["disc_bore"], R - r - 1.0)))
    return SpringFlexure(wire_radius=r, mean_diameter=spring.mean_diameter,
                         pitch_angle=spring.pitch_angle, active_coils=spring.active_coils,
                         ends=ends, **kw)


def spring_material(spring: HelicalSpring) -> Material:
    """Isotropic wire material with the spring's E and G (nu = E / 2G - 1)."""
    return Material("spring_wire", E=spring.E, nu=spring.E / (2.0 * spring.G) - 1.0,
                    source="HelicalSpring E, G")


def fem_stiffness(spring, edge_length: float | None = None, order: int = 2,
                  quality: str = "default", solver: str = "direct",
                  progress: Progress | None = None) -> FlexureFEM:
    """FEM 6x6 of a spring flexure: mesh the helix, clamp ``flexure_base``, rigid ``flexure_tip``.

    spring:      a :class:`~designlab.sensors.flexure.spring.HelicalSpring` (its E, G are used for the wire)
                 or a ``SpringFlexure`` (its material name is used).
    edge_length: tet edge length, mm (default: the wire radius).
    solver:      "direct" by default: a slender wire has little fill-in (114k TET10 dofs of the
                 Visiflex helix factor in ~10 s) while AMG-CG converges slowly on it.
    The master sits on the axis at the tip face (``z = length``); :attr:`FlexureFEM.K_centre` is
    at the spring centre ``(0, 0, length / 2)``, the closed form's frame.
    """
    from designlab.mesh.meshing import mesh_part

    step = progress or (lambda text, done, total: None)
    if isinstance(spring, HelicalSpring):
        flexure, materials = flexure_from_spring(spring), {"spring": spring_material(spring)}
    else:
        flexure, materials = spring, None
    h = flexure.wire_radius if edge_length is None else float(edge_length)
    if not (np.isfinite(h) and h > 0):
        raise ParameterError("edge_length", edge_length, "a number > 0 mm")
    step("meshing the helix (gmsh)", 0, 4)
    mesh = mesh_part(flexure, order=order, edge_length=h, quality=quality, mesher="gmsh")
    L = float(flexure.length)

    def sub(text, done, total):
        step(text, 1 + done, 4)

    return stiffness_6x6(mesh, "flexure_base", "flexure_tip", master=(0.0, 0.0, L),
                         centre=(0.0, 0.0, L / 2), materials=materials, solver=solver,
                         progress=sub)


# ------------------------------------------------------------------ contact in the solid FEM

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

    R = flexure.mean_diameter / 2
    lo, _ = flexure._cut_planes()
    N = flexure.total_coils
    u = np.linspace(0.0, N, int(N * samples_per_turn) + 1)
    c = np.column_stack([R * np.cos(2 * np.pi * u), R * np.sin(2 * np.pi * u),
                         flexure.centerline_z(u) - lo])
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
#: progress bar's ETA is a time estimate: `designlab flexure --fem` on the Visiflex catalogue
#: spring (timings_s of its JSON, two runs on 2026-11-25: mesh 11-14 %, assembly 4 %,
#: factorisation 11-20 %, back-substitutions 62-73 %, contact < 1 %; docs/flexure.md)
_STAGES = (("mesh", 120), ("assemble", 40), ("factorise", 150), ("condense", 680),
           ("contact", 10))
_PROGRESS_TOTAL = sum(w for _, w in _STAGES)
#: back-substitution calls of the condensation (progress granularity: every call streams the
#: whole factor once more, ~1.3 s CPU each for the Visiflex helix)
_CHUNKS = 4


def _at(stage: str, fraction: float = 0.0) -> tuple[int, int]:
    """(done, total) progress units at ``fraction`` of ``stage``."""
    done = 0
    for name, w in _STAGES:
        if name == stage:
            return int(done + fraction * w), _PROGRESS_TOTAL
        done += w
    raise KeyError(stage)


def fem_contact_stiffness(spring, edge_length: float | None = None, order: int = 2,
                          quality: str = "default", solver: str = "auto",
                          gaps: str = "as_built", stations_per_turn: int = 36,
                          settings=None, mesh: TetMesh | None = None,
                          progress: Progress | None = None) -> ContactFEM:
    """Solid FEM 6x6 of a closed-and-ground spring with contact (the reference of the chain).

    The helix is meshed as the part builds it (gmsh, TET10; dead turns ``DEAD_GAP d`` clear of
    the first active turn so the solid does not touch itself), the ground faces clamped to the
    base and rigid with the tip master (bonded, as ``ChainSettings(seat="bonded")``). Contact,
    unilateral and frictionless, node to node along z between the stations of the top contact
    line of a turn and the bottom line one turn above (over each end's dead turn and ramp), and
    between the dead turns' bottom (top) line and the base (tip) seat plane where not bonded.
    ``gaps="as_built"`` (default): the initial gap of each contact is the spring's as built at
    the same turn count (:func:`~designlab.sensors.flexure.beam_chain.as_built`: dead pitch d,
    gap 0 at the wire end, the chain's geometry), the meshed clearance being what the mesher
    needs to keep the solid from touching itself; ``"meshed"``: the part's own gaps
    (dead turns ``DEAD_GAP d`` clear, pitch ramp from ``1 - RAMP / 2``: >= 0.4 mm for Visiflex). Penalty per contact ``k_n = E* h`` with ``h`` the
    station spacing along the wire (the chain's rule; seat E* with the disc material of
    ``settings.seat_material``).

    The linear model is condensed exactly on the contact nodes' z displacements and the master
    (one factorisation, one back-substitution per kept dof); the active-set iteration of
    :class:`~designlab.sensors.flexure.beam_chain.ActiveSet` then runs on that small system:
    symmetric perturbations about the unloaded state and about ``settings.working_load_N``
    (force-controlled axial preload), like the chain. Geometrically linear. ``mesh``: a mesh
    of this part already made (the same call otherwise meshes it).
    """
    import time

    import scipy.sparse as sp

    from designlab.fem.materials import get_material
    from designlab.fem.solvers import factorize
    from designlab.mesh.meshing import mesh_part
    from designlab.sensors.flexure.beam_chain import ActiveSet, ChainSettings, RAMP

    cs = settings or ChainSettings()
    step = progress or (lambda text, done, total: None)
    t0 = time.perf_counter()
    if isinstance(spring, HelicalSpring):
        flexure, mat = flexure_from_spring(spring), spring_material(spring)
    else:
        flexure, mat = spring, get_material(spring.material)
    if flexure.ends != "closed_ground":
        raise ParameterError("ends", flexure.ends, "closed_ground for the contact FEM (plain "
                             "ends have no dead turn)")
    h_mesh = flexure.wire_radius if edge_length is None else float(edge_length)
    d, r = flexure.wire_diameter, flexure.wire_radius
    if gaps not in ("as_built", "meshed"):
        raise ParameterError("gaps", gaps, "as_built or meshed")
    L, N = float(flexure.length), flexure.total_coils
    timings = {}
    step("meshing the helix (gmsh)", *_at("mesh"))
    if mesh is None:
        mesh = mesh_part(flexure, order=order, edge_length=h_mesh, quality=quality, mesher="gmsh")
    timings["mesh"] = time.perf_counter() - t0
    step("contact lines and assembly", *_at("assemble"))
    t1 = time.perf_counter()
    model = Model(mesh, materials={"spring": mat} if isinstance(spring, HelicalSpring) else None)
    model.fix("flexure_base")
    ref = model.rigid("tip_master", "flexure_tip", ref_point=(0.0, 0.0, L))
    system = model.build()
    base_nodes, tip_nodes = set(model.nodes("flexure_base")), set(model.nodes("flexure_tip"))
    cand = contact_candidates(mesh, flexure, stations_per_turn)
    if gaps == "as_built":
        from designlab.sensors.flexure.beam_chain import as_built

        coil = as_built(HelicalSpring(wire_radius=r, mean_diameter=flexure.mean_diameter,
                                      coils=N, inactive_coils=2.0,
                                      pitch_angle=flexure.pitch_angle))

        def zc(u):
            """As-built centreline height above the base seat at turn count u."""
            return float(coil.z_of_u(u)) - coil.seat_lo
    else:
        z_lo = flexure._cut_planes()[0]

        def zc(u):
            """Meshed centreline height above the base seat at turn count u."""
            return float(flexure.centerline_z(u)[0]) - z_lo

    top, bot, su = cand["top"], cand["bottom"], cand["station_u"]
    span = 1.0 + RAMP
    pairs = []                                    # (lower node, upper node, gap0)
    for k in range(len(su)):
        k_up = k + stations_per_turn
        if k_up >= len(su) or top[k] < 0 or bot[k_up] < 0:
            continue
        if not (su[k] <= span or su[k_up] >= N - span):
            continue
        i, j = top[k], bot[k_up]
        # gap between the wire surfaces along z at the two nodes' stations (from the
        # centreline, as the chain: a node a few degrees off the top would add up to 0.27 mm)
        g = zc(cand["u"][j]) - zc(cand["u"][i]) - d
        pairs.append((i, j, max(g, 0.0)))
    seats = []                                    # (node, gap0, +1 base / -1 tip)
    for k in range(len(su)):
        if su[k] <= 1.0 and bot[k] >= 0 and bot[k] not in base_nodes:
            seats.append((bot[k], max(zc(cand["u"][bot[k]]) - r, 0.0), 1))
        if su[k] >= N - 1.0 and top[k] >= 0 and top[k] not in tip_nodes:
            seats.append((top[k], max(L - zc(cand["u"][top[k]]) - r, 0.0), -1))
    # kept dofs: u_z of every contact node (slaves of the master are expressed through it)
    nodes = sorted({n for p in pairs for n in p[:2]} | {s[0] for s in seats})
    nodes = [n for n in nodes if n not in base_nodes and n not in tip_nodes]
    npts = mesh.n_points
    keep = [3 * n + 2 for n in nodes] + list(ref.dofs(npts))
    T = system.T.tocsr()
    Lmap = T[keep]                                 # (n_keep, n_free): q -> kept dofs
    K_full = system.K()
    Kr = system.reduce(K_full)
    timings["assemble"] = time.perf_counter() - t1
    step(f"factorising ({Kr.shape[0]} dofs)", *_at("factorise"))
    t1 = time.perf_counter()
    lin = factorize(Kr, solver, n_rhs=len(keep))
    timings["factorise"] = time.perf_counter() - t1
    # the condensation's back-substitutions in chunks, so the bar (and its ETA) moves
    t2 = time.perf_counter()
    B = np.asarray(Lmap.T.todense())
    X = np.empty_like(B)
    chunks = np.array_split(np.arange(len(keep)), min(_CHUNKS, len(keep)))
    for c, cols in enumerate(chunks):
        step(f"condensing on {len(keep)} dofs ({cols[0]}/{len(keep)})",
             *_at("condense", c / len(chunks)))
        X[:, cols] = lin.solve(B[:, cols])
    C = np.asarray(Lmap @ X)
    timings["back_substitution"] = time.perf_counter() - t2
    asym = float(np.abs(C - C.T).max() / np.abs(C).max())
    C = (C + C.T) / 2
    Kc = np.linalg.inv(C)
    Kc = (Kc + Kc.T) / 2
    timings["condense"] = time.perf_counter() - t1
    step("contact active sets", *_at("contact"))
    t1 = time.perf_counter()
    n_keep = len(keep)
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

    nu = mat.E / (2 * mat.G) - 1 if hasattr(mat, "G") and mat.G else mat.nu
    E_ss = mat.E / (2 * (1 - nu ** 2))
    seat_m = get_material(cs.seat_material)
    E_seat = 1.0 / ((1 - nu ** 2) / mat.E + (1 - seat_m.nu ** 2) / seat_m.E)
    h_st = np.hypot(np.pi * flexure.mean_diameter, flexure.dead_pitch) / stations_per_turn
    rows, kn, g0, kinds = [], [], [], []
    for i, j, g in pairs:
        row = uz(j) - uz(i)
        if np.any(row):
            rows.append(row), kn.append(E_ss * h_st), g0.append(g), kinds.append("coil")
    for n, g, side in seats:
        if side > 0:
            row = uz(n)                                         # wire bottom above the base
        else:
            x = mesh.points[n] - master
            seat = np.zeros(n_keep)
            seat[m] = [0.0, 0.0, 1.0, x[1], -x[0], 0.0]
            row = seat - uz(n)                                  # tip seat above the wire top
        rows.append(row), kn.append(E_seat * h_st), g0.append(g), kinds.append("seat")

    class _Solid(ActiveSet):
        pass

    prob = _Solid()
    prob.Kq, prob.nq, prob.m, prob.s = sp.csr_matrix(Kc), n_keep, m, cs
    prob.N = sp.csr_matrix(np.array(rows).reshape(-1, n_keep))
    prob.kn, prob.g0 = np.array(kn), np.array(g0)
    perm = np.array([3, 4, 5, 0, 1, 2])
    K_free = np.linalg.inv(C[np.ix_(m, m)])[np.ix_(perm, perm)]
    K_free = (K_free + K_free.T) / 2
    K, closed = prob.stiffness()
    K_loaded, info_l = None, None
    if cs.working_load_N > 0:
        pre = prob.solve(f_master=np.r_[0.0, 0.0, -cs.working_load_N, 0.0, 0.0, 0.0])
        K_loaded, closed_l = prob.stiffness(ref=pre)
        info_l = {"axial_deflection_mm": float(-pre["q"][m][2]),
                  "closed_contacts": int(np.count_nonzero(pre["closed"])),
                  "closed_during_perturbations": [min(closed_l), max(closed_l)]}
    timings["contact"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    step("done", _PROGRESS_TOTAL, _PROGRESS_TOTAL)
    info = {"n_nodes": int(mesh.n_points), "n_cells": int(mesh.n_cells),
            "cell_nodes": int(mesh.cells.shape[1]), "dofs": int(Kr.shape[0]),
            "condensed_dofs": n_keep, "coil_pairs": kinds.count("coil"),
            "seat_contacts": kinds.count("seat"), "gaps": gaps,
            "closed_gaps_at_start": int(np.sum(np.array(g0) <= 0)),
            "stations_per_turn": stations_per_turn, "asymmetry": asym,
            "closed_during_perturbations": [min(closed), max(closed)],
            "working_load": info_l, "solver": type(lin).__name__, "timings_s": timings}
    return ContactFEM(K, K_loaded, K_free, master, np.array([0.0, 0.0, L / 2]), info, mesh)
