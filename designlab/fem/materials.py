"""Material library: isotropic linear elastic (optionally viscoelastic, piezoresistive) solids.

Units: E in MPa, density in t/mm^3 (1 g/cm^3 = 1e-9 t/mm^3), resistivity in ohm*mm, tcr per K.
Every value carries its source in a comment. ``get_material(name)`` looks one up;
``dataclasses.replace(m, prony=...)`` gives a variant (e.g. with a fitted Prony series);
``material_table()`` lists the library with its sources.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from designlab.errors import ParameterError
from designlab.params import did_you_mean, load_json
from designlab.fem.prony import Prony


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic solid.

    name: library name; E: Young's modulus (MPa, instantaneous when ``prony`` is given);
    nu: Poisson's ratio (-1 < nu < 0.5); density: t/mm^3; prony: generalized Maxwell terms or None;
    gauge_factor: dR/R per unit strain (piezoresistive materials) or None;
    gauge_quadratic: second-order coefficient c2 in dR/R = GF eps + c2 eps^2;
    tcr: temperature coefficient of resistance, 1/K; resistivity: ohm*mm or None;
    stand_ins: the fields whose values are stand-ins; max_elongation: strain at break or None.
    """

    name: str
    E: float
    nu: float
    density: float = 0.0
    prony: Prony | None = None
    gauge_factor: float | None = None
    gauge_quadratic: float = 0.0
    tcr: float = 0.0
    resistivity: float | None = None
    source: str = field(default="", compare=False)
    #: properties whose values are stand-ins (borrowed from another material), named as the
    #: fields: every output that uses such a material lists them (see :func:`stand_in_note`)
    stand_ins: tuple[str, ...] = field(default=(), compare=False)
    #: elongation at break (strain, 1 = 100 %) or None
    max_elongation: float | None = None
    #: the stress (MPa) a safety factor is taken against (von Mises): tensile yield strength
    #: where the source gives one, else tensile strength; None: no documented value
    strength: float | None = field(default=None, compare=False, repr=False)
    #: which strength ``strength`` is (yield, break, derived...)
    strength_basis: str = field(default="", compare=False, repr=False)
    #: where ``strength`` comes from
    strength_source: str = field(default="", compare=False, repr=False)
    #: the fields set from measured printed-material records (:func:`with_measured`): a model
    #: that otherwise derives a value (the strap's back-calculated resistivity) takes these
    measured: tuple[str, ...] = field(default=(), compare=False, repr=False)

    def __post_init__(self):
        if not (self.E > 0):
            raise ParameterError(f"{self.name}.E", self.E, "Young's modulus > 0 MPa")
        if not (-1.0 < self.nu < 0.5):
            raise ParameterError(f"{self.name}.nu", self.nu, "Poisson's ratio in (-1, 0.5)")
        if not (self.density >= 0):
            raise ParameterError(f"{self.name}.density", self.density, ">= 0 t/mm^3")

    @property
    def G(self) -> float:
        """Shear modulus, MPa."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def K(self) -> float:
        """Bulk modulus, MPa."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    @property
    def lame(self) -> tuple[float, float]:
        """(lambda, mu) in MPa."""
        return self.K - 2.0 * self.G / 3.0, self.G


#: Relaxation of the carbon-black-filled elastomer of the stretch rig, fitted to its measured
#: stepped-strain test (``python examples/fit_silicone_prony.py``: E0 0.298 MPa, 2.6 % rms error
#: over 2351 samples). ../shared/data/README.md: "the same physics as the carbon-doped TPU gauges
#: of seed 000", so the TPUs use the same relative terms as a stand-in until measured.
ELASTOMER_PRONY = Prony(g=(0.0486, 0.246), tau=(1.70, 10.81))
#: Printed-part relaxation stand-in: seed 002 measured "< 4 % over six seconds, approximately a
#: first-order decay" on its printed fingertip (Visiflex); tau = 2 s (6 s / 3) assumed, so the
#: decay is 95 % complete in that window. Used for ABS and PLA until measured.
PRINTED_PRONY = Prony(g=(0.04,), tau=(2.0,))

