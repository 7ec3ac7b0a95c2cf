"""Fit the Prony series of the stretch-rig elastomer from its measured stepped-strain test.

    python examples/fit_silicone_prony.py

Reads ../shared/data/stretch/2_7-5_4Epin_20mm_10prestrain3.csv through a dataset card, turns
elongation into strain (40 mm gauge length) and force into stress (10 x 4 mm section, the
force offset of the first second removed), and fits a 2-term generalized Maxwell material to the
whole history. The printed numbers are the ``silicone`` entry of designlab.fem.materials (and the
stand-in relaxation of the conductive TPU, same physics per ../shared/data/README.md).
"""

from pathlib import Path

from designlab.measured.dataset import load_card
from designlab.fem.prony_fit import fit_prony_history

LENGTH_MM, AREA_MM2 = 40.0, 10.0 * 4.0


def main() -> None:
    card = Path(__file__).parent / "cards" / "stretch_relaxation.toml"
    d = load_card(card)
    f = d.outputs["force"]
    f0 = f[d.t - d.t[0] < 1.0].mean()
    E0, prony, rep = fit_prony_history(d.t, d.inputs["displacement"] / LENGTH_MM,
                                       (f - f0) / AREA_MM2, n_terms=2, start="relaxed")
    print(f"E0 = {E0:.4f} MPa, g = {tuple(round(x, 4) for x in prony.g)}, "
          f"tau = {tuple(round(x, 2) for x in prony.tau)} s, "
          f"rms error {100 * rep['rms_rel_error']:.2f} % of max stress ({rep['n_points']} samples)")


if __name__ == "__main__":
    main()
