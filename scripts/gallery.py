"""The images of docs/gallery.md (and the part renders of docs/parts.md), made by the example
scripts and the README's commands, shrunk for the repository.

    python scripts/gallery.py              # all images into docs/img/ and docs/gallery.md
    python scripts/gallery.py --page-only  # only docs/gallery.md (no image is made)
    python scripts/gallery.py --only fingertip --reuse fingertip=OUT   # images of a finished run

Each image is made by the command its entry names (run in a temporary folder), then scaled to at
most ``MAX_WIDTH`` pixels and stored as a 128-colour PNG (``shrink``) so that the whole gallery
stays a few hundred kB. ``tests/docs/test_docs_gallery.py`` checks that the page is
:func:`gallery_page` and that every image it links exists.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
PAGE = ROOT / "docs" / "gallery.md"
MAX_WIDTH = 720
COLOURS = 128


@dataclass(frozen=True)
class Entry:
    image: str        # file name under docs/img/
    source: str       # the job that makes it (a key of JOBS)
    produced: str     # the file that job writes (relative to its output folder)
    caption: str


#: job -> (section title, the command a user types (``OUT``: the output folder), a note)
JOBS = {
    "parts": ("Parts at their defaults", "examples/parts_gallery.py",
              "its `render_parts(OUT)`; `designlab show PART --out F.png` renders one part"),
    "readme": ("The README's figure", "python scripts/readme_figures.py --only figure",
               "drawn from the part's outline and load points, no FEM"),
    "main-job": ("The main job: a sweep of the fingertip over h and r",
                 "designlab optimize examples/sweep_fingertip_quick.toml --out OUT", ""),
    "fingertip": ("The seed 001 fingertip's virtual test",
                  "designlab predict fingertip --out OUT", ""),
    "validate": ("The seed 001 fingertip beside its paper",
                 "designlab validate fingertip --out OUT", ""),
    "flexure": ("The seed 002 flexure's virtual test", "designlab predict flexure --out OUT", ""),
    "loop": ("The measured-data loop on the fingertip's example data",
             "designlab loop --data examples/data/fingertip_card.toml --base load-arm --out OUT",
             "the data: `python examples/loop_synthetic.py`"),
}

ENTRIES = [
    Entry("part_strap.png", "parts", "part_strap.png",
          "Seed 000 arch strap, printed flat: NinjaFlex strap, two PI-ETPU gauge meanders "
          "(black), the nail plate beside it."),
    Entry("part_fingertip.png", "parts", "part_fingertip.png",
          "Seed 001 fingertip at its defaults (the optimised Table III dome, h = 0, r = 9): "
          "printed fingertip, base and cap; the steel ball, bolt and three FSS015 sensors "
          "(bought) see-through."),
    Entry("part_fingertip_tested.png", "parts", "part_fingertip_tested.png",
          "The tested sensor of seed 001 Table II (h = 28.5, r = 9, 48.5 mm high)."),
    Entry("part_flexure.png", "parts", "part_flexure.png",
          "Seed 002 Visiflex flexure: the SS302 spring (1.75 active coils, closed and ground "
          "ends) between two printed PLA discs."),
    Entry("fingertip_loads.png", "readme", "fingertip_loads.png",
          "h, r and the load points of seed 001: G1 lateral loads at heights h1.., G2 axial "
          "loads at radii r1.. (Table II)."),
    Entry("main_job_pareto.png", "main-job", "pareto.png",
          "G1 friction hysteresis against condition number of the four designs (the two "
          "h = 22 designs coincide), with their mesh error bars; the chosen design ringed."),
    Entry("fingertip_deformed.png", "fingertip", "deformed.png",
          "The meshed bodies (printed base and cap) deformed under load case h1 (G1), with the "
          "load arrow, the case and the bodies named."),
    Entry("fingertip_hysteresis_loops.png", "fingertip", "hysteresis_loops.png",
          "Loading (solid, filled) and unloading (dashed, open) per sensor and load point."),
    Entry("fingertip_paper_comparison.png", "validate", "paper_comparison.png",
          "Seed 001 beside the contact model: G1 and G2 hysteresis per location, the compressed "
          "sensor's rise, the Table III design's force errors."),
    Entry("flexure_wrench.png", "flexure", "flexure_wrench.png",
          "The flexure's virtual test: the wrench estimated from the pose with the closed-form "
          "K_f against the applied one (the beam chain of the spring as built is the truth)."),
    Entry("loop_timeseries_sensor_1.png", "loop", "timeseries_sensor_1.png",
          "Sensor 1 on the held-out data: measured, the base model, the base with the learned "
          "effects (physics) and the NARX peer, with their residuals."),
    Entry("loop_effect_friction_arm.png", "loop", "effect_sensor_1_1_friction_arm_weight_.png",
          "The first effect the loop accepted for sensor 1, friction x moment arm: the residual "
          "before against the effect's regressor and its fitted contribution."),
]


def shrink(src: Path, dst: Path, max_width: int = MAX_WIDTH, colours: int = COLOURS) -> Path:
    """``src`` scaled to at most ``max_width`` pixels wide, as a ``colours``-colour PNG."""
    from PIL import Image

    im = Image.open(src).convert("RGB")
    w, h = im.size
    if w > max_width:
        im = im.resize((max_width, round(h * max_width / w)), Image.LANCZOS)
    q = im.quantize(colors=colours, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    dst.parent.mkdir(parents=True, exist_ok=True)
    q.save(dst, optimize=True)
    return dst


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def _designlab(*args: str, cwd: Path) -> None:
    cmd = [sys.executable, "-m", "designlab.cli", *args]
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed (exit {p.returncode}):\n{p.stderr[-2000:]}")


def run_job(job: str, out: Path) -> Path:
    """Run ``job`` with its output in ``out``; returns ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    if job == "parts":
        _load(ROOT / "examples" / "parts_gallery.py", "parts_gallery").render_parts(out)
    elif job == "readme":      # the README's own figure, in place (not shrunk)
        _load(ROOT / "scripts" / "readme_figures.py", "readme_figures").fingertip_figure(
            IMG / "fingertip_loads.png")
    elif job == "main-job":
        _designlab("optimize", str(ROOT / "examples" / "sweep_fingertip_quick.toml"), "--out",
                   str(out / "o"), cwd=ROOT)
        return out / "o"
    elif job in ("fingertip", "flexure"):
        _designlab("predict", job, "--out", str(out / "o"), cwd=ROOT)
        return out / "o"
    elif job == "validate":
        _designlab("validate", "fingertip", "--out", str(out / "o"), cwd=ROOT)
        return out / "o"
    elif job == "loop":
        _designlab("loop", "--data", str(ROOT / "examples" / "data" / "fingertip_card.toml"),
                   "--base", "load-arm", "--out", str(out / "o"), cwd=ROOT)
        return out / "o"
    else:
        raise SystemExit(f"unknown job {job!r}; one of {', '.join(JOBS)}")
    return out


