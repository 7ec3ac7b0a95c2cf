"""Linear solvers for SPD stiffness systems: factor once, solve many right-hand sides.

``factorize(K, solver="auto", near_null=None)`` returns a :class:`LinearSolver` whose
``.solve(F)`` takes (n,) or (n, k). Choices: ``"direct"`` (SuperLU, scipy), ``"cholmod"``
(scikit-sparse, when installed), ``"amg"`` (pyamg smoothed aggregation with rigid-body modes as
near-null space, preconditioned CG). ``"auto"``: cholmod if installed, else direct up to
:data:`DIRECT_MAX_DOFS` unknowns, else amg.
"""

from __future__ import annotations

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

SOLVERS = ("auto", "direct", "cholmod", "amg")
#: above this many unknowns "auto" prefers AMG-CG over SuperLU (fill-in of 3D TET10 grows fast)
DIRECT_MAX_DOFS = 60_000


def has_cholmod() -> bool:
    return _cholmod_cholesky is not None


class LinearSolver:
    """A factorised (or preconditioned) system. ``solve(F)``: F (n,) or (n, k) -> same shape.
    ``kind`` names the method, ``setup_seconds`` the factorisation time."""

    kind = ""

    def __init__(self, K: sp.spmatrix):
        self.n = K.shape[0]
        self.setup_seconds = 0.0

    def solve(self, F: np.ndarray) -> np.ndarray:
        F = np.asarray(F, float)
        if F.shape[0] != self.n:
            raise ParameterError("F", F.shape, f"first dimension {self.n}")
        U = self._solve(F.reshape(self.n, -1))
        if not np.all(np.isfinite(U)):
            raise ModelError("model is under-constrained or singular: solution is not finite")
        return U.reshape(F.shape)

    def _solve(self, F):  # pragma: no cover - abstract
        raise NotImplementedError


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


class AMGSolver(LinearSolver):
    """Smoothed-aggregation AMG (pyamg) preconditioning CG; ``near_null``: (n, 6) rigid-body
    modes of the reduced system (improves convergence a lot for elasticity)."""

    kind = "amg"

    def __init__(self, K, near_null=None, rtol=1e-10, maxiter=2000):
        import pyamg

        super().__init__(K)
        t = time.perf_counter()
        self.K = sp.csr_matrix(K)
        B = None if near_null is None else np.ascontiguousarray(near_null, float)
        self._ml = pyamg.smoothed_aggregation_solver(self.K, B=B, symmetry="symmetric",
                                                     max_coarse=500)
        self._M = self._ml.aspreconditioner(cycle="V")
        self.rtol, self.maxiter = rtol, maxiter
        self.iterations: list[int] = []
        self.setup_seconds = time.perf_counter() - t

    def _solve(self, F):
        U = np.zeros_like(F)
        for j in range(F.shape[1]):
            b = F[:, j]
            if not np.any(b):
                continue
            it = [0]

            def count(_):
                it[0] += 1

            x, info = spla.cg(self.K, b, rtol=self.rtol, atol=0.0, maxiter=self.maxiter,
                              M=self._M, callback=count)
            if info != 0:
                raise ModelError(f"AMG-CG did not converge in {self.maxiter} iterations "
                                 f"(model ill-conditioned or under-constrained)")
            self.iterations.append(it[0])
            U[:, j] = x
        return U


def choose_solver(n: int, solver: str = "auto") -> str:
    """The concrete method ``factorize`` uses for ``n`` unknowns."""
    if solver not in SOLVERS:
        raise ParameterError("solver", solver, "one of " + ", ".join(SOLVERS))
    if solver == "auto":
        if has_cholmod():
            return "cholmod"
        return "direct" if n <= DIRECT_MAX_DOFS else "amg"
    return solver


def factorize(K: sp.spmatrix, solver: str = "auto", near_null=None) -> LinearSolver:
    """Factor (or precondition) the SPD matrix ``K`` once; see module docstring.
    ``near_null``: (n, k) array or a callable returning it (evaluated only for AMG)."""
    solver = choose_solver(K.shape[0], solver)
    if solver == "direct":
        return DirectSolver(K)
    if solver == "cholmod":
        return CholmodSolver(K)
    return AMGSolver(K, near_null=near_null() if callable(near_null) else near_null)
