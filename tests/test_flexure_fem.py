"""FEM 6x6 of a flexure: a clamped prism against beam theory, then the meshed Visiflex helix."""

import numpy as np
import pytest

from designlab.fem import get_material
from designlab.fem.flexure_fem import stiffness_6x6
from designlab.geometry.frames import transform, transform_stiffness
from designlab.geometry.mesh import box_tet_mesh


@pytest.fixture(scope="module")
def bar():
    a, L = 10.0, 100.0
    mesh = box_tet_mesh(a, a, L, 3, 3, 20, origin=(-a / 2, -a / 2, 0), material="steel").quadratic()
    return a, L, mesh, stiffness_6x6(mesh, "zmin", "zmax")


def test_prism_6x6_matches_beam_theory(bar):
    """Square steel bar 10 x 10 x 100 mm clamped at z=0, rigid tip: K at the bar centre."""
    a, L, mesh, fem = bar
    mat = get_material("steel")
    E, G = mat.E, mat.G
    I, A, J = a**4 / 12, a * a, 0.1406 * a**4          # J of a square section (Roark)
    k_lat = 1 / (L**3 / (12 * E * I) + L / (5 / 6 * G * A))  # Timoshenko, guided ends
    K = fem.K_centre
    assert K[0, 0] == pytest.approx(E * I / L, rel=0.03)
    assert K[1, 1] == pytest.approx(E * I / L, rel=0.03)
    assert K[2, 2] == pytest.approx(G * J / L, rel=0.03)
    assert K[3, 3] == pytest.approx(k_lat, rel=0.03)
    assert K[5, 5] == pytest.approx(E * A / L, rel=0.03)   # clamped ends stiffen by < 1 %
    # at the centre the couplings vanish (to 1 % of the geometric mean of the diagonal terms)
    scale = np.sqrt(np.outer(np.diag(K), np.diag(K)))
    off = np.abs(K - np.diag(np.diag(K))) / scale
    assert off.max() < 0.01
    assert fem.asymmetry < 1e-9
    np.testing.assert_allclose(fem.centre, [0, 0, L / 2], atol=1e-9)


def test_tip_frame_couplings_follow_the_adjoint(bar):
    a, L, mesh, fem = bar
    K_tip = fem.K
    np.testing.assert_allclose(fem.master, [0, 0, L], atol=1e-9)
    K_from_centre = transform_stiffness(fem.K_centre, transform(translation=(0, 0, -L / 2)))
    np.testing.assert_allclose(K_tip, K_from_centre, rtol=1e-9, atol=1e-6 * np.abs(K_tip).max())
    # Euler-Bernoulli tip: k_wy_vx = -L/2 * k_vx(centre) ... sign: m_y from v_x at the tip
    assert K_tip[1, 3] == pytest.approx(-L / 2 * fem.K_centre[3, 3], rel=0.02)


def test_missing_sets_raise_model_error(bar):
    from designlab.errors import ModelError

    a, L, mesh, fem = bar
    with pytest.raises(ModelError, match="does not exist"):
        stiffness_6x6(mesh, "flexure_base", "zmax")
