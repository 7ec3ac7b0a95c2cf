"""Crash safety of the sweep store: kill -9 at the exact write points (right after a temporary
file is created, right before it is renamed) and at random moments, then resume: every design
once, the same table as an uninterrupted run, no temporary file left, no process left alive;
one writer per --out."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from designlab.errors import DesignlabError
from designlab.optimize.executors import LocalExecutor
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep
from sweep_fixtures import quadratic

HERE = Path(__file__).parents[1]  # tests/, where sweep_fixtures.py is
CFG = {"part": "fingertip", "method": "grid",
       "parameters": {"h": {"range": [0.0, 5.0], "levels": 6}, "r": [6.0, 9.0]},
       "objectives": {"condition_number": "min"}}
N_DESIGNS = 6 * 3          # h = 4 fails: 3 designs with a row only, 15 with cache + row
N_WRITES = 15 * 2 + 3      # temporary files of an uninterrupted run

# the subprocess: a sweep that SIGKILLs itself at the n-th call of a write step
SCRIPT = """
import os, signal, sys, tempfile
sys.path.insert(0, {here!r})
from designlab.optimize.space import sweep_config
from designlab.optimize.sweep import run_sweep
from designlab.optimize.executors import LocalExecutor
import sweep_fixtures
point, n = {point!r}, {n!r}
calls = [0]
if point == "after_temp":
    real = tempfile.mkstemp
    def mkstemp(*a, **k):
        r = real(*a, **k)
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)
        return r
    tempfile.mkstemp = mkstemp
elif point == "before_rename":
    real = os.replace
    def replace(a, b):
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)
        return real(a, b)
    os.replace = replace
run_sweep(sweep_config({cfg!r}), {out!r}, evaluator=getattr(sweep_fixtures, {fn!r}),
          executor=LocalExecutor({workers!r}))
"""


def _spawn(out: Path, point: str = "", n: int = 0, fn: str = "quadratic", workers: int = 1):
    code = SCRIPT.format(here=str(HERE), point=point, n=n, cfg=CFG, out=str(out), fn=fn,
                         workers=workers)
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)])


def _table(out: Path) -> dict:
    t = pq.read_table(out / "results.parquet").to_pylist()
    return {r["key"]: (r["status"], r.get("condition_number"), r.get("error")) for r in t}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("ref")
    run_sweep(sweep_config(CFG), out, evaluator=quadratic, executor=LocalExecutor(1))
    return _table(out)


def _check_resumed(out: Path, reference: dict) -> None:
    res = run_sweep(sweep_config(CFG), out, evaluator=quadratic, executor=LocalExecutor(1))
    assert res.new + res.reused == N_DESIGNS
    keys = pq.read_table(out / "results.parquet").column("key").to_pylist()
    assert len(keys) == N_DESIGNS and len(set(keys)) == N_DESIGNS
    assert _table(out) == reference
    leftovers = [p.name for p in out.rglob("*") if ".tmp" in p.name]
    assert leftovers == []


# 1st..N_WRITES-th temporary file: the first, a cache file, a row file, a failing design's
# row (h = 4 comes 5th in the grid: its row is write 2*(4*3)+1 = 25), the last
# (the default run tries two of them; the slow suite all 2 x 8)
KILL_POINTS = [1, 2, 3, 4, 12, 25, 26, N_WRITES]
FAST = {("after_temp", 2), ("before_rename", 25)}


@pytest.mark.parametrize("point, n", [
    pytest.param(p, n, marks=() if (p, n) in FAST else pytest.mark.slow)
    for p in ("after_temp", "before_rename") for n in KILL_POINTS])
@pytest.mark.slow
def test_kill_9_at_a_write_point_then_resume(tmp_path, reference, point, n):
    proc = _spawn(tmp_path, point, n)
    assert proc.wait(timeout=120) == -signal.SIGKILL
    temps = [p for p in tmp_path.rglob("*") if ".tmp" in p.name]
    assert temps, "the kill happened at a write: a temporary file is left"
    # no temporary file is a row: the store sees only complete designs
    from designlab.optimize.store import ResultStore

    assert all(".tmp" not in k for k in ResultStore(tmp_path).keys())
    _check_resumed(tmp_path, reference)


def _children(pid: int) -> set[int]:
    out = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            pass
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow),
                                  pytest.param(2, marks=pytest.mark.slow),
                                  pytest.param(3, marks=pytest.mark.slow),
                                  pytest.param(4, marks=pytest.mark.slow)])
@pytest.mark.slow
def test_kill_9_at_random_moments_with_a_pool_leaves_no_process(tmp_path, reference, seed):
    """kill -9 of a sweep running on 2 pool workers: the workers die with it (parent-death
    signal), and the resume completes the table exactly once."""
    rnd = random.Random(seed)
    proc = _spawn(tmp_path, fn="slow_quadratic", workers=2)
    deadline = time.time() + 60
    kids: set[int] = set()
    while time.time() < deadline and len(kids) < 2:
        kids |= _children(proc.pid)
        time.sleep(0.05)
    rows = tmp_path / "results"
    while time.time() < deadline and not (rows.is_dir() and any(rows.glob("*.parquet"))):
        kids |= _children(proc.pid)
        time.sleep(0.02)
    time.sleep(rnd.uniform(0.0, 1.2))
    kids |= _children(proc.pid)
    proc.kill()
    proc.wait()
    assert len(kids) >= 2
    deadline = time.time() + 10
    while time.time() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.05)
    assert [k for k in kids if _alive(k)] == []
    _check_resumed(tmp_path, reference)


@pytest.mark.slow
def test_one_writer_per_out_and_a_killed_holder_is_taken_over(tmp_path, reference):
    proc = _spawn(tmp_path, fn="slow_quadratic")
    lock = tmp_path / ".designlab.lock"
    deadline = time.time() + 60
    while time.time() < deadline and not (lock.exists() and lock.stat().st_size):
        time.sleep(0.02)
    with pytest.raises(DesignlabError, match=rf"in use by pid {proc.pid} on .*designlab sweep"):
        run_sweep(sweep_config(CFG), tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    proc.kill()
    proc.wait()
    _check_resumed(tmp_path, reference)  # the stale lock of the killed run is taken over


def test_temporary_names_never_match_the_store(tmp_path, reference):
    """A leftover temp file of a live writer (its PID runs) is neither a row nor removed; one of
    a dead writer is removed on start."""
    run_sweep(sweep_config(CFG), tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    rows = tmp_path / "results"
    live = rows / f".{'0' * 20}.{os.getpid()}.abcdefgh.tmp"
    dead = rows / f".{'1' * 20}.999999999.abcdefgh.tmp"
    live.write_bytes(b"")
    dead.write_bytes(b"PAR1")
    res = run_sweep(sweep_config(CFG), tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    assert res.reused == N_DESIGNS and res.new == 0
    assert live.exists() and not dead.exists()
    live.unlink()
    assert _table(tmp_path) == reference


@pytest.mark.slow
def test_a_kill_at_the_table_write_leaves_a_temp_the_resume_removes(tmp_path, reference):
    """kill -9 while the consolidated table (``OUT/results.parquet``, the write after the last
    row) is written: its temporary file at the folder's top level is removed by the resume,
    and a top-level temp of a live writer (its PID runs) is kept."""
    proc = _spawn(tmp_path, "after_temp", N_WRITES + 1)
    assert proc.wait(timeout=120) == -signal.SIGKILL
    dead = [p for p in tmp_path.iterdir() if ".tmp" in p.name]
    assert len(dead) == 1 and dead[0].name.startswith(".results.")
    live = tmp_path / f".report.{os.getpid()}.abcdefgh.tmp.html"
    live.write_bytes(b"<html>")
    res = run_sweep(sweep_config(CFG), tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    assert res.reused == N_DESIGNS and res.new == 0
    assert not dead[0].exists() and live.exists()
    live.unlink()
    assert [p.name for p in tmp_path.rglob("*") if ".tmp" in p.name] == []
    assert _table(tmp_path) == reference


FEM_SCRIPT = """
import os, signal
import numpy as np
from designlab.fem.cache import FEMCache
real = os.replace
def replace(a, b):
    os.kill(os.getpid(), signal.SIGKILL)          # killed right before the rename
