"""Regenerate the README's figure and measured numbers, and check the README against them.

    python scripts/readme_figures.py                       # everything: the main job, 3 predicts
    python scripts/readme_figures.py --only main-job,flexure --check
    python scripts/readme_figures.py --json out/readme_figures.json

Parts (``--only``, comma-separated; default all):

* ``figure``: ``docs/img/fingertip_loads.png``, the seed 001 fingertip in section with h, r and
  the load points (G1 lateral at the heights h1.., G2 axial at the radii r1..), drawn from
  ``CantileverFingertip`` (its outline and ``load_points()``); no FEM.
* ``main-job``: ``designlab optimize examples/sweep_fingertip_quick.toml`` in a temporary
  folder: every design's G1 friction hysteresis and condition number with their mesh error bars
  (|value - coarse-mesh value|) and the chosen design.
* ``flexure``: ``designlab predict flexure``'s numbers (no mesh: condition number, K_f diagonal).
* ``fingertip``, ``strap``: ``designlab predict PART``'s condition number and hysteresis at the
  chosen mesh and the coarse one.

Every number is written to the JSON (default ``out/readme_figures.json``). ``--check`` compares
the README with them and exits 1 naming each disagreement: a README number agrees when it lies
within the number's error bar, or within half a unit of its last printed digit when that is
larger (a number without a mesh has only the rounding). The README's measured numbers are the
main-job block and the one table under "## Measured numbers"; the README names the machine once
and carries no timings.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FIGURE = ROOT / "docs" / "img" / "fingertip_loads.png"
MAIN_JOB = ROOT / "examples" / "sweep_fingertip_quick.toml"
G1 = "hysteresis_percent.by_group_noise_free.G1"
COND = "condition_number"
PARTS = ("figure", "main-job", "flexure", "fingertip", "strap")
#: the main job's README block (between these markers), written by ``--write-readme``
BLOCK = re.compile(r"(<!-- main job: python scripts/readme_figures.py --only main-job "
                   r"--write-readme -->\n)(.*?)(<!-- end main job -->)", re.DOTALL)


# ---------------------------------------------------------------------------------- figure
def fingertip_figure(path: Path = FIGURE) -> Path:
    """Two sections of the seed 001 fingertip (x-z plane): the tested sensor of Table II read
    from its table (h = 16.70, r = 6.37 on its 25.4 mm base: ``CantileverFingertip.table_ii``)
    and the main job's h = 3, r = 6 on the same Table II load points, with the
    straight height h, the rounding radius r, the G1 (lateral, at heights h_i) and G2 (axial, at
    radii r_i) loads, the ball, the base and the cap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    from designlab.geometry.fingertip import CantileverFingertip

    designs = [("seed 001 Table II sensor (h = 16.70, r = 6.37)", CantileverFingertip.table_ii()),
               ("the main job's h = 3, r = 6 on the Table II points",
                CantileverFingertip(h=3.0, r=6.0, load_table="II"))]
    plt.rcParams.update({"font.size": 9, "svg.hashsalt": "designlab"})
    fig, axes = plt.subplots(1, 2, figsize=(8.0, 5.6), layout="constrained",
                             gridspec_kw={"width_ratios": [1, 1]})
    g1c, g2c = "#0072B2", "#D55E00"
    for ax, (title, p) in zip(axes, designs):
        import numpy as np

        z = np.linspace(0.0, p.top_z, 400)
        rad = np.array([p.surface_radius(float(v)) for v in z])
        xs = np.concatenate([-rad[::-1], rad])
        zs = np.concatenate([z[::-1], z])
        ax.fill(xs, zs, color="#E69F00", alpha=0.35, lw=0)
        ax.plot(xs, zs, color="#a06000", lw=1.2, label="printed fingertip (ABS)")
        ax.add_patch(Circle((0, 0), p.ball_radius, fc="#bbbbbb", ec="k", lw=0.8,
                            label="steel ball (on three FSS015)"))
        b0, b1 = p.base_z
        ax.add_patch(Rectangle((-p.base_radius, b0), 2 * p.base_radius, b1 - b0, fc="#dddddd",
                               ec="k", lw=0.8, label="printed base with the sensor wells"))
        c0, c1 = p.cap_z
        ax.add_patch(Rectangle((-p.base_radius, c0), 2 * p.base_radius, c1 - c0, fc="#999999",
                               ec="k", lw=0.8, label="cap (holds the bolt)"))
        R = p.outer_radius
        # h: straight height of the side, from the fingertip's bottom (z = 0, ball centre)
        xd = -R - 3.0
        ax.annotate("", (xd, 0), (xd, p.h), arrowprops=dict(arrowstyle="<->", lw=0.9))
        ax.plot([xd - 0.6, -R], [p.h, p.h], "k:", lw=0.6)
        ax.plot([xd - 0.6, -R], [0, 0], "k:", lw=0.6)
        ax.text(xd - 0.8, p.h / 2, "h", ha="right", va="center", fontsize=11, style="italic")
        # r: rounding radius, drawn from its centre (-(R - r), h) at 135 deg
        if p.r > 0:
            cx, ang = -(R - p.r), math.radians(135)
            ax.annotate("", (cx + p.r * math.cos(ang), p.h + p.r * math.sin(ang)), (cx, p.h),
                        arrowprops=dict(arrowstyle="->", lw=0.9))
            ax.plot(cx, p.h, "k+", ms=5)
            ax.text(cx - 0.3 * p.r, p.h + 0.25 * p.r, "r", ha="right", fontsize=11,
                    style="italic")
        pts = p.load_points()
        for name, (pt, d) in pts.items():
            x, zz = float(pt[0]), float(pt[2])
            if name.startswith("h"):
                ax.annotate("", (x, zz), (x + 4.0, zz), arrowprops=dict(
                    arrowstyle="-|>", color=g1c, lw=1.0, mutation_scale=8))
                ax.text(x + 4.3, zz, name, color=g1c, va="center", fontsize=7)
            else:
                ax.annotate("", (x, zz), (x, zz + 4.0), arrowprops=dict(
                    arrowstyle="-|>", color=g2c, lw=1.0, mutation_scale=8))
                ax.text(x, zz + 4.3, name, color=g2c, ha="center", fontsize=7, rotation=90,
                        va="bottom")
        ax.plot([], [], color=g1c, marker=">", ls="-", label="G1: lateral loads at heights h1..")
        ax.plot([], [], color=g2c, marker="v", ls="-", label="G2: axial loads at radii r1..")
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("z (mm), 0 at the ball centre")
        ax.set_xlim(-R - 8, R + 9)
        ax.set_ylim(c0 - 1, max(p.top_z + 9, 20))
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=2, fontsize=8, labelcolor="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, metadata={"Software": None})
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------------- numbers
def _designlab(*args: str) -> None:
    cmd = [sys.executable, "-m", "designlab.cli", *args]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"designlab {' '.join(args)} failed (exit {p.returncode}):\n"
                         f"{p.stderr[-2000:]}")


