"""Model definition: materials per region, constraints, loads, couplings and springs.

A :class:`Model` wraps a :class:`~designlab.mesh.tetmesh.TetMesh` and collects definitions;
:meth:`Model.build` turns them into a :class:`System` (plain sparse arrays) that the static and
viscoelastic solvers share. Everything is linear, so loads live in named *load cases* that a
solver solves together (factor once) and a history can scale independently.

Degrees of freedom: ``3 * node + component`` for mesh nodes, then 6 per rigid reference point
(``3 * n_points + 6 * i + (v_x, v_y, v_z, w_x, w_y, w_z)``, translation then rotation).
Set names (``where``) may be facet sets, point sets, or an int array of node ids.
Components are strings: ``"xyz"``, ``"x"``, ``"all"``; rotations of reference points ``"rx"``...
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from designlab.errors import ModelError, ParameterError
from designlab.fem.assembly import CellBasis, body_load, cell_basis, stiffness, strain_operator
from designlab.fem.facets import area_weights, facet_basis, pressure_load, traction_load
from designlab.fem.materials import Material, get_material
from designlab.mesh.tetmesh import TetMesh

_COMP = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}


def _components(spec, allow_rot: bool) -> list[int]:
    if isinstance(spec, str):
        if spec == "all":
            return [0, 1, 2, 3, 4, 5] if allow_rot else [0, 1, 2]
        tokens = re.findall(r"r?[xyz]", spec)
        if "".join(tokens) != spec:
            tokens = None
    else:
        tokens = list(spec)
    if not tokens or any(t not in _COMP for t in tokens):
        raise ParameterError("components", spec, "letters of 'xyz' (and 'rx', 'ry', 'rz' on "
                             "reference points) or 'all'")
    comps = sorted({_COMP[t] for t in tokens})
    if not allow_rot and max(comps) > 2:
        raise ParameterError("components", spec, "x, y, z on mesh nodes (rotations only on "
                             "rigid reference points)")
    return comps


def skew(r: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices: skew(r) @ v == r x v."""
    r = np.asarray(r, float)
    z = np.zeros(r.shape[:-1])
    return np.stack([np.stack([z, -r[..., 2], r[..., 1]], -1),
                     np.stack([r[..., 2], z, -r[..., 0]], -1),
                     np.stack([-r[..., 1], r[..., 0], z], -1)], -2)


@dataclass(frozen=True, eq=False)
class RefPoint:
    """A reference point coupled to mesh nodes: ``kind`` "rigid" (6 own dofs, slaves follow
    rigidly) or "distributing" (no dofs; loads spread by ``weights``, motion is their weighted
    least-squares rigid fit). ``x``: position, mm."""

    name: str
    x: np.ndarray
    kind: str
    nodes: np.ndarray
    weights: np.ndarray
    index: int = -1             # rigid master number

    def dofs(self, n_points: int) -> np.ndarray:
        """The 6 master dofs (rigid only)."""
        return 3 * n_points + 6 * self.index + np.arange(6)


@dataclass(frozen=True, eq=False)
class Spring:
    """Linear spring between ends ``a`` and ``b`` (``b`` None = ground) acting along ``axis``
    (unit vector) or isotropic (axis None, three springs). Reading (N) =
    ``k * ((u_a - u_b) . axis) + preload``: positive when ``a`` moves along ``+axis`` relative
    to ``b`` (a button whose axis points into the sensor reads compression positive)."""

    name: str
    a: object
    b: object
    k: float
    axis: np.ndarray | None
    preload: float = 0.0
    case: str = "default"


@dataclass(frozen=True, eq=False)
class Beam:
    """A 12 x 12 stiffness ``K`` (e.g. :func:`designlab.fem.beam.beam_stiffness`) between two
    6-dof ends ``a``, ``b`` (RefPoint or (RefPoint, xyz) on rigid reference points); dofs per
    end (u_x, u_y, u_z, theta_x, theta_y, theta_z)."""

    name: str
    a: object
    b: object
    K: np.ndarray