MATERIALS: dict[str, Material] = {m.name: m for m in [
    # Seed 000 Table I (../shared/data/papers/fingertip_strap_tpu.json): E = 12 MPa, Shore 85A.
    # nu: TPU elastomers are nearly incompressible; 0.45 is the usual small-strain value for
    # printed TPU (an assumption, not in the paper). Density 1.19 g/cm^3 (NinjaTek datasheet).
    # Max elongation 660 % (seed 000 Table I).
    Material("NinjaFlex", E=12.0, nu=0.45, density=1.19e-9, prony=ELASTOMER_PRONY,
             source="E: seed 000 Table I; nu assumed 0.45; density NinjaTek datasheet; "
                    "Prony: stretch-rig elastomer stand-in",
             stand_ins=("prony",), max_elongation=6.6,
             strength=4.0, strength_basis="tensile strength at yield (ASTM D638)",
             strength_source="NinjaTek NinjaFlex 85A technical data sheet: tensile strength "
                             "at yield 4 MPa (at 65 % elongation), at break 26 MPa"),
    # Seed 000 Table I: PI-ETPU 95-250 carbon black, E = 12 MPa, Shore 95A, resistivity
    # <= 800 ohm*cm = 8000 ohm*mm; TCR 0.002 /K (seed 000 discussion, ref [32]). The paper
    # gives no gauge factor: GF = 3.8 is the carbon-black elastomer value measured from the
    # stretch-rig data (see `silicone` below), a stand-in until calibrated on seed-000 data.
    # Density 1.25 g/cm^3 (assumed: TPU plus carbon black).
    Material("PI-ETPU", E=12.0, nu=0.45, density=1.25e-9, gauge_factor=3.8, tcr=0.002,
             resistivity=8000.0, prony=ELASTOMER_PRONY,
             source="E, resistivity: seed 000 Table I; TCR: seed 000 [32]; nu assumed; "
                    "GF and Prony: stand-ins (carbon-black elastomer), calibrate",
             stand_ins=("gauge_factor", "prony"), max_elongation=2.2,   # 220 %: Table I
             # no strength: seed 000 Table I gives none, and we have no datasheet value for the
             # carbon-black grade; predictions say its safety factor is not computed
             strength=None, strength_basis="not documented",
             strength_source="seed 000 Table I lists no strength for PI-ETPU 95-250"),
    # Stratasys ABSplus-P430 datasheet (seed 001 printer Dimension BST 768): tensile modulus
    # 2200 MPa (XZ); nu 0.35 typical for ABS; density 1.04 g/cm^3.
    Material("ABS", E=2200.0, nu=0.35, density=1.04e-9, prony=PRINTED_PRONY,
             source="ABSplus-P430 datasheet (E); nu, density: typical ABS; Prony: printed-part "
                    "stand-in (seed 002 relaxation)", stand_ins=("prony",),
             strength=26.0, strength_basis="tensile yield strength across the layers (ZX)",
             strength_source="Stratasys ABSplus-P430 data sheet: tensile strength, yield "
                             "31 MPa (XZ), 26 MPa (ZX, across layers; the weaker is used)"),
    # Printed PLA: E ~ 3500 MPa (NatureWorks 4043D datasheet, bulk); nu 0.36; 1.24 g/cm^3.
    Material("PLA", E=3500.0, nu=0.36, density=1.24e-9, prony=PRINTED_PRONY,
             source="NatureWorks Ingeo 4043D datasheet; nu typical; Prony: printed-part "
                    "stand-in (seed 002 relaxation)", stand_ins=("prony",),
             strength=60.0, strength_basis="tensile yield strength (bulk, not printed)",
             strength_source="NatureWorks Ingeo 4043D technical data sheet: tensile yield "
                             "strength 60 MPa (ASTM D882); printed parts are weaker across "
                             "layers"),
    # Seed 002 spring: stainless 302, ASTM A313 spring wire. Handbook design values
    # E = 193 GPa, G = 69 GPa (SMI/Associated Spring tables); nu = E/(2G) - 1 = 0.399 keeps
    # the shear modulus that governs a coil spring exact. Density 7.92 g/cm^3.
    Material("SS302", E=193000.0, nu=193000.0 / (2.0 * 69000.0) - 1.0, density=7.92e-9,
             source="ASTM A313 302 spring wire: E 193 GPa, G 69 GPa (spring handbooks)",
             # Shigley's Mechanical Engineering Design (10th ed.) Table 10-4: A302 stainless
             # wire 0.3-2.5 mm, S_ut = A / d^m with A = 1867 MPa mm^m, m = 0.146 -> 1683 MPa at
             # the seed 002 wire d = 2.03 mm; Table 10-6: torsional yield S_sy = 0.35 S_ut
             # (austenitic stainless, set not removed); as a von Mises stress (pure torsion:
             # sigma_vM = sqrt(3) tau) the yield is sqrt(3) x 0.35 x 1683 = 1020 MPa
             strength=1020.0, strength_basis="torsional yield of the 2.03 mm wire as a von "
                                             "Mises stress (sqrt(3) S_sy)",
             strength_source="Shigley 10th ed. Tables 10-4 (S_ut = 1867/d^0.146 MPa, 1683 MPa "
                             "at d = 2.03 mm) and 10-6 (S_sy = 0.35 S_ut)"),
    # Generic structural / bearing steel (seed 001 ball and M2.5 bolt): E 210 GPa, nu 0.30.
    Material("steel", E=210000.0, nu=0.30, density=7.85e-9, source="EN 10025 typical values",
             strength=235.0, strength_basis="minimum yield strength of S235 (t <= 16 mm)",
             strength_source="EN 10025-2 S235: R_eH >= 235 MPa (the least structural steel "
                             "grade; bearing balls and 8.8 bolts are stronger)"),
    # Dragon Skin silicone filled with 7.5 wt% carbon black: the stretch-rig specimen
    # (../shared/data/README.md: 40 x 10 x 4 mm). Straight-line fits of force and 4-wire
    # resistance against elongation over the lower half of the range of three runs
    # (E4pin_20mm_v8_0.3Strain, 4Epin_rand_sawtooth, multisine_600s_1) give
    # E = 0.29 / 0.31 / 0.29 MPa and GF = 2.4 / 5.4 / 3.7 (strain = elongation / 40 mm):
    # E = 0.3 MPa, GF = 3.8 (mean). Nearly incompressible: nu = 0.49 (assumed). Density
    # 1.08 g/cm^3 (Dragon Skin 20 datasheet; filler neglected).
    Material("silicone", E=0.298, nu=0.49, density=1.08e-9, gauge_factor=3.8,
             prony=ELASTOMER_PRONY,
             source="E0 and Prony: fit to the stepped-strain test, GF: line fits, all "
                    "../shared/data/stretch; nu assumed; Dragon Skin datasheet",
             strength=3.8, strength_basis="tensile strength of the unfilled silicone",
             strength_source="Smooth-On Dragon Skin 20 technical bulletin: tensile strength "
                             "550 psi (3.8 MPa, ASTM D412); carbon-black filler not included"),
    # ---- materials a designer prints or buys (no built-in sensor uses them) ----
    # PETG: the glycol-modified copolyester of most PETG filaments. E 2000 MPa and the yield
    # strength are typical values (moulded copolyester data sheets such as Eastman Eastar 6763
    # give about 2 GPa and 50 MPa; printed-filament sheets 1.5-2.1 GPa); nu 0.38 typical for
    # PET; density 1.27 g/cm^3 (filament data sheets agree).
    Material("PETG", E=2000.0, nu=0.38, density=1.27e-9, prony=PRINTED_PRONY,
             source="E, density: typical PETG values (moulded copolyester data sheets, e.g. "
                    "Eastman Eastar 6763: about 2 GPa, 1.27 g/cm^3); nu typical for PET; "
                    "Prony: printed-part stand-in (seed 002 relaxation)", stand_ins=("prony",),
             strength=50.0, strength_basis="tensile yield strength (typical, moulded)",
             strength_source="typical PETG value: moulded copolyester data sheets (e.g. Eastman "
                             "Eastar 6763) give about 50 MPa at yield; printed parts are "
                             "weaker across layers"),
    # Ultimaker TPU 95A technical data sheet (printed ISO 527 specimens): tensile modulus
    # 26 MPa, yield 8.6 MPa (at 55 %), break 39 MPa at 580 %, Shore 95A, 1.22 g/cm^3. nu 0.45
    # as NinjaFlex (assumed). Relaxation: the elastomer stand-in as for the other TPUs.
    Material("TPU95A", E=26.0, nu=0.45, density=1.22e-9, prony=ELASTOMER_PRONY,
             source="Ultimaker TPU 95A technical data sheet (E, density, elongation); nu "
                    "assumed 0.45; Prony: stretch-rig elastomer stand-in",
             stand_ins=("prony",), max_elongation=5.8,
             strength=8.6, strength_basis="tensile stress at yield (ISO 527, printed)",
             strength_source="Ultimaker TPU 95A technical data sheet: tensile stress at yield "
                             "8.6 MPa (at 55 %), at break 39 MPa"),
    # Laser-sintered polyamide 12: EOS PA 2200 material data sheet (ISO 527, X direction):
    # tensile modulus 1650 MPa, tensile strength 48 MPa, elongation at break 18 %, part
    # density 0.93 g/cm^3. nu 0.39 typical for PA12 (assumed).
    Material("PA12", E=1650.0, nu=0.39, density=0.93e-9, prony=PRINTED_PRONY,
             source="EOS PA 2200 material data sheet (E, density, elongation); nu typical for "
                    "PA12; Prony: printed-part stand-in (seed 002 relaxation)",
             stand_ins=("prony",), max_elongation=0.18,
             strength=48.0, strength_basis="tensile strength (the data sheet gives no yield)",
             strength_source="EOS PA 2200 material data sheet: tensile strength 48 MPa "
                             "(ISO 527-1/-2, X direction)"),
    # A standard SLA resin, post-cured: Formlabs Grey (Standard) resin data sheet: tensile
    # modulus 2.8 GPa, ultimate tensile strength 65 MPa, elongation 6 % (green: 1.6 GPa,
    # 38 MPa). nu 0.35 and density 1.18 g/cm^3 are typical values of cured methacrylate
    # photopolymers (assumed). Relaxation: the printed-part stand-in.
    Material("SLA-Grey", E=2800.0, nu=0.35, density=1.18e-9, prony=PRINTED_PRONY,
             source="Formlabs Grey (Standard) resin data sheet, post-cured (E, elongation); nu, "
                    "density: typical cured photopolymer; Prony: printed-part stand-in "
                    "(seed 002 relaxation)", stand_ins=("prony",), max_elongation=0.06,
             strength=65.0, strength_basis="ultimate tensile strength, post-cured (brittle: "
                                           "no yield given)",
             strength_source="Formlabs Grey (Standard) resin data sheet: ultimate tensile "
                             "strength 65 MPa post-cured (ASTM D638), 38 MPa green"),
    # A bought aluminium part: 6061-T6 (ASM Aerospace Specification Metals / MatWeb data
    # sheet, MMPDS typical values): E 68.9 GPa, nu 0.33, density 2.70 g/cm^3, tensile yield
    # 276 MPa, ultimate 310 MPa, elongation 12 %. Metals do not relax at these stresses: no
    # Prony terms.
    Material("Al6061-T6", E=68900.0, nu=0.33, density=2.70e-9, max_elongation=0.12,
             source="ASM data sheet for aluminium 6061-T6 (E, nu, density, elongation)",
             strength=276.0, strength_basis="tensile yield strength (0.2 % offset)",
             strength_source="ASM data sheet for aluminium 6061-T6: tensile yield 276 MPa, "
                             "ultimate 310 MPa"),
]}


