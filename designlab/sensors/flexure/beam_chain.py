"""Fast helix model: the spring wire as a chain of Timoshenko beams, its ends seated and in contact.

The wire centreline (mean radius ``R``, wire radius ``r``, ``d = 2 r``) is cut into straight
12-dof Timoshenko beams (:func:`designlab.fem.beam.beam_stiffness`, round section, shear
coefficient 0.9), ``elements_per_turn`` per turn. Frame: the base seat (the top face of the base
disc) is ``z = 0``, the tip seat (bottom face of the fingertip disc) ``z = L``; the tip disc is a
rigid 6-dof master at ``(0, 0, L)``; the spring centre, the closed form's frame {f}, is
``(0, 0, L / 2)``.

Ends (``closed_ground``, one dead turn at each end):

* **as built** (:func:`as_built`): the dead turn has pitch ``d`` (its gap to the next turn closes
  to zero: the wire end touches the first active turn), the pitch ramps linearly to the active
  pitch over ``RAMP`` turn after it, and the end is ground flat ``GRIND x d`` above the end's
  centreline (the solid part's convention, :mod:`designlab.geometry.flexure`). The active pitch is
  set so the seat-to-seat length is the handbook free length ``n_a p + 2 d`` (seed 002: 19.80 mm,
  its measured rest length).
* **the solid's geometry** (:func:`from_part`): the centreline and cut planes of the meshed
  ``SpringFlexure`` (dead turns 0.1 d clear of their neighbours), for the check against the
  solid FEM.

Seats. ``seat="bonded"``: every node whose wire section reaches the ground plane (the ground
face, ``c < r`` with ``c`` the centreline's height above the seat) is clamped to its disc
(seed 002: "epoxy interfaces between the housings and the flexure"); this is what the solid FEM
does with the ground faces. ``seat="contact"``: only the wire's end node is bonded (the epoxy
spot that locates the spring); the rest of the ground face sits on the seat with unilateral
contact at zero gap. ``seat="potted"``: the whole dead turn clamped. ``seat_base`` /
``seat_tip`` set one end's condition only (an asymmetric assembly; ``ChainResult.zero_coupling``
shows the elastic centre moving towards the more compliant end).

Contact (``contact=True``): the wire against the wire one turn above over the dead turn and the
ramp at each end (the dead turn against the first active turn, gap ``z(u + 1) - z(u) - d``), and
the dead turn against its seat (gap ``c - r``). **Line contacts** (default,
``contact_spacing_mm`` 0.1 mm): contact points at a fixed spacing along the wire, independent of
the beam nodes, each moving with the Timoshenko beams' own shape functions; the beams are
refined to ``contact_mesh_mm`` (0.25 mm) wherever a contact is within 0.1 mm of closing at
rest (plus 3 mm either side, both wires of a coil pair) and around any contact the working
load closes outside those windows (:func:`resolved_chain`). At the working load the dead turn
meets the next turn along a grazing line (its gap grows as the square of the distance from the
wire end): the closed zone is ~0.5 mm long, shorter than a default beam, so contacts at the
nodes (``contact_spacing_mm=0``, the scheme before 2026-11-25) closed 2 or 4 nodes depending on
where they fell and the 10 N 6x6 jumped with ``elements_per_turn``; the line contacts converge
(docs/flexure.md, "Beam chain"). A closed contact is a stiff normal penalty spring,
frictionless in :func:`chain_stiffness`, solved by an active-set iteration.
Coulomb friction: :func:`friction_stiffness` and :func:`loop_stiffness` solve it inside the
contact problem, incrementally (:meth:`ActiveSet.solve_friction`: return map with a tangential
penalty ``k_t = k_n 2 (1 - nu) / (2 - nu)``, ``ChainSettings.mu``); :func:`friction_bounds`
gives its two limits at the working-load state: gross slip (the frictionless tangent, plus a
force band ``mu sum f_n``) and full stick. Penalty stiffness per contact point: a line contact
of length ``h`` (the point spacing along the wire, mm; the node spacing for node contacts)
between an elastic cylinder and a flat or a cylinder has a stiffness per unit length of the
order of the contact modulus ``E*`` (Johnson, *Contact Mechanics*, 1985, sec. 5.6: the approach
grows only logarithmically with the load), so ``k_n = E* h`` (x0.1 or x10 moves the 10 N
diagonal error by +0.0 / -0.3 points).

The 6x6 comes from small symmetric perturbations of the tip disc around a reference state (the
unloaded spring, or the spring under an axial working load): ``K[:, j] = (W(+d e_j) - W(-d e_j)) /
(2 d)``, each perturbation solved with its own active set. Geometrically linear: no stress
stiffening (the axial working load stiffens only through contact).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import ThreadpoolController

from designlab.errors import ModelError, ParameterError
from designlab.fem.beam import beam_stiffness, circular_section
from designlab.frames import transform, transform_stiffness
from designlab.params import rng, validate
from designlab.sensors.flexure.spring import HelicalSpring, check_working_load, to_si

#: turns over which the pitch ramps from the dead pitch d to the active pitch (the solid part's
#: RAMP, designlab.geometry.flexure)
RAMP = 0.25
#: grinding plane above the wire end's centreline, in wire diameters (the solid part's
#: DEAD_GAP-sized grind, designlab.geometry.flexure._cut_planes)
GRIND = 0.1
#: printed seat discs (seed 002: PLA housings): the default ``ChainSettings.seat_material``,
#: E and nu from designlab.fem.materials
SEAT_MATERIAL = "PLA"
#: Coulomb coefficient of the wire's coil contacts (steel on steel, dry, kinetic: the contacts
#: slide under the perturbations): 0.3 in S. A. Hill's table "Coefficients of Friction"
#: (howwhy.nfshost.com/new/book1/motion/coefficients.html, 2023), which gives dry steel on
#: steel static 0.6 / kinetic 0.3 and oiled 0.05 / 0.03. No value is published for the spring.
MU_STEEL = 0.3


def mindlin_ratio(nu: float) -> float:
    """Mindlin's tangential / normal contact stiffness of two like elastic bodies,
    ``2 (1 - nu) / (2 - nu)`` (Johnson, *Contact Mechanics*, 1985, sec. 7.2)."""
    return 2 * (1 - nu) / (2 - nu)


#: master order (u_x, u_y, u_z, th_x, th_y, th_z) -> twist/wrench order (w, v) / (m, f)
_PERM = np.array([3, 4, 5, 0, 1, 2])


@dataclass(frozen=True)
class ChainSettings:
    """Settings of the beam-chain model (mm, N, rad)."""

    elements_per_turn: int = field(default=36, metadata=rng(8, 400,
                                   doc="straight beams per turn of wire"))
    contact: bool = True
    seat: str = field(default="bonded", metadata=rng(choices=("bonded", "contact", "potted"),
                      doc="ground faces bonded (epoxy), only seated, or the whole dead turn "
                          "set in epoxy"))
    seat_base: str = field(default="", metadata=rng(choices=("", "bonded", "contact", "potted"),
                           doc="end condition of the base end only ('' = seat)"))
    seat_tip: str = field(default="", metadata=rng(choices=("", "bonded", "contact", "potted"),
                          doc="end condition of the tip end only ('' = seat)"))
    working_load_N: float = field(default=10.0, metadata=rng(0, 1000, unit="N", doc=(
        "axial compression of the second reference state (seed 002: maximum fingertip force "
        "10 N)")))
    seat_material: str = field(default=SEAT_MATERIAL, metadata=rng(
        choices=("PLA", "ABS"), doc="material of the printed discs (contact modulus of the seats)"))
    mu: float = field(default=MU_STEEL, metadata=rng(0, 1e6, doc=(
        "Coulomb friction coefficient at the coil and seat contacts (friction_stiffness, "
        "loop_stiffness; chain_stiffness is frictionless). Default 0.3: dry steel on steel, "
        "kinetic (S. A. Hill, 'Coefficients of Friction', howwhy.nfshost.com, 2023: static 0.6, "
        "kinetic 0.3; oiled 0.05 / 0.03)")))
    contact_spacing_mm: float = field(default=0.1, metadata=rng(0, 10, unit="mm", doc=(
        "spacing of the contact points along the wire: a line contact (penalty E* per unit "
        "length, each point E* x its length), the points placed independently of the beam "
        "nodes and moving with the beams' shape functions; 0: one contact per beam node (the "
        "scheme before 2026-11-25, whose 10 N state depends on elements_per_turn)")))
    contact_mesh_mm: float = field(default=0.25, metadata=rng(0, 10, unit="mm", doc=(
        "beam length (mm of wire) where a contact can close (within 0.1 mm of closing at rest, "
        "plus 3 mm either side; line contacts only): a contact zone shorter than a beam is not "
        "resolved by the beam's shape functions. 0: elements_per_turn everywhere")))
    perturbation_rad: float = field(default=2e-3, metadata=rng(0, 0.1, lo_open=True, unit="rad"))
    perturbation_mm: float = field(default=0.02, metadata=rng(0, 1, lo_open=True, unit="mm"))
    max_iterations: int = field(default=60, metadata=rng(2, 1000))

    def __post_init__(self):
        validate(self)

    @property
    def end_seats(self) -> tuple[str, str]:
        """(base, tip) end conditions: ``seat_base`` / ``seat_tip`` where set, else ``seat``."""
        return self.seat_base or self.seat, self.seat_tip or self.seat


@dataclass(frozen=True)
class Coil:
    """What the chain needs of a spring (mm, MPa): centreline ``z(u)`` at turn count ``u``
    (``0 <= u <= turns``), seat heights in the same frame, ends, wire and moduli."""

    R: float
    r: float
    turns: float
    z_of_u: Callable[[np.ndarray], np.ndarray]
    seat_lo: float
    seat_hi: float
    ends: str
    E: float
    G: float
    label: str

    @property
    def length(self) -> float:
        return self.seat_hi - self.seat_lo


def _ramp_profile(u, turns, p_dead, p_act, start, ramp):
    """Pitch per turn: ``p_dead`` up to ``start``, linear to ``p_act`` over ``ramp``, mirrored."""
    up = np.clip((u - start) / ramp, 0.0, 1.0)
    down = np.clip((u - (turns - start - ramp)) / ramp, 0.0, 1.0)
    return p_dead + (p_act - p_dead) * (up - down)


def _integrate(profile, turns):
    fine = np.linspace(0.0, turns, 20001)
    P = profile(fine)
    z = np.concatenate([[0.0], np.cumsum((P[1:] + P[:-1]) / 2 * np.diff(fine))])
    return lambda u: np.interp(np.asarray(u, float), fine, z)


def as_built(spring: HelicalSpring) -> Coil:
    """The spring as built: ``inactive_coils`` 2 -> closed-and-ground ends (one dead turn each,
    gap closing to zero, ground); 0 -> plain ends clamped at the wire's end points."""
    R, r, d = spring.mean_radius, spring.wire_radius, 2 * spring.wire_radius
    n_a = spring.active_coils
    if spring.inactive_coils == 0:
        p = spring.pitch
        return Coil(R, r, n_a, lambda u: p * np.asarray(u, float), 0.0, p * n_a, "plain",
                    spring.E, spring.G, "plain ends, clamped wire ends")
    if spring.inactive_coils != 2:
        raise ParameterError("inactive_coils", spring.inactive_coils,
                             "0 (plain ends) or 2 (closed and ground ends: one dead turn each)")
    turns = spring.coils                            # >= 2.5 (HelicalSpring checks it)
    L0 = n_a * spring.pitch + 2 * d                 # handbook free length (seed 002: 19.80 mm)
    e = GRIND * d
    # rise: 2 dead turns of d + n_a p_a - RAMP (p_a - d)  =  L0 + 2 e
    p_a = (L0 + 2 * e - 2 * d - RAMP * d) / (n_a - RAMP)
    z = _integrate(lambda u: _ramp_profile(u, turns, d, p_a, 1.0, RAMP), turns)
    return Coil(R, r, turns, z, e, float(z(turns)) - e, "closed_ground", spring.E, spring.G,
                f"as built: closed (gap 0) and ground ends, active pitch {p_a:.3g} mm")


