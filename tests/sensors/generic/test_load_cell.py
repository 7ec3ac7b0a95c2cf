"""The load cell of examples/sensors/load_cell.py (a PLA cantilever, 80 x 12 x 4 mm, clamped at
x = 0, a foil gauge centred 12 mm from the clamp, weights hung at 75 mm: slenderness
75 / 4 = 18.75) against beam theory, its mesh error bar under refinement, and the hysteresis
of PLA's Prony stand-in.

Beam theory. The cantilever is statically determinate: equilibrium alone fixes the bending
moment M(x) = P (a - x) at every section, whatever the beam's stiffness. Euler-Bernoulli and
Timoshenko therefore share the surface bending strain eps = M (t/2) / (E I) = 6 P (a - x) /
(E w t^2): Timoshenko's shear correction adds a shear strain gamma = V / (k G A) that rotates
the sections relative to the centre line's slope, but leaves the curvature of the sections
(d phi / dx = M / (E I)) and so the axial strain of the surface unchanged (the shear strain
itself vanishes at the free surface). What it changes is the deflection: the shear strain
adds P a / (k G A) to the load point's deflection (Cowper's k = 10 (1 + nu) / (12 + 11 nu)
for a rectangle); beyond the load the beam is straight, so the free end moves by
P a^3 / (3 E I) + P a / (k G A) + (L - a) P a^2 / (2 E I). The gauge strain is checked against
the shared formula, the free end's deflection (a DisplacementProbe of a test-local subclass)
against both theories, each within 2 %.

What the solid model adds to beam theory: the clamped face holds the cross-section's
Poisson contraction, stiffening the beam within about a width of the clamp (up to 1 / (1 -
nu^2), 15 % for PLA, at the face itself). The gauge 12 mm (one width) from the clamp reads 1 %
below beam theory and the free end moves 1.6 % less than Timoshenko says; with nu = 0 both
deviations vanish (0.01 % and 0.00 %: then the solid model agrees with Timoshenko, not with
Euler-Bernoulli, whose deflection is 0.15 % short).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import designlab as dl

ROOT = Path(__file__).resolve().parents[3]
LOAD_CELL = ROOT / "examples" / "sensors" / "load_cell.py"


@pytest.fixture(scope="module")
def LoadCell() -> type:
    """The definition class (loading it imports the CAD kernel once per module)."""
    from designlab.sensors.registry import load_class

    return load_class(str(LOAD_CELL))


def _probed(base: type, name: str) -> type:
    """``base`` with the free end's mean vertical motion read too."""

    class Probed(base):
        def transducers(self):
            end = dl.Face("beam", normal=(1, 0, 0))
            return [*super().transducers(), dl.DisplacementProbe("end", end, (0, 0, 1),
                                                                  noise=1e-3)]

    Probed.name = name
    Probed.__qualname__ = f"Probed_{name}"   # its own FEM stage (the stage key names the class)
    return Probed


def _beam_theory(cell, E: float, nu: float) -> dict[str, float]:
    a, x, L, w, t = cell.load_at, cell.gauge_at, cell.length, cell.width, cell.thickness
    EI, A, G = E * w * t ** 3 / 12.0, w * t, E / (2.0 * (1.0 + nu))
    k = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
    eb = a ** 3 / (3.0 * EI) + a ** 2 * (L - a) / (2.0 * EI)
    return {"strain": 6.0 * (a - x) / (E * w * t ** 2), "eb": eb, "timoshenko": eb + a / (k * G * A)}


def _measure(cell, edge: float) -> dict:
    from designlab.sensors.generic.virtual import run, settings_class

    res = run(cell, settings=settings_class(type(cell))(edge_length=edge, viscoelastic=False))
    sens = res.report["sensitivity"]
    # the weights pull down (Fz < 0): the top face stretches, the free end moves down
    out = {"strain": -sens["gauge"]["tip_Fz"] / (2.0 / 4.0 * 1e3),   # GF 2, quarter bridge, mV/V
           "dof": res.report["mesh"]["dof"]}
    if "end" in sens:
        out["deflection"] = sens["end"]["tip_Fz"]
    return out


def _err(x: float, ref: float) -> float:
    return 100.0 * (x / ref - 1.0)


def test_gauge_strain_per_newton_on_a_coarse_mesh(LoadCell):
    cell = LoadCell()
    assert cell.load_at / cell.thickness >= 10.0
    pla = dl.get_material("PLA")
    got = _measure(cell, 3.0)
    theory = _beam_theory(cell, pla.E, pla.nu)
    assert theory["strain"] == pytest.approx(562.5e-6)        # 6 x 63 / (3500 x 12 x 16)
    assert abs(_err(got["strain"], theory["strain"])) < 2.0


def test_the_docs_page_shows_the_definition_as_it_is():
    src = LOAD_CELL.read_text(encoding="utf-8")
    page = (ROOT / "docs" / "sensors" / "load_cell.md").read_text(encoding="utf-8")
    assert src[src.index("class LoadCell"):].strip() in page


