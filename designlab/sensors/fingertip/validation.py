"""The fingertip beside seed 001 (``designlab validate fingertip``): the paper comparison of a
design's virtual test (its load paths, the contact model on the paper's Table II sensor and
Table III design: :func:`designlab.sensors.fingertip.paper.paper_comparison`), the goal rows
read from it and its figure.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from designlab.sensors.fingertip.model import contact_settings
from designlab.sensors.sensor import Goal

#: seed 001: measured condition number of A_opt (../shared/data/papers/fingertip_xu2014.json)
PAPER_CONDITION_NUMBER = 34.92
#: the paper's words for the radial estimate ("quite well", Fig. 9) read as a relative error
RADIAL_ERROR_GOAL = 0.1
#: the paper's "quite well" for the lateral loads' direction (no number), deg
ROTATION_GOAL_DEG = 10.0
#: the compressed sensor's r1 -> r5 change: within this many points of the paper's 9.6 %
CHANGE_R_POINTS = 15.0

#: Fig. 9's error definitions in words
DEFINITION_WORDS = {"paper_eq3_normal_component": "paper's eq. 3 (normal components)",
                    "full_force": "full-force"}

#: the explanation of the condition number: contact model / linear model (``load_paths`` share)
EXPLANATION = {
    "contact": (
        "The ideal rigid geometry of eq. 8 gives {geo:.3f}. Of an axial force P_z {z:.1f} % "
        "reaches the sensors (radial {x:.0f} % / {y:.0f} %, linear load paths at the "
        "structure's moduli); the rest goes through the M2.5 bolt and the printed cap in "
        "parallel. The contact model adds Hertz compliance, friction (Mindlin's partial slip "
        "and Coulomb sliding) at the three contacts, the bolt preload and the FSS015/DAQ "
        "readout errors; cond(A) here is {cond:.1f} for this design and protocol (the paper's "
        "34.92 is the Table III design's: see contact.table_III_design)."),
    "linear": (
        "The ideal rigid geometry of eq. 8 gives {geo:.3f}. In the model only {z:.1f} % of an "
        "axial force P_z reaches the sensors (radial: {x:.0f} % / {y:.0f} %); the rest goes "
        "through the preloaded M2.5 bolt and the printed bottom cap in parallel, so the axial "
        "sensitivity is {ratio:.0f}x lower than the radial one and cond(A) rises to {cond:.1f} "
        "(paper: {paper}). The paper blames the same path (the bolt pushed out by P_z, the "
        "elastic bottom cap). What the model leaves out: contact compliance and friction at the "
        "ball/sensor contacts, the bolt's preload state, printing anisotropy; the cap support "
        "(setting cap_support) moves the share of P_z most."),
}


def comparison(part, protocol, prediction, report: dict[str, Any], tested=None) -> dict:
    """The design's paper comparison: its condition number beside the paper's and what drives
    it (``report["load_paths"]``); with the contact model (``prediction.condensed``) the
    paper's two designs (``contact``: :func:`~designlab.sensors.fingertip.paper.
    paper_comparison`, Table II on ``tested()``: the tested sensor and its own condensed
    structure) and ``contact.this_design``, the contact run's own comparison
    (``report["paper_comparison"]``)."""
    share = report["load_paths"]["share_through_sensors"]
    cond = report["condition_number"]
    words = {"geo": report["geometric_condition_number"], "cond": cond,
             "paper": PAPER_CONDITION_NUMBER, "ratio": share["x"] / max(share["z"], 1e-12),
             **{k: 100 * v for k, v in share.items()}}
    kind = "linear" if prediction.condensed is None else "contact"
    pc = {"condition_number_paper": PAPER_CONDITION_NUMBER, "condition_number_predicted": cond,
          "geometric_condition_number": report["geometric_condition_number"],
          "explanation": EXPLANATION[kind].format(**words)}
    if prediction.condensed is None:
        return pc
    from designlab.atomic import jsonable
    from designlab.sensors.fingertip.paper import paper_comparison

    own = report.get("paper_comparison")
    out = paper_comparison(part, protocol, contact_settings(prediction.settings),
                           prediction.condensed, report, prediction.settings.rotations_deg,
                           prediction.settings.mesh_fingertip,
                           table_ii=None if tested is None else tested())
    # through JSON as prediction.json held it (non-finite numbers as null)
    pc["contact"] = json.loads(json.dumps(jsonable(out)))
    pc["contact"]["this_design"] = own
    return pc


# ------------------------------------------------------------------------------ goal rows

def quantities(pc: dict[str, Any], load_paths: dict[str, Any]) -> dict[str, Any]:
    """The numbers the goal rows read, by name, from a contact-model paper comparison
    (:func:`comparison`) and the design's load paths."""
    c = pc["contact"]
    g = c["goals"]
    fall, g1, g2 = (g["G1_falls_monotonically_h1_to_h9"], g["lowest_mean_G1"],
                    g["lowest_mean_G2"])
    ch = g["compressed_change_h9_to_h1"]
    ms = ch["moment_sensitivity"]
    pz = g["Pz_error_over_xy"]
    t3 = c["table_III_design"]
    ff = (t3.get("fig9_errors") or {}).get("full_force") or {}
    nf = c["table_II_design"]["hysteresis_percent"]["robust_eq1_span10_noise_free"]
    r5 = c["compressed_change_r1_to_r5"]
    e = t3["relative_error_per_axis_all_weights"]
    q = {"fall": fall.get("h1_over_h9_mean_of_draws", fall["h1_over_h9_with_readout"]),
         "fall_target": fall["target"], "fall_met": fall["met"],
         "fall_share": 100 * fall.get("share_of_draws_monotonic", float("nan")),
         "nf_h1": nf["G1_by_location"]["h1"], "nf_h9": nf["G1_by_location"]["h9"],
         "ch": ch["value_pct"], "ch_paper": ch["paper_pct"], "ch_target": ch["target"],
         "ch_met": ch["met"], "rho": ms["rho_per_mm_fem"]["frictionless"],
         "rho_paper": ms["rho_per_mm_paper"],
         "ch_applied": ch["by_definition"]["percent_of_applied_force"]["value_pct"],
         "ch_applied_met": ch["by_definition"]["percent_of_applied_force"]["met"],
         "r5": r5["value_pct"], "r5_paper": r5["paper_pct"],
         "r5_target": f"within {CHANGE_R_POINTS:g} points of {r5['paper_pct']:g} %",
         "r5_met": bool(r5["value_pct"] is not None
                        and abs(r5["value_pct"] - r5["paper_pct"]) <= CHANGE_R_POINTS),
         "r5_share": 100 * (r5.get("axial_share_through_sensors") or float("nan")),
         "pz": pz["value"], "pz_target": pz["target"], "pz_met": pz["met"],
         "pz_definition": DEFINITION_WORDS.get(pz["definition"], pz["definition"]),
         "pz_ceiling": pz["by_definition"].get(pz["definition"], {}).get("ceiling",
                                                                         float("nan")),
         "cond": t3["condition_number"], "cond_paper": t3["condition_number_paper"],
         "cond_met": bool(abs(t3["condition_number"] / t3["condition_number_paper"] - 1) < 0.5),
         "share_z": 100 * load_paths["share_through_sensors"]["z"],
         "rot": ff.get("xy_rotation_error_rms_deg_heaviest_weight"),
         "rot_all": ff.get("xy_rotation_error_rms_deg", float("nan")),
         "radial": max(e["x"], e["y"]),
         "radial_met": bool(max(e["x"], e["y"]) <= RADIAL_ERROR_GOAL)}
    q["ratio_rho"] = q["rho"] / q["rho_paper"]
    q["rot_met"] = None if q["rot"] is None else bool(q["rot"] < ROTATION_GOAL_DEG)
    for grp, gk in (("g1", g1), ("g2", g2)):
        q |= {grp: gk.get("value_with_readout_mean_of_draws_pct", gk["value_with_readout_pct"]),
              f"{grp}_paper": gk["paper_pct"], f"{grp}_target": gk["target"],
              f"{grp}_met": gk["met"], f"{grp}_nf": gk["value_noise_free_pct"],
              f"{grp}_sd": gk.get("sd_over_draws_pct", float("nan")),
              f"{grp}_draws": gk.get("draws", 0)}
    return q


#: the fingertip's goals: name (unit), then the keys of :func:`quantities` for the value, the
#: paper's number (None: the paper prints none), the target and whether it is met, and the
#: sentence (``str.format`` on the quantities)
GOAL_ROWS = (
    ("G1 hysteresis h1 / h9 (Table II, mean over the readout draws) (-)", "fall", None,
     "fall_target", "fall_met",
     "Friction alone falls at every step from {nf_h1:.3g} % at h1 to {nf_h9:.3g} % at h9 "
     "(Fig. 6's trend), and one readout draw falls at every step in {fall_share:.0f} % of draws."),
    ("lowest mean G1 hysteresis (Table II) (%)", "g1", "g1_paper", "g1_target", "g1_met",
     "With the FSS015/DAQ readout, mean over {g1_draws} draws (sd {g1_sd:.2g} %); friction "
     "alone gives {g1_nf:.3g} %."),
    ("lowest mean G2 hysteresis (Table II) (%)", "g2", "g2_paper", "g2_target", "g2_met",
     "The readout noise on the small G2 spans sets it (mean over {g2_draws} draws, sd "
     "{g2_sd:.2g} %); friction alone gives {g2_nf:.3g} %."),
    ("compressed-sensor change h9 -> h1, of the first span (%)", "ch", "ch_paper", "ch_target",
     "ch_met", "The sensors answer the load's moment about the ball {ratio_rho:.2g}x more than "
     "the paper's number implies ({rho:.3g} against {rho_paper:.2g} per mm of arm, "
     "frictionless FEM)."),
    ("compressed-sensor change h9 -> h1, of the applied force (%)", "ch_applied", "ch_paper",
     "ch_target", "ch_applied_met",
     "The paper's sentence read literally: the change in N of sensor force over the applied "
     "force change from the empty tray to the heaviest weight."),
    ("compressed-sensor change r1 -> r5, of the first span (%)", "r5", "r5_paper", "r5_target",
     "r5_met", "Only {r5_share:.3g} % of P_z reaches the sensors, so the moment of an off-axis "
     "P_z dominates the small axial reading."),
    ("P_z relative error over the x/y errors (Table III design, Fig. 9) (-)", "pz", None,
     "pz_target", "pz_met",
     "In the {pz_definition} definition a least-squares calibration tested on its own sets "
     "caps the ratio at {pz_ceiling:.3g} with these x/y errors, which are the load's moment "
     "arm, not noise."),
    ("condition number (Table III design) (-)", "cond", "cond_paper", None, "cond_met",
     "Only {share_z:.1f} % of an axial force reaches the sensors (the bolt and the printed cap "
     "carry the rest: the path the paper blames), yet the model's calibration is better "
     "conditioned than the printed sensor's."),
    ("lateral load direction error at the heaviest weight (Table III design) (deg)", "rot",
     None, None, "rot_met",
     "The heaviest weight's loads are well above the readout noise; over every weight it is "
     "{rot_all:.2g} deg."),
    ("radial force relative error, larger of x and y (Table III design) (-)", "radial", None,
     None, "radial_met",
     "The readings depend on the load's moment arm about the ball, which a 3 x 3 force "
     "calibration over several arms cannot absorb."),
)

#: targets of the rows whose comparison states none in words
TARGETS = {"cond": f"within 50 % of {PAPER_CONDITION_NUMBER}",
           "rot": f"< {ROTATION_GOAL_DEG:g} deg (Sec. IV: 'quite well', no number)",
           "radial": f"<= {RADIAL_ERROR_GOAL:g} (Fig. 9: 'quite well')"}


def goal_rows(pc: dict[str, Any], load_paths: dict[str, Any]) -> list[Goal]:
    """The goals (:data:`GOAL_ROWS`) of a contact-model paper comparison."""
    q = quantities(pc, load_paths)
    return [Goal(name, q[value], None if paper is None else q[paper],
                 q[target] if target is not None else TARGETS[value], q[met],
                 why.format(**q)) for name, value, paper, target, met, why in GOAL_ROWS]


# ------------------------------------------------------------------------------ figure

def draw(pc: dict[str, Any], out: str | Path) -> Path:
    """``paper_comparison.png`` in ``out`` (:func:`paper_comparison_figure`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from designlab.atomic import atomic_path

    path = Path(out) / "paper_comparison.png"
    fig = paper_comparison_figure(pc["contact"], plt)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path


def paper_comparison_figure(contact: dict[str, Any], plt):
    """Seed 001 beside the contact model: G1/G2 hysteresis by location (Fig. 6's trend and
    lowest means), the compressed-sensor changes (Sec. III), Fig. 9's errors per axis. The
    shared look (:mod:`designlab.sensors.plotstyle`): a colour and marker per series, legends
    beside the data with black text; a fixed grid whose margins and gaps hold the labels and
    the legends (saved without ``bbox_inches="tight"``: one draw; constrained layout and the
    tight box drew it four times, ~1.2 s CPU), the log axes labelled in plain numbers (no
    mathtext). (``plt`` is unused, kept for the caller.)"""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    from designlab.sensors.plotstyle import figure, legend_outside, series_style

    fig, axes = figure(2, 2, width=14.0, height=9.0, fixed=True, top=0.9, wspace=0.7,
                       hspace=0.32)
    fig.subplots_adjust(left=0.065, right=0.85, bottom=0.07)
    t2 = contact.get("table_II_design", {})
    paper = contact["paper"]
    labels = {"robust_eq1_span10": "model, robust eq. 1,\nwith readout",
              "paper_eq1_all_sensors": "model, paper's eq. 1\n(all sensors), with readout",
              "robust_eq1_span10_noise_free": "model, robust eq. 1,\nfriction alone"}
    for ax, grp, xs, xlabel, lo in (
            (axes[0, 0], "G1", t2.get("heights_mm"), "load height above the ball centre "
             "(h9 ... h1), mm", paper["lowest_mean_G1_pct"]),
            (axes[0, 1], "G2", t2.get("radii_mm"), "load radius (r1 ... r5), mm",
             paper["lowest_mean_G2_pct"])):
        hp = t2.get("hysteresis_percent", {})
        for i, (key, lab) in enumerate(labels.items()):
            if key not in hp:
                continue
            vals = np.array(list(hp[key][f"{grp}_by_location"].values()), float)
            ax.semilogy(xs, np.maximum(vals, 1e-6), ls="-", ms=5, label=lab, **series_style(i))
        dr = (t2.get("readout_draws") or {}).get(f"{grp}_by_location")
        if dr and xs is not None and len(dr) == len(xs):
            m = np.array([v["mean"] for v in dr.values()])
            sd = np.array([v["sd"] for v in dr.values()])
            st = series_style(len(labels))
            ax.errorbar(xs, m, yerr=[np.minimum(sd, 0.9 * m), sd], ls=":", capsize=3,
                        color=st["color"], marker=st.get("marker", "o"), ms=4,
                        label=f"model, robust, readout\nmean +- sd, "
                              f"{t2['readout_draws']['draws']} draws")
        ax.axhline(lo, color="k", ls="--", lw=1, label=f"paper: lowest mean\n{grp} {lo} %")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{grp} hysteresis, % of span (eq. 1)")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.grid(alpha=0.3, which="both")
        legend_outside(ax, fontsize=7)
    axes[0, 0].set_title("G1 (Table II design); paper, Fig. 6: falls exponentially\ntoward "
                         "the base", fontsize=9)
    axes[0, 1].set_title("G2 (Table II design)", fontsize=9)
    ax = axes[1, 0]
    g = contact.get("goals", {})
    ch = [("h9 -> h1", g.get("compressed_change_h9_to_h1", {}).get("value_pct"),
           paper["compressed_change_h9_to_h1_pct"]),
          ("r1 -> r5", contact.get("compressed_change_r1_to_r5", {}).get("value_pct"),
           paper["compressed_change_r1_to_r5_pct"])]
    x = np.arange(len(ch))
    ax.bar(x - 0.18, [c[1] if c[1] is not None else np.nan for c in ch], 0.36, label="model",
           color=series_style(0)["color"])
    ax.bar(x + 0.18, [c[2] for c in ch], 0.36, label="paper (Sec. III)", color="0.35",
           hatch="//", edgecolor="white")
    ax.set_xticks(x, [c[0] for c in ch])
    ax.set_xlabel("load moved (Table II design)")
    ax.set_ylabel("change of the compressed sensor's reading, %")
    legend_outside(ax)
    ax.grid(alpha=0.3, axis="y")
    ax = axes[1, 1]
    t3 = contact.get("table_III_design", {})
    f9 = t3.get("fig9_errors", {})
    # the P_z goal's two readings side by side: the paper's eq. 3 (normal components, what
    # Fig. 9 plots; the goal's value) and the full hanging force
    bars = [(f"paper's eq. 3\n(normal components):\nP_z / max(x, y) "
             f"{f9[k]['Pz_over_xy']:.2f}", f9[k]["relative_error_per_axis"])
            for k in ("paper_eq3_normal_component",) if k in f9]
    e = t3.get("relative_error_per_axis_all_weights")
    if e:
        ratio = e["z"] / max(e["x"], e["y"])
        bars.append((f"full force:\nP_z / max(x, y) {ratio:.2f}", e))
    x = np.arange(3)
    width = 0.8 / max(len(bars), 1)
    for i, (label, err) in enumerate(bars):
        ax.bar(x + (i - (len(bars) - 1) / 2) * width, [err["x"], err["y"], err["z"]], width,
               label=label, color=series_style(i)["color"])
    if bars:
        ax.set_title(f"Table III design: cond(A) {t3['condition_number']:.1f} (paper 34.92); "
                     "Fig. 9: P_z worst (goal >= 3x)", fontsize=9)
        legend_outside(ax, fontsize=7)
    ax.set_xticks(x, ["P_x", "P_y", "P_z"])
    ax.set_xlabel("force component (calibration over every weight and location)")
    ax.set_ylabel("relative RMS error, applied vs estimated (-)")
    ax.grid(alpha=0.3, axis="y")
    fig.suptitle("seed 001 beside the contact model (friction, Hertz, preload at the ball)")
    return fig