def from_part(part, E: float | None = None, G: float | None = None) -> Coil:
    """The meshed ``SpringFlexure``'s centreline and cut planes (its E, G from its material)."""
    from designlab.fem.materials import get_material

    m = get_material(part.material)
    lo, hi = part._cut_planes()
    return Coil(part.mean_diameter / 2, part.wire_radius, part.total_coils, part.centerline_z,
                lo, hi, part.ends, m.E if E is None else E, m.G if G is None else G,
                f"solid part geometry ({part.ends})")


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


def _block_diag(blocks: np.ndarray) -> np.ndarray:
    """Dense block-diagonal matrix of ``blocks`` (k, a, b) -> (k a, k b)."""
    k, a, b = blocks.shape
    out = np.zeros((k * a, k * b))
    for i in range(k):
        out[i * a:(i + 1) * a, i * b:(i + 1) * b] = blocks[i]
    return out


def _next_closed(g: np.ndarray, closed: np.ndarray, tol: float, seen: set, runs=None):
    """The next normal active set from the gaps ``g`` (mm): closed where ``g < -tol``, open
    where ``g > tol``, kept in between. A set met before (a cycle) flips only the contact with
    the largest gap instead. ``runs`` (line contacts: an id per contact, equal for neighbours
    along one contact line): from an all-open set only the deepest contact of each run of
    penetrated neighbours closes (a line contact zone then grows from its centre instead of
    shrinking from all the penetrated points, one edge point per solve). Returns (set, whether
    it is unchanged)."""
    new = np.where(g < -tol, True, np.where(g > tol, False, closed))
    if runs is not None and not closed.any() and np.count_nonzero(new) > 1:
        pen = np.nonzero(new)[0]
        brk = np.nonzero((np.diff(pen) > 1) | (np.diff(runs[pen]) != 0))[0] + 1
        new = np.zeros_like(closed)
        for seg in np.split(pen, brk):
            new[seg[np.argmin(g[seg])]] = True
    if np.array_equal(new, closed):
        return closed, True
    key = new.tobytes()
    if key in seen:
        bad = np.nonzero(new != closed)[0]
        new = closed.copy()
        k = bad[np.argmax(np.abs(g[bad]))]
        new[k] = not closed[k]
    seen.add(key)
    return new, False


