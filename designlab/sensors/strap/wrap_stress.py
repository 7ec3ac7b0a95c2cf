"""Stress of the strap's wrap: the uniaxial membrane stress of its initial strain in closed
form, per body, and the warnings of a low safety factor."""

from __future__ import annotations

from typing import Any


def wrap_stress(region_materials, mesh, eps0: float) -> dict[str, Any]:
    """Stress of the wrap's initial strain ``eps0`` in closed form: a uniaxial membrane stress
    along the band, the same strain in every body, the incompressible neo-Hookean stand-in law
    of :func:`designlab.sensors.strap.prestrain.neo_hooke` (``E eps0`` at small strain) with each
    material's instantaneous modulus (when the strap is put on; it relaxes to the long-time
    value while worn). Uniaxial: von Mises = |sigma|. The FEM carries no prestress (linear
    increments on the worn state, docs/models/strap_model.md): under a load the von Mises stress is at
    most this plus the load case's (von Mises is a seminorm: triangle inequality)."""
    from designlab.fem.stress import WARN_SAFETY_FACTOR, relaxed
    from designlab.sensors.strap.prestrain import neo_hooke

    e = max(float(eps0), 0.0)
    factor = neo_hooke(e)["stress_over_linear"]
    bodies, worst = {}, None
    for rid, m in sorted(region_materials.items()):
        body = mesh.region_names.get(rid, str(rid))
        sigma = float(m.E * e * factor)
        sf = (None if m.strength is None else (m.strength / sigma if sigma > 0 else float("inf")))
        bodies[body] = {"material": m.name, "max_von_mises_MPa": sigma,
                        "long_time_MPa": float(relaxed(m).E * e * factor),
                        "linear_E_eps0_MPa": float(m.E * e),
                        "strength_MPa": m.strength, "safety_factor": sf}
        if sf is not None and (worst is None or sf < worst["safety_factor"]):
            worst = {"body": body, **bodies[body]}
    return {"initial_strain": float(eps0),
            "method": "uniaxial membrane stress of the wrap's initial strain (closed form, "
                      "neo-Hookean stand-in, instantaneous modulus); under load the von Mises "
                      "stress is at most this plus the load case's",
            "bodies": bodies, "min_safety_factor": None if worst is None else
            worst["safety_factor"], "critical": worst, "warn_below": WARN_SAFETY_FACTOR}


def wrap_stress_warnings(ws: dict[str, Any]) -> list[str]:
    """One line per body whose wrap safety factor is below the warning level."""
    out = []
    for body, e in ws["bodies"].items():
        sf = e["safety_factor"]
        if sf is not None and sf < ws["warn_below"]:
            out.append(f"safety factor {sf:.2g} < {ws['warn_below']:g} in {body} "
                       f"({e['material']}) from the wrap alone (initial strain "
                       f"{ws['initial_strain']:.3g}): {e['max_von_mises_MPa']:.3g} MPa vs "
                       f"strength {e['strength_MPa']:.3g} MPa")
    return out
