"""Linear solvers for SPD stiffness systems: factor once, solve many right-hand sides.

``factorize(K, solver="auto", near_null=None)`` returns a :class:`LinearSolver` whose
``.solve(F)`` takes (n,) or (n, k). Choices: ``"direct"`` (SuperLU, scipy), ``"pardiso"``
(Intel MKL PARDISO via pypardiso, x86_64), ``"cholmod"`` (scikit-sparse, when installed),
``"amg"`` (CG preconditioned by pyamg smoothed aggregation with rigid-body modes as near-null
space; for TET10 with a TET4 p-multigrid level). ``"auto"``: SuperLU up to
:data:`PARDISO_MIN_DOFS` unknowns, then pardiso or cholmod where installed, else direct up to
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
#: below this many unknowns SuperLU beats PARDISO on one thread (measured on the fingertip's
#: TET10 model, CPU s: 14.8k DOF 5.8 vs 8.3 for a viscoelastic run; 44.6k DOF static 25.1 vs
#: 7.1; benchmarks/bench_fem_solvers.py)
PARDISO_MIN_DOFS = 20_000


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
    """Intel MKL PARDISO (pypardiso), sparse direct LDL^T/LU with a nested-dissection
    ordering: the fastest direct solver here on 3-D TET10 matrices. Run on one thread with
    MKL's conditional numerical reproducibility, so the same matrix gives the same solution
    bit for bit."""

    kind = "pardiso"

    def __init__(self, K):
        super().__init__(K)
        if not has_pardiso():
            raise ParameterError("solver", "pardiso", "pypardiso installed (pip install "
                                 "pypardiso; x86_64 only), or direct/cholmod/amg")
        import pypardiso

        t = time.perf_counter()
        _mkl_single_thread()
        self._s = pypardiso.PyPardisoSolver(mtype=11)
        # pypardiso searches sys.prefix for libmkl_rt on every solver (~2 s CPU): name the
        # library it found once for the rest of the process (and its children)
        name = getattr(self._s.libmkl, "_name", None)
        if name and os.path.isfile(name):
            os.environ.setdefault("PYPARDISO_MKL_RT", name)
        self._s.set_statistical_info_off()
        self._K = sp.csr_matrix(K)
        self._K.sort_indices()
        try:
            self._s.factorize(self._K)
        except Exception as exc:  # PyPardisoError: zero pivot, singular
            raise ModelError(f"model is under-constrained or singular: {exc}") from None
        self.setup_seconds = time.perf_counter() - t

    def _solve(self, F):
        # the factorisation of self._K is reused (pypardiso compares the matrix it was given)
        return np.asarray(self._s.solve(self._K, np.ascontiguousarray(F)), float).reshape(F.shape)


def has_pardiso() -> bool:
    import importlib.util

    return importlib.util.find_spec("pypardiso") is not None


_MKL_THREADS_SET = False


def _mkl_single_thread() -> None:
    """One MKL thread: reproducible results and no oversubscription of sweep workers (set
    once per process: looking the library up is slow)."""
    global _MKL_THREADS_SET
    if _MKL_THREADS_SET:
        return
    _MKL_THREADS_SET = True
    try:
        import mkl  # mkl-service, when present

        mkl.set_num_threads(1)
    except ImportError:
        import ctypes
        import ctypes.util

        for name in ("libmkl_rt.so.2", "libmkl_rt.so", ctypes.util.find_library("mkl_rt")):
            if not name:
                continue
            try:
                lib = ctypes.CDLL(name)
                lib.MKL_Set_Num_Threads(ctypes.c_int(1))
                return
            except (OSError, AttributeError):
                continue


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
        raise ParameterError("solver", solver, "one of " + ", ".join(SOLVERS))
    if solver == "auto":
        if n < PARDISO_MIN_DOFS:
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