_CONTROLLER: list = []


def _blas_controller() -> ThreadpoolController:
    """One threadpool controller for the process (building one scans the loaded libraries:
    ~6 ms a time)."""
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


class ActiveSet:
    """Unilateral penalty contacts on a linear structure with a 6-dof master (u, th), solved by
    an active-set iteration. A subclass sets ``Kq`` (sparse, n_q square: the structure),
    ``N`` (n_c, n_q: the gap opening per dof), ``kn``, ``g0`` (penalty N/mm and initial gap mm
    per contact), ``m`` (the master's 6 indices into q), ``nq`` and ``s`` (a
    :class:`ChainSettings`: perturbations, iteration limit). Shared by the beam chain and the
    condensed solid FEM (:mod:`designlab.sensors.flexure.helix_fem`)."""

    # ------------------------------------------------------------------ solves
    def _settle(self, closed: np.ndarray, step) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """The active-set iteration: ``step(closed) -> (q, g)`` solves the structure with the
        contacts ``closed``; repeat until the set keeps its state (a band of +-tol around zero
        gap: no chatter at g ~ 0); on a cycle change only the contact that violates its state
        most. Returns (q, g, closed, iterations)."""
        tol = 1e-6 * self.s.perturbation_mm
        seen = set()
        runs = getattr(self, "runs", None)
        # the solves' dense products are small: BLAS threads only cost (2x the wall time of
        # `designlab flexure` on the shared 2-core machine)
        with _blas_controller().limit(limits=1, user_api="blas"):
            for it in range(self.s.max_iterations):
                q, g = step(closed)
                closed, settled = _next_closed(g, closed, tol, seen, runs)
                if settled:
                    return q, g, closed, it + 1
        raise ModelError(f"beam chain: contact active set did not settle in "
                         f"{self.s.max_iterations} iterations")

    def solve(self, q_master=None, f_master=None, ref: dict | None = None) -> dict:
        """Active-set solve with the master displaced to ``q_master`` (u, th) or loaded by
        ``f_master`` (f, m; the master free), starting from the active set of ``ref``."""
        nq, m = self.nq, self.m
        nc = len(self.kn)
        closed = np.zeros(nc, bool) if ref is None else ref["closed"].copy()
        q = np.zeros(nq) if ref is None else ref["q"].copy()
        fext = np.zeros(nq)
        if f_master is not None:
            fext[m] = f_master
        free = np.arange(nq) if q_master is None else np.setdiff1d(np.arange(nq), m)
        if q_master is not None:
            q[m] = q_master
        N, kn, g0 = self.N, self.kn, self.g0
        system = {}

        line = getattr(self, "runs", None) is not None

        def step(closed):
            w = kn * closed
            if line:                 # many contacts, few closed: assemble the closed ones only
                i = np.nonzero(closed)[0]
                A = (self.Kq + N[i].T @ sp.diags(w[i]) @ N[i]).tocsc()
            else:
                A = (self.Kq + N.T @ sp.diags(w) @ N).tocsc()
            b = fext - N.T @ (w * g0)
            rhs = b[free] - (A[free][:, m] @ q[m] if q_master is not None else 0.0)
            Aff = A[free][:, free]
            try:
                lu = spla.splu(Aff)
            except RuntimeError:
                raise ModelError("beam chain: singular stiffness (a spring end is not held)") from None
            x = lu.solve(rhs)
            q[free] = x + lu.solve(rhs - Aff @ x)     # one refinement step (stiff penalties)
            system.update(A=A, b=b)
            return q, g0 + N @ q

        q, g, closed, its = self._settle(closed, step)
        reaction = (system["A"] @ q - system["b"])[m] + (fext[m] if q_master is None else 0.0)
        return {"q": q.copy(), "closed": closed, "f_n": np.where(closed, -kn * np.minimum(g, 0), 0.0),
                "reaction": reaction, "iterations": its}

    def solve_force(self, f_master) -> dict:
        """The master loaded by ``f_master`` (f, m; free) from the open state, as :meth:`solve`
        but with one factorisation of the structure for every call: each active set's
        contacts enter as a low-rank update (Woodbury), so many load cases cost little."""
        lu = getattr(self, "_lu_free", None)
        if lu is None:
            lu = self._lu_free = spla.splu(sp.csc_matrix(self.Kq))
        fext = np.zeros(self.nq)
        fext[self.m] = f_master
        N = self.N.tocsr()
        kn, g0 = self.kn, self.g0
        x0 = lu.solve(fext)
        line = getattr(self, "runs", None) is not None

        def step(closed):
            idx = np.nonzero(closed)[0]
            if not len(idx):
                return x0, g0 + N @ x0
            if len(idx) > 40:                               # many contacts: factor directly
                Ni = N[idx]
                A = (self.Kq + Ni.T @ sp.diags(kn[idx]) @ Ni).tocsc()
                b = fext - Ni.T @ (kn[idx] * g0[idx])
                lu_a = spla.splu(A)
                q = lu_a.solve(b)
                q += lu_a.solve(b - A @ q)                  # one refinement step
                return q, g0 + N @ q
            U = N[idx].T.toarray()                          # (nq, k)
            KU = lu.solve(U)
            w = kn[idx]
            S = np.diag(1.0 / w) + U.T @ KU

            def wsolve(rhs):
                xb = lu.solve(rhs)
                return xb - KU @ np.linalg.solve(S, U.T @ xb)

            b = fext - U @ (w * g0[idx])
            q = wsolve(b)
            if line:                                        # one refinement step (stiff
                q += wsolve(b - self.Kq @ q - U @ (w * (U.T @ q)))   # short beams, penalties)
            return q, g0 + N @ q

        q, g, closed, its = self._settle(np.zeros(len(kn), bool), step)
        return {"q": q.copy(), "closed": closed, "f_n": np.where(closed, -kn * np.minimum(g, 0), 0.0),
                "iterations": its}

    def stiffness(self, ref: dict | None = None) -> tuple[np.ndarray, list]:
        """6x6 (twist -> wrench order) by symmetric master perturbations around ``ref``."""
        amp = np.r_[[self.s.perturbation_mm] * 3, [self.s.perturbation_rad] * 3]
        q0 = np.zeros(6) if ref is None else ref["q"][self.m]
        Kq = np.zeros((6, 6))
        closed = []
        for j in range(6):
            res = []
            for sgn in (1.0, -1.0):
                r = self.solve(q_master=q0 + sgn * amp[j] * np.eye(6)[j], ref=ref)
                res.append(r)
                closed.append(int(np.count_nonzero(r["closed"])))
            Kq[:, j] = (res[0]["reaction"] - res[1]["reaction"]) / (2 * amp[j])
        K = Kq[np.ix_(_PERM, _PERM)]
        return (K + K.T) / 2, closed

    # ------------------------------------------------------------------ Coulomb friction
    def rest_state(self) -> dict:
        """The unloaded, undeformed state: no contact force, no tangential traction."""
        nc = len(self.kn)
        return {"q": np.zeros(self.nq), "closed": np.zeros(nc, bool), "t": np.zeros((nc, 2)),
                "fext": np.zeros(self.nq), "reaction": np.zeros(6), "stick": np.zeros(nc, bool)}

    def solve_friction(self, mu: float, kt, q_master=None, f_master=None, ref: dict | None = None,
                       steps: int = 1) -> dict:
        """Frictional contact solved incrementally from the state ``ref`` (default: at rest) to
        the master displaced to ``q_master`` (u, th; the other dofs free) or loaded by
        ``f_master`` (f, m; the master free), in ``steps`` equal increments.

        Each closed contact carries, besides its normal penalty force ``f_n``, a tangential
        traction ``t`` (2 components, the contact's ``rt`` directions) by a penalty ``kt`` (N/mm
        per contact) and Coulomb's law, integrated by the return map (Simo & Hughes,
        *Computational Inelasticity*, 1998, sec. 1.2 and 2.7 for the 1-D/plasticity form; Wriggers,
        *Computational Contact Mechanics*, 2006, sec. 5.2 for contact): the trial
        ``t_tr = t_n + kt * (slip increment)``; stick if ``|t_tr| <= mu f_n``, else slip with
        ``t = mu f_n t_tr / |t_tr|``. Each increment is a Newton iteration with the consistent
        (unsymmetric) tangent, the normal active set updated as in :meth:`_settle`; an increment
        that does not converge is halved (up to 12 times). A contact that opens loses its
        traction. ``mu = 0`` is the frictionless :meth:`solve` (to round-off).
        Returns ``q``, ``closed``, ``t`` (nc, 2), ``f_n``, ``stick``, ``reaction`` (the master's
        load, master order f, m), ``fext`` and ``iterations``."""
        st = self.rest_state() if ref is None else ref
        kt = np.broadcast_to(np.asarray(kt, float), self.kn.shape)
        if q_master is not None:
            q1 = np.asarray(q_master, float)
            q0 = st["q"][self.m]
            target = lambda a: (q0 + a * (q1 - q0), np.zeros(self.nq))       # noqa: E731
        else:
            f1 = np.zeros(self.nq)
            f1[self.m] = f_master
            f0 = st["fext"] if "fext" in st else np.zeros(self.nq)
            target = lambda a: (None, f0 + a * (f1 - f0))                     # noqa: E731
        its = 0
        todo = [(k / steps, (k + 1) / steps, 0) for k in range(steps)][::-1]
        while todo:
            a0, a1, depth = todo.pop()
            qm, fext = target(a1)
            new = self._friction_increment(st, qm, fext, mu, kt)
            if new is None:
                if depth >= 12:
                    raise ModelError("beam chain: frictional contact did not converge (the "
                                     "increment was halved 12 times)")
                mid = (a0 + a1) / 2
                todo += [(mid, a1, depth + 1), (a0, mid, depth + 1)]
                continue
            its += new["iterations"]
            st = new
        return dict(st, iterations=its)

    def _free_parts(self, master_free: bool):
        """Structure, gap and slip operators on the free dofs (the master free or prescribed),
        cached."""
        cache = self.__dict__.setdefault("_free_cache", {})
        if master_free not in cache:
            free = (np.arange(self.nq) if master_free
                    else np.setdiff1d(np.arange(self.nq), self.m))
            Kq = sp.csr_matrix(self.Kq)
            cache[master_free] = (Kq[free][:, free].tocsc(), sp.csr_matrix(self.N)[:, free],
                                  sp.csr_matrix(self.Rt)[:, free])
        return cache[master_free]

    def _friction_increment(self, st: dict, q_m, fext, mu: float, kt) -> dict | None:
        """One increment from the converged state ``st``: Newton on the equilibrium with the
        return-mapped tractions; None when it does not converge (the caller halves it)."""
        nq, m = self.nq, self.m
        N, kn, g0 = self.N, self.kn, self.g0
        Rt = self.Rt
        nc = len(kn)
        free = np.arange(nq) if q_m is None else np.setdiff1d(np.arange(nq), m)
        q = st["q"].copy()
        if q_m is not None:
            q[m] = q_m
        qn, tn = st["q"], np.where(st["closed"][:, None], st["t"], 0.0)
        closed = st["closed"].copy()
        tol = 1e-6 * self.s.perturbation_mm
        seen = set()

        def state(q, closed):
            g = g0 + N @ q
            w = kn * closed
            fn = np.maximum(-w * g, 0.0)
            ttr = np.where(closed[:, None], tn + kt[:, None] * (Rt @ (q - qn)).reshape(nc, 2), 0.0)
            nt = np.linalg.norm(ttr, axis=1)
            lim = mu * fn
            stick = closed & (nt <= lim) & (lim > 0)
            scale = np.where(stick, 1.0, np.where(nt > 0, lim / np.where(nt > 0, nt, 1.0), 0.0))
            t = ttr * scale[:, None]
            fi = self.Kq @ q + N.T @ (w * g) + Rt.T @ t.ravel()
            return g, w, fn, ttr, nt, stick, t, fi

        for it in range(self.s.max_iterations):
            g, w, fn, ttr, nt, stick, t, fi = state(q, closed)
            # consistent tangent of the tractions: stick kt I; slip kt (mu f_n / |t_tr|)
            # (I - n n^T) on the slip and -mu k_n n on the normal gap
            D = np.zeros((nc, 2, 2))
            Cn = np.zeros((nc, 2))
            slip = closed & ~stick & (nt > 0)
            D[stick] = kt[stick, None, None] * np.eye(2)
            if slip.any():
                n = ttr[slip] / nt[slip, None]
                sc = kt[slip] * mu * fn[slip] / nt[slip]
                D[slip] = sc[:, None, None] * (np.eye(2) - n[:, :, None] * n[:, None, :])
                Cn[slip] = np.where((fn[slip] > 0)[:, None], -mu * kn[slip, None] * n, 0.0)
            # the tangent on the free dofs: the structure plus the closed contacts' terms
            idx = np.nonzero(closed)[0]
            Kff, Nf, Rf = self._free_parts(q_m is None)
            A = Kff
            if len(idx):
                Nc = Nf[idx]
                Rc = Rf[np.ravel(np.column_stack([2 * idx, 2 * idx + 1]))]
                Db = sp.csr_matrix(_block_diag(D[idx]))
                Cb = sp.csr_matrix(_block_diag(Cn[idx][:, :, None]))
                A = A + Nc.T @ sp.diags(kn[idx]) @ Nc + Rc.T @ (Db @ Rc + Cb @ Nc)
            r = fi - fext
            try:
                lu = spla.splu(sp.csc_matrix(A))
                dq = lu.solve(-r[free])
                dq += lu.solve(-r[free] - A @ dq)       # one refinement step (stiff penalties)
            except RuntimeError:
                raise ModelError("beam chain: singular stiffness (a spring end is not held)") from None
            # backtracking on the residual (slip directions turn: a full Newton step can cycle)
            r0, alpha = np.linalg.norm(r[free]), 1.0
            for _ in range(30):
                qt = q.copy()
                qt[free] += alpha * dq
                if np.linalg.norm((state(qt, closed)[-1] - fext)[free]) < r0:
                    break
                alpha /= 2
            q = qt
            g_new = g0 + N @ q
            closed, settled = _next_closed(g_new, closed, tol, seen)
            if not settled:
                continue
            # same normal set: converged when the residual is round-off and the stick/slip
            # split of the new state is the one the step was taken with
            g2, w2, fn2, ttr2, nt2, stick2, t2, fi2 = state(q, closed)
            res = np.linalg.norm((fi2 - fext)[free])
            ref_scale = max(np.linalg.norm(fi2), np.linalg.norm(fext), 1e-12)
            if res <= 1e-9 * ref_scale:      # (the return map is continuous at |t_tr| = mu f_n)
                return {"q": q.copy(), "closed": closed, "t": t2, "f_n": fn2, "stick": stick2,
                        "fext": np.asarray(fext, float).copy(), "reaction": fi2[m].copy(),
                        "iterations": it + 1}
        return None

    def friction_stiffness(self, mu: float, kt, ref: dict | None = None, steps: int = 1,
                           amplitude: float = 1.0) -> tuple[np.ndarray, list]:
        """6x6 (twist -> wrench order) by symmetric master perturbations around the frictional
        state ``ref`` (each solved from ``ref`` with its tractions by :meth:`solve_friction`),
        perturbations ``amplitude`` times the settings' (0.02 mm, 2 mrad). With friction this
        is the secant of the two one-sided paths, which depends on the amplitude (a sliding
        contact adds up to ``2 mu f_n`` across the two) and need not be symmetric (returned as
        computed, with the (closed, stuck) contact counts of every path)."""
        amp = amplitude * np.r_[[self.s.perturbation_mm] * 3, [self.s.perturbation_rad] * 3]
        st = self.rest_state() if ref is None else ref
        q0 = st["q"][self.m]
        Kq = np.zeros((6, 6))
        info = []
        for j in range(6):
            res = [self.solve_friction(mu, kt, q_master=q0 + sgn * amp[j] * np.eye(6)[j],
                                       ref=st, steps=steps) for sgn in (1.0, -1.0)]
            info += [(int(np.count_nonzero(r["closed"])), int(np.count_nonzero(r["stick"])))
                     for r in res]
            Kq[:, j] = (res[0]["reaction"] - res[1]["reaction"]) / (2 * amp[j])
        return Kq[np.ix_(_PERM, _PERM)], info


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


