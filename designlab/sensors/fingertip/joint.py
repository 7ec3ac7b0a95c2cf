"""Studies of the fingertip's bolted joint (seed 001): how much of a load's moment about the ball
reaches the sensors (:func:`moment_sensitivity`), whether the fingertip closes its gap to the
base (:func:`gap_closure`) and how the bolt head's seat under the cap changes that
(:func:`bolt_head_joint`). Linearised at the preload, for the paper's compressed-sensor change.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from designlab.sensors.fingertip.contact import CondensedFingertip, contact_laws
from designlab.sensors.fingertip.model import (
    FSS015_STIFFNESS_N_PER_MM,
    ContactSettings,
    wrench_at_ball,
)
from designlab.sensors.fingertip.paper_readings import PAPER
from designlab.sensors.protocols import HangingWeightTest


def moment_sensitivity(part, cf: CondensedFingertip, settings: ContactSettings | None = None,
                       bolt_minor_diameter: float = 2.0) -> dict[str, Any]:
    """How much a load's moment about the ball reaches the sensors, linearised at the preload:
    the most loaded sensor's force per N of lateral force f_x (``per_N``) and per N mm of
    moment m_y (``per_Nmm``), their ratio ``rho`` per mm of arm (> 0: a lateral load's moment
    adds to its force), for the condensed FEM and for an independent hand estimate (rigid ball;
    three springs k_n along the sensor axes, whose lines pass through the ball centre; the bolt
    an Euler-Bernoulli steel beam clamped under its head and fixed in the ball), frictionless
    and with every contact stuck (Mindlin k_t; sensors rigid sideways). ``change_h9_to_h1_pct``
    is the compressed-sensor change the ratio alone gives on the Table II arms. Also: the
    rotational restraint of the ball (about x and y, no sideways coupling, frictionless FEM) that
    would give the paper's 33.9 %, and the axial path (share of P_z through the sensors)."""
    from designlab.fem.beam import beam_stiffness, circular_section
    from designlab.fem.materials import get_material
    from designlab.fem.model import skew
    from designlab.geometry.fingertip import TABLE_II_HEIGHTS

    settings = settings or ContactSettings()
    steel = get_material("steel")
    law = contact_laws(part, settings, cf.k_sensor)[0]
    N0 = settings.bolt_preload_N / (3 * float(cf.axes[0, 2]))
    kn = float(law.normal(law.approach(N0))[1])
    kt = float(law.kt(np.array(N0))[0])
    axes = cf.axes
    zh, a = part.cap_z[0], part.ball_radius
    Kb = beam_stiffness(np.array([0, 0, zh]), np.array([0, 0, -a]), steel.E, steel.G,
                        **circular_section(bolt_minor_diameter))[6:, 6:]
    T = np.block([[np.eye(3), -skew(np.array([0, 0, -a]))], [np.zeros((3, 3)), np.eye(3)]])
    K_hand = T.T @ Kb @ T                               # the bolt's stiffness at the ball centre
    h1, h9 = TABLE_II_HEIGHTS[0], TABLE_II_HEIGHTS[-1]

    def summary(R):
        k = int(np.argmax(np.abs(R[0])))
        rho = float(R[1][k] / R[0][k])
        return {"per_N": float(abs(R[0][k])), "per_Nmm": float(abs(R[1][k])), "rho_per_mm": rho,
                "change_h9_to_h1_pct": 100.0 * ((1 + rho * h1) / (1 + rho * h9) - 1)}

    def fem(stuck: bool, k_rot: float = 0.0):
        K = np.linalg.inv(cf.C)
        K[3, 3] += k_rot
        K[4, 4] += k_rot
        for k in range(3):
            K += kn * np.outer(cf.L[k, 0], cf.L[k, 0])
            if stuck:
                K += kt * (np.outer(cf.L[k, 1], cf.L[k, 1]) + np.outer(cf.L[k, 2], cf.L[k, 2]))
        U = np.linalg.solve(K, cf.f_wrench.T)
        return np.array([[-kn * cf.L[k, 0] @ U[:, c] for k in range(3)] for c in (0, 4)])

    out: dict[str, Any] = {"k_n_N_per_mm": kn, "k_t_N_per_mm": kt}
    for label, stuck in (("frictionless", False), ("stuck", True)):
        K = K_hand.copy()
        for k, n in enumerate(axes):
            tang = [(t, kt) for t in np.linalg.svd(n[None])[2][1:]] if stuck else []
            for d, kk in [(n, kn), *tang]:
                row = np.r_[d, np.cross(cf.contacts[k], d)]
                K += kk * np.outer(row, row)
        U = np.linalg.solve(K, np.eye(6))
        hand = np.array([[-kn * axes[k] @ U[:3, c] for k in range(3)] for c in (0, 4)])
        out[label] = {"hand": summary(hand), "fem": summary(fem(stuck))}
    # rho that gives the paper's change: (1 + rho h1) = (1 + c) (1 + rho h9)
    c = PAPER["compressed_change_h9_to_h1_pct"] / 100.0
    rho_paper = c / (h1 - (1 + c) * h9)
    lo, hi = 0.0, 1e9
    if summary(fem(False))["rho_per_mm"] <= rho_paper:
        hi = 0.0                                        # no restraint needed
    else:
        for _ in range(200):
            mid = np.sqrt(max(lo, 1.0) * hi)
            lo, hi = (mid, hi) if summary(fem(False, mid))["rho_per_mm"] > rho_paper else (lo, mid)
    bolt_rot = 1.0 / np.linalg.inv(K_hand)[4, 4]
    out["paper_rho_per_mm"] = rho_paper
    out["rotational_restraint_for_paper_N_mm_per_rad"] = float(hi)
    out["bolt_rotational_stiffness_at_ball_centre_N_mm_per_rad"] = float(bolt_rot)
    out["axial_share_through_sensors"] = float(abs(axes[:, 2] @ (-cf.linear_unit[2])))
    out["bolt_and_cap_axial_stiffness_N_per_mm"] = float(1.0 / cf.C[2, 2])
    out["bolt_alone_axial_stiffness_N_per_mm"] = float(K_hand[2, 2])
    out["sensors_vertical_stiffness_N_per_mm"] = float(kn * np.sum(axes[:, 2] ** 2))
    out["gap_closure"] = gap_closure(part, cf, kn, kt)
    return out