def _value_bar(row: dict[str, Any], name: str) -> dict[str, float]:
    """A sweep row's metric with its mesh error bar (|value - coarse-mesh value|)."""
    v, c = row.get(name), row.get(f"mesh_convergence.{name}.coarse")
    return {"value": float(v), "bar": abs(float(v) - float(c)) if c is not None else math.nan}


def main_job(tmp: Path) -> dict[str, Any]:
    """The README's main job, run as the README says: every design's G1 friction hysteresis
    and condition number with their bars, and the chosen design."""
    out = tmp / "main-job"
    _designlab("optimize", str(MAIN_JOB), "--out", str(out))
    return main_job_numbers(out)


def main_job_numbers(out: Path) -> dict[str, Any]:
    """The main job's numbers from its output folder ``out``."""
    import pandas as pd

    opt = json.loads((out / "optimize.json").read_text())
    rows = pd.read_parquet(out / "results.parquet").to_dict("records")
    chosen = opt["chosen"]["key"]
    designs = []
    for r in sorted(rows, key=lambda r: (r["param.h"], r["param.r"])):
        designs.append({"h": float(r["param.h"]), "r": float(r["param.r"]),
                        "G1": _value_bar(r, G1), "cond": _value_bar(r, COND),
                        "chosen": r["key"] == chosen,
                        "not_distinguishable": r["key"] in opt.get("not_distinguishable", [])})
    return {"command": f"designlab optimize {MAIN_JOB.relative_to(ROOT)} --out OUT",
            "designs": designs, "choice": opt.get("choice", "")}


def prediction(part: str, tmp: Path) -> dict[str, Any]:
    """``designlab predict PART``'s numbers of the README's table: condition number and
    hysteresis at the chosen mesh and the coarse one (bar = their difference), K_f diagonal."""
    out = tmp / part
    _designlab("predict", part, "--out", str(out))
    return prediction_numbers(part, out)