def wire_contact_points(z_of_u: Callable, R: float, turns: float, spacing: float):
    """Where line contacts sit along a helix of mean radius ``R`` (mm) and centreline height
    ``z_of_u(u)`` over ``turns`` turns: ``(points, coil_spans)``. ``points(lo, hi)`` -> (turn
    counts, lengths of wire in mm): the midpoints of equal steps in turn count over
    [lo, hi], ~``spacing`` mm of wire each. ``coil_spans``: the turn-count ranges of the lower
    wire of each coil-to-coil contact (the dead turn and its pitch ramp at both ends; one range
    for a spring too short to have two). Shared by the beam chain and the solid FEM."""
    fine = np.linspace(0.0, turns, int(turns * 2000) + 1)
    dsdu = np.hypot(2 * np.pi * R, np.gradient(np.asarray(z_of_u(fine), float), fine))

    def points(lo: float, hi: float):
        mid = np.interp((lo + hi) / 2, fine, dsdu)
        n = max(int(math.ceil((hi - lo) * mid / spacing - 1e-9)), 1)
        du = (hi - lo) / n
        us = lo + (np.arange(n) + 0.5) * du
        return us, np.interp(us, fine, dsdu) * du

    span = 1.0 + RAMP
    spans = sorted([(0.0, min(span, turns - 1.0)), (max(turns - 1.0 - span, 0.0), turns - 1.0)])
    if spans[1][0] <= spans[0][1]:                    # short springs: one span
        spans = [(spans[0][0], max(spans[0][1], spans[1][1]))]
    return points, spans


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
        if coil.ends == "plain":
            base_bond, tip_bond = np.array([0]), np.array([n - 1])
        else:
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
    K = S[np.ix_(_PERM, _PERM)]
    return (K + K.T) / 2


