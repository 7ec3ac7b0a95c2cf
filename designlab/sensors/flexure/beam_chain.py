"""Fast helix model: the spring wire as a chain of Timoshenko beams, its ends seated and in
contact with the next turn and the seats (line contacts), solved by an active set.

The 6x6 comes from symmetric perturbations of the tip disc about the unloaded spring and the
spring under the axial working load. Derivations and checks: docs/models/flexure_beam_chain.md.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from designlab.errors import ModelError, ParameterError
from designlab.fem.beam import beam_stiffness, circular_section
from designlab.frames import transform, transform_stiffness
from designlab.sensors.flexure.active_set import PERM, ActiveSet
from designlab.sensors.flexure.chain_geometry import (RAMP, ChainSettings, Coil, as_built,
                                                      from_part, wire_contact_points)
from designlab.sensors.flexure.spring import HelicalSpring, check_working_load, to_si


@dataclass
class _Contact:
    row: np.ndarray         # (n_q,): opening of the gap per reduced dof
    g0: float               # initial gap, mm
    k_n: float              # penalty, N/mm
    kind: str               # "coil" or "seat"
    rt: np.ndarray | None = None   # (2, n_q): tangential (x, y) slip of the contact points
    u: float | None = None         # turn count of the (lower) contact point (line contacts)


@dataclass
class ChainResult:
    """6x6 of the chain (N*mm/rad, N/mm, N) at the tip master ``(0, 0, L)``, global axes."""

    K: np.ndarray
    K_loaded: np.ndarray | None
    master: np.ndarray
    centre: np.ndarray
    coil: Coil
    settings: ChainSettings
    info: dict
    #: the assembled chain (its solves and section forces, e.g. the wire stress)
    chain: "Chain | None" = field(default=None, repr=False, compare=False)

    def at(self, point, loaded: bool = False) -> np.ndarray:
        K = self.K_loaded if loaded else self.K
        return transform_stiffness(K, transform(translation=self.master - np.asarray(point, float)))

    @property
    def K_centre(self) -> np.ndarray:
        return self.at(self.centre)

    def zero_coupling(self, loaded: bool = False) -> dict:
        """Where on the axis the x/y moment-translation couplings vanish (the elastic centre
        along z), mm above the spring centre: ``x`` from ``K[1, 3] / K[3, 3]``, ``y`` from
        ``-K[0, 4] / K[4, 4]`` (``K`` at the centre), and their mean. Symmetric ends put it at
        the centre; it moves towards the end that is rotationally more compliant."""
        K = self.at(self.centre, loaded=loaded)
        zx, zy = float(K[1, 3] / K[3, 3]), float(-K[0, 4] / K[4, 4])
        return {"x_mm": zx, "y_mm": zy, "mean_mm": (zx + zy) / 2}

    @property
    def K_centre_si(self) -> np.ndarray:
        return to_si(self.K_centre)

    @property
    def K_loaded_centre_si(self) -> np.ndarray | None:
        return None if self.K_loaded is None else to_si(self.at(self.centre, loaded=True))


#: contact refinement: beams of at most ``contact_mesh_mm`` where a contact's initial gap is below
#: this (mm), on every wire it involves, plus ``WINDOW_MARGIN_MM`` of wire on either side
REFINE_GAP_MM = 0.1
WINDOW_MARGIN_MM = 3.0


def _held_turns(coil: Coil, seat: str, end: str, u: np.ndarray) -> np.ndarray:
    """Where an end's wire is held by its end condition (the bond rule of :class:`Chain`)."""
    c = coil.z_of_u(u) - coil.seat_lo if end == "base" else coil.seat_hi - coil.z_of_u(u)
    near = u < 1 if end == "base" else u > coil.turns - 1
    if seat == "bonded":
        return near & (c < coil.r)
    if seat == "potted":
        return (u <= 1 + 1e-9) if end == "base" else (u >= coil.turns - 1 - 1e-9)
    return np.zeros(len(u), bool)


