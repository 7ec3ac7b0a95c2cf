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


def _sizes_table(title: str, rows: list[dict], key: str) -> Table:
    """A size (or slot) table: fingers, strain and sensitivity per size."""
    from designlab.sensors.strap.sizes import table_lines

    t = Table(title=title)
    for col in (key, "breadth p5-p95 mm", "perimeter mm", "share", "strain p5/p50/p95",
                "spread %", "sum F_n mV/N p5/p50/p95"):
        t.add_column(col, justify="left" if col == key else "right")
    for line in table_lines(rows, key):
        t.add_row(*[c.strip() for c in line.strip("|").split("|")])
    return t


@app.command("strap-sizes")
def strap_sizes(population: str = typer.Option("all", "--population", help="all | men | women (the shipped anthropometric table)."),
                sizes: str = typer.Option("5", "--sizes", help="N sizes (1-40) or auto: the fewest keeping the initial-strain spread within 10 % for 90 % of the population."),
                out: Path = typer.Option(..., "--out", help="Output directory (sizes.json, sizes.md, size_K/size_K.3mf)."),
                fingers: int = typer.Option(1000, "--fingers", help="Fingers drawn from the table."),
                seed: int = typer.Option(0, "--seed", help="Seed of the drawn fingers."),
                fingers_csv: Optional[Path] = typer.Option(None, "--fingers-csv", help="Measured fingers (CSV: width, depth[, length, perimeter] in mm): replaces the table and the depth assumption."),
                fit_by: str = typer.Option("perimeter", "--fit-by", help="perimeter (a girth at the strap) | breadth (a caliper)."),
                target_strain: Optional[float] = typer.Option(None, "--target-strain", help="Initial strain each size is cut for (default: the paper's medium slot on the reference finger)."),
                pulp_model: str = typer.Option("p50", "--pulp-model", help="off | p50 | p5,p50,p95: the population's fingers (perimeter percentiles) at which the hyperelastic pulp model runs (two nonlinear solves each)."),
                overwrite: bool = typer.Option(False, "--overwrite", help="Write into an --out that holds another command's run (same-named files are replaced).")):
    """Strap sizes for a population: the fingers each size fits, their initial strain and
    sum-channel sensitivity, the paper's three slots on the same fingers, a 3MF per size."""
    from designlab.cli.runs import check_out, write_run
    from designlab.sensors.strap import population as pp
    from designlab.sensors.strap import sizes as sz

    check_out(out, "strap-sizes", overwrite=overwrite)
    request = sz.SizesRequest(sizes=sizes, fit_by=fit_by, target_strain=target_strain,
                              pulp_model=pulp_model)
    request.count()
    request.pulp_percentiles()
    pop = (pp.from_csv(fingers_csv) if fingers_csv is not None
           else pp.draw(population, fingers, seed))
    with progress_bar("strap-sizes") as bar:
        res = sz.strap_sizes(pop, request, out, progress=lambda s: bar(f"strap-sizes: {s}"))
    run = write_run(out, "strap-sizes", {
        "population": pop.group, "fingers": pop.size, "seed": seed,
        "fingers_csv": str(fingers_csv) if fingers_csv else None, "sizes": sizes,
        "fit_by": fit_by, "target_strain": res["target_initial_strain"],
        "pulp_model": pulp_model})
    console.print(_sizes_table(
        f"{res['sizes']} strap sizes, {pop.group} ({pop.size} fingers), target strain "
        f"{res['target_initial_strain']:.3g}: {100 * res['share_within_goal']:.1f} % within "
        f"the {res['goal']['strain_spread_percent']:g} % spread", res["size_table"], "size"))
    sl = res["paper_slots"]
    console.print(_sizes_table(
        f"the paper's slots on the same fingers: {100 * sl['share_within_goal']:.1f} % "
        f"within, {100 * sl['slack_share']:.1f} % slack", sl["rows"], "slot"))
    for a in res["assumptions"]:
        console.print(plain(("assumption:", "bold"), " ", a), highlight=False)
    for r in res["pulp_model"]["fingers"]:
        b = r["band"]["hyperelastic_over_present"]
        console.print(plain(("pulp model:", "bold"), " ", f"p{r['percentile']} finger (size "
                            f"{r['size']}): sum sensitivity x {b['min']:.3g}-{b['max']:.3g} of "
                            "the table's (hyperelastic pulp, cited modulus range; sizes.md)"),
                      highlight=False)
    for f in [*res["files"], str(run)]:
        console.print(f"wrote {f}", highlight=False, markup=False)
    next_step(f"open next: {out / 'sizes.md'} (the table), {out / 'size_1'} (the 3MFs, into "
              "the slicer)")
