"""Certified reduced-order march of a viscoelastic history: the full march's recursion
projected on a K-orthonormal basis, every step's full-order residual checked (derivation:
docs/models/viscoelastic_march.md)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from designlab.fem.history import History, HistoryResult, prony_coefficients
from designlab.fem.model import System
from designlab.fem.solvers import LinearSolver

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

def reduced_ineligible(method: str, nsteps: int, A: np.ndarray, nb: int, has_G: bool,
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
class MarchContext:
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
        return prony_coefficients(dt, self.taus, self.tc, self.tg, len(self.Kg))

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

    def __init__(self, ctx: MarchContext):
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


def march_reduced(ctx: MarchContext, tol: float, r_max: int, r_start: int | None) -> _Rom:
    """Galerkin-projected march on a certified basis (see :func:`solve_history`); dense
    products on one BLAS thread (small or tall-skinny: threads cost more than they give on a
    busy machine, and one thread rounds the same on every machine)."""
    with threadpool_limits(1, user_api="blas"):
        return _reduced_march_1(ctx, tol, r_max, r_start)


def _reduced_march_1(ctx: MarchContext, tol: float, r_max: int, r_start: int | None) -> _Rom:
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


def _long_time(ctx: MarchContext, V: np.ndarray, KV: np.ndarray
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


def _march_projected(ctx: MarchContext, V: np.ndarray, KV: np.ndarray) -> _Rom:
    """The march in the basis' coordinates: y (r, nb) and per tau w_t (z_t = K_g V w_t)."""
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


def _certify(ctx: MarchContext, V: np.ndarray, KV: np.ndarray, rom: _Rom
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
    def make(cls, ctx: MarchContext, rom: _Rom, forces: bool, tol: float
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
