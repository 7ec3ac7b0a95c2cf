"""``designlab flexure``: the spring flexure's 6x6 stiffness by closed form, beam chain and
(optionally) solid FEM, against the paper's theory and measurement."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from designlab.cli.app import app, console, next_step, plain, progress_bar, warn
from designlab.errors import ParameterError
from designlab.params import did_you_mean, parse_sets, with_overrides


def _check_frame(frame: str, frames) -> None:
    if frame not in frames:
        raise ParameterError("--frame", frame, "one of " + ", ".join(frames)
                             + did_you_mean(frame, frames))


def _check_mu_curved(mu: float, curved: Optional[bool], fem: bool) -> None:
    """A friction coefficient in [0, 2]; --curved/--straight only with --fem."""
    if not 0 <= mu <= 2:
        raise ParameterError("--mu", mu, "a friction coefficient 0 <= mu <= 2")
    if curved is not None and not fem:
        raise ParameterError("--curved" if curved else "--straight", True,
                             "only with --fem (the solid FEM's mesh)")


def _chain(spring, seat: str, working_load: float, mu: float):
    """The beam chain's 6x6 (a friction secant when ``mu`` > 0)."""
    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import ChainSettings

    settings = ChainSettings(seat=seat, working_load_N=working_load)
    if mu > 0:
        from designlab.sensors.flexure.chain_friction import friction_stiffness

        return friction_stiffness(spring, settings, mu=mu)
    return chain_stiffness(spring, settings)


def _solid_fem(spring, edge_length: Optional[float], working_load: float,
               curved: Optional[bool]) -> tuple:
    """The solid helix with coil and seat contact: ``(K unloaded, K loaded or None, info)``
    about the spring's centre, SI."""
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.contact_fem import fem_contact_stiffness
    from designlab.sensors.flexure.helix_fem import CURVED_DEFAULT

    with progress_bar("FEM 6x6") as bar:
        def step(text: str, done: int, total: int) -> None:
            bar(f"FEM: {text}", completed=done, total=total)

        sol = fem_contact_stiffness(spring, edge_length=edge_length, progress=step,
                                    settings=ChainSettings(seat="bonded",
                                                           working_load_N=working_load),
                                    curved=CURVED_DEFAULT if curved is None else curved)
    K_fem = sol.centre_si("unloaded")
    K_fem_loaded = sol.centre_si("loaded") if sol.K_loaded is not None else None
    return K_fem, K_fem_loaded, dict(sol.info, K_free_centre_si=sol.centre_si("free").tolist())


def _print_solvers(report: dict, mu: float) -> None:
    """The ratios to the paper's theory and one line each on the beam chain and the FEM."""
    r = report["ratios"]
    console.print("ratios (closed form vs paper theory): " + ", ".join(
        f"{k} {r['closed_form'][k]:.4g} vs {r['paper_theory'][k]:.4g} ({v:+.2f} %)"
        for k, v in r["closed_form_vs_paper_pct"].items()), highlight=False)
    ci = report["chain_info"]
    if mu > 0:
        console.print(f"chain with friction mu {ci['mu']:g}: {ci['contacts']} contact points, "
                      f"secant of +-{ci['amplitude_mm_rad'][0]:g} mm / "
                      f"{1e3 * ci['amplitude_mm_rad'][1]:g} mrad, asymmetry "
                      f"{ci['asymmetry']:.2e}, {ci['seconds']:.2f} s", highlight=False)
    else:
        console.print(f"chain: {ci['geometry']}; {ci['elements']} beams, {ci['contacts']} "
                      f"contact points, {ci['seconds']:.2f} s", highlight=False)
    fem_info = report["fem_info"]
    if fem_info is not None:
        console.print(f"FEM: {fem_info['n_nodes']} nodes, {fem_info['n_cells']} TET{fem_info['cell_nodes']}"
                      f", {fem_info['coil_pairs']} coil + {fem_info['seat_contacts']} seat contacts "
                      f"(frictionless, {fem_info['gaps']} gaps), condensed "
                      f"asymmetry {fem_info['asymmetry']:.2e}, {fem_info['timings_s']['total']:.0f} s",
                      highlight=False)


