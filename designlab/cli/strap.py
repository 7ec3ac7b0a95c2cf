"""``designlab fit-strap``: a strap sized to one finger, its predicted sensitivity and
resolution, the size table against the paper's slots, and the printable 3MF."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

from designlab.cli.app import app, console, next_step, plain, progress_bar
from designlab.errors import ParameterError


def _fit_rows(res: dict) -> list[tuple[str, str]]:
    """The fit's table: strap parameters, prestrain, electrical response, slots, size grid."""
    p, pre, el = res["strap_parameters"], res["prestrain"], res["electrical"]
    sens, reso = res["sensitivity_V_per_N"], res["resolution_mN"]
    sl, st = res["paper_slots_on_this_finger"], res["size_table"]
    return [
        ("arch width x height (mm)", f"{p['arch_width']:.4g} x {p['arch_height']:.4g}"),
        ("tab length (mm), slots", f"{p['tab_length']:.4g}, {p['slot_count']}"),
        ("initial strain (target)", f"{pre['initial_strain']:.4g} ({res['target_initial_strain']:.4g})"),
        ("gauge resistance (ohm)", f"{el['resistance_ohm']['total']:.4g}"),
        ("sum F_n sensitivity (mV/N)", f"{1e3 * sens['sum_F_n']:.4g}"),
        ("diff F_x sensitivity (mV/N)", f"{1e3 * sens['diff_F_x']:.4g}"),
        ("resolution F_n / F_x (mN)", f"{reso['F_n']:.3g} / {reso['F_x']:.3g}"),
        ("paper slots: strains", ", ".join(f"{r['initial_strain']:.3g}" for r in sl["slots"])),
        ("paper slots: sum sensitivity cv %", f"{sl['sum_sensitivity_cv_percent']:.3g}"),
        ("size grid: strain cv % (best paper slot / personalised, caliper sd "
         f"{st['measurement_sd_mm']:.2g} mm, "
         f"{'cited %TEM' if st['measurement_sd_cited'] else 'given'})",
         f"{st['slots_strain_cv_percent']:.3g} / {st['personalised_strain_cv_percent']:.3g}"),
        ("personalised strain cv % by measurement input",
         ", ".join(f"{k} {v['strain_cv_percent']:.2g}"
                   for k, v in st["measurement_spread"]["inputs"].items())),
        (f"personalised cv < {st['goal_cv_percent']:g} %: caliper sd needed (mm), goal met",
         f"<= {st['required_measurement_sd_mm_for_goal']:.2g}, "
         f"{'yes' if st['goal_met'] else 'no'}"),
        ("time (s)", f"{res['timings_s']['total']:.1f}"),
    ]


@app.command("fit-strap")
def fit_strap(finger: Optional[str] = typer.Option(None, "--finger", metavar="WIDTH,DEPTH,LENGTH",
                                                   help="Distal phalanx at the strap, mm."),
              scan: Optional[Path] = typer.Option(None, "--scan", help="Fingertip surface (closed STL)."),
              target_strain: Optional[float] = typer.Option(None, "--target-strain",
                                                            help="Initial strain (default: the paper's medium slot on the reference finger)."),
              slots: int = typer.Option(1, "--slots", help="1 (no adjustment), 3 or 5 fine slots."),
              measured: Optional[Path] = typer.Option(None, "--measured", help="Measured printed-material data (JSON, docs/strap.md): replaces the stand-ins it names."),
              out: Path = typer.Option(..., "--out", help="Output directory (fit.json, strap/strap.3mf).")):
    """A strap sized to one finger: parameters for a target initial strain, its predicted
    sensitivity and resolution, the size table vs the paper's three slots, the printable 3MF."""
    from designlab.sensors.strap import fit as sf

    if (finger is None) == (scan is None):
        raise ParameterError("--finger/--scan", finger or scan, "exactly one of the two")
    fg = sf.parse_finger(finger) if finger is not None else sf.finger_from_scan(scan)
    records = None
    if measured is not None:
        from designlab.fem.materials import load_measured

        records = load_measured(measured)
    with progress_bar("fit-strap") as bar:
        res = sf.fit_strap(fg, out, target_strain=target_strain, slots=slots, measured=records,
                           progress=lambda s: bar(f"fit-strap: {s}"))
    t = Table(title=f"strap for finger {fg.width:g} x {fg.depth:g} x {fg.length:g} mm "
                    f"(perimeter {fg.perimeter:.1f} mm, {fg.perimeter_source})")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    for row in _fit_rows(res):
        t.add_row(*row)
    console.print(t)
    for note in res["material_stand_ins"]:
        console.print(plain(("note:", "bold"), " ", note), highlight=False)
    for f in res["files"]:
        console.print(f"wrote {f}", highlight=False, markup=False)
    threemf = [f for f in res["files"] if str(f).endswith(".3mf")]
    next_step("open next: " + ", ".join([f"{f} (into the slicer)" for f in threemf]
                                        + [f"{out / 'fit.json'} (the fit and size table)"]))
