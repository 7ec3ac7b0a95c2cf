"""Linear viscoelasticity (generalized Maxwell / Prony series) under a load history: the full
march, factored once per step size, with the certified reduced-order march as an option
(derivation and accuracy: docs/models/viscoelastic_march.md)."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from designlab.errors import ModelError, ParameterError
from designlab.fem.assembly import stiffness
from designlab.fem.history import History, HistoryResult, PronyTables, prony_coefficients
from designlab.fem.model import Model, System
from designlab.fem.reduced_march import (ROM_MAX, ROM_TOL, MarchContext, ReducedHistoryResult,
                                         march_reduced, reduced_ineligible)
from designlab.fem.solvers import LinearSolver, factorize
from designlab.fem.static import check_constrained, near_null_space, p1_prolongation

_BLOCK = 16                 # steps gathered before writing into U, F_int


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


def _terms(pr: PronyTables, nq: int) -> tuple[list[float], np.ndarray, np.ndarray]:
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




def _moduli_stiffness(model: Model, G: np.ndarray, K: np.ndarray):
    """Stiffness of per-quadrature-point shear and bulk moduli (constant per cell)."""
    nq = model.basis.dx.shape[1]
    Gc, Kc = G.reshape(-1, nq)[:, 0], K.reshape(-1, nq)[:, 0]
    return stiffness(model.basis, Kc - 2.0 * Gc / 3.0, Gc)


def _grouped_terms(model: Model, pr: PronyTables) -> tuple[list, list, np.ndarray, list]:
    """The time constants, each one's stiffness group and factor on it (K_t = c_t K_group),
    and one stiffness per group of proportional time constants."""
    taus, shear, bulk = _terms(pr, model.basis.dx.shape[1])
    groups = _shapes(np.concatenate([shear, bulk], axis=1))
    Kg = [stiffness(model.basis, bulk[ref] - 2.0 * shear[ref] / 3.0, shear[ref])
          for ref, _ in groups]
    member = {t_: (g, c) for g, (_, ms) in enumerate(groups) for t_, c in ms}
    tg = [member[i][0] for i in range(len(taus))]
    tc = np.array([member[i][1] for i in range(len(taus))])
    return taus, tg, tc, Kg


def _main_step(t: np.ndarray) -> float:
    """The step size used most (to 1e-12): the one factored first (others: preconditioned CG)."""
    steps = np.round(np.diff(t), 12)
    sizes, counts = np.unique(steps, return_counts=True) if len(steps) else ([0.0], [1])
    return float(sizes[int(np.argmax(counts))])


class _FullMarch:
    """The full-order march: its set-up (loads, grouped Prony terms, the main step size's
    factorisation) and the step loop carrying the history forces z_t per time constant."""

    def __init__(self, model: Model, system: System, history: History, solver: str,
                 batch: bool, forces: bool, factor_each_step: bool = False):
        self.model, self.system, self.history = model, system, history
        self.factor_each_step = factor_each_step
        self.solver, self.batch, self.forces = solver, batch, forces
        self.t = history.t
        self.nsteps = len(self.t)
        self.A = np.stack([history.amplitude(c) for c in system.cases], axis=1)  # (steps, cases)
        self.Fc = system.F + system.F_preload
        self.Gp = system.G
        self.nb = self.A.shape[1] if batch else 1
        self.has_G = bool(np.any(self.Gp[:, np.any(self.A != 0.0, axis=0)]))
        self.n3 = 3 * model.n_points
        self.pr = PronyTables(model)
        self.taus, self.tg, self.tc, self.Kg_nodal = _grouped_terms(model, self.pr)
        self.K_inf = (_moduli_stiffness(model, self.pr.G0 * self.pr.ginf,
                                        self.pr.K0 * self.pr.kinf) if forces else None)
        self._dof_layout()
        self.cache: dict[float, tuple[LinearSolver, object]] = {}
        self.coef: dict[float, tuple] = {}
        self.main_dt = _main_step(self.t)
        self.main: LinearSolver | None = None
        self.Kr_main = None
        if self.main_dt != 0.0 and self.nsteps > 1:
            K, self.Kr_main = self._stiffness(self.main_dt)
            self.main = self._factorize(self.Kr_main)
            self.cache[self.main_dt] = (self.main, K)

    def _dof_layout(self) -> None:
        """Without rigid couplings T selects the free dofs (q = r[free], u[free] = q: the same
        numbers as the sparse products, without them); with neither prescribed motions nor
        internal forces the history forces live on the free dofs of the nodes alone."""
        T = self.system.T
        self.Tt = T.T.tocsr()
        self.free = (self.system.free_dofs if T.nnz == T.shape[1] and np.all(T.data == 1.0)
                     else None)
        self.lean = self.free is not None and not self.has_G and not self.forces
        self.pos = None
        self.Kg = list(self.Kg_nodal)
        self.nz = self.n3
        if self.lean:               # rows of q on the nodes: pos
            self.pos = np.nonzero(self.free < self.n3)[0]
            fp = self.free[self.pos]
            self.Kg = [k[fp][:, fp].tocsr() for k in self.Kg_nodal]
            self.nz = len(self.pos)

    def _load(self, M: np.ndarray, n: int) -> np.ndarray:
        """Columns of ``M`` (n_dofs, cases) at step ``n``: (n_dofs, nb)."""
        return M * self.A[n][None] if self.batch else (M @ self.A[n])[:, None]

    def _stiffness(self, dt: float):
        """Effective stiffness of step size ``dt`` on every dof and reduced."""
        Ge, Ke = self.pr.effective(dt)
        K = self.system.K(_moduli_stiffness(self.model, Ge, Ke))
        return K, self.system.reduce(K)

    def _factorize(self, Kr) -> LinearSolver:
        system = self.system
        return factorize(Kr, self.solver, near_null=lambda: near_null_space(system),
                         coarse=lambda: p1_prolongation(system), n_rhs=self.nsteps * self.nb)

    def _solver(self, dt: float) -> tuple[LinearSolver, object]:
        """Solver and full stiffness of step size ``dt`` (made on first use)."""
        key = round(dt, 12)
        if key not in self.cache:
            K, Kr = self._stiffness(dt)
            if key == self.main_dt or self.main is None or self.main.kind == "amg" \
                    or self.factor_each_step:
                lin = self._factorize(Kr)
                if key == self.main_dt:
                    self.main = lin
            else:       # other step sizes: CG preconditioned by the main factorisation
                lin = _Preconditioned(Kr, self.main)
            self.cache[key] = (lin, K)
        return self.cache[key]

    def _coefficients(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if dt not in self.coef:
            self.coef[dt] = prony_coefficients(dt, self.taus, self.tc, self.tg, len(self.Kg))
        return self.coef[dt]

    def context(self) -> MarchContext:
        """What the reduced march takes of this set-up."""
        return MarchContext(system=self.system, history=self.history, A=self.A, Fc=self.Fc,
                             batch=self.batch, taus=self.taus, tg=self.tg, tc=self.tc,
                             Kg=self.Kg_nodal, Kr_main=self.Kr_main, lin=self.main,
                             main_dt=self.main_dt, K_inf=self.K_inf)

    def _history_force(self, a: np.ndarray, gsum: np.ndarray) -> np.ndarray:
        """f_h = sum_t a_t z_t - sum_t gamma_t K_t u^n."""
        fh = np.zeros((self.nz, self.nb))
        for i in range(len(self.taus)):
            fh += a[i] * self.Z[i]
        for g in range(len(self.Kg)):
            fh -= gsum[g] * self.V[g]
        return fh

    def _solve(self, lin: LinearSolver, K, F_n, G_n, fh, q_prev) -> np.ndarray:
        """The step's reduced unknowns q."""
        free = self.free
        if self.lean:
            r = F_n[free]
            r[self.pos] -= fh
            return lin.solve(r, x0=q_prev)
        r = F_n.copy()
        r[:self.n3] -= fh
        if self.has_G:
            r -= K @ G_n
        return lin.solve(r[free] if free is not None else self.Tt @ r, x0=q_prev)

    def _displace(self, u: np.ndarray, q: np.ndarray, G_n) -> np.ndarray:
        """Fill ``u`` (n_dofs, nb) from q; the nodal displacements the history forces see."""
        if self.free is not None:
            u[:] = 0.0
            u[self.free] = q
        else:
            u[:] = self.system.T @ q
        if self.has_G:
            u += G_n
        return q[self.pos] if self.lean else u[:self.n3]

    def _update(self, a: np.ndarray, gc: np.ndarray, un: np.ndarray) -> None:
        """z_t <- a_t z_t + gamma_t c_t (K_g u^{n+1} - K_g u^n), group by group."""
        for g in range(len(self.Kg)):
            Vn = self.Kg[g] @ un
            dV = Vn - self.V[g]
            for i in range(len(self.taus)):
                if self.tg[i] == g:
                    self.Z[i] *= a[i]
                    self.Z[i] += gc[i] * dV
            self.V[g] = Vn

    def run(self) -> tuple[np.ndarray, np.ndarray | None]:
        """March every step: U (n_dofs, nb, steps) and F_int (3 n_points, nb, steps) or None."""
        nd, nb, nsteps, t = self.system.n_dofs, self.nb, self.nsteps, self.t
        self.Z = np.zeros((len(self.taus), self.nz, nb))       # history forces per tau
        self.V = np.zeros((len(self.Kg), self.nz, nb))         # K_group u of the last step
        U = np.zeros((nd, nb, nsteps))
        F_int = np.zeros((self.n3, nb, nsteps)) if self.forces else None
        U_buf = np.zeros((_BLOCK, nd, nb))
        F_buf = np.zeros((_BLOCK, self.n3, nb)) if self.forces else None
        t_prev = t[0]
        q_prev = None
        for n in range(nsteps):
            dt = 0.0 if n == 0 else float(t[n] - t_prev)
            t_prev = t[n]
            F_n = self._load(self.Fc, n)
            G_n = self._load(self.Gp, n) if self.has_G else None
            if n == 0 and not (np.any(F_n) or (self.has_G and np.any(G_n))):
                U_buf[0] = 0.0                              # at rest
                if self.forces:
                    F_buf[0] = 0.0
                continue
            lin, K = self._solver(dt)
            a, gc, gsum = self._coefficients(dt)
            q = self._solve(lin, K, F_n, G_n, self._history_force(a, gsum), q_prev)
            q_prev = q
            un = self._displace(U_buf[n % _BLOCK], q, G_n)
            self._update(a, gc, un)
            if self.forces:  # internal forces: long-term elastic part plus the history forces
                F_buf[n % _BLOCK] = self.K_inf @ un + self.Z.sum(axis=0)
            if n % _BLOCK == _BLOCK - 1 or n == nsteps - 1:
                n0 = n - n % _BLOCK
                U[..., n0:n + 1] = np.moveaxis(U_buf[:n - n0 + 1], 0, -1)
                if self.forces:
                    F_int[..., n0:n + 1] = np.moveaxis(F_buf[:n - n0 + 1], 0, -1)
        return U, F_int