@dataclass(frozen=True, eq=False)
class System:
    """Assembled linear system of a :class:`Model` (all dofs, all cases).

    K_el: elastic stiffness of the mesh (3 n_points square); K_spring (n_dofs square);
    T (n_dofs, n_free): u = T q + G; G (n_dofs, n_cases) prescribed values;
    F (n_dofs, n_cases) applied loads; F_preload (n_dofs, n_cases) spring preloads."""

    model: "Model"
    cases: tuple[str, ...]
    K_el: sp.csr_matrix
    K_spring: sp.csr_matrix
    T: sp.csr_matrix
    G: np.ndarray
    F: np.ndarray
    F_preload: np.ndarray
    constrained: np.ndarray
    free_dofs: np.ndarray        # dof of each column of T (free primary dofs, ascending)
    # all springs stacked: row i of R_spring is a row of spring ``spring_of_row[i]`` (index
    # into ``model.springs``) with stiffness ``k_rows[i]``; K_spring = R^T diag(k) R + beams
    R_spring: sp.csr_matrix | None = None
    k_rows: np.ndarray | None = None
    spring_of_row: np.ndarray | None = None

    @property
    def n_dofs(self) -> int:
        return self.T.shape[0]

    def K(self, K_el: sp.spmatrix | None = None) -> sp.csr_matrix:
        """Full stiffness (n_dofs square): ``K_el`` (default the model's) plus springs."""
        Ke = self.K_el if K_el is None else K_el
        n = self.n_dofs
        pad = sp.csr_matrix((Ke.data, Ke.indices, np.r_[Ke.indptr, np.full(n - Ke.shape[0],
                             Ke.indptr[-1])]), shape=(n, n)) if n > Ke.shape[0] else Ke
        return (pad + self.K_spring).tocsr()

    def reduce(self, K: sp.spmatrix) -> sp.csr_matrix:
        """T^T K T (symmetric positive definite when the model is properly constrained)."""
        if self.T.nnz == self.T.shape[1]:          # no rigid couplings: a plain selection
            K = sp.csr_matrix(K)
            return K[self.free_dofs][:, self.free_dofs].tocsr()
        Kr = (self.T.T @ K @ self.T).tocsr()
        return ((Kr + Kr.T) * 0.5).tocsr()

    def case_index(self, case: str) -> int:
        try:
            return self.cases.index(case)
        except ValueError:
            raise ParameterError("case", case, "one of " + ", ".join(self.cases)) from None


