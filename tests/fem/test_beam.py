import numpy as np

from designlab.fem.beam import beam_stiffness, circular_section


def _cantilever_tip(K, load):
    free = np.arange(6, 12)
    u = np.linalg.solve(K[np.ix_(free, free)], load)
    return u


def test_cantilever_closed_forms_any_orientation():
    E, G, L = 210000.0, 80769.0, 12.0
    s = circular_section(2.0)
    rng = np.random.default_rng(3)
    for _ in range(3):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        K = beam_stiffness(np.zeros(3), L * d, E, G, **s)
        assert np.allclose(K, K.T)
        # transverse load perpendicular to the beam
        p = np.cross(d, [0.3, 0.5, 0.8])
        p /= np.linalg.norm(p)
        u = _cantilever_tip(K, np.r_[p, 0, 0, 0])
        defl = L ** 3 / (3 * E * s["Iy"]) + L / (G * s["As"])   # bending + shear
        assert abs(u[:3] @ p - defl) / defl < 1e-9
        u = _cantilever_tip(K, np.r_[d, 0, 0, 0])
        assert abs(u[:3] @ d - L / (E * s["A"])) < 1e-12
        u = _cantilever_tip(K, np.r_[0, 0, 0, d])
        assert abs(u[3:] @ d - L / (G * s["J"])) < 1e-12


def test_rigid_body_motions_are_free():
    K = beam_stiffness([1, 2, 3], [2, 5, 4], 1000.0, 400.0, **circular_section(1.0))
    x = np.array([[1.0, 2, 3], [2, 5, 4]])
    w = np.array([0.1, -0.2, 0.3])
    u = np.concatenate([np.r_[np.cross(w, xi), w] for xi in x])
    assert np.abs(K @ u).max() < 1e-9 * np.abs(K).max()
    assert np.linalg.matrix_rank(K, tol=1e-8 * np.abs(K).max()) == 6