@pytest.mark.slow
def test_strain_and_end_deflection_within_two_percent_of_beam_theory(LoadCell):
    cell = _probed(LoadCell, "load_cell_end_probe")()
    pla = dl.get_material("PLA")
    theory = _beam_theory(cell, pla.E, pla.nu)
    got = _measure(cell, 4.0 / 3.0)
    assert abs(_err(got["strain"], theory["strain"])) < 2.0
    for ref in ("eb", "timoshenko"):
        assert abs(_err(got["deflection"], theory[ref])) < 2.0, ref
    # the clamp's Poisson restraint stiffens the solid beyond both theories
    assert got["strain"] < theory["strain"] and got["deflection"] < theory["eb"]


@pytest.mark.slow
def test_without_poisson_contraction_the_solid_is_a_timoshenko_beam(LoadCell, monkeypatch):
    """nu = 0: nothing for the clamp to restrain; the gauge reads beam theory and the free end
    moves as Timoshenko says, beyond Euler-Bernoulli by the shear term."""
    from designlab.fem import materials

    pla0 = dataclasses.replace(materials.MATERIALS["PLA"], nu=0.0)
    monkeypatch.setitem(materials.MATERIALS, "PLA", pla0)
    cell = _probed(LoadCell, "load_cell_nu0")()
    theory = _beam_theory(cell, pla0.E, 0.0)
    got = _measure(cell, 2.0)
    assert abs(_err(got["strain"], theory["strain"])) < 0.3
    assert abs(_err(got["deflection"], theory["timoshenko"])) < 0.05
    assert _err(got["deflection"], theory["eb"]) > 0.1


@pytest.mark.slow
def test_mesh_error_bar_shrinks_under_refinement(LoadCell):
    """The error bar at edge h is the relative change of the gauge strain from the mesh of edge
    1.5 h (what ``predict`` reports). Unstructured meshes do not shrink it at every step (it
    stays near 0.1 % from h = 2 to h = 1.33 mm); from the coarsest to the finest level it
    shrinks more than tenfold, and every level stays within 2 % of beam theory."""
    cell = LoadCell()
    pla = dl.get_material("PLA")
    theory = _beam_theory(cell, pla.E, pla.nu)
    levels = (4.5, 3.0, 2.0, 4.0 / 3.0, 8.0 / 9.0)
    got = [_measure(cell, h) for h in levels]
    dof = [g["dof"] for g in got]
    assert dof == sorted(dof)
    s = np.array([g["strain"] for g in got])
    bars = 100.0 * np.abs(np.diff(s)) / np.abs(s[1:])
    assert bars[-1] == bars.min() and bars[-1] < bars[0] / 10.0
    assert np.all(bars[1:] < bars[0]) and np.all(bars < 1.0)
    assert np.all(np.abs(_err(s, theory["strain"])) < 2.0)


@pytest.mark.slow
def test_hysteresis_of_the_pla_stand_in_is_present_and_small(LoadCell):
    """PLA's stand-in Prony series (g = 0.04 on the shear modulus, tau = 2 s) under the
    staircase of six equal weights held 10 s. In uniaxial bending the compliance creeps by
    c = g / (1 - g) x E / (3 G) with the retardation time tau / (1 - g), so the relaxed reading
    is (1 + c) times the instantaneous one, and at the end of a hold a step's creep lags by
    c exp(-hold (1 - g) / tau) of that step: the loop's midpoint readings up and down differ by
    twice that, against a span of six steps (1 + c), a hysteresis of about 0.01 %."""
    from designlab.fem.materials import PRINTED_PRONY
    from designlab.sensors.generic.virtual import DefinitionProtocol, run, settings_class

    cell = LoadCell()
    pla = dl.get_material("PLA")
    assert pla.prony == PRINTED_PRONY and "prony" in pla.stand_ins
    (g,), (tau,) = pla.prony.g, pla.prony.tau
    proto = cell.protocol()
    hold, steps = proto.hold_s, len(proto.weights_g)
    sett = settings_class(type(cell))(edge_length=3.0)
    visco = run(cell, DefinitionProtocol(), settings=sett).report
    elastic = run(cell, settings=dataclasses.replace(sett, viscoelastic=False)).report
    c = g / (1.0 - g) * pla.E / (3.0 * pla.G)
    ratio = visco["sensitivity"]["gauge"]["tip_Fz"] / elastic["sensitivity"]["gauge"]["tip_Fz"]
    assert ratio == pytest.approx(1.0 + c, abs=1e-3)
    hyst = visco["hysteresis_percent"]["overall"]
    expected = 100.0 * 2.0 * c * math.exp(-hold * (1.0 - g) / tau) / (steps * (1.0 + c))
    assert 0.0 < hyst < 0.1
    assert hyst == pytest.approx(expected, rel=0.1)
    assert elastic["hysteresis_percent"]["overall"] is None
