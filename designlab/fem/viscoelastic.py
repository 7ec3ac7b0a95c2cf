"""Linear viscoelasticity (generalized Maxwell / Prony series) under load histories.

Each region whose :class:`~designlab.fem.materials.Material` has a ``prony`` relaxes as

    s(t) = 2 G0 [g_inf e(t) + sum_i g_i h_i(t)],  h_i(t) = int_0^t exp(-(t-s)/tau_i) de/ds ds
    p(t) =   K0 [k_inf th(t) + sum_j k_j m_j(t)]   (bulk terms only if ``prony.k`` is given)

(e: deviatoric strain, th: volumetric strain, G0/K0 instantaneous moduli from E, nu).
Update (Taylor-Pister-Goudreau / Simo-Hughes recursion with the strain *linear in time over each
step*): h_i^{n+1} = a_i h_i^n + gamma_i (e^{n+1} - e^n), a_i = exp(-dt/tau_i),
gamma_i = (1 - a_i) tau_i / dt (-> 1 for dt = 0: a jump, the glassy response). It is exact
whenever the strain history is piecewise linear on the time grid (e.g. relaxation after a step
or a ramp), unconditionally stable, and second-order accurate otherwise (creep under constant
load: error O(dt^2)). With a constant dt the algorithmic moduli G_eff = G0 (g_inf + sum g_i
gamma_i), K_eff likewise, are constant: the system is factored once, for the step size used
most; other step sizes (a jump, dt = 0, needs the glassy moduli) are solved by CG
preconditioned with that factorisation (a few iterations: the matrices differ only by the
moduli scaling per region). With the AMG solver each step size gets its own preconditioner.

The internal variables are carried as the nodal forces of the history stresses, one vector per
time constant: z_i = B^T (W_i h_i) follows z_i <- a_i z_i + gamma_i K_i (u^{n+1} - u^n) with
K_i the stiffness of term i's moduli (the same recursion mapped through B^T W_i B; round-off
apart, the same numbers). Time constants whose moduli are proportional share one K_i: with one
Prony series on every region (or the same relative terms) a step costs one solve and one sparse
product with a stiffness matrix, on the free dofs alone when nothing else needs the rest.

Reduced-order march (``solve_history(..., method="reduced"|"auto")``): at a given step size the
march is a linear time-invariant recursion in (u, z_i), so it is projected on a basis V (the
reduced unknowns q ~ V y, z_i = K_i V w_i, w_i <- a_i w_i + gamma_i c_i (y^{n+1} - y^n): exact
in the subspace) and runs in r unknowns (Galerkin: V^T K_eff V, V^T K_i V, V^T F). V starts from
the load patterns K_eff^-1 F and the block Krylov vectors K_eff^-1 K_g v (per stiffness group,
up to _ROM_DEPTH levels, _ROM_START vectors), K_eff-orthonormal (classical Gram-Schmidt twice,
fixed order), all with the factorisation the full march makes anyway. Every step of the
reduced trajectory is then put into the full-order step equations: the residual
||T^T F_n - history forces - K_n u_n|| over the largest right-hand side of the history, with
K_eff V and K_g V kept as dense n x r arrays (chunks of steps: dense products). While it is
above ``rom_tol`` (:data:`ROM_TOL`) the basis gains K_eff^-1 r of the worst steps (greedy)
and the march re-runs; past ``rom_max`` vectors the full march runs instead. The result says
which march ran (``march``) with the certified residual (``rom_residual``) and the basis size.
On the strap's default model (41.8k DOF, 511 steps; ``benchmarks/bench_viscoelastic_rom.py``)
26 vectors certify to 2.4e-11: the gauge strains agree with the full march to ~6e-12 of their
largest value, and the history takes 2.0 s instead of 12.0 s. Residual 1e-6 gave strain
differences ~1e-8 there (measured with forced basis sizes), hence the 1e-9 default. Not
reduced: prescribed motions (the full march runs and says so); ``method="auto"`` reduces
histories of more than :data:`ROM_MIN_STEPS` steps with at most :data:`ROM_MAX_COLUMNS` load
columns; the default, ``"full"``, keeps every caller's numbers bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from designlab.errors import ModelError, ParameterError
from designlab.fem.assembly import stiffness
from designlab.fem.model import Model, RefPoint, Spring, System
from designlab.fem.solvers import LinearSolver, factorize
from designlab.fem.static import check_constrained, near_null_space, p1_prolongation

_VOIGT_C = np.array([2.0, 2.0, 2.0, 1.0, 1.0, 1.0])     # tensor -> engineering Voigt stress
_ONE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])

#: certified relative residual of the reduced march: max over steps of the full-order step
#: equations' residual norm over the largest right-hand side norm of the history
ROM_TOL = 1e-9
#: largest basis of the reduced march before it gives up (the full march runs instead)
ROM_MAX = 120
#: "auto" takes the reduced march from this many steps on ...
ROM_MIN_STEPS = 50
#: ... for at most this many load columns (load cases with an amplitude, times batch columns)
ROM_MAX_COLUMNS = 4
_ROM_DEPTH = 12          # block Krylov depth of the starting basis ...
_ROM_START = 32          # ... and its largest size
_ROM_ADD = 4             # enrichment: residuals of the worst (per chunk) steps added at a time
_ROM_DROP = 1e-10        # a candidate keeping less than this of its K-norm is dependent
_ROM_CHUNK = 64          # steps per block of the residual check


@dataclass(frozen=True)
class History:
    """Load history: times ``t`` (s, non-decreasing; a repeated time is a jump) and the
    amplitude of each load case (array like ``t`` or callable ``a(t)``); cases not named have
    amplitude 0. The state before ``t[0]`` is undeformed and relaxed."""

    t: np.ndarray
    amplitudes: dict[str, object] = field(default_factory=dict)

    def __post_init__(self):
        t = np.asarray(self.t, float)
        if t.ndim != 1 or len(t) < 1 or np.any(np.diff(t) < 0) or not np.all(np.isfinite(t)):
            raise ParameterError("t", self.t, "a non-empty, non-decreasing 1-D time array (s)")
        object.__setattr__(self, "t", t)

    def amplitude(self, case: str) -> np.ndarray:
        a = self.amplitudes.get(case)
        if a is None:
            return np.zeros(len(self.t))
        v = np.asarray(a(self.t) if callable(a) else a, float)
        if v.shape != self.t.shape:
            raise ParameterError(f"amplitude of {case}", v.shape, f"shape {self.t.shape}")
        return v

    @staticmethod
    def step_hold(t_end: float, n_steps: int, cases: dict[str, float] | None = None
                  ) -> "History":
        """Jump to ``cases`` amplitudes (default {"default": 1}) at t = 0, hold until t_end."""
        t = np.linspace(0.0, t_end, n_steps + 1)
        cases = cases or {"default": 1.0}
        return History(t, {c: np.full(len(t), v) for c, v in cases.items()})

    @staticmethod
    def piecewise(times, values, case: str = "default", dt: float | None = None) -> "History":
        """Piecewise-linear amplitude through the breakpoints ``(times, values)`` (a repeated
        time is a jump), sampled at every breakpoint and at most ``dt`` apart in between, so
        ramps and holds are exactly linear per step."""
        times, values = np.asarray(times, float), np.asarray(values, float)
        if times.shape != values.shape or times.ndim != 1 or len(times) < 1:
            raise ParameterError("times", times, "a 1-D array as long as values")
        ts, vs = [times[0]], [values[0]]
        for a, b, va, vb in zip(times[:-1], times[1:], values[:-1], values[1:]):
            n = 1 if dt is None or b <= a else max(int(np.ceil((b - a) / dt - 1e-9)), 1)
            s = np.linspace(0.0, 1.0, n + 1)[1:]
            ts += list(a + (b - a) * s)
            vs += list(va + (vb - va) * s)
        return History(np.array(ts), {case: np.array(vs)})


class _Prony:
    """Per-quadrature-point Prony tables of the whole mesh (elastic cells: no branches)."""

    def __init__(self, model: Model):
        nq = model.basis.dx.shape[1]
        rep = lambda v: np.repeat(v, nq)  # noqa: E731
        self.G0 = rep(model.cell_values("G"))
        self.K0 = rep(model.cell_values("K"))
        self.ginf = np.ones_like(self.G0)
        self.kinf = np.ones_like(self.K0)
        qp_region = rep(model.mesh.region)
        self.dev: list[tuple[np.ndarray, float, float]] = []      # (qp ids, g_i, tau_i)
        self.vol: list[tuple[np.ndarray, float, float]] = []
        for rid, mat in model.region_materials.items():
            if mat.prony is None:
                continue
            q = np.nonzero(qp_region == rid)[0]
            self.ginf[q] = mat.prony.g_inf
            self.kinf[q] = mat.prony.k_inf
            self.dev += [(q, g, tau) for g, tau in zip(mat.prony.g, mat.prony.tau)]
            self.vol += [(q, k, tau) for k, tau in zip(mat.prony.k, mat.prony.k_tau)]

    def effective(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-qp algorithmic (G_eff, K_eff) for step ``dt``."""
        G, K = self.G0 * self.ginf, self.K0 * self.kinf
        for (q, g, tau), out, base in [(b, G, self.G0) for b in self.dev] + \
                                      [(b, K, self.K0) for b in self.vol]:
            out[q] += base[q] * g * _gamma(dt, tau)
        return G, K