def prediction_numbers(part: str, out: Path) -> dict[str, Any]:
    """``prediction.json``'s numbers of the README from ``designlab predict``'s folder."""
    d = json.loads((out / "prediction.json").read_text())
    mc = d.get("mesh_convergence") or {}

    def metric(name: str, value: float) -> dict[str, float]:
        m = mc.get(name)
        if m is None:              # no mesh (closed form / beam chain): deterministic
            return {"value": float(value), "bar": 0.0}
        return {"value": float(m["value"]), "coarse": float(m["coarse"]),
                "bar": abs(float(m["value"]) - float(m["coarse"]))}

    res: dict[str, Any] = {"command": f"designlab predict {part} --out OUT",
                           "condition_number": metric("condition_number",
                                                      d["condition_number"]),
                           "hysteresis": metric("hysteresis_percent.overall",
                                                d["hysteresis_percent"]["overall"])}
    if "hysteresis_percent.overall_noise_free" in mc:
        res["hysteresis_friction_alone"] = metric("hysteresis_percent.overall_noise_free", 0.0)
    if d.get("K_f") is not None and not mc:
        res["K_f_diagonal"] = [float(d["K_f"][i][i]) for i in range(6)]
    return res


def measure(parts: list[str]) -> dict[str, Any]:
    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for part in parts:
            if part == "figure":
                results["figure"] = str(fingertip_figure().relative_to(ROOT))
            elif part == "main-job":
                results["main_job"] = main_job(Path(tmp))
            else:
                results[part] = prediction(part, Path(tmp))
    return results


# ------------------------------------------------------------------------ README comparison
def _half_unit(text: str) -> float:
    """Half a unit of the last printed digit of ``text`` ("0.0092" -> 5e-5, "9166" -> 0.5,
    "7.8e-06" -> 5e-8)."""
    mant, _, exp = text.lower().partition("e")
    dec = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (-dec) * 10.0 ** (int(exp) if exp else 0)


def agrees(text: str, fresh: float, bar: float) -> bool:
    """A printed README number agrees with a fresh one within its bar or its rounding."""
    tol = max(bar if math.isfinite(bar) else 0.0, _half_unit(text))
    return abs(float(text) - fresh) <= tol * (1 + 1e-9)


NUM = r"([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?)"


def main_job_block(res: dict[str, Any]) -> str:
    """The README's table of the main job."""
    lines = ["| h (mm) | r (mm) | G1 friction hysteresis (%) | +- | condition number | +- | |",
             "|---|---|---|---|---|---|---|"]
    for d in res["designs"]:
        mark = "chosen" if d["chosen"] else ("not distinguishable" if d["not_distinguishable"]
                                             else "")
        lines.append(f"| {d['h']:g} | {d['r']:g} | {d['G1']['value']:.4g} | "
                     f"{d['G1']['bar']:.2g} | {d['cond']['value']:.4g} | "
                     f"{d['cond']['bar']:.2g} | {mark} |")
    return "\n".join(lines)


def check_main_job(readme: str, res: dict[str, Any]) -> list[str]:
    m = BLOCK.search(readme)
    if not m:
        return ["README has no main-job block (markers <!-- main job: ... --> .. "
                "<!-- end main job -->)"]
    rows = re.findall(rf"^\| {NUM} \| {NUM} \| {NUM} \| {NUM} \| {NUM} \| {NUM} \| ([^|]*)\|$",
                      m.group(2), re.M)
    fresh = {(d["h"], d["r"]): d for d in res["designs"]}
    errors = []
    if sorted((float(r[0]), float(r[1])) for r in rows) != sorted(fresh):
        return [f"main job: README designs {[(r[0], r[1]) for r in rows]} vs measured "
                f"{sorted(fresh)}"]
    for h, r, g1, _g1bar, cond, _cbar, mark in rows:
        d = fresh[(float(h), float(r))]
        if not agrees(g1, d["G1"]["value"], d["G1"]["bar"]):
            errors.append(f"main job h={h} r={r}: G1 hysteresis README {g1} %, measured "
                          f"{d['G1']['value']:.6g} +- {d['G1']['bar']:.2g}")
        if not agrees(cond, d["cond"]["value"], d["cond"]["bar"]):
            errors.append(f"main job h={h} r={r}: condition number README {cond}, measured "
                          f"{d['cond']['value']:.6g} +- {d['cond']['bar']:.2g}")
        if (mark.strip() == "chosen") != d["chosen"]:
            errors.append(f"main job h={h} r={r}: README says {mark.strip() or 'not chosen'!r}, "
                          f"measured {'chosen' if d['chosen'] else 'not chosen'}")
    return errors