def _tip_friction_band(chain: "Chain", closed: np.ndarray, fn: np.ndarray, mu: float) -> dict:
    """Half-width of the friction band at the tip master, per master axis: the tip moved along
    the axis (frictionless motion, normal forces of the reference state), every closed contact
    sliding against its relative tangential motion with ``mu f_n``; the master's reaction to
    those forces along the same axis (N for u_x, u_y, u_z; N mm for th_x, th_y, th_z). A loop
    along that axis deviates from its median by this much."""
    A = (chain.Kq + chain.N.T @ sp.diags(chain.kn * closed) @ chain.N).tocsc()
    m = chain.m
    f = np.setdiff1d(np.arange(chain.nq), m)
    lu = spla.splu(A[f][:, f].tocsc())
    Afm = A[f][:, m].toarray()
    out = {}
    for j, name in enumerate(("u_x", "u_y", "u_z", "th_x", "th_y", "th_z")):
        q = np.zeros(chain.nq)
        q[m[j]] = 1.0
        q[f] = lu.solve(-Afm[:, j])
        V = (chain.Rt @ q).reshape(-1, 2)
        nv = np.linalg.norm(V, axis=1)
        slide = closed & (nv > 0)
        tr = np.zeros_like(V)
        tr[slide] = -mu * fn[slide, None] * V[slide] / nv[slide, None]
        g = chain.Rt.T @ tr.ravel()
        reaction = Afm.T @ lu.solve(g[f]) - g[m]         # what holds the master against them
        out[name] = float(reaction[j])
    return out