def gap_closure(part, cf: CondensedFingertip, kn: float, kt: float) -> dict[str, Any]:
    """Does the fingertip touch the base across its ``gap`` under the heaviest Table II weight
    at h1 (a candidate for the rotational restraint the paper's 33.9 % needs)? The fingertip is
    rigid on the ball: the rim of its underside (radius ``outer_radius``, at the gap's top)
    moves by the ball's translation plus rotation, linearised at the preload (frictionless and
    every contact stuck). ``closure_mm`` is the rim's largest downward motion plus the largest
    well-floor motion (a bound for the base's own deflection); the gap closes when it reaches
    ``gap_mm``. Units mm, N."""
    from designlab.geometry.fingertip import TABLE_II_HEIGHTS
    from designlab.sensors.protocols import G_ACC

    test = HangingWeightTest()
    F = (max(test.weights_g) + test.tray_g) * 1e-3 * G_ACC
    w = wrench_at_ball(np.array([0.0, 0.0, TABLE_II_HEIGHTS[0]]), np.array([F, 0.0, 0.0]))
    R = part.outer_radius
    out: dict[str, Any] = {"load_N": F, "arm_mm": TABLE_II_HEIGHTS[0], "rim_radius_mm": R,
                           "gap_mm": part.gap}
    for label, stuck in (("frictionless", False), ("stuck", True)):
        K = np.linalg.inv(cf.C)
        for k in range(3):
            K += kn * np.outer(cf.L[k, 0], cf.L[k, 0])
            if stuck:
                K += kt * (np.outer(cf.L[k, 1], cf.L[k, 1]) + np.outer(cf.L[k, 2], cf.L[k, 2]))
        u = np.linalg.solve(K, cf.f_wrench.T @ w)
        rim = R * float(np.hypot(u[3], u[4])) - float(u[2])   # largest downward rim motion
        wells = float(np.max(np.linalg.norm(u[6:].reshape(3, 6)[:, :3], axis=1)))
        out[label] = {"ball_rotation_rad": float(np.hypot(u[3], u[4])),
                      "rim_down_mm": rim, "closure_mm": rim + wells,
                      "fraction_of_gap": (rim + wells) / part.gap}
    out["closes"] = any(out[k]["closure_mm"] >= part.gap for k in ("frictionless", "stuck"))
    return out


