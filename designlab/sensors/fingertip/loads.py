"""The seed 001 fingertip's load cases for stress: every load point of the protocol (G1 and G2
groups) at every rotation of the test, at the largest hanging weight.

The FEM stage keeps the displacement per unit wrench at the ball (``U_unit``, long time) in the
FEM cache (:func:`designlab.sensors.fingertip.model.fem_key`); a load case is the wrench of its load
point combined with those six fields (exact for the linear model). When the cache no longer
holds the stage, the one displacement of the result (first load point, rotation 0) is used.
"""

from __future__ import annotations

import numpy as np

from designlab.sensors.sensor import LoadCase


def load_cases(part, protocol, settings, result, cache=None) -> list[LoadCase]:
    from designlab.fem.cache import FEMCache
    from designlab.sensors.fingertip.model import fem_key, wrench_at_ball

    if getattr(result, "mesh", None) is None:
        return []
    F = float(np.max(result.load))
    fem = None
    try:
        fem = (cache or FEMCache()).get(fem_key(part, protocol, settings))
    except (TypeError, KeyError, ValueError):   # a changed key layout: the result's one field
        fem = None
    groups = [("G1", n) for n in protocol.g1_locations] + [("G2", n) for n in protocol.g2_locations]
    if fem is None or "U_unit" not in fem or fem["U_unit"].shape[1] != result.mesh.n_points:
        if result.displacement is None:
            return []
        info = result.report.get("vtu_load", {})
        loc = info.get("location", "?")
        p, d = part.load_points(settings.rotations_deg[0]).get(loc, (None, None))
        return [LoadCase(f"{loc} @ {settings.rotations_deg[0]:g} deg",
                         f"{F:.3g} N at load point {loc}, rotation "
                         f"{settings.rotations_deg[0]:g} deg", result.displacement, p, d, F)]
    U = np.asarray(fem["U_unit"])
    out = []
    for rot in settings.rotations_deg:
        pts = part.load_points(rot)
        for group, name in groups:
            if name not in pts:
                continue
            p, d = pts[name]
            w = wrench_at_ball(p, d) * F
            u = np.einsum("c,cpk->pk", w, U)
            dd = ", ".join(f"{x:+.2f}" for x in d)
            out.append(LoadCase(f"{name} @ {rot:g} deg",
                                f"{F:.3g} N at load point {name} ({group}) along ({dd}), "
                                f"fingertip rotated {rot:g} deg", u, np.asarray(p),
                                np.asarray(d), F, vtu=rot == settings.rotations_deg[0]))
    return out
