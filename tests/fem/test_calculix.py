"""CalculiX reference solver: deck writing, running, reading, against closed-form beam/bar answers."""

import numpy as np
import pytest

from conftest import require_tool
from designlab.errors import DesignlabError, ModelError, ParameterError
from designlab.fem import calculix
from designlab.mesh.tetmesh import box_tet_mesh


def traction_forces(mesh, facet_set, traction):
    """Consistent nodal forces (N) of a uniform traction (MPa) on a TRI3/TRI6 facet set."""
    tri = mesh.facet_sets[facet_set]
    p = mesh.points
    area = 0.5 * np.linalg.norm(np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]]), axis=1)
    f = np.zeros((mesh.n_points, 3))
    cols = range(3) if tri.shape[1] == 3 else range(3, 6)  # TRI6: corners carry 0, mid-nodes A/3
    for k in cols:
        np.add.at(f, tri[:, k], np.outer(area / 3, traction))
    return f


def clamp(mesh, facet_set):
    nodes = np.unique(mesh.facet_sets[facet_set].ravel())
    return np.array([(n, d, 0.0) for n in nodes for d in range(3)])


def test_tet10_cantilever_matches_timoshenko():
    require_tool("ccx")
    L, b, h, E, P = 100.0, 10.0, 10.0, 2000.0, 5.0
    mesh = box_tet_mesh(L, b, h, 20, 2, 2).quadratic()
    res = calculix.solve_calculix(mesh, {0: (E, 0.0)}, clamp(mesh, "xmin"),
                                  traction_forces(mesh, "xmax", (0, 0, -P / (b * h))))
    tip = np.unique(mesh.facet_sets["xmax"].ravel())
    I, G, kappa = b * h ** 3 / 12, E / 2, 5 / 6
    timoshenko = P * L ** 3 / (3 * E * I) + P * L / (kappa * G * b * h)
    assert -res.displacement[tip, 2].mean() == pytest.approx(timoshenko, rel=0.005)
    assert res.ccx_version.startswith("2.") and res.wall_time_s > 0
    # clamped root is at rest
    root = np.unique(mesh.facet_sets["xmin"].ravel())
    assert np.all(res.displacement[root] == 0)


def test_tet4_two_material_bar_in_tension_is_exact(tmp_path):
    """Two regions in series (E1, E2, nu = 0): the linear TET4 field is exact, u_tip = F L_i/(E_i A)."""
    require_tool("ccx")
    mesh = box_tet_mesh(40.0, 5.0, 4.0, 8, 2, 2)
    cen = mesh.points[mesh.cells].mean(axis=1)
    region = (cen[:, 0] > 20.0).astype(np.int64)
    mesh = type(mesh)(mesh.points, mesh.cells, region, {0: "a", 1: "b"}, {"a": "x", "b": "y"},
                      mesh.facet_sets)
    E1, E2, F, A = 1000.0, 250.0, 30.0, 20.0
    # root: x fixed everywhere, plus the minimum to stop rigid motion without lateral constraint
    root = np.unique(mesh.facet_sets["xmin"].ravel())
    pres = [(n, 0, 0.0) for n in root]
    o = root[np.argmin(np.linalg.norm(mesh.points[root], axis=1))]
    y_nb = root[np.argmin(np.linalg.norm(mesh.points[root] - [0, 5, 0], axis=1))]
    pres += [(o, 1, 0.0), (o, 2, 0.0), (y_nb, 2, 0.0)]
    res = calculix.solve_calculix(mesh, {0: (E1, 0.0), 1: (E2, 0.0)}, np.array(pres),
                                  traction_forces(mesh, "xmax", (F / A, 0, 0)), workdir=tmp_path)
    x = mesh.points[:, 0]
    exact = np.where(x <= 20, F * x / (E1 * A), F * 20 / (E1 * A) + F * (x - 20) / (E2 * A))
    assert np.max(np.abs(res.displacement[:, 0] - exact)) < 1e-6 * exact.max()
    assert (tmp_path / "job.inp").exists() and "C3D4" in (tmp_path / "job.inp").read_text()


def test_prescribed_displacement_dict_and_threads():
    """A prescribed end displacement: uniform strain, nu = 0.3 lateral contraction (free sides)."""
    require_tool("ccx")
    mesh = box_tet_mesh(10.0, 2.0, 2.0, 4, 1, 1).quadratic()
    x0 = np.unique(mesh.facet_sets["xmin"].ravel())
    x1 = np.unique(mesh.facet_sets["xmax"].ravel())
    pres = {(int(n), 0): 0.0 for n in x0} | {(int(n), 0): 0.1 for n in x1}
    o = x0[np.argmin(np.linalg.norm(mesh.points[x0], axis=1))]
    zn = x0[np.argmin(np.linalg.norm(mesh.points[x0] - [0, 0, 2], axis=1))]
    pres |= {(int(o), 1): 0.0, (int(o), 2): 0.0, (int(zn), 1): 0.0}
    res = calculix.solve_calculix(mesh, {0: (500.0, 0.3)}, pres, np.zeros((mesh.n_points, 3)),
                                  threads=2)
    u = res.displacement
    assert np.allclose(u[:, 0], 0.01 * mesh.points[:, 0], atol=1e-7)
    assert np.allclose(u[:, 1] - u[o, 1], -0.3 * 0.01 * (mesh.points[:, 1] - mesh.points[o, 1]), atol=1e-7)


def test_bad_inputs_and_missing_ccx(monkeypatch):
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    f = np.zeros((mesh.n_points, 3))
    with pytest.raises(ModelError, match="region"):
        calculix.write_inp("/dev/null", mesh, {5: (1.0, 0.3)}, [], f)
    with pytest.raises(ParameterError, match="nu"):
        calculix.write_inp("/dev/null", mesh, {0: (1.0, 0.5)}, [], f)
    with pytest.raises(ParameterError, match="forces"):
        calculix.write_inp("/dev/null", mesh, {0: (1.0, 0.3)}, [], f[:3])
    with pytest.raises(ParameterError, match="dof"):
        calculix.write_inp("/dev/null", mesh, {0: (1.0, 0.3)}, [(0, 3, 0.0)], f)
    monkeypatch.setattr(calculix.shutil, "which", lambda name: None)
    with pytest.raises(DesignlabError, match="ccx") as info:
        calculix.solve_calculix(mesh, {0: (1.0, 0.3)}, [], f)
    assert "\n" not in str(info.value)


def test_singular_model_is_a_model_error():
    require_tool("ccx")
    mesh = box_tet_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    f = np.zeros((mesh.n_points, 3))
    f[-1, 0] = 1.0
    with pytest.raises(ModelError, match="under-constrained"):
        calculix.solve_calculix(mesh, {0: (1.0, 0.3)}, [], f)