def bolt_head_joint(part, settings: ContactSettings | None = None,
                    k_sensor: float = FSS015_STIFFNESS_N_PER_MM,
                    bolt_minor_diameter: float = 2.0) -> dict[str, Any]:
    """The bolt head's seat under the cap as a candidate for the paper's small moment
    sensitivity. Hand estimate of :func:`moment_sensitivity` (rigid ball, three frictionless
    springs through its centre, the bolt an Euler-Bernoulli steel beam from its head to the
    ball), with the head held three ways: ``bonded`` (fixed, as the FEM couples it to the cap),
    ``pinned`` (held sideways, free to tilt: the head tipped off its seat) and ``sliding`` (free
    sideways, held in tilt: the head slipping on the cap). Each: compressed sensor per N of
    lateral force and per N mm of moment, ``rho``, and the change h9 -> h1 it gives
    (``relative_to_first_span``, and ``percent_of_applied_force``: per N mm x (h1 - h9)).
    ``demand``: with the head bonded, the shear and moment the head carries under the heaviest
    Table II weight at h1 and at h9, the friction coefficient the head needs to stay put (shear /
    bolt preload) and the moment at which its preloaded annulus (head diameter on the bolt
    hole) starts to lift on one side, ``T (a^2 + b^2) / (4 a)`` (linear pressure, rigid head).
    Units N, mm."""
    from designlab.fem.beam import beam_stiffness, circular_section
    from designlab.fem.materials import get_material
    from designlab.fem.model import skew
    from designlab.geometry.fingertip import TABLE_II_HEIGHTS
    from designlab.sensors.protocols import G_ACC

    settings = settings or ContactSettings()
    steel = get_material("steel")
    law = contact_laws(part, settings, k_sensor)[0]
    axes, contacts = part.sensor_axes()
    N0 = settings.bolt_preload_N / (3 * float(axes[0, 2]))
    kn = float(law.normal(law.approach(N0))[1])
    zh, a = part.cap_z[0], part.ball_radius
    Kb = beam_stiffness(np.array([0, 0, zh]), np.array([0, 0, -a]), steel.E, steel.G,
                        **circular_section(bolt_minor_diameter))
    T = np.block([[np.eye(3), -skew(np.array([0, 0, -a]))], [np.zeros((3, 3)), np.eye(3)]])
    K_s = np.zeros((6, 6))
    for n in axes:
        K_s += kn * np.outer(np.r_[n, 0, 0, 0], np.r_[n, 0, 0, 0])
    h1, h9 = TABLE_II_HEIGHTS[0], TABLE_II_HEIGHTS[-1]
    big = 1e3 * float(np.abs(Kb).max())
    out: dict[str, Any] = {"k_n_N_per_mm": kn}
    for label, (k_side, k_tilt) in (("bonded", (big, big)), ("pinned", (big, 0.0)),
                                    ("sliding", (0.0, big))):
        K = Kb.copy()
        K[np.arange(6), np.arange(6)] += [k_side, k_side, big, k_tilt, k_tilt, big]
        Kc = K[6:, 6:] - K[6:, :6] @ np.linalg.solve(K[:6, :6], K[:6, 6:])
        U = np.linalg.solve(T.T @ Kc @ T + K_s, np.eye(6))
        R = np.array([[-kn * axes[k] @ U[:3, c] for k in range(3)] for c in (0, 4)])
        k = int(np.argmax(np.abs(R[0])))
        rho = float(R[1][k] / R[0][k])
        out[label] = {"per_N": float(abs(R[0][k])), "per_Nmm": float(abs(R[1][k])),
                      "rho_per_mm": rho,
                      "relative_to_first_span_pct": 100.0 * ((1 + rho * h1) / (1 + rho * h9) - 1),
                      "percent_of_applied_force": 100.0 * float(abs(R[1][k])) * (h1 - h9)}
    test = HangingWeightTest()
    F = (max(test.weights_g) + test.tray_g) * 1e-3 * G_ACC
    Kc = Kb[6:, 6:]
    U = np.linalg.solve(T.T @ Kc @ T + K_s, np.eye(6))
    tension = settings.bolt_preload_N
    ah, bh = part.head_diameter / 2, part.bolt_diameter / 2
    m_lift = tension * (ah ** 2 + bh ** 2) / (4 * ah)
    demand = {}
    for name, arm in (("h1", h1), ("h9", h9)):
        w = wrench_at_ball(np.array([0.0, 0.0, arm]), np.array([F, 0.0, 0.0]))
        u_entry = T @ (U @ w)
        f_head = Kb[:6, 6:] @ u_entry                 # the head's end force (head held)
        shear = float(np.hypot(f_head[0], f_head[1]))
        moment = float(np.hypot(f_head[3], f_head[4]))
        demand[name] = {"arm_mm": arm, "load_N": F, "head_shear_N": shear,
                        "head_moment_N_mm": moment,
                        "friction_needed_to_stay": shear / tension if tension > 0 else None,
                        "lifts_on_one_side": bool(moment > m_lift)}
    out["demand"] = demand
    out["bolt_preload_N"] = tension
    out["head_lift_moment_N_mm"] = m_lift
    return out

