"""CalculiX (``ccx``) as an independent reference solver for linear static TET4/TET10 problems.

The same mesh, materials, prescribed displacements and nodal force vector our FEM assembles are
written to an ``.inp`` deck (C3D4 / C3D10: TetMesh node order is the CalculiX order), solved by
``ccx`` in a work directory, and the nodal displacements (mm) are read back from the ``.dat`` file
(``*NODE PRINT``, 7 significant digits). Units: mm, N, MPa.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from designlab.errors import DesignlabError, ModelError, ParameterError
from designlab.mesh.tetmesh import TetMesh


@dataclass(frozen=True)
class CalculixResult:
    """displacement: (n, 3) mm; wall_time_s: ccx run time (s, writing/reading excluded);
    total_time_s: deck writing + ccx + reading (s); ccx_version: e.g. '2.20'."""

    displacement: np.ndarray
    wall_time_s: float
    total_time_s: float
    ccx_version: str
    threads: int


def ccx_path() -> str:
    """Path of the ``ccx`` executable, or a one-line DesignlabError."""
    path = shutil.which("ccx")
    if path is None:
        raise DesignlabError("ccx (CalculiX) is not on the PATH; install calculix-ccx "
                             "(Debian/Ubuntu: apt-get install calculix-ccx) to use --reference calculix")
    return path


def ccx_version() -> str:
    """Version string printed by ``ccx -v`` (e.g. '2.20')."""
    out = subprocess.run([ccx_path(), "-v"], capture_output=True, text=True, timeout=30).stdout
    m = re.search(r"Version\s+([\w.]+)", out)
    return m.group(1) if m else "unknown"


def _prescribed_array(prescribed, n_points: int) -> np.ndarray:
    """(k, 3) rows ``(node, dof 0..2, value mm)`` from an array or ``{(node, dof): value}``."""
    if isinstance(prescribed, dict):
        rows = [(n, d, v) for (n, d), v in prescribed.items()]
        arr = np.array(rows, float).reshape(-1, 3)
    else:
        arr = np.asarray(prescribed, float).reshape(-1, 3)
    if len(arr):
        nodes, dofs = arr[:, 0], arr[:, 1]
        if np.any(nodes < 0) or np.any(nodes >= n_points) or np.any(nodes != np.round(nodes)):
            raise ParameterError("prescribed", "node index", f"integers 0..{n_points - 1}")
        if np.any(~np.isin(dofs, (0, 1, 2))):
            raise ParameterError("prescribed", "dof", "0, 1 or 2 (x, y, z)")
        if not np.all(np.isfinite(arr[:, 2])):
            raise ParameterError("prescribed", "value", "finite displacements (mm)")
    return arr


def write_inp(path: str | Path, mesh: TetMesh, materials: dict[int, tuple[float, float]],
              prescribed, forces: np.ndarray) -> None:
    """Write a linear static CalculiX deck: nodes, C3D4/C3D10 elements per region (ELSET R<id>),
    *ELASTIC (E MPa, nu) per region, *BOUNDARY, *CLOAD (N), *NODE PRINT U."""
    regions = np.unique(mesh.region)
    missing = [int(r) for r in regions if int(r) not in materials]
    if missing:
        raise ModelError(f"no (E, nu) given for region(s) {missing} of the mesh")
    for r, (E, nu) in materials.items():
        if not (E > 0 and -1 < nu < 0.5):
            raise ParameterError(f"materials[{r}]", (E, nu), "E > 0 MPa and -1 < nu < 0.5")
    forces = np.asarray(forces, float)
    if forces.shape != (mesh.n_points, 3) or not np.all(np.isfinite(forces)):
        raise ParameterError("forces", forces.shape, f"a finite ({mesh.n_points}, 3) array (N)")
    pres = _prescribed_array(prescribed, mesh.n_points)
    etype = "C3D4" if mesh.order == 1 else "C3D10"
    ids = np.arange(1, mesh.n_points + 1)
    with open(path, "w") as fh:
        fh.write("** designlab reference deck (mm, N, MPa)\n*NODE, NSET=NALL\n")
        np.savetxt(fh, np.column_stack([ids, mesh.points]), fmt=["%d", "%.13g", "%.13g", "%.13g"],
                   delimiter=", ")
        eid = 1
        for r in regions:
            cells = mesh.cells[mesh.region == r] + 1
            fh.write(f"*ELEMENT, TYPE={etype}, ELSET=R{int(r)}\n")
            eids = np.arange(eid, eid + len(cells))
            eid += len(cells)
            data = np.column_stack([eids, cells])
            if etype == "C3D10":  # max 16 entries per line: split after 8 nodes
                for row in data:
                    fh.write(", ".join(map(str, row[:9])) + ",\n" + ", ".join(map(str, row[9:])) + "\n")
            else:
                np.savetxt(fh, data, fmt="%d", delimiter=", ")
        for r in regions:
            E, nu = materials[int(r)]
            fh.write(f"*MATERIAL, NAME=M{int(r)}\n*ELASTIC\n{E:.13g}, {nu:.13g}\n"
                     f"*SOLID SECTION, ELSET=R{int(r)}, MATERIAL=M{int(r)}\n")
        fh.write("*STEP\n*STATIC\n")
        if len(pres):
            fh.write("*BOUNDARY\n")
            for n, d, v in pres:
                fh.write(f"{int(n) + 1}, {int(d) + 1}, {int(d) + 1}, {v:.13g}\n")
        nz = np.argwhere(forces != 0)
        if len(nz):
            fh.write("*CLOAD\n")
            np.savetxt(fh, np.column_stack([nz[:, 0] + 1, nz[:, 1] + 1, forces[nz[:, 0], nz[:, 1]]]),
                       fmt=["%d", "%d", "%.13g"], delimiter=", ")
        fh.write("*NODE PRINT, NSET=NALL\nU\n*END STEP\n")


def read_dat_displacements(path: str | Path, n_points: int) -> np.ndarray:
    """(n, 3) displacements (mm) from the ``displacements`` block of a ccx ``.dat`` file."""
    text = Path(path).read_text()
    m = re.search(r"displacements \(vx,vy,vz\)[^\n]*\n\s*\n", text)
    if m is None:
        raise ModelError(f"CalculiX wrote no displacements to {Path(path).name}")
    block = text[m.end():].split("\n\n", 1)[0]
    data = np.array(block.split(), float).reshape(-1, 4)
    u = np.zeros((n_points, 3))
    u[data[:, 0].astype(np.int64) - 1] = data[:, 1:]
    if len(data) != n_points:
        raise ModelError(f"CalculiX returned {len(data)} of {n_points} nodal displacements")
    return u


@contextlib.contextmanager
def ccx_workdir(workdir: str | Path | None = None, prefix: str = "designlab-ccx-"):
    """The folder a ccx job runs in: ``workdir`` (created, kept) or a temporary one (removed
    afterwards)."""
    if workdir is None:
        with tempfile.TemporaryDirectory(prefix=prefix) as d:
            yield Path(d)
    else:
        wd = Path(workdir)
        wd.mkdir(parents=True, exist_ok=True)
        yield wd


def run_ccx(wd: Path, threads: int = 1, timeout_s: float = 3600.0) -> tuple[str, float]:
    """Run ``ccx -i job`` in ``wd`` on ``threads`` threads: (its log, also written to
    ``ccx.log``; wall s). A non-zero exit, an ``*ERROR`` line or no ``job.dat``: ModelError."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_EQUATION_SOLVER=str(threads),
               CCX_NPROC_STIFFNESS=str(threads), CCX_NPROC_RESULTS=str(threads))
    t0 = time.perf_counter()
    proc = subprocess.run([ccx_path(), "-i", "job"], cwd=wd, env=env, capture_output=True,
                          text=True, timeout=timeout_s)
    wall = time.perf_counter() - t0
    log = proc.stdout + proc.stderr
    (wd / "ccx.log").write_text(log)
    err = re.search(r"\*ERROR[^\n]*(?:\n[^\n]+)?", log)
    if proc.returncode != 0 or err is not None or not (wd / "job.dat").exists():
        msg = " ".join(err.group(0).split()) if err else f"exit code {proc.returncode}"
        raise ModelError(f"CalculiX failed: {msg}")
    return log, wall