def stand_in_note(material: Material) -> str | None:
    """One line naming a material's stand-in properties, or None when it has none."""
    if not material.stand_ins:
        return None
    verb = "is a stand-in" if len(material.stand_ins) == 1 else "are stand-ins"
    return (f"{material.name}: {', '.join(material.stand_ins)} {verb} (silicone/"
            "carbon-black elastomer of the stretch rig or a printed-part analogue), not "
            "measured on the printed material")


# ------------------------------------------------------------- measured printed-material data

#: quantities a measured record may give, with their unit
MEASURED_QUANTITIES = {"E": "MPa", "nu": "-", "gauge_factor": "-", "gauge_quadratic": "-",
                       "tcr": "1/K", "resistivity": "ohm*mm", "prony": "g, tau (s)",
                       "max_elongation": "-",
                       "resistance_relaxation": "t (s), R/R0 (-) after a strain step"}
#: quantities that are stored with the material's source but change no field (no model reads
#: them yet): resistance relaxation is a curve {"t_s": [...], "R_over_R0": [...], "strain":
#: step} for the loop's drift effects to be fitted against
STORED_ONLY = ("resistance_relaxation",)


@dataclass(frozen=True)
class MeasuredProperty:
    """One measured property of a *printed* material: the documented place for data that
    replaces a stand-in. ``value``: a number, or for ``prony`` a mapping ``{"g": [...],
    "tau": [...]}``; ``source``: who measured what specimen how; ``date``: ISO date."""

    material: str
    quantity: str
    value: object
    source: str
    date: str
    conditions: str = ""

    def __post_init__(self):
        import datetime

        if self.quantity not in MEASURED_QUANTITIES:
            raise ParameterError("quantity", self.quantity,
                                 "one of " + ", ".join(MEASURED_QUANTITIES))
        if not self.source.strip():
            raise ParameterError(f"{self.material}.{self.quantity}.source", self.source,
                                 "a non-empty description of the measurement")
        try:
            datetime.date.fromisoformat(self.date)
        except (TypeError, ValueError):
            raise ParameterError(f"{self.material}.{self.quantity}.date", self.date,
                                 "an ISO date YYYY-MM-DD") from None


