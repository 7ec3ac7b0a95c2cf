"""The load cell of load_cell.py against beam theory on a sequence of meshes: the gauge's strain
per newton next to Euler-Bernoulli's, and the tip deflection per newton next to Timoshenko's,
with the mesh error bar (the relative change from the mesh 1.5 times coarser) at each level.

    python examples/sensors/load_cell_convergence.py [EDGE_MM ...]

Default edge lengths 4.5, 3, 2, 1.333 and 0.889 mm (each 1.5 times finer than the last). The
readings are the instantaneous elastic ones (the viscoelastic march off), so the beam theory
takes the material's instantaneous modulus. Prints a Markdown table.
"""

from __future__ import annotations

import sys
from pathlib import Path

import designlab as dl
from designlab.fem.materials import get_material
from designlab.sensors.generic.virtual import run, settings_class
from designlab.sensors.registry import load_class

LoadCell = load_class(str(Path(__file__).with_name("load_cell.py")))
LEVELS = (4.5, 3.0, 2.0, 4.0 / 3.0, 8.0 / 9.0)


class ProbedLoadCell(LoadCell):
    """The load cell with the mean vertical motion of its free end face read as well."""

    name = "load_cell_probed"

    def transducers(self):
        end = dl.Face("beam", normal=(1, 0, 0))
        return [*super().transducers(), dl.DisplacementProbe("end", end, (0, 0, 1), noise=1e-3)]


def beam_theory(cell) -> dict[str, float]:
    """Closed forms for a tip load P at ``load_at`` of a clamped rectangular beam: the surface
    bending strain per newton at the gauge (Euler-Bernoulli and Timoshenko alike,
    6 (a - x) / (E w t^2)), and the deflection per newton of the free end (beyond the load the
    beam stays straight at the load point's slope): Euler-Bernoulli a^3/(3EI) + a^2 (L - a)/(2EI),
    Timoshenko adds a/(kGA) with Cowper's k = 10 (1 + nu)/(12 + 11 nu)."""
    m = get_material(cell.material)
    a, x, L = cell.load_at, cell.gauge_at, cell.length
    w, t = cell.width, cell.thickness
    EI, A = m.E * w * t ** 3 / 12.0, w * t
    k = 10.0 * (1.0 + m.nu) / (12.0 + 11.0 * m.nu)
    eb = a ** 3 / (3.0 * EI) + a ** 2 * (L - a) / (2.0 * EI)
    return {"strain_per_N": 6.0 * (a - x) / (m.E * w * t ** 2), "deflection_eb_per_N": eb,
            "deflection_timoshenko_per_N": eb + a / (k * m.G * A), "slenderness": a / t}


def measure(cell, edge_mm: float) -> dict[str, float]:
    """The gauge's strain and the end's deflection per newton of the elastic virtual test on a
    mesh of edge ``edge_mm``, and the mesh's DOF."""
    res = run(cell, settings=settings_class(type(cell))(edge_length=edge_mm, viscoelastic=False))
    sens = res.report["sensitivity"]
    gauge = next(t for t in cell.transducers() if isinstance(t, dl.StrainGauge))
    # the load hangs downwards (Fz < 0): the top face stretches, the end moves down
    return {"edge_mm": edge_mm, "dof": res.report["mesh"]["dof"],
            "strain_per_N": -sens[gauge.name]["tip_Fz"] / (gauge.gauge_factor / 4.0 * 1e3),
            "deflection_per_N": sens["end"]["tip_Fz"]}


def convergence(cell, levels=LEVELS) -> list[dict[str, float]]:
    """One row per mesh: the measurements, their errors against beam theory (%) and the
    relative change (%) from the previous, 1.5 times coarser, level (None on the first)."""
    theory = beam_theory(cell)
    rows, prev = [], None
    for h in levels:
        r = measure(cell, h)
        r["strain_error_percent"] = 100.0 * (r["strain_per_N"] / theory["strain_per_N"] - 1.0)
        r["deflection_error_percent"] = 100.0 * (
            r["deflection_per_N"] / theory["deflection_timoshenko_per_N"] - 1.0)
        for q in ("strain_per_N", "deflection_per_N"):
            r[f"{q}_change_percent"] = (None if prev is None else
                                        100.0 * abs(r[q] - prev[q]) / abs(r[q]))
        rows.append(r)
        prev = r
    return rows


COLUMNS = (
    ("h (mm)", lambda r, t: f"{r['edge_mm']:.3f}"),
    ("DOF", lambda r, t: f"{r['dof']}"),
    ("strain (ue/N)", lambda r, t: f"{1e6 * r['strain_per_N']:.2f}"),
    ("beam theory (ue/N)", lambda r, t: f"{1e6 * t['strain_per_N']:.2f}"),
    ("error (%)", lambda r, t: f"{r['strain_error_percent']:+.2f}"),
    ("change from 1.5 h (%)", lambda r, t: _pct(r["strain_per_N_change_percent"])),
    ("end deflection (um/N)", lambda r, t: f"{1e3 * r['deflection_per_N']:.1f}"),
    ("Timoshenko (um/N)", lambda r, t: f"{1e3 * t['deflection_timoshenko_per_N']:.1f}"),
    ("error (%) ", lambda r, t: f"{r['deflection_error_percent']:+.2f}"),
    ("change from 1.5 h (%) ", lambda r, t: _pct(r["deflection_per_N_change_percent"])),
)


def _pct(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def table(cell, rows) -> str:
    """The rows as a Markdown table under a line of the beam theory's numbers."""
    t = beam_theory(cell)
    m = get_material(cell.material)
    head = (f"{cell.material} (E {m.E:g} MPa, nu {m.nu:g}), {cell.length:g} x {cell.width:g} x "
            f"{cell.thickness:g} mm, load at {cell.load_at:g} mm, gauge at {cell.gauge_at:g} mm, "
            f"slenderness {t['slenderness']:.2f}: Euler-Bernoulli end deflection "
            f"{1e3 * t['deflection_eb_per_N']:.1f} um/N, Timoshenko "
            f"{1e3 * t['deflection_timoshenko_per_N']:.1f} um/N")
    lines = [head, "", "| " + " | ".join(c.strip() for c, _ in COLUMNS) + " |",
             "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(f(r, t) for _, f in COLUMNS) + " |" for r in rows]
    return "\n".join(lines)


if __name__ == "__main__":
    levels = tuple(float(a) for a in sys.argv[1:]) or LEVELS
    cell = ProbedLoadCell()
    print(table(cell, convergence(cell, levels)))
