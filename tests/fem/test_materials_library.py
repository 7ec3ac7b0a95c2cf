"""The material library: every material names its sources, a strength with its basis and
source (or says why it has none), stand-in relaxation is declared, E and nu lie in plausible
ranges for their kind, and docs/materials.md shows the current table."""

from __future__ import annotations

from pathlib import Path

import pytest

from designlab.fem.materials import (ELASTOMER_PRONY, MATERIALS, PRINTED_PRONY, get_material,
                                     material_table, material_table_markdown, stand_in_note)

ROOT = Path(__file__).resolve().parents[2]

#: plausible (E MPa, nu) ranges of each kind of material in the library
KINDS = {
    "elastomer": ((0.1, 100.0), (0.40, 0.4999)),
    "polymer": ((500.0, 5000.0), (0.30, 0.42)),
    "metal": ((40000.0, 250000.0), (0.25, 0.42)),
}
KIND = {"NinjaFlex": "elastomer", "PI-ETPU": "elastomer", "silicone": "elastomer",
        "TPU95A": "elastomer", "ABS": "polymer", "PLA": "polymer", "PETG": "polymer",
        "PA12": "polymer", "SLA-Grey": "polymer", "SS302": "metal", "steel": "metal",
        "Al6061-T6": "metal"}


def test_every_material_has_a_kind_here():
    assert set(KIND) == set(MATERIALS)


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_source_strength_and_plausible_constants(name):
    m = MATERIALS[name]
    assert len(m.source.strip()) > 10, name
    assert m.strength_source.strip(), name
    if m.strength is None:
        # an explicit None says why in its basis and source
        assert m.strength_basis == "not documented" and "no strength" in m.strength_source
    else:
        assert m.strength > 0 and m.strength_basis.strip(), name
        if KIND[name] != "elastomer":      # an elastomer breaks at strains above 100 %
            assert m.strength < 0.1 * m.E, name
    (e_lo, e_hi), (nu_lo, nu_hi) = KINDS[KIND[name]]
    assert e_lo <= m.E <= e_hi, (name, m.E)
    assert nu_lo <= m.nu <= nu_hi, (name, m.nu)
    assert 0.5e-9 <= m.density <= 9e-9, (name, m.density)   # 0.5..9 g/cm^3


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_stand_in_relaxation_is_declared(name):
    """A borrowed Prony series is listed in ``stand_ins`` (outputs then say so); the fit it
    was borrowed from is not."""
    m = MATERIALS[name]
    if m.prony is None:
        assert "prony" not in m.stand_ins
    elif name != "silicone":
        assert m.prony in (PRINTED_PRONY, ELASTOMER_PRONY)
        assert "prony" in m.stand_ins and "stand-in" in m.source
        assert "prony" in stand_in_note(m)


def test_added_materials_carry_their_data_sheet_values():
    petg, tpu, pa12 = get_material("PETG"), get_material("TPU95A"), get_material("PA12")
    resin, al = get_material("SLA-Grey"), get_material("Al6061-T6")
    assert (tpu.E, tpu.strength, tpu.prony) == (26.0, 8.6, ELASTOMER_PRONY)
    assert (pa12.E, pa12.strength, pa12.density) == (1650.0, 48.0, 0.93e-9)
    assert (resin.E, resin.strength) == (2800.0, 65.0)
    assert (al.E, al.nu, al.strength, al.prony) == (68900.0, 0.33, 276.0, None)
    assert "typical" in petg.source and "typical" in petg.strength_source
    for m in (petg, tpu, pa12, resin, al):
        assert "data sheet" in m.source or "datasheet" in m.source or "typical" in m.source


def test_built_in_materials_unchanged():
    """The built-in sensors' materials keep their values (their predictions depend on them)."""
    got = {n: (MATERIALS[n].E, MATERIALS[n].nu, MATERIALS[n].density, MATERIALS[n].strength)
           for n in ("NinjaFlex", "PI-ETPU", "ABS", "PLA", "steel", "silicone")}
    assert got == {"NinjaFlex": (12.0, 0.45, 1.19e-9, 4.0), "PI-ETPU": (12.0, 0.45, 1.25e-9, None),
                   "ABS": (2200.0, 0.35, 1.04e-9, 26.0), "PLA": (3500.0, 0.36, 1.24e-9, 60.0),
                   "steel": (210000.0, 0.30, 7.85e-9, 235.0),
                   "silicone": (0.298, 0.49, 1.08e-9, 3.8)}
    assert MATERIALS["SS302"].E == 193000.0


def test_material_table_rows():
    rows = material_table()
    assert [r.name for r in rows] == list(MATERIALS)
    pla = next(r for r in rows if r.name == "PLA")
    assert (pla.E_MPa, pla.nu, pla.density_g_cm3, pla.strength_MPa) == (3500.0, 0.36, 1.24, 60.0)
    assert pla.prony.startswith("stand-in") and "NatureWorks" in pla.source
    al = next(r for r in rows if r.name == "Al6061-T6")
    assert al.prony.startswith("none")
    assert next(r for r in rows if r.name == "PI-ETPU").strength_MPa is None


def test_docs_page_shows_the_current_table():
    """docs/materials.md holds the output of ``python examples/materials_table.py``."""
    page = (ROOT / "docs" / "materials.md").read_text(encoding="utf-8")
    assert material_table_markdown().strip() in page


@pytest.mark.parametrize("content, message", [
    (bytes(range(256)) * 4, "a JSON text file (it is binary)"),
    (b'{"measured": 5}', "JSON {\"measured\": [{material"),
    (b'[1]', "JSON {\"measured\": [{material"),
    (b'{"measured": NaN}', "valid JSON"),
])
def test_a_measured_file_that_is_not_the_format_is_one_line(tmp_path, content, message):
    from designlab.errors import ParameterError
    from designlab.fem.materials import load_measured

    (tmp_path / "m.json").write_bytes(content)
    with pytest.raises(ParameterError, match="measured=") as exc:
        load_measured(tmp_path / "m.json")
    assert message in str(exc.value)
