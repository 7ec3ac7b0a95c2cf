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

Internal variables live at the quadrature points; strains come from one sparse product with
the strain operator B and stresses return as forces through B^T.
"""

from __future__ import annotations

from dataclasses import dataclass, field
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
    F_ext: np.ndarray
    factorizations: int
    solvers: tuple[LinearSolver, ...]
    batch: bool = False

    @property
    def model(self) -> Model:
        return self.system.model

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


def solve_history(model: Model, history: History, solver: str = "auto",
                  check: bool = True, batch: bool = False, forces: bool = True
                  ) -> HistoryResult:
    """March ``history`` with the exact exponential update (see module docstring).
    ``batch=True`` runs every load case as a separate history (amplitude ``a_c(t)`` on case c
    alone) in the same march: one factorisation, multi-column solves. ``forces=False`` skips
    the internal forces (``F_int`` is None: no reactions, wrenches; one stress evaluation and
    one sparse product per step less)."""
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
    if batch:
        F_all = Fc[:, :, None] * A.T[None]                               # (n_dofs, nb, steps)
        G_all = system.G[:, :, None] * A.T[None]
        Fx = system.F[:, :, None] * A.T[None]
    else:
        F_all, G_all, Fx = (Fc @ A.T)[:, None], (system.G @ A.T)[:, None], \
            (system.F @ A.T)[:, None]
    nb = F_all.shape[1]
    n3 = 3 * model.n_points
    B, dx = model.B, model.basis.dx.ravel()
    Bt = B.T.tocsr()
    pr = _Prony(model)
    nqp = len(dx)
    nq = model.basis.dx.shape[1]
    # Prony terms grouped by time constant (the update of h depends on tau alone): one state
    # array per distinct tau over every qp, weighted per qp (0 outside the term's regions)
    dev, vol = _by_tau(pr.dev, pr.G0, nqp), _by_tau(pr.vol, pr.K0, nqp)
    H = np.zeros((len(dev[0]), nqp, 6, nb))
    M = np.zeros((len(vol[0]), nqp, nb))
    e_old = np.zeros((nqp, 6, nb))              # deviatoric (engineering) strain
    th_old = np.zeros((nqp, nb))
    cvo = (dx[:, None] * _VOIGT_C)[:, :, None]  # dx * tensor -> engineering Voigt stress
    Winf = (pr.G0 * pr.ginf)[:, None, None] * cvo            # long-term part of the stress
    Kinf = (dx * pr.K0 * pr.kinf)[:, None]
    Wdev = dev[1][:, :, None, None] * cvo[None]              # (n_tau, nqp, 6, 1)
    Wvol = (vol[1] * dx[None])[:, :, None]                   # (n_tau_k, nqp, 1)
    coef: dict[float, tuple] = {}
    has_G = bool(np.any(G_all))
    cache: dict[float, tuple[LinearSolver, object]] = {}
    U = np.zeros((system.n_dofs, nb, nsteps))
    F_int = np.zeros((n3, nb, nsteps)) if forces else None
    T = system.T
    Tt = T.T.tocsr()
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
        if n == 0 and not (np.any(F_all[..., 0]) or np.any(G_all[..., 0])):
            continue                                    # at rest
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
            a_d = np.array([np.exp(-dt / tau) for tau in dev[0]])
            g_d = np.array([_gamma(dt, tau) for tau in dev[0]])
            a_v = np.array([np.exp(-dt / tau) for tau in vol[0]])
            g_v = np.array([_gamma(dt, tau) for tau in vol[0]])
            coef[dt] = (a_d[:, None, None, None], g_d[:, None, None, None],
                        a_v[:, None, None], g_v[:, None, None],
                        a_d[:, None, None, None] * Wdev, np.tensordot(g_d, Wdev, 1),
                        a_v[:, None, None] * Wvol, np.tensordot(g_v, Wvol, 1))
        a_d, g_d, a_v, g_v, aW, gW, aWv, gWv = coef[dt]
        # history stress sigma_h (per qp, engineering Voigt, times dx)
        sig_h = -gW * e_old
        for i in range(len(aW)):
            sig_h += aW[i] * H[i]
        if len(aWv):
            p_h = -gWv * th_old
            for i in range(len(aWv)):
                p_h += aWv[i] * M[i]
            sig_h[:, :3] += p_h[:, None]
        f_h = np.zeros((system.n_dofs, nb))
        f_h[:n3] = Bt @ sig_h.reshape(nqp * 6, nb)
        r = F_all[..., n] - f_h
        if has_G:
            r -= K @ G_all[..., n]
        q = lin.solve(Tt @ r, x0=q_prev)
        q_prev = q
        u = T @ q
        if has_G:
            u += G_all[..., n]
        U[..., n] = u
        e = (B @ u[:n3]).reshape(nqp, 6, nb)
        th = e[:, :3].sum(1)
        e[:, :3] -= (th / 3.0)[:, None]
        if len(H):
            de = e - e_old
            H *= a_d
            H += g_d * de[None]
        if len(M):
            M *= a_v
            M += g_v * (th - th_old)[None]
        e_old, th_old = e, th
        if not forces:
            continue
        # full stress -> internal forces
        sig = Winf * e
        for i in range(len(H)):
            sig += Wdev[i] * H[i]
        p = Kinf * th
        for i in range(len(M)):
            p += Wvol[i] * M[i]
        sig[:, :3] += p[:, None]
        F_int[..., n] = Bt @ sig.reshape(nqp * 6, nb)
    F_ext = Fx[:n3]
    if not batch:
        U, F_ext = U[:, 0], F_ext[:, 0]
        F_int = None if F_int is None else F_int[:, 0]
    solvers = tuple(v[0] for v in cache.values())
    return HistoryResult(system, history, U, F_int, F_ext,
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
