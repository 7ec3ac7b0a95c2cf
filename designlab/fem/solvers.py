"""Linear solvers for SPD stiffness systems: factor once, solve many right-hand sides.

``factorize(K, solver="auto", near_null=None)`` returns a :class:`LinearSolver` whose
``.solve(F)`` takes (n,) or (n, k). Choices: ``"direct"`` (SuperLU, scipy), ``"pardiso"``
(Intel MKL PARDISO's Cholesky, the library pypardiso installs, x86_64), ``"cholmod"``
(scikit-sparse, when installed), ``"amg"`` (CG preconditioned by pyamg smoothed aggregation
with rigid-body modes as near-null space; for TET10 with a TET4 p-multigrid level).
``"auto"``: SuperLU up to
:data:`PARDISO_MIN_DOFS` unknowns (:data:`PARDISO_MIN_DOFS_MANY_RHS` for many right-hand
sides), then pardiso or cholmod where installed, else direct up to
:data:`DIRECT_MAX_DOFS` unknowns (more when many right-hand sides reuse the factorisation),
else amg.
"""

from __future__ import annotations

import abc
import os
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from designlab.errors import ModelError, ParameterError
from designlab.params import did_you_mean

try:  # optional: scikit-sparse's CHOLMOD
    from sksparse.cholmod import CholmodNotPositiveDefiniteError
    from sksparse.cholmod import cholesky as _cholmod_cholesky
except ImportError:  # pragma: no cover - depends on the environment
    _cholmod_cholesky = None

#: "auto" uses SuperLU up to this many unknowns for one or a few right-hand sides (its
#: fill-in on 3D TET10 meshes grows fast: ~6 s for 14k, ~400 s for 108k unknowns here) ...
DIRECT_MAX_DOFS = 12_000
#: ... and up to this many when many right-hand sides (time steps) reuse the factorisation:
#: measured at 28k DOF, 100 steps cost 3 static direct solves but 67 AMG-CG solves
DIRECT_MAX_DOFS_MANY_RHS = 150_000
MANY_RHS = 20
#: "auto" takes PARDISO from this many unknowns on for one or a few right-hand sides (SuperLU
#: below: the static solves of the smaller models keep the results they had) ...
PARDISO_MIN_DOFS = 20_000
#: ... and from this many for many right-hand sides (time histories): PARDISO's Cholesky without
#: iterative refinement beats SuperLU from ~2k unknowns on, in the factorisation and in every
#: solve (benchmarks/bench_pardiso.py: TET10 boxes, CPU s, one thread; 12.2k DOF: 0.43 vs 1.58 s,
#: 7.4 vs 15.1 ms per solve); below 5k both take well under a second.
PARDISO_MIN_DOFS_MANY_RHS = 5_000


def has_cholmod() -> bool:
    return _cholmod_cholesky is not None