def friction_bounds(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                    mu: float = 0.3) -> dict:
    """What Coulomb friction at the closed coil and seat contacts can do to the chain's 6x6 at
    the working load, as two bounds (the closed contacts of the frictionless 10 N state held;
    :func:`friction_stiffness` solves the frictional path between them):

    * **slip** (gross sliding, any perturbation larger than ``mu f_n / k_t``): a sliding contact
      carries a constant ``mu f_n`` whose tangent is zero, so the tangent 6x6 is the
      frictionless one; friction shows as a force band (hysteresis), not as stiffness;
    * **stick** (perturbations below that): every closed contact holds tangentially with the
      Mindlin ratio ``k_t = k_n 2 (1 - nu) / (2 - nu)`` (Johnson 1985, sec. 7.2), a stiffness
      independent of ``mu``.

    Returns the two 6x6 at the spring centre (N mm/rad, N/mm; SI too), the normal forces, the
    band ``mu sum f_n`` at the contacts, its half-width at the tip per master axis
    (``tip_friction_band``: the hysteresis a loop along that axis shows) and the largest stick
    displacement ``mu f_n / k_t``. ``mu``: see :data:`MU_STEEL` (no value is published for
    the spring)."""
    if not (isinstance(mu, (int, float)) and 0 <= mu <= 2):
        raise ParameterError("mu", mu, "a friction coefficient 0 <= mu <= 2")
    settings = settings or ChainSettings()
    if settings.working_load_N <= 0 or not settings.contact:
        raise ParameterError("working_load_N", settings.working_load_N,
                             "> 0 with contact=True (friction needs a preloaded contact)")
    check_working_load(spring, settings.working_load_N)
    chain = Chain(as_built(spring), settings)
    pre = chain.solve(f_master=np.r_[0.0, 0.0, -settings.working_load_N, 0.0, 0.0, 0.0])
    closed, fn = pre["closed"], pre["f_n"]
    nu = chain.coil.E / (2 * chain.coil.G) - 1
    kt = np.where(closed, chain.kn * mindlin_ratio(nu), 0.0)
    K_slip = condensed_6x6(chain, closed)
    K_stick = condensed_6x6(chain, closed, kt)
    K_pert, _ = chain.stiffness(ref=pre)
    band = _tip_friction_band(chain, closed, fn, mu)
    centre = np.array([0.0, 0.0, chain.coil.length / 2])
    move = transform(translation=chain.master - centre)
    at = {k: transform_stiffness(v, move) for k, v in
          (("slip", K_slip), ("stick", K_stick), ("perturbation", K_pert))}
    kinds = np.array([c.kind for c in chain.contacts])
    with np.errstate(divide="ignore", invalid="ignore"):
        stick_disp = np.where(closed, mu * fn / np.where(kt > 0, kt, 1.0), 0.0)
    return {"K_slip_centre": at["slip"], "K_stick_centre": at["stick"],
            "K_perturbation_centre": at["perturbation"],
            "K_slip_centre_si": to_si(at["slip"]), "K_stick_centre_si": to_si(at["stick"]),
            "closed": {"coil": int(np.count_nonzero(closed & (kinds == "coil"))),
                       "seat": int(np.count_nonzero(closed & (kinds == "seat")))},
            "normal_force_N": {"coil": float(fn[kinds == "coil"].sum()),
                               "seat": float(fn[kinds == "seat"].sum())},
            "friction_band_N": float(mu * fn.sum()), "mu": float(mu),
            "max_stick_displacement_mm": float(stick_disp.max()) if closed.any() else 0.0,
            "tip_friction_band": band,
            "k_t_over_k_n": float(2 * (1 - nu) / (2 - nu))}