def _by_tau(terms, base: np.ndarray, nqp: int) -> tuple[list[float], np.ndarray]:
    """Prony terms ``(qp ids, weight, tau)`` grouped by tau: the distinct taus (in order of
    first appearance) and per tau the per-qp modulus ``base * weight`` (0 where no term)."""
    taus: list[float] = []
    rows: list[np.ndarray] = []
    for q, w, tau in terms:
        if tau not in taus:
            taus.append(tau)
            rows.append(np.zeros(nqp))
        rows[taus.index(tau)][q] += base[q] * w
    return taus, np.array(rows).reshape(len(taus), nqp)


def _gamma(dt: float, tau: float) -> float:
    return 1.0 if dt <= 0 else -np.expm1(-dt / tau) * tau / dt


@dataclass(frozen=True, eq=False)
class HistoryResult:
    """Response to a :class:`History`: ``U`` (n_dofs, n_steps) displacements and ``F_int``,
    ``F_ext`` (3 n_points, n_steps) internal / applied nodal forces (``F_int`` None when
    solved with ``forces=False``). In batch mode
    (``solve_history(..., batch=True)``) every load case is its own history with its own
    amplitude: ``U`` is (n_dofs, n_cases, n_steps) and every output gains a leading case axis
    (order ``cases``). Methods mirror StaticResult with a time axis."""

    system: System
    history: History
    U: np.ndarray
    F_int: np.ndarray
    factorizations: int
    solvers: tuple[LinearSolver, ...]
    batch: bool = False
    march: str = "full"                 #: "full", "reduced" or "full (why not reduced)"
    rom_residual: float | None = None   #: reduced march: its certified relative residual
    basis_size: int = 0                 #: reduced march: the basis' size

    @property
    def model(self) -> Model:
        return self.system.model

    @cached_property
    def F_ext(self) -> np.ndarray:
        """Applied nodal forces (3 n_points, n_steps) (batch: (3 n_points, n_cases, n_steps)),
        from the load cases and the history's amplitudes (made when first asked for)."""
        A = np.stack([self.history.amplitude(c) for c in self.cases], axis=1)
        F = self.system.F[: 3 * self.model.n_points]
        return F[:, :, None] * A.T[None] if self.batch else F @ A.T

    @property
    def t(self) -> np.ndarray:
        return self.history.t

    @property
    def cases(self) -> tuple[str, ...]:
        return self.system.cases

    def displacement(self, step: int = -1) -> np.ndarray:
        """(n_points, 3) displacements at ``step`` (batch: (n_cases, n_points, 3)), mm."""
        u = self._at(step)[: 3 * self.model.n_points]
        return np.moveaxis(u.reshape(-1, 3, *u.shape[1:]), (0, 1), (-2, -1))

    def reactions(self, step: int = -1) -> np.ndarray:
        """(n_points, 3) forces of supports/couplings/springs on the body at ``step``, N
        (batch: (n_cases, n_points, 3))."""
        r = self._f_int()[..., step] - self.F_ext[..., step]
        return np.moveaxis(r.reshape(-1, 3, *r.shape[1:]), (0, 1), (-2, -1))

    def wrench(self, where, about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """(n_steps, 6) reaction resultant (m_x, m_y, m_z, f_x, f_y, f_z) on a set
        (batch: (n_cases, n_steps, 6))."""
        ids = self.model.nodes(where)
        d = 3 * ids[:, None] + np.arange(3)
        r = np.moveaxis(self._f_int()[d] - self.F_ext[d], (0, 1), (-2, -1))   # (..., steps, k, 3)
        arm = self.model.mesh.points[ids] - np.asarray(about, float)
        return np.concatenate([np.cross(arm, r).sum(-2), r.sum(-2)], axis=-1)

    def _f_int(self) -> np.ndarray:
        if self.F_int is None:
            raise ModelError("no internal forces: the history was solved with forces=False")
        return self.F_int

    def _at(self, step: int) -> np.ndarray:
        """Displacements (n_dofs,) (batch: (n_dofs, n_cases)) at ``step``."""
        return self.U[..., step]

    def long_time(self) -> tuple[np.ndarray, float] | None:
        """A reduced march's long-time (relaxed) displacements of every load case, (n_dofs,
        n_cases) as :func:`long_time_displacements` gives them, from its basis (Galerkin with
        the relaxed stiffness), with their certified relative residual; None for a full march
        or when the residual is above the march's ``rom_tol`` (then factor the relaxed
        stiffness: :func:`long_time_displacements`)."""
        return None

    def linear(self, f) -> np.ndarray:
        """``f(U)`` for a map ``f`` linear in each column that takes (n_dofs, k) to (..., k)
        (e.g. :meth:`~designlab.fem.transducers.StrainGauge.strain`): (..., n_steps) (batch:
        (..., n_cases, n_steps)). A reduced march applies it to its basis alone."""
        return f(self.U)

    def _apply(self, L) -> np.ndarray:
        """Linear map (k, n_dofs) of every column: (..., n_steps, k)."""
        U = self.U.reshape(self.U.shape[0], -1)
        out = np.asarray(L @ U).reshape(L.shape[0], *self.U.shape[1:])
        return np.moveaxis(out, 0, -1)

    def twist(self, ref: RefPoint | str) -> np.ndarray:
        """(n_steps, 6) (w, v) of a reference point (batch: (n_cases, n_steps, 6))."""
        ref = self.model.refs[ref] if isinstance(ref, str) else ref
        vw = self._apply(self.model.twist_map(ref))
        return np.concatenate([vw[..., 3:], vw[..., :3]], axis=-1)

    def spring_force(self, spring: Spring | str) -> np.ndarray:
        """(n_steps,) spring reading k * elongation + preload(t), N (batch: (n_cases,
        n_steps)); isotropic springs add a trailing axis of 3."""
        s = self.model.springs[spring] if isinstance(spring, str) else spring
        f = s.k * self._apply(self.model.spring_map(s))                 # (..., steps, 1|3)
        if s.preload:
            amp = self.history.amplitude(s.case)
            if self.batch:
                amp = np.where(np.array(self.cases)[:, None] == s.case, amp[None], 0.0)
            f = f + s.preload * amp[..., None]
        return f[..., 0] if s.axis is not None else f

    def beam_force(self, beam) -> np.ndarray:
        """(n_steps, 12) K (L u) of a beam (batch: (n_cases, n_steps, 12))."""
        b = self.model.beams[beam] if isinstance(beam, str) else beam
        return self._apply(sp.csr_matrix(b.K) @ self.model.beam_map(b))

    def dofs(self, dofs) -> np.ndarray:
        """(n_steps, k) history of selected dofs (batch: (n_cases, n_steps, k))."""
        return np.moveaxis(self.U[np.asarray(dofs)], 0, -1)


def _terms(pr: _Prony, nq: int) -> tuple[list[float], np.ndarray, np.ndarray]:
    """Prony terms grouped by time constant: the distinct taus (deviatoric ones first, in order
    of first appearance) and per tau the per-cell shear and bulk moduli of its terms (0 where
    a cell has none)."""
    nqp = len(pr.G0)
    dt_, dev = _by_tau(pr.dev, pr.G0, nqp)
    vt_, vol = _by_tau(pr.vol, pr.K0, nqp)
    taus = list(dt_) + [t for t in vt_ if t not in dt_]
    shear = np.zeros((len(taus), nqp // nq))
    bulk = np.zeros((len(taus), nqp // nq))
    for i, t in enumerate(dt_):
        shear[taus.index(t)] = dev[i].reshape(-1, nq)[:, 0]
    for i, t in enumerate(vt_):
        bulk[taus.index(t)] = vol[i].reshape(-1, nq)[:, 0]
    return taus, shear, bulk


def _shapes(fields: np.ndarray, rtol: float = 1e-13) -> list[tuple[int, list[tuple[int, float]]]]:
    """Group rows of ``fields`` that are scalar multiples of one another (to ``rtol``: round-off
    of the products ``modulus * weight``): [(reference row, [(row, factor), ...]), ...]."""
    groups: list[tuple[int, list[tuple[int, float]]]] = []
    for t, f in enumerate(fields):
        for ref, members in groups:
            r = fields[ref]
            i = int(np.argmax(np.abs(r)))
            c = float(f[i] / r[i])
            if c != 0.0 and np.allclose(f, c * r, rtol=rtol, atol=0.0):
                members.append((t, c))
                break
        else:
            groups.append((t, [(t, 1.0)]))
    return groups


def solve_history(model: Model, history: History, solver: str = "auto",
                  check: bool = True, batch: bool = False, forces: bool = True,
                  method: str = "full", rom_tol: float = ROM_TOL, rom_max: int = ROM_MAX,
                  rom_basis: int | None = None) -> HistoryResult:
    """March ``history`` with the exact exponential update (see module docstring).
    ``batch=True`` runs every load case as a separate history (amplitude ``a_c(t)`` on case c
    alone) in the same march: one factorisation, multi-column solves. ``forces=False`` skips
    the internal forces (``F_int`` is None: no reactions, wrenches; one sparse product per step
    less).

    The internal variables are carried as nodal forces: per time constant tau_t the force
    z_t = B^T (W_t h_t) of its history stresses (h_t at the quadrature points, W_t its moduli
    times the quadrature weights). The recursion h_t <- a_t h_t + gamma_t (e^{n+1} - e^n) maps
    to z_t <- a_t z_t + gamma_t K_t (u^{n+1} - u^n), with K_t the stiffness of tau_t's moduli
    (the same identity, summed in another order: round-off apart, the result of carrying h_t).
    Time constants whose moduli are proportional (one Prony series on every region, or the
    same relative terms) share one K: one sparse product per step instead of the strain and
    the force products of the strain operator. Without internal forces, prescribed motions or
    rigid couplings the march runs on the free dofs alone.

    ``method``: "full" (the march above, the default), "reduced" (the certified reduced-order
    march of the module docstring; the full one when it does not certify or the model has
    prescribed motions) or "auto" (reduced for more than :data:`ROM_MIN_STEPS` steps and at
    most :data:`ROM_MAX_COLUMNS` load columns). ``rom_tol``: the certified relative residual;
    ``rom_max``: the largest basis; ``rom_basis``: the starting basis' size (default
    _ROM_START, then enriched). The result's ``march`` says which ran and why not reduced."""
    if method not in ("auto", "full", "reduced"):
        raise ParameterError("method", method, "one of auto, full, reduced")
    if not rom_tol > 0:
        raise ParameterError("rom_tol", rom_tol, "a relative residual > 0")
    if int(rom_max) != rom_max or rom_max < 1:
        raise ParameterError("rom_max", rom_max, "an integer >= 1")
    if rom_basis is not None and (int(rom_basis) != rom_basis or rom_basis < 1):
        raise ParameterError("rom_basis", rom_basis, "None or an integer >= 1")
    system = model.build()
    if check:
        check_constrained(system)
    unknown = set(history.amplitudes) - set(system.cases)
    if unknown:
        raise ParameterError("history case", sorted(unknown)[0],
                             "one of the model's load cases: " + ", ".join(system.cases))
    t = history.t
    nsteps = len(t)
    A = np.stack([history.amplitude(c) for c in system.cases], axis=1)   # (steps, cases)
    Fc = system.F + system.F_preload
    Gp = system.G
    nb = A.shape[1] if batch else 1
    if batch:
        load = lambda M, n: M * A[n][None]                    # noqa: E731  (n_dofs, nb)
    else:
        load = lambda M, n: (M @ A[n])[:, None]               # noqa: E731
    has_G = bool(np.any(Gp[:, np.any(A != 0.0, axis=0)]))
    n3 = 3 * model.n_points
    nd = system.n_dofs
    pr = _Prony(model)
    nq = model.basis.dx.shape[1]
    taus, shear, bulk = _terms(pr, nq)
    groups = _shapes(np.concatenate([shear, bulk], axis=1))
    # one stiffness per group of proportional time constants: K_t = c_t K_group
    Kg = [stiffness(model.basis, bulk[ref] - 2.0 * shear[ref] / 3.0, shear[ref])
          for ref, _ in groups]
    member = {t_: (g, c) for g, (_, ms) in enumerate(groups) for t_, c in ms}
    tg = [member[i][0] for i in range(len(taus))]
    tc = np.array([member[i][1] for i in range(len(taus))])
    K_inf = None
    if forces:
        Gi, Ki = (pr.G0 * pr.ginf).reshape(-1, nq)[:, 0], (pr.K0 * pr.kinf).reshape(-1, nq)[:, 0]
        K_inf = stiffness(model.basis, Ki - 2.0 * Gi / 3.0, Gi)
    T = system.T
    Tt = T.T.tocsr()
    # no rigid couplings: T selects the free dofs (q = r[free], u[free] = q: the same numbers
    # as the sparse products, without them)
    free = system.free_dofs if T.nnz == T.shape[1] and np.all(T.data == 1.0) else None
    lean = free is not None and not has_G and not forces
    Kg_nodal = list(Kg)                        # the groups' stiffnesses on every nodal dof
    if lean:        # history forces on the free dofs of the nodes only (rows of q: pos)
        pos = np.nonzero(free < n3)[0]
        Kg = [k[free[pos]][:, free[pos]].tocsr() for k in Kg]
        nz = len(pos)
    else:
        nz = n3
    Z = np.zeros((len(taus), nz, nb))          # history forces per tau
    V = np.zeros((len(Kg), nz, nb))            # K_group u of the last step
    coef: dict[float, tuple] = {}
    cache: dict[float, tuple[LinearSolver, object]] = {}
    U = np.zeros((nd, nb, nsteps))
    F_int = np.zeros((n3, nb, nsteps)) if forces else None
    blk = 16                                   # steps gathered before writing into U, F_int
    U_buf = np.zeros((blk, nd, nb))
    F_buf = np.zeros((blk, n3, nb)) if forces else None
    t_prev = t[0]
    q_prev = None
    # the step size used most: factor it first and only (other sizes: preconditioned CG)
    steps = np.round(np.diff(t), 12)
    sizes, counts = np.unique(steps, return_counts=True) if len(steps) else ([0.0], [1])
    main_dt = float(sizes[int(np.argmax(counts))])
    main = None
    if main_dt != 0.0 and len(steps):
        Ge, Ke = pr.effective(main_dt)
        Gc, Kc = Ge.reshape(-1, nq)[:, 0], Ke.reshape(-1, nq)[:, 0]
        K = system.K(stiffness(model.basis, Kc - 2.0 * Gc / 3.0, Gc))
        Kr_main = system.reduce(K)
        lin = factorize(Kr_main, solver, near_null=lambda: near_null_space(system),
                        coarse=lambda: p1_prolongation(system), n_rhs=nsteps * nb)
        main = (lin,)
        cache[main_dt] = (lin, K)
    why = _reduced_ineligible(method, nsteps, A, nb, has_G, main)
    if why is None:
        ctx = _MarchContext(system=system, history=history, A=A, Fc=Fc, batch=batch,
                            taus=taus, tg=tg, tc=tc, Kg=Kg_nodal, Kr_main=Kr_main,
                            lin=main[0], main_dt=main_dt, K_inf=K_inf)
        rom = _reduced_march(ctx, rom_tol, rom_max, rom_basis)
        if rom.ok:
            return ReducedHistoryResult.make(ctx, rom, forces, rom_tol)
        why = rom.why
    march = "full" if why is None or method == "full" else f"full ({why})"
    for n in range(nsteps):
        dt = 0.0 if n == 0 else float(t[n] - t_prev)
        t_prev = t[n]
        F_n = load(Fc, n)
        G_n = load(Gp, n) if has_G else None
        if n == 0 and not (np.any(F_n) or (has_G and np.any(G_n))):
            U_buf[0] = 0.0                              # at rest
            if forces:
                F_buf[0] = 0.0
            continue
        key = round(dt, 12)
        if key not in cache:
            Ge, Ke = pr.effective(dt)
            Gc, Kc = Ge.reshape(-1, nq)[:, 0], Ke.reshape(-1, nq)[:, 0]
            K = system.K(stiffness(model.basis, Kc - 2.0 * Gc / 3.0, Gc))
            Kr = system.reduce(K)
            if key == main_dt or main is None or main[0].kind == "amg":
                lin = factorize(Kr, solver, near_null=lambda: near_null_space(system),
                                coarse=lambda: p1_prolongation(system), n_rhs=nsteps * nb)
                if key == main_dt:
                    main = (lin,)
            else:       # other step sizes: CG preconditioned by the main factorisation
                lin = _Preconditioned(Kr, main[0])
            cache[key] = (lin, K)
        lin, K = cache[key]
        if dt not in coef:
            a = np.array([np.exp(-dt / tau) for tau in taus])
            gc = np.array([_gamma(dt, tau) for tau in taus]) * tc        # gamma_t c_t
            gsum = np.zeros(len(Kg))
            np.add.at(gsum, tg, gc)
            coef[dt] = (a, gc, gsum)
        a, gc, gsum = coef[dt]
        # history force f_h = sum_t a_t z_t - sum_t gamma_t K_t u^n
        fh = np.zeros((nz, nb))
        for i in range(len(taus)):
            fh += a[i] * Z[i]
        for g in range(len(Kg)):
            fh -= gsum[g] * V[g]
        if lean:
            r = F_n[free]
            r[pos] -= fh
            q = lin.solve(r, x0=q_prev)
        else:
            r = F_n.copy()
            r[:n3] -= fh
            if has_G:
                r -= K @ G_n
            q = lin.solve(r[free] if free is not None else Tt @ r, x0=q_prev)
        q_prev = q
        u = U_buf[n % blk]
        if free is not None:
            u[:] = 0.0
            u[free] = q
        else:
            u[:] = T @ q
        if has_G:
            u += G_n
        un = q[pos] if lean else u[:n3]
        for g in range(len(Kg)):
            Vn = Kg[g] @ un
            dV = Vn - V[g]
            for i in range(len(taus)):
                if tg[i] == g:
                    Z[i] *= a[i]
                    Z[i] += gc[i] * dV
            V[g] = Vn
        if forces:       # internal forces: long-term elastic part plus the history forces
            F_buf[n % blk] = K_inf @ un + Z.sum(axis=0)
        if n % blk == blk - 1 or n == nsteps - 1:
            n0 = n - n % blk
            U[..., n0:n + 1] = np.moveaxis(U_buf[:n - n0 + 1], 0, -1)
            if forces:
                F_int[..., n0:n + 1] = np.moveaxis(F_buf[:n - n0 + 1], 0, -1)
    if not batch:
        U = U[:, 0]
        F_int = None if F_int is None else F_int[:, 0]
    solvers = tuple(v[0] for v in cache.values())
    return HistoryResult(system, history, U, F_int,
                         sum(not isinstance(x, _Preconditioned) for x in solvers), solvers, batch,
                         march=march)


class _Preconditioned(LinearSolver):
    """CG on ``K`` preconditioned by another step size's factorisation (same sparsity, moduli
    scaled per region: converges in a few iterations)."""

    kind = "pcg"

    def __init__(self, K, pre: LinearSolver, rtol: float = 1e-12):
        super().__init__(K)
        self.K, self.pre, self.rtol = K, pre, rtol
        self.iterations: list[int] = []

    def _solve(self, F):
        M = spla.LinearOperator(self.K.shape, matvec=lambda r: self.pre.solve(r), dtype=float)
        U = np.zeros_like(F)
        for j in range(F.shape[1]):
            if not np.any(F[:, j]):
                continue
            it = [0]
            x, info = spla.cg(self.K, F[:, j], rtol=self.rtol, atol=0.0, maxiter=200, M=M,
                              callback=lambda _: it.__setitem__(0, it[0] + 1))
            if info != 0:
                raise ModelError("viscoelastic step did not converge (preconditioned CG)")
            self.iterations.append(it[0])
            U[:, j] = x
        return U


def long_time_displacements(model: Model, solver: str = "auto") -> np.ndarray:
    """(n_dofs, n_cases) static displacements of every load case with the long-time (relaxed)
    moduli, G0 g_inf and K0 k_inf (a load held for ever), on the model's own system: the same
    supports, couplings and springs (elastic), no second model to build. Equal, to round-off,
    to ``solve_static`` of the model with :func:`designlab.fem.stress.relaxed` materials."""
    system = model.build()
    pr = _Prony(model)
    nq = model.basis.dx.shape[1]
    G = (pr.G0 * pr.ginf).reshape(-1, nq)[:, 0]
    K = (pr.K0 * pr.kinf).reshape(-1, nq)[:, 0]
    Kf = system.K(stiffness(model.basis, K - 2.0 * G / 3.0, G))
    Fr = system.T.T @ (system.F + system.F_preload - Kf @ system.G)
    lin = factorize(system.reduce(Kf), solver, near_null=lambda: near_null_space(system),
                    coarse=lambda: p1_prolongation(system), n_rhs=Fr.shape[1])
    return system.T @ lin.solve(Fr) + system.G


# --- reduced-order march ------------------------------------------------------------------


def _reduced_ineligible(method: str, nsteps: int, A: np.ndarray, nb: int, has_G: bool,
                        main) -> str | None:
    """Why the reduced march does not run (None: it does)."""
    if method == "full":
        return "asked for"
    if has_G:
        return "prescribed motions"
    if main is None:
        return "no constant step size"
    cols = int(np.count_nonzero(np.any(A != 0.0, axis=0))) * (nb if nb > 1 else 1)
    if method == "auto" and nsteps <= ROM_MIN_STEPS:
        return f"{nsteps} steps <= {ROM_MIN_STEPS}"
    if method == "auto" and cols > ROM_MAX_COLUMNS:
        return f"{cols} load columns > {ROM_MAX_COLUMNS}"
    return None


@dataclass(eq=False)
class _MarchContext:
    """What the reduced march needs of solve_history's set-up (q: the reduced unknowns of
    ``system.reduce``; no prescribed motions)."""

    system: System
    history: History
    A: np.ndarray                   # (steps, cases) amplitudes
    Fc: np.ndarray                  # (n_dofs, cases) loads incl. preloads
    batch: bool
    taus: list
    tg: list                        # group of each tau
    tc: np.ndarray                  # factor of each tau on its group's stiffness
    Kg: list                        # groups' stiffnesses (3 n_points square)
    Kr_main: sp.csr_matrix          # reduced effective stiffness of the main step size
    lin: LinearSolver               # its factorisation
    main_dt: float
    K_inf: sp.spmatrix | None       # long-term stiffness (3 n_points) when forces are wanted

    @property
    def t(self) -> np.ndarray:
        return self.history.t

    def at_rest(self) -> bool:
        """The first step has no load (skipped: the state before the history)."""
        a = self.A[0]
        return not np.any(self.Fc * a[None] if self.batch else self.Fc @ a)

    @cached_property
    def Tn(self) -> sp.csr_matrix:
        return sp.csr_matrix(self.system.T[: 3 * self.system.model.n_points])

    @cached_property
    def Kq(self) -> list:
        """The groups' stiffnesses on q (T^T K_g T over the nodal rows)."""
        Tn = self.Tn
        return [(Tn.T @ k @ Tn).tocsr() for k in self.Kg]

    @cached_property
    def Fq(self) -> np.ndarray:
        return np.asarray(self.system.T.T @ self.Fc)

    def coefficients(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a_t, gamma_t c_t, per group sum of gamma_t c_t), as the full march makes them."""
        a = np.array([np.exp(-dt / tau) for tau in self.taus])
        gc = np.array([_gamma(dt, tau) for tau in self.taus]) * self.tc
        gsum = np.zeros(len(self.Kg))
        np.add.at(gsum, self.tg, gc)
        return a, gc, gsum

    def loads(self, steps: np.ndarray) -> np.ndarray:
        """(n_q, nb, k) right-hand sides T^T F of ``steps``."""
        if self.batch:
            return self.Fq[:, :, None] * self.A[steps].T[None]
        return (self.Fq @ self.A[steps].T)[:, None]


@dataclass(eq=False)
class _Rom:
    ok: bool
    why: str | None = None
    V: np.ndarray | None = None     # (n_q, r) K_main-orthonormal basis
    Y: np.ndarray | None = None     # (r, nb, steps) coordinates
    W: np.ndarray | None = None     # (taus, r, nb, steps) history coordinates after each step
    residual: float = np.inf
    enrichments: int = 0
    long_time: np.ndarray | None = None     # (n_q, cases) relaxed response in the basis
    long_residual: float = np.inf


class _Basis:
    """K-orthonormal basis grown one candidate at a time (classical Gram-Schmidt twice, in a
    fixed order: deterministic), with K V and the groups' K_g V kept alongside."""

    def __init__(self, ctx: _MarchContext):
        self.ctx = ctx
        n = ctx.Kr_main.shape[0]
        self.V = np.zeros((n, 0))
        self.KV = np.zeros((n, 0))

    @property
    def r(self) -> int:
        return self.V.shape[1]

    def add(self, X: np.ndarray) -> int:
        """Orthonormalise the columns of ``X`` into the basis; the number kept."""
        K = self.ctx.Kr_main
        new_V, new_KV = [], []
        for x in np.asarray(X, float).reshape(X.shape[0], -1).T:
            Kx = K @ x
            n0 = float(np.sqrt(max(x @ Kx, 0.0)))
            if n0 == 0.0:
                continue
            V = np.column_stack([self.V] + new_V) if new_V else self.V
            KV = np.column_stack([self.KV] + new_KV) if new_KV else self.KV
            for _ in range(2):
                c = KV.T @ x
                x = x - V @ c
                Kx = Kx - KV @ c
            nrm = float(np.sqrt(max(x @ Kx, 0.0)))
            if nrm <= _ROM_DROP * n0:
                continue
            new_V.append(x / nrm)
            new_KV.append(K @ new_V[-1])      # exact K v (not the updated Kx: no drift)
        if new_V:
            self.V = np.column_stack([self.V] + new_V)
            self.KV = np.column_stack([self.KV] + new_KV)
        return len(new_V)


def _reduced_march(ctx: _MarchContext, tol: float, r_max: int, r_start: int | None) -> _Rom:
    """Galerkin-projected march on a certified basis (see :func:`solve_history`); dense
    products on one BLAS thread (small or tall-skinny: threads cost more than they give on a
    busy machine, and one thread rounds the same on every machine)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        return _reduced_march_1(ctx, tol, r_max, r_start)


def _reduced_march_1(ctx: _MarchContext, tol: float, r_max: int, r_start: int | None) -> _Rom:
    active = np.nonzero(np.any(ctx.A != 0.0, axis=0))[0]
    basis = _Basis(ctx)
    block_start = basis.r
    basis.add(ctx.lin.solve(ctx.Fq[:, active]))            # the load patterns
    limit = min(_ROM_START if r_start is None else r_start, r_max)
    for _ in range(_ROM_DEPTH):                             # block Krylov K^-1 K_g v
        block = basis.V[:, block_start:basis.r]
        block_start = basis.r
        for Kq in ctx.Kq:
            if basis.r >= limit:
                break
            basis.add(ctx.lin.solve(np.asarray(Kq @ block[:, :limit - basis.r])))
        if basis.r >= limit or basis.r == block_start:
            break
    if basis.r > limit:
        basis.V, basis.KV = basis.V[:, :limit], basis.KV[:, :limit]
    enrich = 0
    while True:
        rom = _march_projected(ctx, basis.V, basis.KV)
        res, worst = _certify(ctx, basis.V, basis.KV, rom)
        rom.residual, rom.enrichments = res, enrich
        if res <= tol:
            rom.ok = True
            rom.long_time, rom.long_residual = _long_time(ctx, basis.V, basis.KV)
            return rom
        if basis.r >= r_max:
            return _Rom(False, f"reduced basis of {basis.r} left residual {res:.1e} > {tol:.0e}",
                        residual=res)
        if basis.add(ctx.lin.solve(worst[:, :r_max - basis.r])) == 0:
            return _Rom(False, f"reduced basis stalled at {basis.r} (residual {res:.1e})",
                        residual=res)
        enrich += 1


def _long_time(ctx: _MarchContext, V: np.ndarray, KV: np.ndarray
               ) -> tuple[np.ndarray | None, float]:
    """The long-time (relaxed) response of every load case in the basis (Galerkin with the
    relaxed stiffness K_inf = K_main - sum_g gsum_g K_g, whose Neumann series in
    K_main^-1 K_g the Krylov basis holds) and its full-order residual: max over the cases of
    ||T^T F_c - K_inf q_c|| / ||T^T F_c|| (None, inf without loads or with prescribed
    motions)."""
    if np.any(ctx.system.G) or not np.any(ctx.Fq):
        return None, np.inf
    _, _, g_main = ctx.coefficients(ctx.main_dt)
    KiV = KV - sum(g_main[g] * np.asarray(Kq @ V) for g, Kq in enumerate(ctx.Kq))
    M = V.T @ KiV
    Y = np.linalg.solve(0.5 * (M + M.T), V.T @ ctx.Fq)
    R = ctx.Fq - KiV @ Y
    fn = np.linalg.norm(ctx.Fq, axis=0)
    on = fn > 0
    return V @ Y, float((np.linalg.norm(R, axis=0)[on] / fn[on]).max())


def _step_sizes(t: np.ndarray, main_dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Per step, as the full march takes them: dt (0 for the first; the history's
    coefficients) and the dt of the step's matrix (``main_dt`` for its size, else the first dt
    of the same size, to 1e-12)."""
    dts = np.concatenate([[0.0], np.diff(t)])
    first: dict[float, float] = {round(main_dt, 12): main_dt}
    mdts = np.array([first.setdefault(round(float(d), 12), float(d)) for d in dts])
    return dts, mdts


def _march_projected(ctx: _MarchContext, V: np.ndarray, KV: np.ndarray) -> _Rom:
    """The march in the basis' coordinates: y (r, nb) and per tau w_t (z_t = K_g V w_t)."""
    import scipy.linalg as sla

    A, nsteps = ctx.A, len(ctx.t)
    r = V.shape[1]
    nb = A.shape[1] if ctx.batch else 1
    M0 = V.T @ KV
    M0 = 0.5 * (M0 + M0.T)
    Kgr = []
    for Kq in ctx.Kq:
        m = V.T @ (Kq @ V)
        Kgr.append(0.5 * (m + m.T))
    Fr = V.T @ ctx.Fq                                        # (r, cases)
    _, _, g_main = ctx.coefficients(ctx.main_dt)
    dts, mdts = _step_sizes(ctx.t, ctx.main_dt)
    Y = np.zeros((r, nb, nsteps))
    W = np.zeros((len(ctx.taus), r, nb, nsteps))
    w = np.zeros((len(ctx.taus), r, nb))
    y = np.zeros((r, nb))
    facs: dict[float, object] = {}
    coefs: dict[float, tuple] = {}
    for n in range(nsteps):
        dt, mdt = float(dts[n]), float(mdts[n])
        a_n = A[n]
        load = Fr * a_n[None] if ctx.batch else (Fr @ a_n)[:, None]
        if n == 0 and ctx.at_rest():
            continue                                          # at rest, as the full march
        if mdt not in facs:
            gm = ctx.coefficients(mdt)[2]
            M = M0 + sum((gm[g] - g_main[g]) * Kgr[g] for g in range(len(Kgr)))
            facs[mdt] = sla.cho_factor(M, check_finite=False)
        if dt not in coefs:
            coefs[dt] = ctx.coefficients(dt)
        fac, (a, gc, gsum) = facs[mdt], coefs[dt]
        rhs = load.copy()
        for g in range(len(Kgr)):
            c = -gsum[g] * y
            for i in range(len(ctx.taus)):
                if ctx.tg[i] == g:
                    c = c + a[i] * w[i]
            rhs -= Kgr[g] @ c
        y_new = sla.cho_solve(fac, rhs, check_finite=False)
        dy = y_new - y
        for i in range(len(ctx.taus)):
            w[i] = a[i] * w[i] + gc[i] * dy
        y = y_new
        Y[..., n] = y
        W[..., n] = w
    return _Rom(False, V=V, Y=Y, W=W)


def _certify(ctx: _MarchContext, V: np.ndarray, KV: np.ndarray, rom: _Rom
             ) -> tuple[float, np.ndarray]:
    """Full-order residual of every step of the reduced trajectory: max_n ||b_n - K_n u_n||
    over max_n ||b_n|| (b_n: T^T F_n minus the history forces of the reduced state, K_n: the
    step's effective stiffness) and the residuals (n_q, <= _ROM_ADD) of the worst steps (the
    worst step (batch: column) of each chunk of steps, largest first)."""
    nsteps = len(ctx.t)
    ng = len(ctx.Kq)
    KgV = [np.asarray(Kq @ V) for Kq in ctx.Kq]
    _, _, g_main = ctx.coefficients(ctx.main_dt)
    dts, mdts = _step_sizes(ctx.t, ctx.main_dt)
    coefs = {float(dt): ctx.coefficients(float(dt)) for dt in np.unique(np.r_[dts, mdts])}
    Y, W = rom.Y, rom.W
    r, nb = Y.shape[0], Y.shape[1]
    # history coordinates before each step: c_g^n = sum_t a_t w_t^{n-1} - gsum_g y^{n-1}
    Wp = np.concatenate([np.zeros_like(W[..., :1]), W[..., :-1]], axis=-1)
    Yp = np.concatenate([np.zeros_like(Y[..., :1]), Y[..., :-1]], axis=-1)
    a_s = np.array([coefs[float(d)][0] for d in dts])        # (steps, taus)
    g_s = np.array([coefs[float(d)][2] for d in dts])        # (steps, groups)
    g_m = np.array([coefs[float(d)][2] for d in mdts])       # the steps' matrices
    skipped = np.zeros(nsteps, bool)
    skipped[0] = ctx.at_rest()
    worst: list[tuple[float, int, np.ndarray]] = []
    scale, res_max = 0.0, 0.0
    for s0 in range(0, nsteps, _ROM_CHUNK):
        st = np.arange(s0, min(s0 + _ROM_CHUNK, nsteps))
        k = len(st)
        b = ctx.loads(st).reshape(-1, nb * k)
        for g in range(ng):
            C = -g_s[st, g][None, None] * Yp[..., st]
            for i in range(len(ctx.taus)):
                if ctx.tg[i] == g:
                    C = C + a_s[st, i][None, None] * Wp[i][..., st]
            b = b - KgV[g] @ C.reshape(r, nb * k)
        R = b - KV @ Y[..., st].reshape(r, nb * k)
        for g in range(ng):
            dY = (g_m[st, g] - g_main[g])[None, None] * Y[..., st]
            R -= KgV[g] @ dY.reshape(r, nb * k)
        bn = np.linalg.norm(b, axis=0).reshape(nb, k)
        rn = np.linalg.norm(R, axis=0).reshape(nb, k)
        rn[:, skipped[st]] = 0.0
        scale = max(scale, float(bn.max()))
        j = int(np.argmax(rn))
        worst.append((-float(rn.flat[j]), s0, R[:, j].copy()))
        res_max = max(res_max, float(rn.max()))
    res = res_max / scale if scale > 0 else 0.0
    worst.sort(key=lambda w: w[:2])
    return res, np.column_stack([w[2] for w in worst[:_ROM_ADD]])


class ReducedHistoryResult(HistoryResult):
    """A :class:`HistoryResult` of the reduced march: displacements ``basis @ coords`` (U made
    when first asked for; :meth:`linear`, :meth:`displacement`, ``twist``, ``dofs``... from
    the basis alone)."""

    basis: np.ndarray           # (n_dofs, r)
    coords: np.ndarray          # (r, nb, n_steps)

    @classmethod
    def make(cls, ctx: _MarchContext, rom: _Rom, forces: bool, tol: float
             ) -> "ReducedHistoryResult":
        self = cls.__new__(cls)
        system = ctx.system
        basis = np.asarray(system.T @ rom.V)
        F_int = None
        if forces:
            Un = basis[: 3 * system.model.n_points]
            r, nb, ns = rom.Y.shape
            F_int = np.asarray(ctx.K_inf @ Un) @ rom.Y.reshape(r, -1)
            for g, k in enumerate(ctx.Kg):
                Wg = sum(rom.W[i] for i in range(len(ctx.taus)) if ctx.tg[i] == g)
                F_int = F_int + np.asarray(k @ Un) @ Wg.reshape(r, -1)
            F_int = F_int.reshape(-1, nb, ns)
            if not ctx.batch:
                F_int = F_int[:, 0]
        for k, v in dict(system=system, history=ctx.history, F_int=F_int,
                         factorizations=1, solvers=(ctx.lin,), batch=ctx.batch,
                         march="reduced", rom_residual=float(rom.residual),
                         basis_size=int(rom.V.shape[1]), basis=basis, coords=rom.Y,
                         _long=(None if rom.long_time is None else
                                np.asarray(system.T @ rom.long_time)),
                         _long_residual=rom.long_residual, _tol=tol).items():
            object.__setattr__(self, k, v)
        return self

    @cached_property
    def U(self) -> np.ndarray:
        """(n_dofs, n_steps) displacements (batch: (n_dofs, n_cases, n_steps))."""
        return np.tensordot(self.basis, self._coords(), axes=([-1], [0]))

    def _coords(self) -> np.ndarray:
        return self.coords if self.batch else self.coords[:, 0]

    def long_time(self) -> tuple[np.ndarray, float] | None:
        return None if self._long is None or not self._long_residual <= self._tol else \
            (self._long, self._long_residual)

    def _at(self, step: int) -> np.ndarray:
        return self.basis @ self._coords()[..., step]

    def linear(self, f) -> np.ndarray:
        return np.tensordot(np.asarray(f(self.basis)), self._coords(), axes=([-1], [0]))

    def _apply(self, L) -> np.ndarray:
        return np.moveaxis(np.tensordot(np.asarray(L @ self.basis), self._coords(),
                                        axes=([-1], [0])), 0, -1)

    def dofs(self, dofs) -> np.ndarray:
        return np.moveaxis(np.tensordot(self.basis[np.asarray(dofs)], self._coords(),
                                        axes=([-1], [0])), 0, -1)