def _table_row(readme: str, first_cell: str) -> list[str]:
    """The cells (after the first) of the predictions table's row ``first_cell``."""
    sec = readme.split("## Measured numbers", 1)
    if len(sec) < 2:
        return []
    for line in sec[1].splitlines():
        if line.startswith(f"| {first_cell} |"):
            return [c.strip() for c in line.strip().strip("|").split(" | ")][1:]
    return []


COLUMN = {"fingertip": 0, "strap": 1, "flexure": 2}


def check_predictions(readme: str, results: dict[str, Any]) -> list[str]:
    errors = []
    for part, col in COLUMN.items():
        res = results.get(part)
        if res is None:
            continue
        for row, key in (("condition number", "condition_number"),
                         ("hysteresis % (eq. 1)", "hysteresis")):
            cells = _table_row(readme, row)
            if len(cells) <= col:
                errors.append(f"README predictions table: no row {row!r} with a {part} column")
                continue
            cell, fresh = cells[col], res[key]
            m = re.match(NUM, cell)
            if not m:
                errors.append(f"{part} {row}: no number at the start of {cell!r}")
                continue
            if not agrees(m.group(1), fresh["value"], fresh["bar"]):
                errors.append(f"{part} {row}: README {m.group(1)}, measured "
                              f"{fresh['value']:.6g} +- {fresh['bar']:.2g}")
            c = re.search(rf"coarse mesh {NUM}", cell)
            if c and "coarse" in fresh and not agrees(c.group(1), fresh["coarse"], fresh["bar"]):
                errors.append(f"{part} {row}: README coarse mesh {c.group(1)}, measured "
                              f"{fresh['coarse']:.6g}")
            if "coarse" in fresh and not c:
                errors.append(f"{part} {row}: README gives no coarse-mesh value in {cell!r}")
        if "hysteresis_friction_alone" in res:
            cell = _table_row(readme, "hysteresis % (eq. 1)")[col]
            f = re.search(rf"friction alone {NUM}", cell)
            fr = res["hysteresis_friction_alone"]
            if f and not agrees(f.group(1), fr["value"], fr["bar"]):
                errors.append(f"{part} friction-alone hysteresis: README {f.group(1)}, measured "
                              f"{fr['value']:.6g} +- {fr['bar']:.2g}")
        if "K_f_diagonal" in res:
            cells = _table_row(readme, "other")
            k = re.search(r"K_f diagonal ([-+\d., e]+)", cells[col] if len(cells) > col else "")
            texts = [t.strip() for t in k.group(1).split(",")] if k else []
            if len(texts) != 6:
                errors.append(f"{part}: README has no 6-entry K_f diagonal")
            else:
                for i, (t, v) in enumerate(zip(texts, res["K_f_diagonal"])):
                    if not agrees(t, v, 0.0):
                        errors.append(f"{part} K_f[{i},{i}]: README {t}, measured {v:.6g}")
    return errors


def check(readme: str, results: dict[str, Any]) -> list[str]:
    """Every disagreement of the README with ``results`` (empty: it agrees)."""
    errors = []
    if "main_job" in results:
        errors += check_main_job(readme, results["main_job"])
    errors += check_predictions(readme, results)
    return errors


def write_readme_block(res: dict[str, Any], path: Path = README) -> None:
    text = path.read_text(encoding="utf-8")
    if not BLOCK.search(text):
        raise SystemExit("README has no main-job block to write")
    path.write_text(BLOCK.sub(lambda m: m.group(1) + main_job_block(res) + "\n" + m.group(3),
                              text),
                    encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=",".join(PARTS),
                    help="comma-separated parts: " + ", ".join(PARTS))
    ap.add_argument("--json", type=Path, default=ROOT / "out" / "readme_figures.json",
                    help="where to write the numbers (default out/readme_figures.json)")
    ap.add_argument("--check", action="store_true",
                    help="compare the README with the numbers; exit 1 on a disagreement")
    ap.add_argument("--write-readme", action="store_true",
                    help="rewrite the README's main-job table from the numbers")
    args = ap.parse_args(argv)
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    for p in parts:
        if p not in PARTS:
            ap.error(f"--only: {p!r} is not a part; one of {', '.join(PARTS)}")
    results = measure(parts)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")
    if args.write_readme and "main_job" in results:
        write_readme_block(results["main_job"])
        print("rewrote the README's main-job table")
    if args.check:
        errors = check(README.read_text(encoding="utf-8"), results)
        for e in errors:
            print("README disagrees:", e)
        if errors:
            return 1
        print("README agrees with " + ", ".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
