"""PARDISO called directly (fem.solvers.PardisoSolver): Cholesky on SPD stiffness matrices,
the LU fallback for a symmetric matrix that is not positive definite, one-line errors for a
singular one, the same bits run to run, and "auto" choosing it from PARDISO_MIN_DOFS on."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from designlab.errors import ModelError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.solvers import (MANY_RHS, PARDISO_MIN_DOFS, PARDISO_MIN_DOFS_MANY_RHS,
                                   DirectSolver, PardisoSolver, choose_solver, has_pardiso)
from designlab.mesh.tetmesh import box_tet_mesh

pytestmark = pytest.mark.skipif(not has_pardiso(), reason="pypardiso (MKL) not installed")


def _stiffness(n: int = 3):
    mesh = box_tet_mesh(8.0, 2.0, 2.0, 2 * n, n, n).quadratic()
    model = Model(mesh, {"block": Material("m", E=2200.0, nu=0.35)})
    model.fix("xmin")
    system = model.build()
    return system.reduce(system.K())


def test_cholesky_solves_like_superlu():
    K = _stiffness()
    F = np.random.default_rng(1).standard_normal((K.shape[0], 3))
    s = PardisoSolver(K)
    assert s.mtype == 2 and s.factor_nonzeros > K.shape[0]
    U = s.solve(F)
    ref = DirectSolver(K).solve(F)
    assert U.shape == F.shape
    np.testing.assert_allclose(U, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    np.testing.assert_allclose(s.solve(F[:, 1]), ref[:, 1], rtol=0, atol=1e-10 * np.abs(ref).max())
    # reused factorisation, same bits every time (also from a non-contiguous right-hand side)
    np.testing.assert_array_equal(s.solve(F), U)
    np.testing.assert_array_equal(s.solve(np.asfortranarray(F)), U)
    np.testing.assert_array_equal(PardisoSolver(K).solve(F), U)


def test_indefinite_falls_back_to_lu_and_singular_is_one_line():
    n = 50
    d = np.where(np.arange(n) % 2 == 0, 3.0, -3.0)          # symmetric, indefinite, regular
    K = sp.diags([np.ones(n - 1), d, np.ones(n - 1)], [-1, 0, 1]).tocsr()
    F = np.arange(1.0, n + 1)
    s = PardisoSolver(K)
    assert s.mtype == 11
    np.testing.assert_allclose(K @ s.solve(F), F, rtol=0, atol=1e-10 * np.abs(F).max())
    L = sp.diags([-np.ones(n - 1), np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1)],
                 [-1, 0, 1]).tocsr()                          # free-free chain: singular
    with pytest.raises(ModelError) as e:
        PardisoSolver(L).solve(F)
    assert "\n" not in str(e.value)


def test_auto_takes_pardiso_from_its_threshold():
    assert choose_solver(PARDISO_MIN_DOFS - 1) == "direct"
    assert choose_solver(PARDISO_MIN_DOFS) == "pardiso"
    # time histories (many right-hand sides) from far fewer unknowns
    assert PARDISO_MIN_DOFS_MANY_RHS < PARDISO_MIN_DOFS
    assert choose_solver(PARDISO_MIN_DOFS_MANY_RHS - 1, n_rhs=MANY_RHS) == "direct"
    assert choose_solver(PARDISO_MIN_DOFS_MANY_RHS, n_rhs=MANY_RHS) == "pardiso"
    assert choose_solver(PARDISO_MIN_DOFS_MANY_RHS, n_rhs=MANY_RHS - 1) == "direct"