def gallery_page() -> str:
    lines = ["# Gallery", "",
             "<!-- generated by `python scripts/gallery.py`; tests/docs/test_docs_gallery.py checks "
             "that this page is the generated one and that every image exists -->", "",
             "Images made by the example scripts and the README's commands, at the defaults, "
             "shrunk to at most "
             f"{MAX_WIDTH} px wide and {COLOURS} colours for the repository (the commands write "
             "them full size). Regenerate all of them and this page with "
             "`python scripts/gallery.py` (it runs every command below; `--reuse JOB=DIR` takes "
             "a job's images from a folder the same command wrote). Each section names the "
             "command that makes its images; `OUT` is any output folder. The parameters of each "
             "part: [parts.md](parts.md).", ""]
    for job, (title, command, note) in JOBS.items():
        entries = [e for e in ENTRIES if e.source == job]
        lines += [f"## {title}", "", f"`{command}`" + (f" ({note})" if note else ""), ""]
        for e in entries:
            lines += [f"![{e.caption}](img/{e.image})", "", f"*{e.image}* (`{e.produced}`): "
                      f"{e.caption}", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--page-only", action="store_true", help="only write docs/gallery.md")
    ap.add_argument("--only", default=",".join(JOBS),
                    help="comma-separated jobs to run: " + ", ".join(JOBS))
    ap.add_argument("--reuse", action="append", default=[], metavar="JOB=DIR",
                    help="take JOB's images from DIR, the output folder of the same command "
                         "run before, instead of running it")
    args = ap.parse_args(argv)
    reuse = {}
    for item in args.reuse:
        job, sep, folder = item.partition("=")
        if not sep or job not in JOBS or not Path(folder).is_dir():
            ap.error(f"--reuse: {item!r} is not JOB=DIR with JOB one of {', '.join(JOBS)} "
                     "and DIR an existing folder")
        reuse[job] = Path(folder)
    if not args.page_only:
        jobs = [j.strip() for j in args.only.split(",") if j.strip()]
        for j in jobs:
            if j not in JOBS:
                ap.error(f"--only: {j!r} is not a job; one of {', '.join(JOBS)}")
        with tempfile.TemporaryDirectory() as tmp:
            for job in jobs:
                out = reuse.get(job) or run_job(job, Path(tmp) / job)
                for e in ENTRIES:
                    if e.source == job and job != "readme":
                        dst = shrink(out / e.produced, IMG / e.image)
                        print(f"{dst.relative_to(ROOT)}: {dst.stat().st_size / 1024:.0f} kB")
    PAGE.write_text(gallery_page(), encoding="utf-8")
    total = sum((IMG / e.image).stat().st_size for e in ENTRIES if (IMG / e.image).exists())
    print(f"wrote {PAGE.relative_to(ROOT)}; gallery images {total / 1024:.0f} kB in total")
    return 0


if __name__ == "__main__":
    sys.exit(main())
