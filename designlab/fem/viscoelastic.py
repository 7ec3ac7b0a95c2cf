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
        u = self.U[: 3 * self.model.n_points, ..., step]
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
                  check: bool = True, batch: bool = False, forces: bool = True
                  ) -> HistoryResult:
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
    rigid couplings the march runs on the free dofs alone."""
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
        lin = factorize(system.reduce(K), solver, near_null=lambda: near_null_space(system),
                        coarse=lambda: p1_prolongation(system), n_rhs=nsteps * nb)
        main = (lin,)
        cache[main_dt] = (lin, K)
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
                         sum(not isinstance(x, _Preconditioned) for x in solvers), solvers, batch)


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
