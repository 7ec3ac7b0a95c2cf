"""The FEM stage of a sensor definition: mesh from the B-rep with its named faces, the model
(materials, rigid bodies, supports, interfaces, force sensors' springs, load couplings), the
unit-load responses and the transducers' linear read-out operators.

Each load point gets six unit load cases at its face's centroid (Fx, Fy, Fz in N, Mx, My, Mz in
N mm); any held load is a combination of them, so one factorisation serves every load state of
the protocol and every design that differs only in where loads act."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from designlab.errors import ParameterError
from designlab.fem.model import Model
from designlab.mesh.meshing import MeshResult, mesh_part_detailed
from designlab.mesh.tetmesh import TetMesh
from designlab.sensors import definition as d
from designlab.sensors.generic.faces import region_nodes, select, select_owned

COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
UNITS = ("N", "N", "N", "N mm", "N mm", "N mm")


@dataclass
class Channel:
    """One reading of a transducer: name, unit, noise (one standard deviation, same unit)."""

    name: str
    unit: str
    noise: float
    transducer: str


def mesh_definition(defn, settings) -> MeshResult:
    """The definition's declared bodies (:meth:`solids`) meshed together, one region per body
    (a built-in's CAD part meshes fewer, those its own physics models)."""
    return mesh_part_detailed(defn, names=tuple(defn.solids()), order=settings.order,
                              edge_length=settings.edge_length, quality=settings.mesh_quality,
                              mesher=settings.mesher)


def _coupled(model: Model, name: str, face, what: str, at=None):
    tri = select(model.mesh, face, what)
    model.mesh.facet_sets[name] = tri
    return model.distributing_coupling(name, name, ref_point=at)


def _supports(model: Model, defn, rigid: dict[str, Any]) -> None:
    items = defn.supports()
    if not any(isinstance(s, (d.Clamped, d.ElasticSupport)) for s in items):
        raise ParameterError("supports", [type(s).__name__ for s in items],
                             "at least one Clamped or ElasticSupport face (the sensor must be held)")
    for k, s in enumerate(items):
        what = f"supports[{k}]"
        if isinstance(s, d.Clamped):
            nodes = np.unique(select(model.mesh, s.face, f"{what}.face"))
            # a rigid body's nodes follow its reference point: clamping the face holds it
            model.fix(rigid[s.face.body] if s.face.body in rigid else nodes)
        elif isinstance(s, d.ElasticSupport):
            ref = _coupled(model, f"support{k}", s.face, f"{what}.face")
            for i, kk in enumerate(s.stiffness_N_per_mm):
                if kk > 0:
                    model.spring(f"support{k}_{i}", ref, None, float(kk), axis=np.eye(3)[i])
        elif isinstance(s, d.ElasticInterface):
            a = _coupled(model, f"interface{k}a", s.face_a, f"{what}.face_a")
            b = _coupled(model, f"interface{k}b", s.face_b, f"{what}.face_b")
            for i, kk in enumerate(s.stiffness_N_per_mm):
                if kk > 0:
                    model.spring(f"interface{k}_{i}", a, b, float(kk), axis=np.eye(3)[i])
        else:
            raise ParameterError(what, type(s).__name__,
                                 "Clamped, ElasticSupport or ElasticInterface")


def _rigid_bodies(model: Model, defn) -> dict[str, Any]:
    """{body: its rigid coupling's reference point} of the rigid bodies."""
    out = {}
    for name, s in defn.solids().items():
        if s.rigid:
            out[name] = model.rigid(f"rigid_{name}", model.mesh.cells[
                model.mesh.region == model.mesh.region_id(name)].ravel())
    return out


def _force_sensor_springs(model: Model, defn) -> None:
    for k, t in enumerate(defn.transducers()):
        if not isinstance(t, d.ForceSensor):
            continue
        what = f"transducers[{k}] ({t.name})"
        a = _coupled(model, f"fs_{t.name}_a", t.face_a, f"{what}.face_a")
        b = None if t.face_b is None else _coupled(model, f"fs_{t.name}_b", t.face_b,
                                                    f"{what}.face_b")
        axis = d.check_vector(f"{what}.axis", t.axis)
        axis = axis / np.linalg.norm(axis)
        model.spring(f"fs_{t.name}", a, b, float(t.stiffness_N_per_mm), axis=axis)
        lat = t.lateral_N_per_mm if t.lateral_N_per_mm is not None else t.stiffness_N_per_mm
        for i, e in enumerate(_perpendicular(axis)):
            model.spring(f"fs_{t.name}_lat{i}", a, b, float(lat), axis=e)


def _perpendicular(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.eye(3)[int(np.argmin(np.abs(axis)))]
    u = np.cross(axis, e)
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


def check_load_points(defn, mesh: TetMesh) -> None:
    """Every load point inside the part's bounding box (a load acting elsewhere is a wrench
    about a point of the part); unique names."""
    lo, hi = mesh.points.min(0), mesh.points.max(0)
    tol = 1e-6 * float(np.linalg.norm(hi - lo))
    seen = set()
    for k, lp in enumerate(defn.loads()):
        if not isinstance(lp, d.LoadPoint):
            raise ParameterError(f"loads[{k}]", type(lp).__name__, "a LoadPoint")
        if lp.name in seen:
            raise ParameterError(f"loads[{k}].name", lp.name, "a name no other load point has")
        seen.add(lp.name)
        if lp.at is not None:
            at = np.asarray(lp.at, float)
            if at.shape != (3,) or np.any(at < lo - tol) or np.any(at > hi + tol):
                raise ParameterError(f"loads[{k}] ({lp.name}).at", tuple(lp.at),
                                     "a point inside the part's bounding box "
                                     f"{np.round(lo, 3).tolist()}..{np.round(hi, 3).tolist()} mm "
                                     "(a load acting elsewhere is a wrench about it)")


def load_couplings(model: Model, defn) -> dict[str, np.ndarray]:
    """Distributing couplings of the load points at their faces' centroids; {name: centroid}."""
    check_load_points(defn, model.mesh)
    out = {}
    for k, lp in enumerate(defn.loads()):
        ref = _coupled(model, f"load_{lp.name}", lp.face, f"loads[{k}] ({lp.name}).face")
        out[lp.name] = np.asarray(ref.x, float)
        for j, comp in enumerate(COMPONENTS):
            f = np.zeros(6)
            f[j] = 1.0
            model.force(ref, f[:3], f[3:], case=f"{lp.name}.{comp}")
    if not out:
        raise ParameterError("loads", [], "at least one LoadPoint")
    return out


def build_model(mesh: TetMesh, defn) -> tuple[Model, dict[str, np.ndarray]]:
    """The linear model of the definition on ``mesh`` and its load points' centroids."""
    model = Model(mesh)
    rigid = _rigid_bodies(model, defn)
    _supports(model, defn, rigid)
    _force_sensor_springs(model, defn)
    centroids = load_couplings(model, defn)
    return model, centroids


# ----------------------------------------------------------------------------- read-out

def _mean_motion(model: Model, nodes: np.ndarray) -> sp.csr_matrix:
    """(3, n_dofs) map u -> mean displacement of ``nodes``."""
    n = len(nodes)
    rows = np.repeat(np.arange(3), n)
    cols = (3 * nodes[None, :] + np.arange(3)[:, None]).ravel()
    return sp.csr_matrix((np.full(3 * n, 1.0 / n), (rows, cols)), shape=(3, model.n_dofs))


#: sample points of a gauge's grid (along x across) at which the surface strain is averaged
GRID_SAMPLES = (7, 3)


def _gauge_operator(model: Model, t: d.StrainGauge, what: str) -> sp.csr_matrix:
    """(1, n_dofs) map u -> the strain along the gauge's direction, averaged over sample points
    of its grid on the face's surface (each evaluated in the cell under it, so the reading is
    the surface strain a bonded foil sees, not a cell average)."""
    from designlab.fem.elements import tet_element

    mesh = model.mesh
    tri, owner = select_owned(mesh, t.face, f"{what}.face")
    tri = tri[:, :3]
    p = mesh.points
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    n = np.cross(b - a, c - a).sum(0)
    n /= np.linalg.norm(n)
    e1 = d.check_vector(f"{what}.direction", t.direction)
    e1 = e1 - (e1 @ n) * n
    if not np.linalg.norm(e1) > 1e-9:
        raise ParameterError(f"{what}.direction", tuple(t.direction), "a direction along the face")
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    ctr = np.asarray(t.center, float)
    u_s = np.linspace(-0.5, 0.5, GRID_SAMPLES[0]) * t.length_mm
    v_s = np.linspace(-0.5, 0.5, GRID_SAMPLES[1]) * t.width_mm
    pts = np.array([ctr + u * e1 + v * e2 for u in u_s for v in v_s])
    cells = owner[_facets_under(p, tri, pts, what, t)]
    el = tet_element(mesh.cells.shape[1])
    rows_c, vals = [], []
    for x, e in zip(pts, cells):
        nodes = mesh.cells[e]
        X0 = p[nodes[:4]]
        xi = np.linalg.solve((X0[1:] - X0[0]).T, x - X0[0])
        dN = el.dN(xi[None])[0]                                  # (nn, 3) natural
        J = p[nodes].T @ dN                                      # (3, 3)
        g = dN @ np.linalg.inv(J)                                # (nn, 3) d/dx
        # strain along e1: sum_a (e1 . grad N_a)(e1 . u_a)
        w = (g @ e1)[:, None] * e1[None, :]                      # (nn, 3)
        rows_c.append((3 * nodes[:, None] + np.arange(3)).ravel())
        vals.append(w.ravel() / len(pts))
    cols = np.concatenate(rows_c)
    return sp.csr_matrix((np.concatenate(vals), (np.zeros(len(cols), int), cols)),
                         shape=(1, model.n_dofs))


def _facets_under(p: np.ndarray, tri: np.ndarray, pts: np.ndarray, what: str, t) -> np.ndarray:
    """The index of the face triangle under each point (within the face's plane)."""
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    v0, v1 = b - a, c - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    den = d00 * d11 - d01 ** 2
    out = []
    for x in pts:
        v2 = x - a
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        l1 = (d11 * d20 - d01 * d21) / den
        l2 = (d00 * d21 - d01 * d20) / den
        inside = np.minimum(np.minimum(l1, l2), 1 - l1 - l2)
        k = int(np.argmax(inside))
        h = np.abs(((x - a[k]) @ np.cross(v0[k], v1[k])) / np.linalg.norm(np.cross(v0[k], v1[k])))
        if inside[k] < -1e-6 or h > 1e-3 * (1.0 + np.linalg.norm(x)):
            raise ParameterError(f"{what}.center", tuple(t.center), f"a point whose "
                                 f"{t.length_mm:g} x {t.width_mm:g} mm grid lies on its face")
        out.append(k)
    return np.asarray(out)


def read_operators(model: Model, defn) -> tuple[sp.csr_matrix, list[Channel]]:
    """(n_channels, n_dofs) operator from displacements to the transducers' readings (linear
    about the unloaded state) and the channels."""
    from designlab.fem.transducers import divider_slope

    rows, chans = [], []
    for k, t in enumerate(defn.transducers()):
        what = f"transducers[{k}] ({getattr(t, 'name', type(t).__name__)})"
        if isinstance(t, d.ForceSensor):
            L = t.stiffness_N_per_mm * t.sensitivity_V_per_N * model.spring_map(
                model.springs[f"fs_{t.name}"])
            rows.append(L)
            chans.append(Channel(t.name, "V", t.noise_V, t.name))
        elif isinstance(t, d.StrainGauge):
            if t.kind not in ("foil", "printed"):
                raise ParameterError(f"{what}.kind", t.kind, "'foil' or 'printed'")
            op = _gauge_operator(model, t, what)
            if t.kind == "foil":
                scale, noise = t.gauge_factor / 4.0 * 1e3, (
                    t.noise if t.noise is not None else d.HX711_NOISE_MV_PER_V)
            else:
                if t.noise is None:
                    raise ParameterError(f"{what}.noise", None, "the read-out's noise in V "
                                         "(a printed gauge has no default read-out)")
                scale, noise = float(divider_slope(t.R0_ohm)) * t.R0_ohm * t.gauge_factor, t.noise
            rows.append(scale * op)
            chans.append(Channel(t.name, t.unit, float(noise), t.name))
        elif isinstance(t, d.DisplacementProbe):
            dv = d.check_vector(f"{what}.direction", t.direction)
            L = _mean_motion(model, region_nodes(model.mesh, t.where, f"{what}.where"))
            if t.relative_to is not None:
                L = L - _mean_motion(model, region_nodes(model.mesh, t.relative_to,
                                                          f"{what}.relative_to"))
            rows.append(sp.csr_matrix(t.gain * (dv[None] @ L)))
            chans.append(Channel(t.name, t.unit, t.noise, t.name))
        elif isinstance(t, d.RotationProbe):
            ax = d.check_vector(f"{what}.axis", t.axis)
            ref = _probe_ref(model, t.where, f"probe_{t.name}", f"{what}.where")
            tw = model.twist_map(ref)[3:]
            rows.append(sp.csr_matrix(t.gain * (ax / np.linalg.norm(ax))[None] @ tw))
            chans.append(Channel(t.name, t.unit, t.noise, t.name))
        elif isinstance(t, d.CapacitiveGap):
            tri = select(model.mesh, t.face_a, f"{what}.face_a")[:, :3]
            p = model.mesh.points
            n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]]).sum(0)
            n /= np.linalg.norm(n)
            a = _mean_motion(model, np.unique(tri))
            b = _mean_motion(model, region_nodes(model.mesh, t.face_b, f"{what}.face_b"))
            c0 = d.EPS0_PF_PER_MM * t.eps_r * t.area_mm2 / t.gap_mm
            # the gap closes when face a moves along its outward normal towards b: dC = C0/g dg
            rows.append(sp.csr_matrix(c0 / t.gap_mm * (n[None] @ (a - b))))
            chans.append(Channel(t.name, "pF", t.noise_pF, t.name))
        elif isinstance(t, d.Magnet):
            ref = _probe_ref(model, t.carrier, f"magnet_{t.name}", f"{what}.carrier",
                             at=t.position)
            J = dipole_jacobian(np.asarray(t.position, float), np.asarray(t.moment_Am2, float),
                                np.asarray(t.sensor_at, float))
            rows.append(sp.csr_matrix(J @ model.twist_map(ref)))
            for axis in "xyz":
                chans.append(Channel(f"{t.name}.B{axis}", "uT", t.noise_uT, t.name))
        else:
            raise ParameterError(what, type(t).__name__, "one of " + ", ".join(
                c.__name__ for c in d.TRANSDUCERS))
    if not rows:
        raise ParameterError("transducers", [], "at least one transducer")
    _unique_names(chans)
    return sp.vstack([sp.csr_matrix(r) for r in rows]).tocsr(), chans