os.replace = replace
FEMCache({fem!r}).get_or_compute("ab" * 32, lambda: {{"K": np.eye(3)}})
"""


def test_recover_removes_the_temporary_files_of_a_killed_fem_stage(tmp_path, reference):
    """A worker killed while it wrote a shared FEM stage (``OUT/fem``, the sweep's
    :class:`~designlab.fem.cache.FEMCache`) leaves its temporary file; the next run's recovery
    removes it, keeps a live writer's, and the FEM stage is computed again."""
    from designlab.fem.cache import FEMCache
    from designlab.optimize.store import ResultStore

    fem = tmp_path / "fem"
    proc = subprocess.run([sys.executable, "-c", FEM_SCRIPT.format(fem=str(fem))], timeout=120)
    assert proc.returncode == -signal.SIGKILL
    dead = [p for p in fem.iterdir() if ".tmp" in p.name]
    assert len(dead) == 1 and dead[0].name.endswith(".tmp.npz")   # FEMCache's own naming
    assert not (fem / f"{'ab' * 32}.npz").exists()
    live = fem / f".{'cd' * 32}.{os.getpid()}.abcdefgh.tmp.npz"
    live.write_bytes(b"PK")
    assert ResultStore(tmp_path).recover()["temporary_files"] == 1
    assert not dead[0].exists() and live.exists()
    live.unlink()
    cache = FEMCache(fem)
    assert cache.get_or_compute("ab" * 32, lambda: {"K": 2 * np.eye(3)})["K"][0, 0] == 2.0
    assert cache.misses == 1 and (fem / f"{'ab' * 32}.npz").is_file()
    # the sweep's start runs the same recovery (ResultStore.recover on OUT)
    dead2 = fem / f".{'ef' * 32}.999999999.abcdefgh.tmp.npz"
    dead2.write_bytes(b"PK")
    run_sweep(sweep_config(CFG), tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    assert not dead2.exists()
    assert _table(tmp_path) == reference
