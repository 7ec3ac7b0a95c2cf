"""Springs assembled at once (one stacked map R, K_spring = R^T diag(k) R) give the numbers of
the spring-by-spring sum, and the rank test of check_constrained still sees what they hold."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from designlab.errors import ModelError
from designlab.fem.materials import Material
from designlab.fem.model import Model
from designlab.fem.static import solve_static
from designlab.fem.static import check_constrained
from designlab.mesh.tetmesh import box_tet_mesh

SOFT = Material("soft", E=10.0, nu=0.3)


def _winkler(axis_of, nodes_from="zmin"):
    mesh = box_tet_mesh(4.0, 3.0, 2.0, 4, 3, 2)
    model = Model(mesh, materials={"block": SOFT})
    rng = np.random.default_rng(3)
    for i in model.nodes(nodes_from):
        model.spring(f"t{i}", a=int(i), k=float(rng.uniform(0.5, 2.0)), axis=axis_of(rng))
    return model


def test_stacked_springs_equal_spring_by_spring_sum():
    model = _winkler(lambda rng: rng.normal(size=3))
    top = model.rigid("top", "zmax")
    model.spring("iso", a=top, b=int(model.nodes("zmin")[0]), k=3.0)        # 3 rows
    model.spring("ab", a=int(model.nodes("xmax")[0]), b=int(model.nodes("xmin")[0]), k=7.0,
                 axis=(0.3, 0.0, 1.0), preload=0.5, case="pre")
    system = model.build()
    n = system.n_dofs
    K = sp.csr_matrix((n, n))
    for s in model.springs.values():
        R = model.spring_map(s)
        K = K + s.k * (R.T @ R)
    diff = abs(system.K_spring - K)
    assert diff.max() <= 1e-14 * abs(K).max()
    assert system.R_spring.shape[0] == len(model.springs) - 1 + 3
    # the one-row node springs: bit for bit
    wink = [s for s in model.springs.values() if s.name.startswith("t")]
    Kw = sp.csr_matrix((n, n))
    for s in wink:
        R = model.spring_map(s)
        Kw = Kw + s.k * (R.T @ R)
    rows = np.isin(system.spring_of_row, np.arange(len(wink)))
    from designlab.fem.model import _gram
    Kw2 = _gram(system.R_spring[np.nonzero(rows)[0]], system.k_rows[rows], n)
    assert (Kw != Kw2).nnz == 0
    # the preload uses the spring's row
    ab = model.springs["ab"]
    np.testing.assert_array_equal(system.F_preload[:, model.cases.index("pre")],
                                  -0.5 * model.spring_map(ab).toarray()[0])


def test_fast_node_spring_map_matches_general_path():
    model = _winkler(lambda rng: rng.normal(size=3))
    s = next(iter(model.springs.values()))
    fast = model.spring_map(s).toarray()
    general = s.axis[None] @ model.point_map(s.a)
    np.testing.assert_array_equal(fast, general)


def test_winkler_springs_along_z_leave_three_modes_free():
    model = _winkler(lambda rng: np.array([0.0, 0.0, 1.0]))
    model.traction("zmax", (0.0, 0.0, -1.0))
    with pytest.raises(ModelError, match=r"under-constrained: 3 rigid-body modes free"):
        check_constrained(model.build())


def test_tilted_winkler_springs_hold_the_block():
    model = _winkler(lambda rng: rng.normal(size=3))
    model.traction("zmax", (0.0, 0.0, -1.0))
    res = solve_static(model)                     # check_constrained passes
    total = sum(res.spring_force(s) * s.axis for s in model.springs.values())
    # readings along +axis of the node = the load the springs carry (the traction, -12 N z)
    np.testing.assert_allclose(total, [0.0, 0.0, -4.0 * 3.0], rtol=1e-8, atol=1e-8)