class LinearSolver(abc.ABC):
    """A factorised (or preconditioned) system. ``solve(F)``: F (n,) or (n, k) -> same shape.
    ``kind`` names the method, ``setup_seconds`` the factorisation time."""

    kind = ""
    #: ``solve(F, x0)`` uses the starting guess (iterative kinds)
    uses_x0 = False

    def __init__(self, K: sp.spmatrix):
        self.n = K.shape[0]
        self.setup_seconds = 0.0

    @classmethod
    def create(cls, K: sp.spmatrix, near_null=None, coarse=None) -> "LinearSolver":
        """The solver of ``K`` as :func:`factorize` builds it (``near_null``/``coarse`` are
        for the kinds that use them: values or callables returning them)."""
        return cls(K)

    def solve(self, F: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solution of K U = F; ``x0`` (same shape) is a starting guess for iterative kinds."""
        F = np.asarray(F, float)
        if F.shape[0] != self.n:
            raise ParameterError("F", F.shape, f"first dimension {self.n}")
        if x0 is not None and self.uses_x0:
            U = self._solve(F.reshape(self.n, -1), np.asarray(x0, float).reshape(self.n, -1))
        else:
            U = self._solve(F.reshape(self.n, -1))
        if not np.all(np.isfinite(U)):
            raise ModelError("model is under-constrained or singular: solution is not finite")
        return U.reshape(F.shape)

    @abc.abstractmethod
    def _solve(self, F):
        """K^-1 F for F (n, k)."""


class DirectSolver(LinearSolver):
    kind = "direct"

    def __init__(self, K):
        super().__init__(K)
        t = time.perf_counter()
        try:
            self._lu = spla.splu(sp.csc_matrix(K), permc_spec="MMD_AT_PLUS_A",
                                 diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:
            raise ModelError(f"model is under-constrained or singular: {exc}") from None
        self.setup_seconds = time.perf_counter() - t

    def _solve(self, F):
        return self._lu.solve(F)


class CholmodSolver(LinearSolver):  # pragma: no cover - needs scikit-sparse
    kind = "cholmod"

    def __init__(self, K):
        super().__init__(K)
        if _cholmod_cholesky is None:
            raise ParameterError("solver", "cholmod", "scikit-sparse installed "
                                 "(pip install scikit-sparse), or direct/amg")
        t = time.perf_counter()
        try:
            self._f = _cholmod_cholesky(sp.csc_matrix(K))
        except CholmodNotPositiveDefiniteError as exc:
            raise ModelError(f"model is under-constrained or singular: {exc}") from None
        self.setup_seconds = time.perf_counter() - t

    def _solve(self, F):
        return self._f(F)


class PardisoSolver(LinearSolver):
    """Intel MKL PARDISO (the library pypardiso installs), called directly: sparse Cholesky
    (``mtype`` 2, the upper triangle) with a nested-dissection ordering, the fastest direct
    solver here on 3-D TET10 matrices. One factorisation serves every ``solve`` (phase 33 only:
    no per-call matrix comparison or index conversion) and the solve does no iterative
    refinement (a Cholesky factor of an SPD matrix needs none: no perturbed pivots). A matrix
    that is not positive definite is factored as before (``mtype`` 11, LU with PARDISO's
    defaults). One MKL thread, right-hand sides copied into 64-byte aligned buffers: the same
    matrix gives the same solution bit for bit; a matrix that is neither positive definite
    nor regular enough for LU without perturbed pivots is a one-line :class:`ModelError`."""

    kind = "pardiso"
    #: the last factorisation's PARDISO matrix type (2: Cholesky, 11: LU fallback)
    mtype = 2

    def __init__(self, K):
        super().__init__(K)
        if not has_pardiso():
            raise ParameterError("solver", "pardiso", "pypardiso installed (pip install "
                                 "pypardiso; x86_64 only), or direct/cholmod/amg")
        t = time.perf_counter()
        self._lib = _mkl_library()
        self._pt = np.zeros(64, np.int64)
        self._iparm = np.zeros(64, np.int32)
        self._live = False
        K = sp.csr_matrix(K, dtype=float)
        K.sum_duplicates()
        K.sort_indices()
        try:
            self._factor(sp.triu(K, format="csr"), 2)
            self._check_pivots()
        except _PardisoError as exc:
            if exc.code != -4:          # -4: zero pivot (not positive definite)
                raise ModelError(f"model is under-constrained or singular: {exc}") from None
            self._release()
            try:
                self._factor(K, 11)
            except _PardisoError as exc2:
                raise ModelError(f"model is under-constrained or singular: {exc2}") from None
            if self._iparm[13] > 0:     # pivots PARDISO had to perturb: (nearly) singular
                self._release()
                raise ModelError(f"model is under-constrained or singular: not positive "
                                 f"definite, {int(self._iparm[13])} pivot(s) perturbed in LU")
        self.setup_seconds = time.perf_counter() - t

    def _factor(self, A: sp.csr_matrix, mtype: int) -> None:
        A.sort_indices()
        self.mtype = mtype
        self._a = np.ascontiguousarray(A.data, float)
        self._ia = np.ascontiguousarray(A.indptr, np.int32)
        self._ja = np.ascontiguousarray(A.indices, np.int32)
        ip = self._iparm
        ip[:] = 0
        if mtype == 2:
            ip[0] = 1           # iparm given (not defaults)
            ip[1] = 2           # nested dissection (METIS)
            ip[7] = 0           # no iterative refinement (none needed without perturbed pivots)
            ip[9] = 8           # pivot perturbation 1e-8 (default for symmetric)
            ip[17] = -1         # report the factor's nonzeros
            ip[34] = 1          # zero-based indices
            ip[55] = 1          # keep the pivots (pardiso_getdiag: the singularity check)
        else:                   # LU with PARDISO's defaults (pypardiso's former setting)
            ip[0] = 0
        self._live = True
        if mtype != 2:          # defaults: one-based indices
            self._ia, self._ja = self._ia + 1, self._ja + 1
        self._call(12, np.zeros((1, self.n)), np.zeros((1, self.n)), 1)

    def _call(self, phase: int, b: np.ndarray, x: np.ndarray, nrhs: int) -> None:
        import ctypes

        i32 = ctypes.c_int32
        err = i32(0)
        P = lambda arr: arr.ctypes.data_as(ctypes.c_void_p)  # noqa: E731
        self._lib.pardiso(P(self._pt), ctypes.byref(i32(1)), ctypes.byref(i32(1)),
                          ctypes.byref(i32(self.mtype)), ctypes.byref(i32(phase)),
                          ctypes.byref(i32(self.n)), P(self._a), P(self._ia), P(self._ja),
                          None, ctypes.byref(i32(nrhs)), P(self._iparm),
                          ctypes.byref(i32(0)), P(b), P(x), ctypes.byref(err))
        if err.value != 0:
            raise _PardisoError(err.value)

    #: a Cholesky pivot this much below its matrix diagonal: the matrix is singular to
    #: round-off (a properly supported model: > 1e-3 on the strap, 1e-15 on a free chain)
    MIN_PIVOT_RATIO = 1e-12

    def _check_pivots(self) -> None:
        import ctypes

        df, da = np.zeros(self.n), np.zeros(self.n)
        err = ctypes.c_int32(0)
        P = lambda arr: arr.ctypes.data_as(ctypes.c_void_p)  # noqa: E731
        self._lib.pardiso_getdiag(P(self._pt), P(df), P(da), ctypes.byref(ctypes.c_int32(1)),
                                  ctypes.byref(err))
        if err.value != 0 or not np.all(da > 0):
            return
        ratio = df / da
        i = int(np.argmin(ratio))
        self.min_pivot_ratio = float(ratio[i])
        if not ratio[i] > self.MIN_PIVOT_RATIO:
            self._release()
            raise ModelError(f"model is under-constrained or singular: the pivot of unknown {i} "
                             f"is {ratio[i]:.1e} of its diagonal (PARDISO Cholesky)")

    @property
    def factor_nonzeros(self) -> int:
        """Nonzeros of the factor (PARDISO's iparm[17])."""
        return int(self._iparm[17])

    def _solve(self, F):
        k = F.shape[1]
        b = _aligned((k, self.n))
        b[:] = F.T
        x = _aligned((k, self.n))
        try:
            self._call(33, b, x, k)
        except _PardisoError as exc:
            raise ModelError(f"PARDISO solve failed: {exc}") from None
        return x.T

    def _release(self) -> None:
        if getattr(self, "_live", False):
            self._live = False
            try:
                self._call(-1, np.zeros(1), np.zeros(1), 1)
            except Exception:  # noqa: BLE001 - nothing to do at teardown
                pass

    def __del__(self):
        self._release()


class _PardisoError(Exception):
    def __init__(self, code: int):
        super().__init__(f"PARDISO error {code}")
        self.code = code


def _aligned(shape: tuple[int, ...]) -> np.ndarray:
    """A C-ordered float array whose data starts on a 64-byte boundary (MKL's code paths, and so
    its last bits, can depend on the alignment of its operands)."""
    n = int(np.prod(shape))
    raw = np.empty(n + 8, float)
    off = (-raw.ctypes.data % 64) // 8
    return raw[off:off + n].reshape(shape)


def has_pardiso() -> bool:
    import importlib.util

    return importlib.util.find_spec("pypardiso") is not None


_MKL = None


def _mkl_library():
    """MKL's runtime library (the one pypardiso installs), loaded once per process and set to
    one thread: reproducible results, no oversubscription of sweep workers, no idle threads
    spinning on the CPU. Looked up in the environment's lib folders first (pypardiso's own
    search walks all of sys.prefix: ~1.4 s)."""
    global _MKL
    if _MKL is not None:
        return _MKL
    import ctypes
    import glob
    import sys

    found = [p for d in ("lib", "lib64") for p in glob.glob(f"{sys.prefix}/{d}/libmkl_rt.so*")]
    names = [os.environ.get("PYPARDISO_MKL_RT")] + sorted(found, key=len)
    lib = None
    for name in names:
        if name and os.path.isfile(name):
            try:
                lib = ctypes.CDLL(name)
                break
            except OSError:
                continue
    if lib is None:
        import pypardiso

        lib = pypardiso.PyPardisoSolver().libmkl
    name = getattr(lib, "_name", None)
    if name and os.path.isfile(name):       # pypardiso (and children) find it without a search
        os.environ.setdefault("PYPARDISO_MKL_RT", name)
    lib.pardiso.restype = None
    lib.pardiso_getdiag.restype = None
    try:
        lib.MKL_Set_Num_Threads(ctypes.c_int(1))
    except AttributeError:  # pragma: no cover - every libmkl_rt has it
        pass
    _MKL = lib
    return lib


class AMGSolver(LinearSolver):
    """Preconditioned CG with smoothed-aggregation AMG (pyamg). ``near_null``: (n, 6)
    rigid-body modes (aggregation keeps them, essential for elasticity). ``coarse``:
    optional (P, B_c) p-multigrid level (TET10 -> TET4 interpolation and its rigid modes):
    the preconditioner is then symmetric Gauss-Seidel on K around one SA-AMG V-cycle on
    P^T K P, which converges far better than SA-AMG on quadratic elements directly."""

    kind = "amg"
    uses_x0 = True

    def __init__(self, K, near_null=None, coarse=None, rtol=1e-10, maxiter=1000):
        import pyamg

        super().__init__(K)
        t = time.perf_counter()
        self.K = sp.csr_matrix(K)
        self.rtol, self.maxiter = rtol, maxiter
        self.iterations: list[int] = []
        if coarse is not None:
            P, Bc = coarse
            self._P, self._PT = sp.csr_matrix(P), sp.csr_matrix(P.T)
            Kc = (self._PT @ self.K @ self._P).tocsr()
            ml = pyamg.smoothed_aggregation_solver(Kc, B=np.ascontiguousarray(Bc),
                                                   symmetry="symmetric", max_coarse=500)
            Mc = ml.aspreconditioner(cycle="V")
            self._M = spla.LinearOperator(self.K.shape, matvec=lambda r: self._two_level(r, Mc),
                                          dtype=float)
        else:
            B = None if near_null is None else np.ascontiguousarray(near_null, float)
            ml = pyamg.smoothed_aggregation_solver(self.K, B=B, symmetry="symmetric",
                                                   max_coarse=500)
            self._M = ml.aspreconditioner(cycle="V")
        self.setup_seconds = time.perf_counter() - t

    @classmethod
    def create(cls, K, near_null=None, coarse=None) -> "AMGSolver":
        ev = lambda v: v() if callable(v) else v  # noqa: E731
        return cls(K, near_null=ev(near_null), coarse=ev(coarse))

    def _two_level(self, r, Mc):
        from pyamg.relaxation.relaxation import gauss_seidel

        r = np.asarray(r, float).ravel()
        x = np.zeros_like(r)
        gauss_seidel(self.K, x, r, iterations=1, sweep="forward")
        x += self._P @ Mc(self._PT @ (r - self.K @ x))
        gauss_seidel(self.K, x, r, iterations=1, sweep="backward")
        return x

    def _solve(self, F, X0=None):
        U = np.zeros_like(F)
        for j in range(F.shape[1]):
            b = F[:, j]
            if not np.any(b):
                continue
            it = [0]

            def count(_):
                it[0] += 1

            x, info = spla.cg(self.K, b, x0=None if X0 is None else X0[:, j], rtol=self.rtol,
                              atol=0.0, maxiter=self.maxiter, M=self._M, callback=count)
            if info != 0:
                raise ModelError(f"AMG-CG did not converge in {self.maxiter} iterations "
                                 f"(model ill-conditioned or under-constrained)")
            self.iterations.append(it[0])
            U[:, j] = x
        return U


#: the solver kinds by name: adding a solver is a :class:`LinearSolver` subclass and its entry
#: here (every ``solver`` setting accepts it from then on)
KINDS: dict[str, type[LinearSolver]] = {
    "direct": DirectSolver,
    "pardiso": PardisoSolver,
    "cholmod": CholmodSolver,
    "amg": AMGSolver,
}
#: the choices of a ``solver`` setting: "auto" (see :func:`choose_solver`) and the kinds
SOLVERS: tuple[str, ...] = ("auto", *KINDS)


def choose_solver(n: int, solver: str = "auto", n_rhs: int = 1) -> str:
    """The concrete method ``factorize`` uses for ``n`` unknowns and ``n_rhs`` expected
    right-hand sides; an unknown ``solver`` is a one-line :class:`ParameterError`."""
    if solver not in SOLVERS:
        raise ParameterError("solver", solver, "one of " + ", ".join(SOLVERS)
                             + did_you_mean(solver, SOLVERS))
    if solver == "auto":
        if n < (PARDISO_MIN_DOFS_MANY_RHS if n_rhs >= MANY_RHS else PARDISO_MIN_DOFS):
            return "direct"
        if has_pardiso():
            return "pardiso"
        if has_cholmod():
            return "cholmod"
        limit = DIRECT_MAX_DOFS_MANY_RHS if n_rhs >= MANY_RHS else DIRECT_MAX_DOFS
        return "direct" if n <= limit else "amg"
    return solver


def factorize(K: sp.spmatrix, solver: str = "auto", near_null=None, coarse=None,
              n_rhs: int = 1) -> LinearSolver:
    """Factor (or precondition) the SPD matrix ``K`` once; see module docstring.
    ``near_null`` ((n, k) array) and ``coarse`` ((P, B_c) or None): values or callables
    returning them, evaluated only for AMG. ``n_rhs``: expected number of solves (guides
    "auto"). The kind is looked up in :data:`KINDS`."""
    return KINDS[choose_solver(K.shape[0], solver, n_rhs)].create(K, near_null, coarse)