@app.command()
def flexure(preset: str = typer.Option("visiflex-catalog", "--preset",
                                       help="Spring preset: visiflex-catalog (default: wire diameter 2.03 mm, "
                                            "1.75 active turns, the spring `predict flexure` builds) or "
                                            "visiflex (seed 002 as printed)."),
            set_: Optional[List[str]] = typer.Option(None, "--set", metavar="NAME=VALUE",
                                                     help="Override a spring parameter (mm, rad, MPa)."),
            frame: str = typer.Option("camera", "--frame", help="spring (centre of the spring) or camera."),
            json_out: Optional[Path] = typer.Option(None, "--json", help="Write all matrices as JSON (SI)."),
            fem: bool = typer.Option(False, "--fem/--no-fem",
                                     help="Also mesh and solve the solid helix with coil and seat "
                                          "contact (minutes; the beam chain always runs)."),
            seat: str = typer.Option("bonded", "--seat",
                                     help="Beam chain ends: bonded (ground faces epoxied), "
                                          "contact (seated, wire end bonded) or potted (dead turn in epoxy)."),
            working_load: float = typer.Option(10.0, "--working-load",
                                               help="Axial load of the second linearisation, N (0: none)."),
            mu: float = typer.Option(0.0, "--mu",
                                     help="Coulomb friction at the beam chain's coil and seat contacts "
                                          "(0: frictionless, the default; 0.3: dry steel on steel). With "
                                          "friction the 6x6 is a secant of +-0.02 mm / 2 mrad perturbations."),
            edge_length: Optional[float] = typer.Option(None, "--edge-length",
                                                        help="FEM tet edge length, mm (default: wire radius)."),
            curved: Optional[bool] = typer.Option(None, "--curved/--straight",
                                                  help="With --fem: TET10 mid-edge nodes on the wire's surface "
                                                       "(the default: the round section not faceted, no-contact "
                                                       "6x6 converged, 6.9 % stiffer than --straight; "
                                                       "docs/validation/flexure.md)."),
            paper_json: Optional[Path] = typer.Option(None, "--paper-json",
                                                      help="Seed 002 paper data (JSON; default: the copy packaged with designlab, "
                                                           "designlab/data/papers/visiflex_flexure.json, the same file as "
                                                           "shared/data/papers/, which is read first when present).")):
    """Seed 002 spring flexure 6x6 stiffness: closed form, beam chain, solid FEM (--fem), paper theory and measurement (SI)."""
    from designlab.sensors.flexure import report as fr
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.spring import preset as spring_preset
    from designlab.sensors.flexure.stress import stress_table, wire_stress

    _check_frame(frame, fr.FRAMES)
    spring = with_overrides(spring_preset(preset), parse_sets(set_))
    paper = fr.load_paper(paper_json)
    _check_mu_curved(mu, curved, fem)
    chain = _chain(spring, seat, working_load, mu)
    K_fem = K_fem_loaded = fem_info = None
    if fem:
        K_fem, K_fem_loaded, fem_info = _solid_fem(spring, edge_length, working_load, curved)
    report = fr.flexure_report(spring, frame=frame, K_fem_spring_si=K_fem, paper=paper,
                               K_chain_spring_si=chain.K_centre_si,
                               K_chain_loaded_si=chain.K_loaded_centre_si,
                               K_fem_loaded_si=K_fem_loaded)
    report["fem_info"] = fem_info
    report["chain_info"] = chain.info
    for table in fr.report_tables(report):
        console.print(table)
    _print_solvers(report, mu)
    for note in report["notes"]:
        console.print(plain(("note:", "bold"), " ", note), highlight=False)
    report["stress"] = wire_stress(spring, chain_settings=ChainSettings(seat=seat))
    console.print(stress_table(report["stress"]))
    for w in report["stress"]["warnings"]:
        warn(w)
    if json_out is not None:
        fr.write_json(json_out, report)
        console.print(f"wrote {json_out}", highlight=False, markup=False)
        next_step(f"open next: {json_out} (every matrix, SI units); designlab predict "
                  "flexure --out OUT (its virtual test and report)")
    else:
        next_step("open next: designlab flexure --json FILE (every matrix, SI units), or "
                  "designlab predict flexure --out OUT (its virtual test and report)")
