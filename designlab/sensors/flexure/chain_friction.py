"""Coulomb friction at the beam chain's coil and seat contacts: its bounds at the working
load (:func:`friction_bounds`), the frictional 6x6 (:func:`friction_stiffness`) and the 6x6 fitted
to hysteresis loops (:func:`loop_stiffness`).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from designlab.errors import ParameterError
from designlab.frames import transform, transform_stiffness
from designlab.sensors.flexure.active_set import PERM
from designlab.sensors.flexure.beam_chain import Chain, ChainResult, condensed_6x6
from designlab.sensors.flexure.chain_geometry import ChainSettings, as_built, mindlin_ratio
from designlab.sensors.flexure.spring import HelicalSpring, check_working_load, to_si


def _tip_friction_band(chain: "Chain", closed: np.ndarray, fn: np.ndarray, mu: float) -> dict:
    """Half-width of the friction band at the tip master, per master axis: the tip moved along
    the axis (frictionless motion, normal forces of the reference state), every closed contact
    sliding against its relative tangential motion with ``mu f_n``; the master's reaction to
    those forces along the same axis (N for u_x, u_y, u_z; N mm for th_x, th_y, th_z). A loop
    along that axis deviates from its median by this much."""
    A = (chain.Kq + chain.N.T @ sp.diags(chain.kn * closed) @ chain.N).tocsc()
    m = chain.m
    f = np.setdiff1d(np.arange(chain.nq), m)
    lu = spla.splu(A[f][:, f].tocsc())
    Afm = A[f][:, m].toarray()
    out = {}
    for j, name in enumerate(("u_x", "u_y", "u_z", "th_x", "th_y", "th_z")):
        q = np.zeros(chain.nq)
        q[m[j]] = 1.0
        q[f] = lu.solve(-Afm[:, j])
        V = (chain.Rt @ q).reshape(-1, 2)
        nv = np.linalg.norm(V, axis=1)
        slide = closed & (nv > 0)
        tr = np.zeros_like(V)
        tr[slide] = -mu * fn[slide, None] * V[slide] / nv[slide, None]
        g = chain.Rt.T @ tr.ravel()
        reaction = Afm.T @ lu.solve(g[f]) - g[m]         # what holds the master against them
        out[name] = float(reaction[j])
    return out


def friction_bounds(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                    mu: float = 0.3) -> dict:
    """What Coulomb friction at the closed coil and seat contacts can do to the chain's 6x6 at
    the working load, as two bounds (the closed contacts of the frictionless 10 N state held;
    :func:`friction_stiffness` solves the frictional path between them):

    * **slip** (gross sliding, any perturbation larger than ``mu f_n / k_t``): a sliding contact
      carries a constant ``mu f_n`` whose tangent is zero, so the tangent 6x6 is the
      frictionless one; friction shows as a force band (hysteresis), not as stiffness;
    * **stick** (perturbations below that): every closed contact holds tangentially with the
      Mindlin ratio ``k_t = k_n 2 (1 - nu) / (2 - nu)`` (Johnson 1985, sec. 7.2), a stiffness
      independent of ``mu``.

    Returns the two 6x6 at the spring centre (N mm/rad, N/mm; SI too), the normal forces, the
    band ``mu sum f_n`` at the contacts, its half-width at the tip per master axis
    (``tip_friction_band``: the hysteresis a loop along that axis shows) and the largest stick
    displacement ``mu f_n / k_t``. ``mu``: see :data:`MU_STEEL` (no value is published for
    the spring)."""
    if not (isinstance(mu, (int, float)) and 0 <= mu <= 2):
        raise ParameterError("mu", mu, "a friction coefficient 0 <= mu <= 2")
    settings = settings or ChainSettings()
    if settings.working_load_N <= 0 or not settings.contact:
        raise ParameterError("working_load_N", settings.working_load_N,
                             "> 0 with contact=True (friction needs a preloaded contact)")
    check_working_load(spring, settings.working_load_N)
    chain = Chain(as_built(spring), settings)
    pre = chain.solve(f_master=np.r_[0.0, 0.0, -settings.working_load_N, 0.0, 0.0, 0.0])
    closed, fn = pre["closed"], pre["f_n"]
    nu = chain.coil.E / (2 * chain.coil.G) - 1
    kt = np.where(closed, chain.kn * mindlin_ratio(nu), 0.0)
    K_slip = condensed_6x6(chain, closed)
    K_stick = condensed_6x6(chain, closed, kt)
    K_pert, _ = chain.stiffness(ref=pre)
    band = _tip_friction_band(chain, closed, fn, mu)
    centre = np.array([0.0, 0.0, chain.coil.length / 2])
    move = transform(translation=chain.master - centre)
    at = {k: transform_stiffness(v, move) for k, v in
          (("slip", K_slip), ("stick", K_stick), ("perturbation", K_pert))}
    kinds = np.array([c.kind for c in chain.contacts])
    with np.errstate(divide="ignore", invalid="ignore"):
        stick_disp = np.where(closed, mu * fn / np.where(kt > 0, kt, 1.0), 0.0)
    return {"K_slip_centre": at["slip"], "K_stick_centre": at["stick"],
            "K_perturbation_centre": at["perturbation"],
            "K_slip_centre_si": to_si(at["slip"]), "K_stick_centre_si": to_si(at["stick"]),
            "closed": {"coil": int(np.count_nonzero(closed & (kinds == "coil"))),
                       "seat": int(np.count_nonzero(closed & (kinds == "seat")))},
            "normal_force_N": {"coil": float(fn[kinds == "coil"].sum()),
                               "seat": float(fn[kinds == "seat"].sum())},
            "friction_band_N": float(mu * fn.sum()), "mu": float(mu),
            "max_stick_displacement_mm": float(stick_disp.max()) if closed.any() else 0.0,
            "tip_friction_band": band,
            "k_t_over_k_n": float(2 * (1 - nu) / (2 - nu))}


def _friction_setup(spring: HelicalSpring, settings: ChainSettings | None, mu: float | None):
    settings = settings or ChainSettings()
    mu = settings.mu if mu is None else mu
    if not (isinstance(mu, (int, float)) and 0 <= mu <= 1e6):
        raise ParameterError("mu", mu, "a friction coefficient 0 <= mu <= 1e6")
    if not settings.contact:
        raise ParameterError("contact", settings.contact, "True (friction acts at the contacts)")
    if settings.working_load_N > 0:
        check_working_load(spring, settings.working_load_N)
    chain = Chain(as_built(spring), settings)
    nu = chain.coil.E / (2 * chain.coil.G) - 1
    return settings, float(mu), chain, chain.kn * mindlin_ratio(nu)


def friction_stiffness(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                       mu: float | None = None, amplitude: float = 1.0,
                       preload_steps: int = 10) -> ChainResult:
    """The chain's 6x6 with Coulomb friction at the coil and seat contacts, unloaded and at the
    axial working load: the working load applied in ``preload_steps`` force increments from rest
    (each contact's traction follows its slip history), then symmetric perturbations of the tip
    master (``amplitude`` x the settings' 0.02 mm / 2 mrad), each solved incrementally from that
    state (:meth:`ActiveSet.solve_friction`: return map, tangential penalty
    ``k_t = k_n 2 (1 - nu) / (2 - nu)``). ``mu``: default ``settings.mu`` (0.3, dry steel on
    steel). ``mu = 0`` is :func:`chain_stiffness`; ``mu -> inf`` the stuck bound of
    :func:`friction_bounds`. With ``0 < mu < inf`` the result is a secant: it depends on the
    amplitude. ``K`` and ``K_loaded`` are symmetrised; the raw ones and their asymmetry are in
    ``info``."""
    t0 = time.perf_counter()
    settings, mu, chain, kt = _friction_setup(spring, settings, mu)
    K_raw, paths = chain.friction_stiffness(mu, kt, amplitude=amplitude)
    K_loaded = K_l_raw = None
    info_l = None
    if settings.working_load_N > 0:
        pre = chain.solve_friction(mu, kt, f_master=np.r_[0.0, 0.0, -settings.working_load_N,
                                                          0.0, 0.0, 0.0], steps=preload_steps)
        K_l_raw, paths_l = chain.friction_stiffness(mu, kt, ref=pre, amplitude=amplitude)
        K_loaded = (K_l_raw + K_l_raw.T) / 2
        c = pre["closed"]
        info_l = {"axial_deflection_mm": float(-pre["q"][chain.m][2]),
                  "closed_contacts": int(np.count_nonzero(c)),
                  "stuck_contacts": int(np.count_nonzero(pre["stick"])),
                  "normal_force_N": float(pre["f_n"].sum()),
                  "traction_over_limit": [float(x) for x in
                                          np.linalg.norm(pre["t"][c], axis=1)
                                          / np.maximum(mu * pre["f_n"][c], 1e-300)],
                  "paths_closed_stuck": paths_l,
                  "asymmetry": float(np.abs(K_l_raw - K_l_raw.T).max() / np.abs(K_l_raw).max()),
                  "K_raw": K_l_raw.tolist()}
    info = {"mu": mu, "k_t_over_k_n": float(kt[0] / chain.kn[0]) if len(kt) else None,
            "amplitude_mm_rad": [amplitude * settings.perturbation_mm,
                                 amplitude * settings.perturbation_rad],
            "paths_closed_stuck": paths,
            "asymmetry": float(np.abs(K_raw - K_raw.T).max() / np.abs(K_raw).max()),
            "K_raw": K_raw.tolist(), "working_load": info_l, "contacts": len(chain.contacts),
            "seconds": time.perf_counter() - t0}
    return ChainResult((K_raw + K_raw.T) / 2, K_loaded, chain.master,
                       np.array([0, 0, chain.coil.length / 2]), chain.coil, settings, info, chain)


def loop_stiffness(spring: HelicalSpring, settings: ChainSettings | None = None, *,
                   mu: float | None = None, amplitude_mm: float = 1.0,
                   amplitude_rad: float = 0.05, points: int = 8, preload_N: float = 0.0) -> dict:
    """The 6x6 as seed 002 fitted it: hysteresis loops about the relaxed configuration (Sec.
    V-B: each axis cycled between its largest positive and negative displacement), ``F = K X``
    by least squares. Per master axis (at the tip seat, global axes): 0 -> +A -> -A -> +A in
    ``points`` increments per quarter, each by :meth:`ActiveSet.solve_friction`; the last full
    cycle (+A -> -A -> +A) gives the column ``K[:, j] = sum(F x) / sum(x^2)`` (no intercept, as
    the paper's fit) and the loop's half-width along the axis (half the largest difference of
    the two branches at the same displacement). The paper's 21-entry fit is symmetric: ``K`` is symmetrised, the
    raw columns are ``K_raw``. ``A``: ``amplitude_mm`` for translations, ``amplitude_rad`` for
    rotations (the paper does not print its loop amplitudes: its random poses span 1 mm in x, y
    and 4 mm in z). ``preload_N``: an axial load held before the loops (0: relaxed).
    Geometrically linear, the contacts' normal forces follow the motion."""
    t0 = time.perf_counter()
    settings, mu, chain, kt = _friction_setup(spring, settings, mu)
    if not (amplitude_mm > 0 and amplitude_rad > 0 and isinstance(points, int) and points >= 2):
        raise ParameterError("amplitude", (amplitude_mm, amplitude_rad, points),
                             "amplitudes > 0 and points >= 2")
    ref = chain.rest_state()
    if preload_N > 0:
        ref = chain.solve_friction(mu, kt, f_master=np.r_[0.0, 0.0, -preload_N, 0, 0, 0],
                                   steps=10)
    q0 = ref["q"][chain.m]
    amp = np.r_[[amplitude_mm] * 3, [amplitude_rad] * 3]
    path = np.concatenate([np.linspace(0, 1, points + 1)[1:], np.linspace(1, -1, 2 * points + 1)[1:],
                           np.linspace(-1, 1, 2 * points + 1)[1:]])
    Kq = np.zeros((6, 6))
    half = np.zeros(6)
    loops = []
    for j in range(6):
        st, xs, Fs = ref, [], []
        for a in path:
            st = chain.solve_friction(mu, kt, q_master=q0 + a * amp[j] * np.eye(6)[j], ref=st)
            xs.append(a * amp[j])
            Fs.append(st["reaction"] - ref["reaction"])
        xs, Fs = np.array(xs[points:]), np.array(Fs[points:])          # the last full cycle
        Kq[:, j] = Fs.T @ xs / (xs @ xs)
        # the two branches at the same x: descending k <-> ascending 2 points - 2 - k
        k = np.arange(2 * points - 1)
        half[j] = float(np.abs(Fs[k, j] - Fs[4 * points - 2 - k, j]).max() / 2)
        loops.append({"x": xs.tolist(), "F": Fs[:, j].tolist()})
    K_raw = Kq[np.ix_(PERM, PERM)]
    return {"K": (K_raw + K_raw.T) / 2, "K_raw": K_raw, "master": chain.master,
            "centre": np.array([0.0, 0.0, chain.coil.length / 2]), "mu": mu,
            "half_width": dict(zip(("u_x", "u_y", "u_z", "th_x", "th_y", "th_z"), half.tolist())),
            "amplitude_mm_rad": [amplitude_mm, amplitude_rad], "preload_N": preload_N,
            "loops": loops, "seconds": time.perf_counter() - t0}
