"""The flexure beside seed 002 (``designlab validate flexure``): the Visiflex spring's 6x6
stiffness by closed form and beam chain against the paper's theory and measured K_c
(:func:`designlab.sensors.flexure.report.flexure_report`, as ``designlab flexure`` computes it
at its defaults), and the force-sensing test beside Table I
(:func:`designlab.sensors.flexure.force_error.run_force_test` on the default virtual test).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from designlab.sensors.sensor import Goal

#: the stiffness goals (seed 002's measured K_c, camera frame): mean |error| over the diagonal
DIAGONAL_GOAL_PCT = 15.0
#: ... and each coupling within this factor of the measured
COUPLING_FACTOR = 1.5
#: the beam chain's second linearisation, N (``designlab flexure --working-load``)
WORKING_LOAD_N = 10.0
#: the closed form reproduces the paper's theory K_f within this on every diagonal entry, %
THEORY_PCT = 3.0
#: the models compared with the measurement, in words
MODELS = {"closed_form_timoshenko": "Timoshenko's closed form",
          "chain": "the beam chain, unloaded",
          "chain_loaded": f"the beam chain at {WORKING_LOAD_N:g} N (coil contacts closed)"}
AXES = ("x", "y", "z")


def stiffness_report(progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """``designlab flexure``'s report at its defaults: the catalogue spring, camera frame, the
    beam chain bonded at both ends, unloaded and at :data:`WORKING_LOAD_N`, no solid FEM."""
    from designlab.sensors.flexure import report as fr
    from designlab.sensors.flexure.beam_chain import chain_stiffness
    from designlab.sensors.flexure.chain_geometry import ChainSettings
    from designlab.sensors.flexure.spring import preset

    if progress:
        progress("beam chain of the Visiflex spring")
    spring = preset("visiflex-catalog")
    chain = chain_stiffness(spring, ChainSettings(seat="bonded", working_load_N=WORKING_LOAD_N))
    return fr.flexure_report(spring, frame="camera", paper=fr.load_paper(),
                             K_chain_spring_si=chain.K_centre_si,
                             K_chain_loaded_si=chain.K_loaded_centre_si)


def _within(ratio: float, factor: float) -> bool:
    return bool(1 / factor <= ratio <= factor)


def stiffness_goals(rep: dict[str, Any]) -> list[Goal]:
    """The diagonal and coupling goals per model (:data:`MODELS`), the closed form against the
    paper's theory and the offset-free bound."""
    h_mm, centre_mm = 1e3 * rep["offset_m"], 1e3 * rep["measured_elastic_centre_m"]
    rows = {r["entry"]: r for r in rep["rows"]}
    out = []
    for key, words in MODELS.items():
        d = rep["goals"][key]["diagonal_mean_abs_error_pct"]
        out.append(Goal(f"mean |error| over the measured diagonal, {words} (%)", d, None,
                        f"<= {DIAGONAL_GOAL_PCT:g} %", bool(d <= DIAGONAL_GOAL_PCT),
                        f"The camera frame at the paper's {h_mm:.2f} mm offset; the six "
                        "diagonal entries of K_c against seed 002's measured ones."))
        for entry in ("k_wx_vy", "k_wy_vx"):
            r = rows[entry]
            out.append(Goal(
                f"coupling {entry}, {words} (N)", r[key], r["paper_measured"],
                f"within {COUPLING_FACTOR:g}x of the measured", _within(
                    r[key] / r["paper_measured"], COUPLING_FACTOR),
                f"The measured K_c's couplings vanish {centre_mm:.2f} mm above the camera, "
                f"a symmetric-ended model's at the spring centre, {h_mm:.2f} mm above it."))
    dev = 100 * max(abs(r - 1) for r in rep["common_factor"]["per_entry"])
    out.append(Goal("closed form against the paper's theory K_f, largest deviation on the "
                    "diagonal (%)", dev, None, f"<= {THEORY_PCT:g} %", bool(dev <= THEORY_PCT),
                    "The paper's 2.03 mm read as the wire diameter with the closed end coils "
                    "inactive (the catalogue reading): the paper's own formula at the spring "
                    "centre."))
    inv = rep["offset_free"]
    limit = inv["ratio_limit_paper_offset"]["lateral_over_rocking"]
    q = inv["chain_loaded"]["lateral_over_rocking"]["x"]
    out.append(Goal(
        f"lateral over rocking stiffness at the elastic centre, {MODELS['chain_loaded']}, x "
        "(1/m^2)", q, inv["paper_measured"]["lateral_over_rocking"]["x"],
        f"<= {limit:.0f}: else no model meets both stiffness goals at the paper's offset",
        bool(limit is not None and q <= limit),
        "No camera offset or pose point changes this ratio: the measured spring rocks stiffer "
        "for its lateral stiffness than the model."))
    return out


def force_goals(test: dict[str, Any]) -> list[Goal]:
    """The force error per axis beside Table I (std, N)."""
    b = test["budget"]
    return [Goal(f"force error std, {a} (N)", test["per_axis"][a]["std"],
                 test["paper_table_I"][a]["std"], f"within {COUPLING_FACTOR:g}x of Table I",
                 _within(test["std_over_paper"][a], COUPLING_FACTOR),
                 f"Pose noise {1e3 * b['pose_noise_mm']:.0f} um and {b['hysteresis_percent']:g} "
                 f"% hysteresis through K_c fitted on {b['model_points']} points, tested on "
                 f"{b['test_points']}; hysteresis is "
                 f"{100 * test['split_variance_share'][a]['hysteresis']:.0f} % of the variance.")
            for a in AXES]


def validate(details: dict[str, Any], out: str | Path | None = None,
             progress: Callable[[str], None] | None = None) -> list[Goal]:
    """``designlab validate flexure``: the stiffness comparison (:func:`stiffness_report`) and
    the force-sensing test of the default virtual test; ``details`` gets both (JSON-able). No
    figure (``out`` unused)."""
    from designlab.atomic import jsonable
    from designlab.sensors.flexure.force_error import run_force_test
    from designlab.sensors.flexure.model import run

    rep = stiffness_report(progress)
    if progress:
        progress("force-sensing test (Table I)")
    pred = run(progress=progress, wire_stress=False)
    test = run_force_test(pred.K_true, pred.K_design)
    details.update({"stiffness": jsonable({k: v for k, v in rep.items()
                                           if not isinstance(v, np.ndarray)}),
                    "force_error_test": jsonable(test)})
    return stiffness_goals(rep) + force_goals(test)