def solve_calculix(mesh: TetMesh, materials: dict[int, tuple[float, float]], prescribed,
                   forces: np.ndarray, threads: int = 1, workdir: str | Path | None = None,
                   timeout_s: float = 3600.0) -> CalculixResult:
    """Solve the linear static problem with CalculiX.

    materials: {region id: (E MPa, nu)}; prescribed: (k, 3) rows ``(node, dof 0..2, value mm)``
    or ``{(node, dof): value}``; forces: (n, 3) nodal forces (N); threads: OMP/SPOOLES threads;
    workdir: keep the deck and outputs there (default: a temporary directory, removed).
    """
    ccx_path()                      # one line when ccx is not installed, before any writing
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ParameterError("threads", threads, "an integer >= 1")
    t_total = time.perf_counter()
    with ccx_workdir(workdir) as wd:
        write_inp(wd / "job.inp", mesh, materials, prescribed, forces)
        log, wall = run_ccx(wd, threads, timeout_s)
        version = re.search(r"Version\s+([\w.]+)", log)
        u = read_dat_displacements(wd / "job.dat", mesh.n_points)
        size = float(np.ptp(mesh.points, axis=0).max())
        if not np.all(np.isfinite(u)) or np.abs(u).max() > 1e3 * size:
            # SPOOLES factors a singular matrix without complaint: catch the rigid-body blow-up
            raise ModelError("CalculiX displacements exceed 1000x the model size: the model is "
                             "under-constrained (rigid-body motion not prevented)")
    return CalculixResult(u, wall, time.perf_counter() - t_total,
                          version.group(1) if version else "unknown", threads)