def _check_method(method: str, rom_tol: float, rom_max: int, rom_basis: int | None) -> None:
    if method not in ("auto", "full", "reduced"):
        raise ParameterError("method", method, "one of auto, full, reduced")
    if not rom_tol > 0:
        raise ParameterError("rom_tol", rom_tol, "a relative residual > 0")
    if int(rom_max) != rom_max or rom_max < 1:
        raise ParameterError("rom_max", rom_max, "an integer >= 1")
    if rom_basis is not None and (int(rom_basis) != rom_basis or rom_basis < 1):
        raise ParameterError("rom_basis", rom_basis, "None or an integer >= 1")


def solve_history(model: Model, history: History, solver: str = "auto",
                  check: bool = True, batch: bool = False, forces: bool = True,
                  method: str = "full", rom_tol: float = ROM_TOL, rom_max: int = ROM_MAX,
                  rom_basis: int | None = None, factor_each_step: bool = False) -> HistoryResult:
    """March ``history`` with the exact exponential update.

    The internal variables are carried as nodal forces, one vector per time constant; time
    constants whose moduli are proportional share one stiffness. Without internal forces,
    prescribed motions or rigid couplings the march runs on the free dofs alone
    (docs/models/viscoelastic_march.md).

    Args:
        model: the model; regions whose material has a ``prony`` relax.
        history: times (s) and the amplitude of each load case.
        solver: linear solver of :func:`~designlab.fem.solvers.factorize`.
        check: check the model is constrained first.
        batch: every load case is a separate history (amplitude ``a_c(t)`` on case c alone)
            in the same march: one factorisation, multi-column solves.
        forces: compute the internal forces (False: ``F_int`` is None, no reactions or
            wrenches; one sparse product per step less).
        method: "full" (the default), "reduced" (the certified reduced-order march; the full
            one when it does not certify or the model has prescribed motions) or "auto"
            (reduced for more than ``ROM_MIN_STEPS`` steps and at most ``ROM_MAX_COLUMNS``
            load columns).
        rom_tol: the reduced march's certified relative residual.
        rom_max: the reduced march's largest basis.
        rom_basis: the starting basis' size (default ``_ROM_START``, then enriched).
        factor_each_step: factorise every step size the history has (the instantaneous
            response at t = 0 among them) instead of solving the other step sizes by CG
            preconditioned with the main step's factorisation: cheaper when many load columns
            share a few such steps (each column is one CG solve).

    Returns:
        The :class:`HistoryResult` (a ``ReducedHistoryResult`` for the reduced march); its
        ``march`` says which ran and why not reduced.
    """
    _check_method(method, rom_tol, rom_max, rom_basis)
    system = model.build()
    if check:
        check_constrained(system)
    unknown = set(history.amplitudes) - set(system.cases)
    if unknown:
        raise ParameterError("history case", sorted(unknown)[0],
                             "one of the model's load cases: " + ", ".join(system.cases))
    full = _FullMarch(model, system, history, solver, batch, forces, factor_each_step)
    why = reduced_ineligible(method, full.nsteps, full.A, full.nb, full.has_G, full.main)
    if why is None:
        ctx = full.context()
        rom = march_reduced(ctx, rom_tol, rom_max, rom_basis)
        if rom.ok:
            return ReducedHistoryResult.make(ctx, rom, forces, rom_tol)
        why = rom.why
    march = "full" if why is None or method == "full" else f"full ({why})"
    U, F_int = full.run()
    if not batch:
        U = U[:, 0]
        F_int = None if F_int is None else F_int[:, 0]
    solvers = tuple(v[0] for v in full.cache.values())
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
    pr = PronyTables(model)
    Kf = system.K(_moduli_stiffness(model, pr.G0 * pr.ginf, pr.K0 * pr.kinf))
    Fr = system.T.T @ (system.F + system.F_preload - Kf @ system.G)
    lin = factorize(system.reduce(Kf), solver, near_null=lambda: near_null_space(system),
                    coarse=lambda: p1_prolongation(system), n_rhs=Fr.shape[1])
    return system.T @ lin.solve(Fr) + system.G