class Model:
    """Linear elastic model on ``mesh``. ``materials`` overrides/extends ``mesh.materials``:
    {body name: Material or library name}."""

    def __init__(self, mesh: TetMesh, materials: dict[str, Material | str] | None = None):
        self.mesh = mesh
        self._materials = dict(materials or {})
        self.refs: dict[str, RefPoint] = {}
        self.springs: dict[str, Spring] = {}
        self.beams: dict[str, Beam] = {}
        self._constraints: list[tuple[np.ndarray, np.ndarray, str | None]] = []
        self._loads: list[tuple[str, np.ndarray, np.ndarray]] = []
        self._cases: list[str] = []
        self._system: System | None = None
        self.region_materials           # validate materials up front

    # ----- materials -----
    @cached_property
    def region_materials(self) -> dict[int, Material]:
        """{region id: Material} for every region present in the mesh."""
        out = {}
        for rid in np.unique(self.mesh.region):
            body = self.mesh.region_names.get(int(rid), str(rid))
            spec = self._materials.get(body, self.mesh.materials.get(body))
            if spec is None:
                raise ModelError(f"region {int(rid)} ({body}) has no material: give one in "
                                 f"mesh.materials or Model(materials={{'{body}': ...}})")
            out[int(rid)] = spec if isinstance(spec, Material) else get_material(spec)
        return out

    def cell_values(self, attr: str) -> np.ndarray:
        """(m,) per-cell value of a Material attribute or property (e.g. "G", "K", "density")."""
        table = {rid: getattr(m, attr) for rid, m in self.region_materials.items()}
        lut = np.zeros(max(table) + 1)
        for k, v in table.items():
            lut[k] = v
        return lut[self.mesh.region]

    @cached_property
    def basis(self) -> CellBasis:
        """Cell quadrature of the mesh (checks Jacobians)."""
        return cell_basis(self.mesh)

    @cached_property
    def B(self) -> sp.csr_matrix:
        """Strain operator u (3 n_points) -> strains at quadrature points (see assembly)."""
        return strain_operator(self.basis)

    @cached_property
    def K_el(self) -> sp.csr_matrix:
        """Elastic stiffness of the mesh with the instantaneous moduli, N/mm."""
        G, K = self.cell_values("G"), self.cell_values("K")
        return stiffness(self.basis, K - 2.0 * G / 3.0, G)

    # ----- sets -----
    @property
    def n_points(self) -> int:
        return self.mesh.n_points

    @property
    def n_dofs(self) -> int:
        return 3 * self.mesh.n_points + 6 * sum(r.kind == "rigid" for r in self.refs.values())

    def facets(self, name: str) -> np.ndarray:
        """Triangles of facet set ``name``; ModelError listing the available ones."""
        fs = self.mesh.facet_sets
        if name not in fs:
            raise ModelError(f"facet set '{name}' does not exist; available: "
                             f"{', '.join(sorted(fs)) or 'none'}")
        return np.asarray(fs[name])

    def nodes(self, where) -> np.ndarray:
        """Sorted unique node ids of a facet set, point set, or explicit node array."""
        if isinstance(where, str):
            if where in self.mesh.point_sets:
                ids = np.asarray(self.mesh.point_sets[where])
            elif where in self.mesh.facet_sets:
                ids = np.asarray(self.mesh.facet_sets[where])
            else:
                names = sorted(self.mesh.facet_sets) + sorted(self.mesh.point_sets)
                raise ModelError(f"set '{where}' does not exist; available: "
                                 f"{', '.join(names) or 'none'}")
        else:
            ids = np.asarray(where)
        ids = np.unique(ids.astype(np.int64).ravel())
        if ids.size == 0:
            raise ModelError(f"set {where if isinstance(where, str) else '(array)'} is empty")
        if ids.min() < 0 or ids.max() >= self.n_points:
            raise ModelError(f"node ids out of range 0..{self.n_points - 1}")
        return ids

    # ----- bookkeeping -----
    def _case(self, case: str) -> str:
        if case not in self._cases:
            self._cases.append(case)
        self._system = None
        return case

    @property
    def cases(self) -> tuple[str, ...]:
        return tuple(self._cases) or ("default",)

    def _dofs(self, where, components) -> np.ndarray:
        if isinstance(where, RefPoint):
            if where.kind != "rigid":
                raise ModelError(f"reference point '{where.name}' is distributing: constrain "
                                 "its set instead, or use a rigid coupling")
            return where.dofs(self.n_points)[_components(components, True)]
        comps = _components(components, False)
        return (3 * self.nodes(where)[:, None] + np.asarray(comps)).ravel()

    # ----- constraints -----
    def fix(self, where, components="all") -> None:
        """Zero displacement (and rotation on rigid reference points) in ``components``."""
        d = self._dofs(where, components)
        self._constraints.append((d, np.zeros(len(d)), None))
        self._system = None

    def prescribe(self, where, displacement=(None, None, None), rotation=(None, None, None),
                  case: str = "default") -> None:
        """Prescribed displacement (mm; None = free) of a node set or rigid reference point,
        and rotation (rad) of a rigid reference point, in load case ``case``. The dofs are
        constrained in every case (value 0 in the other cases). ``displacement`` may also be a
        callable ``f(x) -> (k, 3)`` of the set's node coordinates (all components fixed)."""
        if callable(displacement):
            ids = self.nodes(where)
            v = np.asarray(displacement(self.mesh.points[ids]), float).reshape(len(ids), 3)
            self._constraints.append(((3 * ids[:, None] + np.arange(3)).ravel(), v.ravel(),
                                      self._case(case)))
            return
        vals = list(displacement) + list(rotation)
        if len(vals) != 6:
            raise ParameterError("displacement", displacement, "three values (None = free)")
        if not isinstance(where, RefPoint) and any(v is not None for v in rotation):
            raise ParameterError("rotation", rotation, "only on rigid reference points")
        comps = [i for i, v in enumerate(vals) if v is not None]
        if not comps:
            raise ParameterError("displacement", displacement, "at least one value not None")
        names = [k for k, v in _COMP.items() if v in comps]
        d = self._dofs(where, names)
        per = np.array([vals[i] for i in comps], float)
        self._constraints.append((d, np.tile(per, len(d) // len(comps)), self._case(case)))

    # ----- loads -----
    def _add_load(self, case, dofs, values):
        self._loads.append((self._case(case), np.asarray(dofs, np.int64).ravel(),
                            np.asarray(values, float).ravel()))

    def nodal_force(self, where, force, case: str = "default") -> None:
        """Force (N, (3,)) applied to each node of the set."""
        ids = self.nodes(where)
        f = np.asarray(force, float)
        self._add_load(case, 3 * ids[:, None] + np.arange(3), np.tile(f, (len(ids), 1)))

    def traction(self, where: str, t, case: str = "default") -> None:
        """Surface traction (MPa): (3,) vector or callable ``t(x) -> (..., 3)``."""
        f = traction_load(self.mesh, facet_basis(self.mesh, self.facets(where)), t)
        nz = np.nonzero(f)[0]
        self._add_load(case, nz, f[nz])

    def pressure(self, where: str, p, case: str = "default") -> None:
        """Pressure (MPa, positive pushes into the body): scalar or callable ``p(x)``."""
        f = pressure_load(self.mesh, facet_basis(self.mesh, self.facets(where)), p)
        nz = np.nonzero(f)[0]
        self._add_load(case, nz, f[nz])

    def body_force(self, b, region: str | None = None, case: str = "default") -> None:
        """Body force density (N/mm^3): (3,), (m, 3) per cell, or callable ``b(x)``; on all
        cells or on the body ``region``."""
        cells = None
        if region is not None:
            cells = self.mesh.region == self.mesh.region_id(region)
        f = body_load(self.basis, b, cells)
        nz = np.nonzero(f)[0]
        self._add_load(case, nz, f[nz])

    def gravity(self, g=(0.0, 0.0, -9810.0), case: str = "gravity") -> None:
        """Self weight from material densities, ``g`` in mm/s^2."""
        rho = self.cell_values("density")
        self.body_force(rho[:, None] * np.asarray(g, float)[None], case=case)

    # ----- couplings -----
    def _ref_xyz(self, name, ids, w, ref_point):
        if name in self.refs:
            raise ParameterError("name", name, "a new reference point name")
        c = (w[:, None] * self.mesh.points[ids]).sum(0) / w.sum()
        return c if ref_point is None else np.asarray(ref_point, float)

    def distributing_coupling(self, name: str, where, ref_point=None) -> RefPoint:
        """RBE3-like reference point on the nodes of ``where`` (facet set: weights = consistent
        nodal areas; point set: equal weights). Forces/moments applied to it are distributed
        so that the nodal forces have the same resultant wrench. Default point: weighted
        centroid."""
        if isinstance(where, str) and where in self.mesh.facet_sets:
            w = area_weights(self.mesh, facet_basis(self.mesh, self.facets(where)))
            ids = np.nonzero(w > 1e-14 * w.max())[0]
            w = w[ids]
        else:
            ids = self.nodes(where)
            w = np.ones(len(ids))
        ref = RefPoint(name, self._ref_xyz(name, ids, w, ref_point), "distributing", ids, w)
        self.refs[name] = ref
        self._system = None
        return ref

    def rigid(self, name: str, where, ref_point=None) -> RefPoint:
        """RBE2-like rigid coupling: the nodes of ``where`` follow the 6-dof master at
        ``ref_point`` (default: centroid of the nodes): u = v + w x (x - x_ref)."""
        ids = self.nodes(where)
        for r in self.refs.values():
            if r.kind == "rigid" and np.intersect1d(r.nodes, ids).size:
                raise ModelError(f"rigid couplings '{r.name}' and '{name}' share nodes: merge "
                                 "them into one set")
        idx = sum(r.kind == "rigid" for r in self.refs.values())
        ref = RefPoint(name, self._ref_xyz(name, ids, np.ones(len(ids)), ref_point), "rigid",
                       ids, np.ones(len(ids)), idx)
        self.refs[name] = ref
        self._system = None
        return ref

    def free_body(self, name: str, ref_point) -> RefPoint:
        """A rigid body with its own 6-dof master at ``ref_point`` (mm) and no mesh nodes: a
        bought rigid part (e.g. the steel ball of seed 001) held only by springs and beams."""
        if name in self.refs:
            raise ParameterError("name", name, "a new reference point name")
        idx = sum(r.kind == "rigid" for r in self.refs.values())
        ref = RefPoint(name, np.asarray(ref_point, float), "rigid", np.zeros(0, np.int64),
                       np.zeros(0), idx)
        self.refs[name] = ref
        self._system = None
        return ref

    def twist_map(self, ref: RefPoint) -> sp.csr_matrix:
        """(6, n_dofs) map u -> (v, w) of the reference point (translation, rotation)."""
        n = self.n_dofs
        if ref.kind == "rigid":
            d = ref.dofs(self.n_points)
            return sp.csr_matrix((np.ones(6), (np.arange(6), d)), shape=(6, n))
        x = self.mesh.points[ref.nodes]
        w = ref.weights
        c = (w[:, None] * x).sum(0) / w.sum()
        r = x - c
        J = (w[:, None, None] * ((r * r).sum(1)[:, None, None] * np.eye(3)
                                 - r[:, :, None] * r[:, None, :])).sum(0)
        Rk = np.linalg.pinv(J) @ (w[:, None, None] * skew(r))       # (k, 3, 3) theta per u_i
        Tk = (w / w.sum())[:, None, None] * np.eye(3) - skew(ref.x - c) @ Rk
        blocks = np.concatenate([Tk, Rk], axis=1)                    # (k, 6, 3)
        rows = np.broadcast_to(np.arange(6)[None, :, None], blocks.shape)
        cols = np.broadcast_to(3 * ref.nodes[:, None, None] + np.arange(3)[None, None],
                               blocks.shape)
        return sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(6, n))

    def force(self, ref: RefPoint, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0),
              case: str = "default") -> None:
        """Force (N) and moment (N mm) at a reference point (through its coupling)."""
        L = self.twist_map(ref).tocoo()
        fm = np.r_[np.asarray(force, float), np.asarray(moment, float)]
        self._add_load(case, L.col, L.data * fm[L.row])

    # ----- springs -----
    def point_map(self, end) -> sp.csr_matrix:
        """(3, n_dofs) map u -> displacement of a spring end: node id, single-node set name,
        RefPoint (its point), or (RefPoint, xyz) a point moving with the reference point."""
        n = self.n_dofs
        if isinstance(end, tuple) and len(end) == 2 and isinstance(end[0], RefPoint):
            ref, p = end
            L = self.twist_map(ref)
            M = np.hstack([np.eye(3), -skew(np.asarray(p, float) - ref.x)])
            return sp.csr_matrix(M @ L)
        if isinstance(end, RefPoint):
            return self.twist_map(end)[:3]
        if isinstance(end, (str, np.ndarray, list)):
            ids = self.nodes(end)
            if len(ids) != 1:
                raise ModelError(f"spring end {end!r} has {len(ids)} nodes: use a single-node "
                                 "point set or a coupling")
            end = int(ids[0])
        if isinstance(end, (int, np.integer)):
            return sp.csr_matrix((np.ones(3), (np.arange(3), 3 * int(end) + np.arange(3))),
                                 shape=(3, n))
        raise ParameterError("spring end", end, "node id, set name, RefPoint or (RefPoint, xyz)")

    def spring(self, name: str, a, b=None, k: float = 1.0, axis=None, preload: float = 0.0,
               case: str = "default") -> Spring:
        """Spring of stiffness ``k`` (N/mm) from ``a`` to ``b`` (None = ground) along ``axis``
        (None = isotropic); ``preload`` (N) is applied in load case ``case``."""
        if not (k > 0):
            raise ParameterError("k", k, "> 0 N/mm")
        if name in self.springs:
            raise ParameterError("name", name, "a new spring name")
        ax = None
        if axis is not None:
            ax = np.asarray(axis, float)
            if ax.shape != (3,) or not np.linalg.norm(ax) > 0:
                raise ParameterError("axis", axis, "a non-zero 3-vector")
            ax = ax / np.linalg.norm(ax)
        s = Spring(name, a, b, float(k), ax, float(preload), self._case(case) if preload
                   else case)
        self._system = None
        self.springs[name] = s
        return s

    def frame_map(self, end) -> sp.csr_matrix:
        """(6, n_dofs) map u -> (translation, rotation) of a point moving with a rigid
        reference point: ``RefPoint`` (its own point) or ``(RefPoint, xyz)``."""
        ref, p = (end if isinstance(end, tuple) else (end, None))
        if not isinstance(ref, RefPoint) or ref.kind != "rigid":
            raise ParameterError("beam end", end, "a rigid RefPoint or (rigid RefPoint, xyz)")
        L = self.twist_map(ref)
        if p is None:
            return L
        M = np.eye(6)
        M[:3, 3:] = -skew(np.asarray(p, float) - ref.x)
        return sp.csr_matrix(M @ L)

    def beam(self, name: str, a, b, K) -> Beam:
        """Connect two rigid reference points (or points on them) by a 12 x 12 stiffness
        (N/mm, N, N mm/rad), e.g. a bolt modelled as a Timoshenko beam; ``b`` None: the
        second end is clamped to ground."""
        K = np.asarray(K, float)
        if K.shape != (12, 12) or not np.allclose(K, K.T, rtol=1e-10, atol=1e-12 * abs(K).max()):
            raise ParameterError("K", K.shape, "a symmetric 12 x 12 matrix")
        if name in self.beams:
            raise ParameterError("name", name, "a new beam name")
        self.frame_map(a)                                # validate ends now
        if b is not None:
            self.frame_map(b)
        beam = Beam(name, a, b, K)
        self.beams[name] = beam
        self._system = None
        return beam

    def beam_map(self, beam: Beam) -> sp.csr_matrix:
        """(12, n_dofs) map u -> end motions of a beam."""
        Lb = sp.csr_matrix((6, self.n_dofs)) if beam.b is None else self.frame_map(beam.b)
        return sp.vstack([self.frame_map(beam.a), Lb]).tocsr()

    def spring_map(self, s: Spring) -> sp.csr_matrix:
        """(1 or 3, n_dofs) map u -> elongation along the axis (or the 3 relative motions)."""
        if s.axis is not None and _is_node(s.a) and (s.b is None or _is_node(s.b)):
            # node to node/ground along an axis (e.g. Winkler springs): the row directly
            # (the same numbers as the general path: axis[k] * +-1, zeros dropped)
            nz = np.nonzero(s.axis)[0]
            cols, vals = 3 * int(s.a) + nz, s.axis[nz]
            if s.b is not None:
                cols, vals = np.r_[cols, 3 * int(s.b) + nz], np.r_[vals, -s.axis[nz]]
            if s.b is None or int(s.b) != int(s.a):
                return sp.csr_matrix((vals, (np.zeros(len(cols), int), cols)),
                                     shape=(1, self.n_dofs))
        L = self.point_map(s.a)
        if s.b is not None:
            L = L - self.point_map(s.b)
        return sp.csr_matrix(s.axis[None] @ L) if s.axis is not None else sp.csr_matrix(L)

    # ----- assembly -----
    def build(self) -> System:
        """Assemble (cached until the model changes)."""
        if self._system is None:
            self._system = self._build()
        return self._system

    def _build(self) -> System:
        n, npts = self.n_dofs, self.n_points
        cases = self.cases
        nc = len(cases)
        # springs: all rows stacked into one R, K_spring = R^T diag(k) R (built once)
        F_pre = np.zeros((n, nc))
        rr, cc, vv, kk, own = [], [], [], [], []
        nrow = 0
        for i, s in enumerate(self.springs.values()):
            R = self.spring_map(s).tocoo()
            m = R.shape[0]
            rr.append(R.row + nrow)
            cc.append(R.col)
            vv.append(R.data)
            kk.append(np.full(m, s.k))
            own.append(np.full(m, i))
            if s.preload:
                F_pre[:, cases.index(s.case)] -= s.preload * R.tocsr()[0].toarray()[0]
            nrow += m
        if nrow:
            R_spring = sp.csr_matrix((np.concatenate(vv), (np.concatenate(rr),
                                      np.concatenate(cc))), shape=(nrow, n))
            k_rows, spring_of_row = np.concatenate(kk), np.concatenate(own)
            K_spring = _gram(R_spring, k_rows, n)
        else:
            R_spring = sp.csr_matrix((0, n))
            k_rows, spring_of_row = np.zeros(0), np.zeros(0, int)
            K_spring = sp.csr_matrix((n, n))
        for bm in self.beams.values():
            Lb = self.beam_map(bm)
            K_spring = K_spring + Lb.T @ sp.csr_matrix(bm.K) @ Lb
        # loads
        F = np.zeros((n, nc))
        for case, d, v in self._loads:
            np.add.at(F[:, cases.index(case)], d, v)
        # constraints
        constrained = np.zeros(n, bool)
        G = np.zeros((n, nc))
        for d, v, case in self._constraints:
            constrained[d] = True
            if case is not None:
                G[d, cases.index(case)] = v
        # rigid couplings: slaves follow masters
        slave = np.zeros(n, bool)
        rows, cols, vals = [], [], []
        for r in self.refs.values():
            if r.kind != "rigid":
                continue
            sd = 3 * r.nodes[:, None] + np.arange(3)
            if constrained[sd].any():
                raise ModelError(f"nodes of rigid coupling '{r.name}' are also constrained: "
                                 "constrain its reference point instead")
            slave[sd] = True
            md = r.dofs(npts)
            blk = np.concatenate([np.broadcast_to(np.eye(3), (len(r.nodes), 3, 3)),
                                  -skew(self.mesh.points[r.nodes] - r.x)], axis=2)  # (k,3,6)
            rows.append(np.broadcast_to(sd[:, :, None], blk.shape).ravel())
            cols.append(np.broadcast_to(md[None, None, :], blk.shape).ravel())
            vals.append(blk.ravel())
        free = ~slave & ~constrained
        col = np.cumsum(free) - 1
        S = sp.csr_matrix((np.ones(free.sum()), (np.nonzero(free)[0], col[free])),
                          shape=(n, int(free.sum())))
        if rows:
            C = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                               np.concatenate(cols))), shape=(n, n))
            T = (S + C @ S).tocsr()
            G = G + C @ G
        else:
            T = S
        return System(self, cases, self.K_el, K_spring.tocsr(), T, G, F, F_pre, constrained,
                      np.nonzero(free)[0], R_spring, k_rows, spring_of_row)


def _is_node(end) -> bool:
    return isinstance(end, (int, np.integer)) and not isinstance(end, bool)


def _gram(R: sp.csr_matrix, k: np.ndarray, n: int) -> sp.csr_matrix:
    """R^T diag(k) R (n square) from the products within each row, k_r * (R_ri * R_rj): the
    same numbers as summing k * (R_s^T R_s) spring by spring for one-row springs."""
    R = R.tocsr()
    R.sum_duplicates()
    cnt = np.diff(R.indptr)
    sq = cnt * cnt
    row = np.repeat(np.arange(len(cnt)), sq)
    off = np.arange(int(sq.sum())) - np.repeat(np.cumsum(sq) - sq, sq)
    c = cnt[row]
    i = R.indptr[row] + off // c
    j = R.indptr[row] + off % c
    return sp.csr_matrix((k[row] * (R.data[i] * R.data[j]), (R.indices[i], R.indices[j])),
                         shape=(n, n))