def _contact_windows(coil: Coil, settings: ChainSettings) -> list[tuple[float, float]]:
    """Turn-count intervals of wire to mesh finely: where a coil or seat contact starts within
    ``REFINE_GAP_MM`` of closing, on the wires it involves (not where an end holds the wire),
    widened by ``WINDOW_MARGIN_MM``."""
    N, r = coil.turns, coil.r
    base, tip = settings.end_seats
    fine = np.linspace(0.0, N, int(N * 2000) + 1)
    held = _held_turns(coil, base, "base", fine) | _held_turns(coil, tip, "tip", fine)
    z = coil.z_of_u(fine)
    near = np.zeros(len(fine), bool)
    du = fine[1] - fine[0]
    shift = int(round(1.0 / du))                       # one turn up
    g_coil = z[shift:] - z[:-shift] - 2 * r
    lo_span = (fine[:-shift] <= 1 + RAMP) | (fine[:-shift] >= N - 2 - RAMP)
    close = (g_coil <= REFINE_GAP_MM) & lo_span
    # coil contacts: both wires, held or not (a held wire moves rigidly with its disc, and a
    # coarse chord misplaces the contact point by its sagitta times the disc's tilt)
    near[:-shift] |= close
    near[shift:] |= close
    seat = (((fine <= 1) & (z - coil.seat_lo - r <= REFINE_GAP_MM))
            | ((fine >= N - 1) & (coil.seat_hi - z - r <= REFINE_GAP_MM)))
    near |= seat & ~held
    margin = WINDOW_MARGIN_MM / (2 * np.pi * coil.R)
    out = []
    idx = np.nonzero(near)[0]
    if len(idx):
        breaks = np.nonzero(np.diff(idx) > 1)[0]
        for a, b in zip(np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]):
            out.append((max(fine[a] - margin, 0.0), min(fine[b] + margin, N)))
    return out


def _merge(windows) -> list[tuple[float, float]]:
    out = []
    for a, b in sorted(windows):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _refine(u: np.ndarray, windows, step: float) -> np.ndarray:
    """The background nodes ``u`` with every window meshed uniformly at most ``step`` (turns);
    background nodes closer than half a step to a window are dropped."""
    parts = [u[[0, -1]]]
    keep = np.ones(len(u), bool)
    for a, b in windows:
        k = max(int(math.ceil((b - a) / step - 1e-9)), 1)
        parts.append(np.linspace(a, b, k + 1))
        keep &= ~((u > a - step / 2) & (u < b + step / 2))
    return np.unique(np.concatenate(parts + [u[keep]]))