def _friction_setup(spring: HelicalSpring, settings: ChainSettings | None, mu: float | None):
    settings = settings or ChainSettings()
    mu = settings.mu if mu is None else mu
    if not (isinstance(mu, (int, float)) and 0 <= mu <= 1e6):
        raise ParameterError("mu", mu, "a friction coefficient 0 <= mu <= 1e6")
    if not settings.contact:
        raise ParameterError("contact", settings.contact, "True (friction acts at the contacts)")
    if settings.working_load_N > 0:
        check_working_load(spring, settings.working_load_N)
    chain = Chain(as_built(spring), settings)
    nu = chain.coil.E / (2 * chain.coil.G) - 1
    return settings, float(mu), chain, chain.kn * mindlin_ratio(nu)


def friction_stiffness(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                       mu: float | None = None, amplitude: float = 1.0,
                       preload_steps: int = 10) -> ChainResult:
    """The chain's 6x6 with Coulomb friction at the coil and seat contacts, unloaded and at the
    axial working load: the working load applied in ``preload_steps`` force increments from rest
    (each contact's traction follows its slip history), then symmetric perturbations of the tip
    master (``amplitude`` x the settings' 0.02 mm / 2 mrad), each solved incrementally from that
    state (:meth:`ActiveSet.solve_friction`: return map, tangential penalty
    ``k_t = k_n 2 (1 - nu) / (2 - nu)``). ``mu``: default ``settings.mu`` (0.3, dry steel on
    steel). ``mu = 0`` is :func:`chain_stiffness`; ``mu -> inf`` the stuck bound of
    :func:`friction_bounds`. With ``0 < mu < inf`` the result is a secant: it depends on the
    amplitude. ``K`` and ``K_loaded`` are symmetrised; the raw ones and their asymmetry are in
    ``info``."""
    t0 = time.perf_counter()
    settings, mu, chain, kt = _friction_setup(spring, settings, mu)
    K_raw, paths = chain.friction_stiffness(mu, kt, amplitude=amplitude)
    K_loaded = K_l_raw = None
    info_l = None
    if settings.working_load_N > 0:
        pre = chain.solve_friction(mu, kt, f_master=np.r_[0.0, 0.0, -settings.working_load_N,
                                                          0.0, 0.0, 0.0], steps=preload_steps)
        K_l_raw, paths_l = chain.friction_stiffness(mu, kt, ref=pre, amplitude=amplitude)
        K_loaded = (K_l_raw + K_l_raw.T) / 2
        c = pre["closed"]
        info_l = {"axial_deflection_mm": float(-pre["q"][chain.m][2]),
                  "closed_contacts": int(np.count_nonzero(c)),
                  "stuck_contacts": int(np.count_nonzero(pre["stick"])),
                  "normal_force_N": float(pre["f_n"].sum()),
                  "traction_over_limit": [float(x) for x in
                                          np.linalg.norm(pre["t"][c], axis=1)
                                          / np.maximum(mu * pre["f_n"][c], 1e-300)],
                  "paths_closed_stuck": paths_l,
                  "asymmetry": float(np.abs(K_l_raw - K_l_raw.T).max() / np.abs(K_l_raw).max()),
                  "K_raw": K_l_raw.tolist()}
    info = {"mu": mu, "k_t_over_k_n": float(kt[0] / chain.kn[0]) if len(kt) else None,
            "amplitude_mm_rad": [amplitude * settings.perturbation_mm,
                                 amplitude * settings.perturbation_rad],
            "paths_closed_stuck": paths,
            "asymmetry": float(np.abs(K_raw - K_raw.T).max() / np.abs(K_raw).max()),
            "K_raw": K_raw.tolist(), "working_load": info_l, "contacts": len(chain.contacts),
            "seconds": time.perf_counter() - t0}
    return ChainResult((K_raw + K_raw.T) / 2, K_loaded, chain.master,
                       np.array([0, 0, chain.coil.length / 2]), chain.coil, settings, info, chain)


