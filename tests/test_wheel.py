"""The wheel works outside the repository: build it, install it into a fresh venv in a temporary
folder, run ``designlab flexure --no-fem`` and ``designlab export fingertip`` from another
temporary folder, and check that the package imported is the wheel's and that the paper tables
come from inside it (importlib.resources), not from ../shared or the source tree.

The fresh venv gets the wheel with ``--no-deps``; its dependencies (CAD kernel, gmsh, scipy, ...:
gigabytes, minutes to install) are made visible through one ``.pth`` line naming this
interpreter's site-packages, added *after* the install (so pip never sees, let alone touches, the
development install there). A ``.pth`` path line adds that folder to ``sys.path`` after the venv's
own site-packages without running the ``.pth`` files inside it, so the editable install of the
source tree is not activated: ``designlab`` can only come from the wheel.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _run(cmd, cwd, env, timeout=300):
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, f"{cmd} exit {p.returncode}\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return p


@pytest.fixture(scope="module")
def wheel_venv(tmp_path_factory):
    base = tmp_path_factory.mktemp("wheel")
    # build from a copy of the sources: pip builds in the source tree (build/, *.egg-info)
    src = base / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    shutil.copytree(ROOT / "designlab", src / "designlab",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    dist = base / "dist"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)],
         cwd=base, env=env)
    wheels = list(dist.glob("designlab-*.whl"))
    assert len(wheels) == 1, wheels

    venv = base / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], cwd=base, env=env)
    py = venv / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps",
          "--no-index", str(wheels[0])], cwd=base, env=env)
    site = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=base, env=env).stdout.strip())
    assert (site / "designlab" / "data" / "papers" / "visiflex_flexure.json").is_file()
    (site / "_designlab_test_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    work = base / "elsewhere"
    work.mkdir()
    return {"venv": venv, "py": py, "site": site, "work": work, "env": env}


def test_the_installed_package_is_the_wheel_and_reads_its_own_paper_tables(wheel_venv):
    v = wheel_venv
    code = (
        "import json, designlab\n"
        "from importlib import resources\n"
        "from designlab.sensors.flexure.report import find_paper_json, load_paper\n"
        "p = find_paper_json()\n"
        "names = sorted(f.name for f in (resources.files('designlab') / 'data' / 'papers')"
        ".iterdir() if f.name.endswith('.json'))\n"
        "print(json.dumps({'file': designlab.__file__, 'version': designlab.__version__,"
        " 'paper': str(p), 'kc': load_paper(p)['K_c_measured'].shape, 'names': names}))\n")
    out = json.loads(_run([str(v["py"]), "-c", code], cwd=v["work"], env=v["env"])
                     .stdout.strip().splitlines()[-1])
    assert Path(out["file"]).resolve().is_relative_to(v["site"].resolve()), out["file"]
    assert not Path(out["file"]).resolve().is_relative_to(ROOT), out["file"]
    assert Path(out["paper"]).resolve().is_relative_to(v["site"].resolve()), out["paper"]
    assert out["kc"] == [6, 6]
    assert out["names"] == sorted(p.name for p in (ROOT / "designlab" / "data" / "papers")
                                  .glob("*.json"))


def test_designlab_flexure_runs_from_the_wheel(wheel_venv):
    v = wheel_venv
    exe = v["venv"] / "bin" / "designlab"
    p = _run([str(exe), "flexure", "--no-fem", "--json", "k.json"], cwd=v["work"], env=v["env"])
    assert "open next:" in p.stdout
    doc = json.loads((v["work"] / "k.json").read_text())
    assert doc, "empty flexure JSON"


def test_designlab_export_fingertip_runs_from_the_wheel(wheel_venv):
    v = wheel_venv
    exe = v["venv"] / "bin" / "designlab"
    out = v["work"] / "x"
    _run([str(exe), "export", "fingertip", "--out", str(out)], cwd=v["work"], env=v["env"])
    files = {p.suffix for p in out.rglob("*") if p.is_file()}
    assert {".stl", ".3mf", ".step"} <= files, files
    run = json.loads((out / "run.json").read_text())
    assert run["what"] == "export fingertip" and run["designlab"], run