def _unique_names(chans: list[Channel]) -> None:
    seen = set()
    for c in chans:
        if c.name in seen:
            raise ParameterError("transducers", c.name, "unique transducer names")
        seen.add(c.name)


def _probe_ref(model: Model, where, name: str, what: str, at=None):
    nodes = region_nodes(model.mesh, where, what)
    return model.distributing_coupling(name, nodes, ref_point=at)


MU0_4PI = 1e-7   # mu_0 / 4 pi, T m / A


def dipole_field_uT(p_mm: np.ndarray, m_Am2: np.ndarray, s_mm: np.ndarray) -> np.ndarray:
    """Flux density (uT) at ``s`` of a point dipole ``m`` at ``p``: mu0/4pi (3 r^(m.r^) - m)/r^3."""
    r = (s_mm - p_mm) * 1e-3
    rn = np.linalg.norm(r)
    rh = r / rn
    return MU0_4PI * (3.0 * rh * (m_Am2 @ rh) - m_Am2) / rn ** 3 * 1e6


def dipole_jacobian(p: np.ndarray, m: np.ndarray, s: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """(3, 6) change of the field at ``s`` per translation (mm) and rotation (rad) of the magnet
    (central differences; the rotation turns the moment, m' = m + theta x m)."""
    J = np.zeros((3, 6))
    for i in range(3):
        e = np.eye(3)[i] * h
        J[:, i] = (dipole_field_uT(p + e, m, s) - dipole_field_uT(p - e, m, s)) / (2 * h)
        J[:, 3 + i] = (dipole_field_uT(p, m + np.cross(e, m), s)
                       - dipole_field_uT(p, m - np.cross(e, m), s)) / (2 * h)
    return J


# ----------------------------------------------------------------------------- the stage

def fem_stage(defn, settings, progress=None) -> dict[str, Any]:
    """Mesh, model and read-out of ``defn``: the model with its unit load cases, the channel
    table, the mesh; the unit loads' static solve is :func:`static_response`'s (a
    viscoelastic run marches instead)."""
    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    say("meshing")
    meshed = mesh_definition(defn, settings)
    mesh = meshed.mesh
    t1 = time.perf_counter()
    model, centroids = build_model(mesh, defn)
    read, chans = read_operators(model, defn)
    t2 = time.perf_counter()
    return {"model": model, "mesh": model.mesh, "mesh_result": meshed, "centroids": centroids,
            "cases": list(model.cases), "read": read, "channels": chans,
            "timings_s": {"mesh": t1 - t0, "assemble": t2 - t1}}


def static_response(stage: dict[str, Any], solver: str, progress=None) -> tuple[np.ndarray,
                                                                                 np.ndarray]:
    """(U (n_dofs, n_cases) mm, R (n_channels, n_cases) readings) of the unit load cases with
    the instantaneous moduli, solved once per stage."""
    if "U" not in stage:
        from designlab.fem.static import solve_static

        model = stage["model"]
        if progress:
            progress(f"solving {len(model.cases)} unit load cases on {3 * model.mesh.n_points} "
                     "dofs")
        res = solve_static(model, solver=solver)
        stage["U"] = np.asarray(res.U)
        stage["R"] = np.asarray(stage["read"] @ stage["U"])
    return stage["U"], stage["R"]