def load_measured(path) -> list[MeasuredProperty]:
    """Measured printed-material data from a JSON file ``{"measured": [{"material": ...,
    "quantity": ..., "value": ..., "source": ..., "date": ...}, ...]}``."""
    from pathlib import Path

    p = Path(path)
    if not p.is_file():
        raise ParameterError("measured", str(p), "an existing JSON file")
    data = load_json(p, "measured")     # size, UTF-8 text, nesting, no NaN: one line each
    try:
        rows = data["measured"]
        return [MeasuredProperty(**r) for r in rows]
    except (KeyError, TypeError) as exc:
        raise ParameterError("measured", str(p), 'JSON {"measured": [{material, quantity, '
                             f'value, source, date}}, ...]}} ({exc})') from None


def with_measured(material: Material, records) -> Material:
    """``material`` with the measured properties of ``records`` that name it; those
    properties leave its ``stand_ins``, are listed in its ``measured`` and its ``source`` says
    where they come from."""
    import dataclasses
    import math

    mine = [r for r in records if r.material == material.name]
    if not mine:
        return material
    kw: dict = {}
    for r in mine:
        if r.quantity in STORED_ONLY:
            _check_curve(material.name, r)
        elif r.quantity == "prony":
            try:
                kw["prony"] = Prony(g=tuple(r.value["g"]), tau=tuple(r.value["tau"]))
            except (TypeError, KeyError):
                raise ParameterError(f"{material.name}.prony", r.value,
                                     '{"g": [...], "tau": [...]}') from None
        else:
            try:
                kw[r.quantity] = float(r.value)
            except (TypeError, ValueError):
                raise ParameterError(f"{material.name}.{r.quantity}", r.value,
                                     "a number") from None
            if r.quantity == "resistivity" and not (math.isfinite(kw[r.quantity])
                                                    and kw[r.quantity] > 0):
                raise ParameterError(f"{material.name}.resistivity", r.value,
                                     "a finite number > 0 ohm*mm (printed trace, along the "
                                     "raster)")
    measured = {r.quantity for r in mine if r.quantity not in STORED_ONLY}
    src = "; ".join(f"{r.quantity}: {r.source} ({r.date})" for r in mine)
    return dataclasses.replace(material, **kw,
                               stand_ins=tuple(q for q in material.stand_ins
                                               if q not in measured),
                               measured=tuple(sorted(set(material.measured) | measured)),
                               source=f"{material.source}; measured: {src}")