def _bonded_nodes(coil: Coil, settings: ChainSettings, u: np.ndarray, c_base: np.ndarray,
                  c_tip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(base, tip) node indices held by their end condition: plain ends at the wire's end
    nodes; ``bonded`` the nodes whose wire section reaches the seat in the dead turn; ``potted``
    the whole dead turn; ``contact`` the wire's end node only."""
    r, N, n = coil.r, coil.turns, len(u)
    if coil.ends == "plain":
        return np.array([0]), np.array([n - 1])
    base_seat, tip_seat = settings.end_seats
    if base_seat == "bonded":
        base_bond = np.nonzero((c_base < r) & (u < 1))[0]
    elif base_seat == "potted":
        base_bond = np.nonzero(u <= 1 + 1e-9)[0]
    else:
        base_bond = np.array([0])
    if tip_seat == "bonded":
        tip_bond = np.nonzero((c_tip < r) & (u > N - 1))[0]
    elif tip_seat == "potted":
        tip_bond = np.nonzero(u >= N - 1 - 1e-9)[0]
    else:
        tip_bond = np.array([n - 1])
    return base_bond, tip_bond


class Chain(ActiveSet):
    """Assembled chain: reduced stiffness, contact operators, active-set solves."""

    def __init__(self, coil: Coil, settings: ChainSettings, windows=()):
        self.coil, self.s = coil, settings
        R, r, N = coil.R, coil.r, coil.turns
        n_el = max(int(math.ceil(N * settings.elements_per_turn - 1e-9)), 4)
        u = np.linspace(0.0, N, n_el + 1)
        self.h = N / n_el
        line = (settings.contact and coil.ends == "closed_ground"
                and settings.contact_spacing_mm > 0 and settings.contact_mesh_mm > 0)
        self.windows = _merge(list(_contact_windows(coil, settings)) + list(windows)) if line else []
        if self.windows:
            u = _refine(u, self.windows, settings.contact_mesh_mm / (2 * np.pi * R))
        self.u = u
        n_el = len(u) - 1
        z = coil.z_of_u(u) - coil.seat_lo
        X = np.column_stack([R * np.cos(2 * np.pi * u), R * np.sin(2 * np.pi * u), z])
        self.X, L = X, coil.length
        self.master = np.array([0.0, 0.0, L])
        n = len(u)
        sec = circular_section(2 * r)
        self.ke = np.zeros((n_el, 12, 12))         # element stiffnesses (section forces)
        for e in range(n_el):
            self.ke[e] = beam_stiffness(X[e], X[e + 1], coil.E, coil.G, sec["A"], sec["Iy"],
                                        sec["Iz"], sec["J"], sec["As"])
        # sparse assembly: a node is shared by two beams at most, so each entry is the same
        # sum (0 + a + b) as the dense one; exact zeros dropped as the dense -> CSR did
        idx = 6 * np.arange(n_el)[:, None] + np.arange(12)[None, :]
        K = sp.csr_matrix((self.ke.ravel(), (np.repeat(idx, 12, axis=1).ravel(),
                                             np.tile(idx, (1, 12)).ravel())), shape=(6 * n, 6 * n))
        K.eliminate_zeros()
        # ---- ends: bonded nodes (base fixed, tip rigid to the master)
        c_base, c_tip = z, L - z                 # centreline heights above the seats
        base_bond, tip_bond = _bonded_nodes(coil, settings, u, c_base, c_tip)
        self.base_bond, self.tip_bond = base_bond, tip_bond
        # T: reduced q = [free node dofs, master 6] -> full node dofs
        fixed = np.zeros(6 * n, bool)
        tied = np.zeros(6 * n, bool)
        for k in base_bond:
            fixed[6 * k:6 * k + 6] = True
        for k in tip_bond:
            tied[6 * k:6 * k + 6] = True
        free = np.nonzero(~fixed & ~tied)[0]
        nq = len(free) + 6
        T = np.zeros((6 * n, nq))
        T[free, np.arange(len(free))] = 1.0
        m0 = len(free)
        for k in tip_bond:
            T[6 * k:6 * k + 6, m0:] = self._rigid(X[k])
        self.T, self.nq, self.m = T, nq, np.arange(m0, nq)
        Ts = sp.csr_matrix(T)
        self.Kq = (Ts.T @ K @ Ts).tocsr()
        self.K_full = K
        self.n_dofs = 6 * n
        # ---- contacts
        nu = coil.E / (2 * coil.G) - 1
        E_ss = coil.E / (2 * (1 - nu ** 2))                   # E* of two identical bodies
        from designlab.fem.materials import get_material

        seat = get_material(settings.seat_material)
        E_seat = 1.0 / ((1 - nu ** 2) / coil.E + (1 - seat.nu ** 2) / seat.E)
        self.contacts: list[_Contact] = []
        # line contact of one node spacing along the wire, mm (self.h is in turns)
        self.spacing = float(np.linalg.norm(np.diff(X, axis=0), axis=1).mean())
        self._phi = 12 * coil.E * sec["Iy"] / (coil.G * sec["As"])      # x L^-2 per element
        self.n_dofs = 6 * n
        self._Ts = Ts
        if settings.contact and coil.ends == "closed_ground" and settings.contact_spacing_mm > 0:
            self._line_contacts(E_ss, E_seat, settings.contact_spacing_mm)
            self.N, self.Rt = self._line_N, self._line_Rt
        else:
            if settings.contact and coil.ends == "closed_ground":
                self._coil_contacts(E_ss * self.spacing)
                self._seat_contacts(E_seat * self.spacing, c_base, c_tip)
            self.N = sp.csr_matrix(np.array([c.row for c in self.contacts]).reshape(-1, nq))
            self.Rt = sp.csr_matrix(np.array([c.rt for c in self.contacts]).reshape(-1, nq))
        self.kn = np.array([c.k_n for c in self.contacts])
        self.g0 = np.array([c.g0 for c in self.contacts])
        if self.windows:            # bonded length per end, each node with the beam beyond it
            du = np.diff(u)
            self.bonded_turns = float(np.ptp(u[base_bond]) + du[min(base_bond.max(), n - 2)]
                                      + np.ptp(u[tip_bond]) + du[max(tip_bond.min() - 1, 0)]) / 2
        else:
            self.bonded_turns = (len(base_bond) + len(tip_bond)) * self.h / 2

    # ------------------------------------------------------------------ section forces
    def section_forces(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Wire section forces of the reduced state ``q`` at both ends of every beam: the
        element's end forces ``k_e u_e`` (global) split on the beam axis into axial force
        ``N``, shear ``V``, torsion ``T`` and bending moment ``M`` (magnitudes, N and N mm),
        with the end points ``X`` (mm). Arrays of shape (2 n_el,): element ends a, b in turn."""
        u = self.T @ np.asarray(q, float)
        n_el = len(self.u) - 1
        ue = np.lib.stride_tricks.sliding_window_view(u, 12)[::6][:n_el]     # (n_el, 12)
        f = np.matmul(self.ke, ue[:, :, None]).reshape(n_el, 2, 2, 3)    # end, (F, M), xyz
        t = np.diff(self.X, axis=0)
        t /= np.linalg.norm(t, axis=1)[:, None]
        F, M = f[:, :, 0].reshape(-1, 3), f[:, :, 1].reshape(-1, 3)
        t2 = np.repeat(t, 2, axis=0)
        n, tq = np.einsum("ij,ij->i", F, t2), np.einsum("ij,ij->i", M, t2)
        return {"N": np.abs(n), "T": np.abs(tq),
                "V": np.linalg.norm(F - n[:, None] * t2, axis=1),
                "M": np.linalg.norm(M - tq[:, None] * t2, axis=1),
                "X": np.stack([self.X[:-1], self.X[1:]], axis=1).reshape(-1, 3),
                "element": np.repeat(np.arange(n_el), 2)}

    # ------------------------------------------------------------------ operators
    def _rigid(self, x) -> np.ndarray:
        """(6, 6) master (u, th) -> node (u, th) of a point ``x`` rigid with the master."""
        from designlab.frames import skew

        A = np.zeros((6, 6))
        A[:3, :3] = np.eye(3)
        A[:3, 3:] = -skew(np.asarray(x, float) - self.master)     # th x (x - x_m)
        A[3:, 3:] = np.eye(3)
        return A

    def _uz(self, k) -> np.ndarray:
        """(n_q,) axial displacement of node k per reduced dof."""
        return self.T[6 * k + 2]

    def _ut(self, k, dz: float) -> np.ndarray:
        """(2, n_q) x, y displacement of the wire surface point ``dz`` above node k's
        centreline per reduced dof: u + th x (dz e_z)."""
        T = self.T
        return np.vstack([T[6 * k] + dz * T[6 * k + 4], T[6 * k + 1] - dz * T[6 * k + 3]])

    def _node_at(self, u):
        j = min(int(np.floor(u / self.h + 1e-9)), len(self.u) - 2)
        s = (u - self.u[j]) / self.h
        return j, float(np.clip(s, 0.0, 1.0))

    def _ops(self, us: np.ndarray, full: bool = False
             ) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
        """Centreline displacement and section rotation at the turn counts ``us`` per reduced
        dof: two sparse (3 k, n_q) operators (row ``3 i + c``: component ``c`` of point ``i``),
        and whether each point's beam is held at both nodes (bonded). Inside a beam the
        displacement follows the two-node Timoshenko beam's own shape functions (exact for a
        beam loaded at its ends: linear along the chord, cubic across it with the shear
        parameter ``phi = 12 EI / (kappa G A L^2)``; Przemieniecki, *Theory of Matrix
        Structural Analysis*, 1968, sec. 5.6), the rotation is linear between the nodes.
        ``full``: per node dof (6 n) instead of per reduced dof."""
        u = self.u
        us = np.asarray(us, float)
        k = len(us)
        e = np.clip(np.searchsorted(u, us, side="right") - 1, 0, len(u) - 2)
        xi = np.clip((us - u[e]) / (u[e + 1] - u[e]), 0.0, 1.0)
        d = self.X[e + 1] - self.X[e]
        L = np.linalg.norm(d, axis=1)
        t = d / L[:, None]
        phi = self._phi / L ** 2
        c = 1.0 / (1.0 + phi)
        n1 = c * (1 - 3 * xi ** 2 + 2 * xi ** 3 + phi * (1 - xi))
        n3 = 1.0 - n1
        n2 = c * L * (xi - (2 + phi / 2) * xi ** 2 + xi ** 3 + phi / 2 * xi)
        n4 = c * L * (-(1 - phi / 2) * xi ** 2 + xi ** 3 - phi / 2 * xi)
        tt = t[:, :, None] * t[:, None, :]
        P = np.eye(3) - tt
        St = np.zeros((k, 3, 3))                        # skew(t): th x t = -St th
        St[:, 0, 1], St[:, 0, 2], St[:, 1, 2] = -t[:, 2], t[:, 1], -t[:, 0]
        St[:, 1, 0], St[:, 2, 0], St[:, 2, 1] = t[:, 2], -t[:, 1], t[:, 0]
        w = lambda a: a[:, None, None]                  # noqa: E731
        op = np.concatenate([w(1 - xi) * tt + w(n1) * P, -w(n2) * St,
                             w(xi) * tt + w(n3) * P, -w(n4) * St], axis=2)        # (k, 3, 12)
        I3 = np.broadcast_to(np.eye(3), (k, 3, 3))
        Z3 = np.zeros((k, 3, 3))
        rot = np.concatenate([Z3, w(1 - xi) * I3, Z3, w(xi) * I3], axis=2)
        rows = np.repeat(np.arange(3 * k), 12)
        cols = (6 * e[:, None, None] + np.arange(12)[None, None, :]).repeat(3, axis=1).ravel()
        Ts = self._Ts if not full else sp.identity(self.n_dofs, format="csr")
        shape = (3 * k, self.n_dofs)
        D = sp.csr_matrix((op.ravel(), (rows, cols)), shape=shape) @ Ts
        Rr = sp.csr_matrix((rot.ravel(), (rows, cols)), shape=shape) @ Ts
        held = np.zeros(len(u), bool)
        held[self.base_bond] = True
        held[self.tip_bond] = True
        return D.tocsr(), Rr.tocsr(), held[e] & held[e + 1]

    def unresolved(self, closed: np.ndarray) -> list[tuple[float, float]]:
        """Windows (turn counts) around the closed line contacts whose wire lies in a beam
        longer than 1.5 ``contact_mesh_mm`` (a seat contact on a held beam excepted): where
        the mesh should be refined. Empty for node contacts or ``contact_mesh_mm = 0``."""
        mesh = self.s.contact_mesh_mm
        if not (self.s.contact_spacing_mm > 0 and mesh > 0) or not np.any(closed):
            return []
        idx = np.nonzero(closed)[0]
        pos = [(self.contacts[i].u, True) for i in idx]
        pos += [(self.contacts[i].u + 1, True) for i in idx if self.contacts[i].kind == "coil"]
        us = np.array([p for p, _ in pos])
        e = np.clip(np.searchsorted(self.u, us, side="right") - 1, 0, len(self.u) - 2)
        held = np.zeros(len(self.u), bool)
        held[self.base_bond] = True
        held[self.tip_bond] = True
        seat = np.array([self.contacts[i].kind == "seat" for i in idx]
                        + [False] * (len(us) - len(idx)))
        long = (self.u[e + 1] - self.u[e]) * 2 * np.pi * self.coil.R > 1.5 * mesh
        bad = long & ~(seat & held[e] & held[e + 1])
        m = WINDOW_MARGIN_MM / (2 * np.pi * self.coil.R)
        return _merge([(max(x - m, 0.0), min(x + m, self.coil.turns)) for x in us[bad]])

    def _line_contacts(self, E_ss: float, E_seat: float, spacing: float):
        """Line contacts resolved independently of the beam nodes: contact points at a fixed
        spacing (mm of wire, the midpoints of equal steps in turn count) over the same spans as
        the node contacts: the dead turn and ramp against the wire one turn above (gap
        ``z(u + 1) - z(u) - d``), the dead turn against its seat (gap ``c - r``). Each point is
        a penalty spring of ``E* x`` its length of wire (the line contact's stiffness per unit
        length, Johnson 1985 sec. 5.6), its displacement interpolated by :meth:`_ops`; a point
        whose beams are held entirely (bonded) is dropped. The closed contact *length*, not the
        count of closed nodes, carries the load. Sets ``N``, ``Rt`` (sparse) and the contact
        list (kind, gap, penalty, turn count; no dense rows)."""
        c, r, N = self.coil, self.coil.r, self.coil.turns
        points, lo_spans = wire_contact_points(c.z_of_u, c.R, N, spacing)
        kinds, us_all, ws, g0s, rows, rts = [], [], [], [], [], []
        for lo, hi in lo_spans:
            us, w = points(lo, hi)
            A, Ar, ha = self._ops(us)
            B, Br, hb = self._ops(us + 1)
            row = B[2::3] - A[2::3]                                   # upper - lower
            rt = [B[0::3] - r * Br[1::3] - A[0::3] - r * Ar[1::3],     # upper at -r, lower at +r
                  B[1::3] + r * Br[0::3] - A[1::3] + r * Ar[0::3]]
            g0 = np.maximum(c.z_of_u(us + 1) - c.z_of_u(us) - 2 * r, 0.0)
            keep = ~(ha & hb)
            kinds += ["coil"] * int(keep.sum())
            us_all.append(us[keep]), ws.append(E_ss * w[keep]), g0s.append(g0[keep])
            rows.append(row[keep]), rts.append((rt[0][keep], rt[1][keep]))
        for lo, hi, end in ((0.0, 1.0, "base"), (N - 1.0, N, "tip")):
            us, w = points(lo, hi)
            A, Ar, held = self._ops(us)
            z = c.z_of_u(us) - c.seat_lo
            if end == "base":
                row = A[2::3]                                          # wire bottom - seat
                rt = [A[0::3] - r * Ar[1::3], A[1::3] + r * Ar[0::3]]
                g0 = z - r
            else:
                e = np.clip(np.searchsorted(self.u, us, side="right") - 1, 0, len(self.u) - 2)
                xi = np.clip((us - self.u[e]) / (self.u[e + 1] - self.u[e]), 0.0, 1.0)[:, None]
                p = (1 - xi) * self.X[e] + xi * self.X[e + 1] + np.array([0.0, 0.0, r]) - self.master
                k = len(us)
                S = np.zeros((3, k, 6))                 # seat point rigid with the master
                S[0, :, 0], S[0, :, 4], S[0, :, 5] = 1.0, p[:, 2], -p[:, 1]
                S[1, :, 1], S[1, :, 3], S[1, :, 5] = 1.0, -p[:, 2], p[:, 0]
                S[2, :, 2], S[2, :, 3], S[2, :, 4] = 1.0, p[:, 1], -p[:, 0]
                seat = [sp.csr_matrix((S[i].ravel(), (np.repeat(np.arange(k), 6),
                                                      np.tile(self.m, k))), shape=(k, self.nq))
                        for i in range(3)]
                row = seat[2] - A[2::3]                                # seat - wire top
                rt = [seat[0] - A[0::3] - r * Ar[1::3], seat[1] - A[1::3] + r * Ar[0::3]]
                g0 = c.length - z - r
            keep = ~held
            kinds += ["seat"] * int(keep.sum())
            us_all.append(us[keep]), ws.append(E_seat * w[keep]), g0s.append(np.maximum(g0, 0.0)[keep])
            rows.append(row[keep]), rts.append((rt[0][keep], rt[1][keep]))
        Nm = sp.vstack(rows).tocsr()
        live = np.diff(Nm.indptr) > 0                   # drop rows that nothing moves
        Rx = sp.vstack([a for a, _ in rts]).tocsr()
        Ry = sp.vstack([b for _, b in rts]).tocsr()
        us_all_parts = list(us_all)
        us_all, kn, g0 = (np.concatenate(a) for a in (us_all, ws, g0s))
        idx = np.nonzero(live)[0]
        self._line_N = Nm[idx]
        Rt = sp.vstack([Rx[idx], Ry[idx]]).tocsr()
        n = len(idx)
        order = np.ravel(np.column_stack([np.arange(n), n + np.arange(n)]))    # x0 y0 x1 y1 ...
        self._line_Rt = Rt[order]
        self.contacts = [_Contact(None, float(g0[i]), float(kn[i]), kinds[i], None, float(us_all[i]))
                         for i in idx]
        # one run id per contact line (span and kind); the points are in order along it
        line_id = np.concatenate([np.full(len(a), k) for k, a in enumerate(us_all_parts)])
        self.runs = line_id[idx]

    def _coil_contacts(self, k_n):
        """The wire at ``u`` against the wire one turn above, over each end's dead turn and
        ramp; contact points on the wire surfaces (``+-r`` along z)."""
        c, r, N = self.coil, self.coil.r, self.coil.turns
        span = 1.0 + RAMP + 2.0 / self.s.elements_per_turn
        for i, ui in enumerate(self.u):
            if ui + 1 > N + 1e-9 or not (ui <= span or ui + 1 >= N - span):
                continue
            g0 = float(c.z_of_u(ui + 1) - c.z_of_u(ui)) - 2 * r
            j, s = self._node_at(ui + 1)
            # the z motion of a surface point is its node's u_z (a rotation moves it sideways)
            row = (1 - s) * self._uz(j) + s * self._uz(j + 1) - self._uz(i)   # upper - lower
            rt = (1 - s) * self._ut(j, -r) + s * self._ut(j + 1, -r) - self._ut(i, r)
            if np.any(row):
                self.contacts.append(_Contact(row, max(g0, 0.0), k_n, "coil", rt))

    def _seat_contacts(self, k_n, c_base, c_tip):
        """The dead turn's wire surface against its seat plane (the tip seat moves with the
        master), where the node is not bonded."""
        r, N = self.coil.r, self.coil.turns
        ez = np.array([0.0, 0.0, r])
        for i, ui in enumerate(self.u):
            if ui <= 1.0 and i not in self.base_bond:
                row = self._uz(i)                                       # wire bottom - seat
                self.contacts.append(_Contact(row, max(float(c_base[i]) - r, 0.0), k_n, "seat",
                                              self._ut(i, -r)))
            if ui >= N - 1.0 and i not in self.tip_bond:
                seat = np.zeros((3, self.nq))
                seat[:, self.m] = self._rigid(self.X[i] + ez)[:3]
                row = seat[2] - self._uz(i)                             # seat - wire top
                self.contacts.append(_Contact(row, max(float(c_tip[i]) - r, 0.0), k_n, "seat",
                                              seat[:2] - self._ut(i, r)))


def resolved_chain(coil: Coil, settings: ChainSettings) -> tuple["Chain", dict | None]:
    """The assembled chain and its frictionless working-load state (None without a working
    load or contact). With line contacts, a contact closed at the working load in a beam
    longer than 1.5 ``contact_mesh_mm`` (outside the windows meshed finely from the gaps at
    rest) gets a window of its own and the chain is rebuilt (at most 3 times)."""
    chain = Chain(coil, settings)
    if not (settings.working_load_N > 0 and settings.contact and coil.ends == "closed_ground"):
        return chain, None
    f = np.r_[0.0, 0.0, -settings.working_load_N, 0.0, 0.0, 0.0]
    extra: list = []
    for _ in range(4):
        pre = chain.solve(f_master=f)
        add = chain.unresolved(pre["closed"])
        if not add:
            return chain, pre
        extra += add
        chain = Chain(coil, settings, extra)
    raise ModelError("beam chain: the contact zones at the working load moved out of the "
                     "refined windows 3 times")


def chain_stiffness(spring, settings: ChainSettings | None = None, *,
                    geometry: str = "as_built") -> ChainResult:
    """6x6 of a spring flexure by the beam chain, unloaded and at the axial working load.

    spring:   a :class:`~designlab.sensors.flexure.spring.HelicalSpring` (geometry
              ``"as_built"``) or a ``SpringFlexure`` (the solid part's centreline).
    """
    settings = settings or ChainSettings()
    t0 = time.perf_counter()
    if isinstance(spring, HelicalSpring):
        if geometry != "as_built":
            raise ParameterError("geometry", geometry, "as_built for a HelicalSpring")
        coil = as_built(spring)
        if settings.working_load_N > 0:
            check_working_load(spring, settings.working_load_N)
    else:
        coil = from_part(spring)
    chain, pre = resolved_chain(coil, settings)
    K, closed = chain.stiffness()
    K_loaded, info_l = None, None
    if pre is not None:
        K_loaded, closed_l = chain.stiffness(ref=pre)
        info_l = {"axial_deflection_mm": float(-pre["q"][chain.m][2]),
                  "closed_contacts": int(np.count_nonzero(pre["closed"])),
                  "closed_during_perturbations": [min(closed_l), max(closed_l)]}
    if np.any(np.linalg.eigvalsh(K) <= 0):
        raise ModelError("beam chain: 6x6 stiffness not positive definite")
    info = {"nodes": len(chain.u), "elements": len(chain.u) - 1, "dofs": int(chain.nq),
            "contacts": len(chain.contacts), "bonded_turns_per_end": chain.bonded_turns,
            "closed_during_perturbations": [min(closed), max(closed)],
            "length_mm": coil.length, "geometry": coil.label, "working_load": info_l,
            "seats": dict(zip(("base", "tip"), settings.end_seats)),
            "seconds": time.perf_counter() - t0}
    return ChainResult(K, K_loaded, chain.master, np.array([0, 0, coil.length / 2]), coil,
                       settings, info, chain)


def condensed_6x6(chain: "Chain", closed: np.ndarray, kt: np.ndarray | None = None
                  ) -> np.ndarray:
    """Tangent 6x6 at the master (twist/wrench order) with the normal contacts ``closed`` held
    (no active-set change) and, where ``kt`` (N/mm per contact) is > 0, the contact stuck
    tangentially (x and y penalty springs between the contact points): the Schur complement of
    the reduced stiffness on the master."""
    w = chain.kn * closed
    A = chain.Kq + chain.N.T @ sp.diags(w) @ chain.N
    if kt is not None:
        A = A + chain.Rt.T @ sp.diags(np.repeat(np.maximum(kt, 0.0), 2)) @ chain.Rt
    A = A.tocsc()
    m = chain.m
    f = np.setdiff1d(np.arange(chain.nq), m)
    Aff = A[f][:, f].tocsc()
    Afm = A[f][:, m].toarray()
    S = A[m][:, m].toarray() - Afm.T @ spla.splu(Aff).solve(Afm)
    K = S[np.ix_(PERM, PERM)]
    return (K + K.T) / 2