def loop_stiffness(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                   mu: float | None = None, amplitude_mm: float = 1.0,
                   amplitude_rad: float = 0.05, points: int = 8, preload_N: float = 0.0) -> dict:
    """The 6x6 as seed 002 fitted it: hysteresis loops about the relaxed configuration (Sec.
    V-B: each axis cycled between its largest positive and negative displacement), ``F = K X``
    by least squares. Per master axis (at the tip seat, global axes): 0 -> +A -> -A -> +A in
    ``points`` increments per quarter, each by :meth:`ActiveSet.solve_friction`; the last full
    cycle (+A -> -A -> +A) gives the column ``K[:, j] = sum(F x) / sum(x^2)`` (no intercept, as
    the paper's fit) and the loop's half-width along the axis (half the largest difference of
    the two branches at the same displacement). The paper's 21-entry fit is symmetric: ``K`` is symmetrised, the
    raw columns are ``K_raw``. ``A``: ``amplitude_mm`` for translations, ``amplitude_rad`` for
    rotations (the paper does not print its loop amplitudes: its random poses span 1 mm in x, y
    and 4 mm in z). ``preload_N``: an axial load held before the loops (0: relaxed).
    Geometrically linear, the contacts' normal forces follow the motion."""
    t0 = time.perf_counter()
    settings, mu, chain, kt = _friction_setup(spring, settings, mu)
    if not (amplitude_mm > 0 and amplitude_rad > 0 and isinstance(points, int) and points >= 2):
        raise ParameterError("amplitude", (amplitude_mm, amplitude_rad, points),
                             "amplitudes > 0 and points >= 2")
    ref = chain.rest_state()
    if preload_N > 0:
        ref = chain.solve_friction(mu, kt, f_master=np.r_[0.0, 0.0, -preload_N, 0, 0, 0],
                                   steps=10)
    q0 = ref["q"][chain.m]
    amp = np.r_[[amplitude_mm] * 3, [amplitude_rad] * 3]
    path = np.concatenate([np.linspace(0, 1, points + 1)[1:], np.linspace(1, -1, 2 * points + 1)[1:],
                           np.linspace(-1, 1, 2 * points + 1)[1:]])
    Kq = np.zeros((6, 6))
    half = np.zeros(6)
    loops = []
    for j in range(6):
        st, xs, Fs = ref, [], []
        for a in path:
            st = chain.solve_friction(mu, kt, q_master=q0 + a * amp[j] * np.eye(6)[j], ref=st)
            xs.append(a * amp[j])
            Fs.append(st["reaction"] - ref["reaction"])
        xs, Fs = np.array(xs[points:]), np.array(Fs[points:])          # the last full cycle
        Kq[:, j] = Fs.T @ xs / (xs @ xs)
        # the two branches at the same x: descending k <-> ascending 2 points - 2 - k
        k = np.arange(2 * points - 1)
        half[j] = float(np.abs(Fs[k, j] - Fs[4 * points - 2 - k, j]).max() / 2)
        loops.append({"x": xs.tolist(), "F": Fs[:, j].tolist()})
    K_raw = Kq[np.ix_(_PERM, _PERM)]
    return {"K": (K_raw + K_raw.T) / 2, "K_raw": K_raw, "master": chain.master,
            "centre": np.array([0.0, 0.0, chain.coil.length / 2]), "mu": mu,
            "half_width": dict(zip(("u_x", "u_y", "u_z", "th_x", "th_y", "th_z"), half.tolist())),
            "amplitude_mm_rad": [amplitude_mm, amplitude_rad], "preload_N": preload_N,
            "loops": loops, "seconds": time.perf_counter() - t0}


def with_settings(base: ChainSettings | None = None, **kw) -> ChainSettings:
    return replace(base or ChainSettings(), **kw)