def _check_curve(material: str, r: MeasuredProperty) -> None:
    """A stored-only relaxation curve: equal-length increasing ``t_s`` and positive
    ``R_over_R0`` (at least two points)."""
    allowed = ('{"t_s": [increasing times, s], "R_over_R0": [positive ratios], "strain": '
               'step}, equal lengths >= 2')
    try:
        t = [float(x) for x in r.value["t_s"]]
        y = [float(x) for x in r.value["R_over_R0"]]
    except (TypeError, KeyError, ValueError):
        raise ParameterError(f"{material}.{r.quantity}", r.value, allowed) from None
    if (len(t) != len(y) or len(t) < 2 or any(b <= a for a, b in zip(t, t[1:]))
            or any(not v > 0 for v in y)):
        raise ParameterError(f"{material}.{r.quantity}", r.value, allowed)


def get_material(name: str) -> Material:
    """Library material by name (case-sensitive), else ParameterError listing the names."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise ParameterError("material", name, "one of " + ", ".join(MATERIALS)
                             + did_you_mean(name, MATERIALS)) from None


# ------------------------------------------------------------------------ the library as a table

class MaterialRow(NamedTuple):
    """One material of the library as the docs and the CLI list it: E (MPa), nu, density
    (g/cm^3), strength (MPa, None: not documented), its relaxation (Prony terms, and whether
    they are a stand-in) and where the values come from."""

    name: str
    E_MPa: float
    nu: float
    density_g_cm3: float
    strength_MPa: float | None
    strength_basis: str
    prony: str
    source: str
    strength_source: str


def _prony_text(m: Material) -> str:
    if m.prony is None:
        return "none (elastic)"
    terms = (f"g {', '.join(f'{g:g}' for g in m.prony.g)}; tau "
             f"{', '.join(f'{t:g}' for t in m.prony.tau)} s")
    return f"stand-in: {terms}" if "prony" in m.stand_ins else terms


def material_table(materials: dict[str, Material] | None = None) -> list[MaterialRow]:
    """The library (or ``materials``) as rows, in library order."""
    lib = MATERIALS if materials is None else materials
    return [MaterialRow(m.name, float(m.E), round(float(m.nu), 4),
                        round(float(m.density) * 1e9, 4), m.strength, m.strength_basis,
                        _prony_text(m), m.source, m.strength_source) for m in lib.values()]


#: columns of :func:`material_table_markdown`: (header, row -> text)
_COLUMNS = (("material", lambda r: f"`{r.name}`"), ("E (MPa)", lambda r: f"{r.E_MPa:g}"),
            ("nu", lambda r: f"{r.nu:g}"), ("density (g/cm^3)", lambda r: f"{r.density_g_cm3:g}"),
            ("strength (MPa)", lambda r: "none" if r.strength_MPa is None
             else f"{r.strength_MPa:g}"),
            ("relaxation (Prony)", lambda r: r.prony))


def material_table_markdown(rows: list[MaterialRow] | None = None) -> str:
    """The rows as Markdown: the properties table, then each material's sources."""
    rows = material_table() if rows is None else rows
    head = [h for h, _ in _COLUMNS]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(f(r) for _, f in _COLUMNS) + " |" for r in rows]
    lines += ["", "Sources:", ""]
    lines += [f"- `{r.name}`: {r.source}. Strength, {r.strength_basis}: {r.strength_source}."
              for r in rows]
    return "\n".join(lines) + "\n"
