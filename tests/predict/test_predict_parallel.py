"""predict/write_prediction with their forked helpers (the coarse mesh of the error bar beside
the run, the plots beside the renders) give the same files as one process, and leave no
process behind. Each side runs in a fresh interpreter: the coarse-mesh child is forked only
before gmsh has run in a process."""

import json
import subprocess
import sys

import pytest

SCRIPT = r"""
import json, multiprocessing, sys
from designlab.predict.record import write_prediction
from designlab.predict.run import predict, predict_and_write
from designlab.predict.side import _use_parallel
parallel = {"1": True, "0": False, "P": True}[sys.argv[1]]
assert _use_parallel(parallel, None) == parallel
if sys.argv[1] == "P":          # designlab predict --out: the painter and the plotting side
    predict_and_write("fingertip", {}, out=sys.argv[2], parallel=True,
                      settings={"edge_length": 4.0})
else:
    pred = predict("fingertip", {}, parallel=parallel, settings={"edge_length": 4.0})
    write_prediction(pred, sys.argv[2], parallel=parallel)
assert not multiprocessing.active_children()
assert not _use_parallel(True, None)        # gmsh ran in this process: never forks again
# FEM stages computed here: with the side process the coarse mesh is computed there
from designlab.fem.cache import STATS
assert STATS["computed"] >= 1, STATS
"""


def _run(tmp_path, parallel: str):
    out = tmp_path / f"p{parallel}"
    subprocess.run([sys.executable, "-c", SCRIPT, parallel, str(out)], check=True,
                   timeout=600)
    return out


def _strip(doc):
    doc = dict(doc)
    doc.pop("timings_s")
    return doc


@pytest.mark.slow
def test_parallel_predict_same_files(tmp_path):
    a, b, c = _run(tmp_path, "0"), _run(tmp_path, "1"), _run(tmp_path, "P")
    ja = json.loads((a / "prediction.json").read_text())
    assert ja["mesh_convergence"]["condition_number"]["coarse"] is not None
    for other in (b, c):
        jb = json.loads((other / "prediction.json").read_text())
        assert _strip(ja) == _strip(jb)
        # the painter draws one group of plots, the coarse mesh's process the other
        for name in ("hysteresis_loops.png", "hysteresis_by_location.png",
                     "applied_vs_estimated.png", "design.png",
                     "deformed.png", "deformed.vtu", "model.json"):
            assert (a / name).read_bytes() == (other / name).read_bytes(), (other.name, name)
        assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in other.iterdir())


def test_jobs_larger_than_a_pipe_both_ways():
    """A job and its result both far larger than a pipe's buffer, several queued before the
    first result is read: no deadlock, results in order, nothing left running."""
    import multiprocessing

    import numpy as np

    from designlab.predict.side import _Side

    side = _Side(lambda: np.zeros(300_000))
    big = np.arange(500_000, dtype=float)
    tickets = [side.submit(np.multiply, big, k) for k in (2.0, 3.0, 4.0)]
    assert tickets[2].get()[-1] == 4.0 * big[-1]
    assert tickets[0].get()[1] == 2.0
    assert side.first.get().shape == (300_000,)
    side.stop()
    assert not multiprocessing.active_children()


def test_a_failing_job_is_none_and_the_next_runs():
    import multiprocessing

    from designlab.predict.side import _Side

    side = _Side(None)
    bad = side.submit(int, "not a number")
    good = side.submit(int, "7")
    assert bad.get() is None and good.get() == 7
    side.stop()
    assert not multiprocessing.active_children()


def _once(fn):
    """The first job's result of a child that runs ``fn``, the child stopped after."""
    from designlab.predict.side import _Side

    side = _Side(fn)
    try:
        return side.first.get()
    finally:
        side.stop()


def test_side_failure_is_none_and_child_gone():
    """A child that raises gives None (the caller recomputes in-process) and is reaped."""
    import multiprocessing

    def boom():
        raise ValueError("no")

    assert _once(boom) is None
    assert _once(lambda: {"x": 1.5}) == {"x": 1.5}
    assert not multiprocessing.active_children()


def test_stop_kills_a_running_child():
    import multiprocessing
    import time

    from designlab.predict.side import _Side

    side = _Side(lambda: time.sleep(60))
    t0 = time.perf_counter()
    side.stop()
    assert time.perf_counter() - t0 < 10
    assert not multiprocessing.active_children()


@pytest.mark.slow
def test_a_stalled_child_is_killed_and_gives_none(monkeypatch):
    """A child that waits for ever (no CPU time) is given up on: None, and it is gone."""
    import multiprocessing
    import time

    from designlab.predict.side import _Side

    monkeypatch.setattr(_Side, "STALL_S", 2.0)
    t0 = time.perf_counter()
    assert _once(lambda: time.sleep(120)) is None
    assert time.perf_counter() - t0 < 30
    assert not multiprocessing.active_children()


@pytest.mark.slow
def test_jobs_sent_to_a_stuck_child_do_not_block_the_caller(monkeypatch):
    """A child that does not read its jobs (here: its first call never ends, and it reads jobs
    only after it; a child waiting in C on a lock copied from the parent, holding the
    interpreter lock, cannot read either) lets its job pipe fill: submitting more than the
    pipe holds returns at once, and the results are None once the child is found stalled (the
    caller recomputes in-process). Before, the send itself blocked for ever (seen on
    `benchmarks/bench_predict.py fingertip`'s peer run)."""
    import multiprocessing
    import threading
    import time

    import numpy as np

    from designlab.predict.side import _Side

    monkeypatch.setattr(_Side, "STALL_S", 2.0)
    side = _Side(lambda: time.sleep(120))
    big = np.zeros(1_000_000)                    # 8 MB a job, far beyond a pipe's buffer
    tickets: list = []
    t0 = time.perf_counter()
    # submitted from a thread, so that a send that blocks fails the test instead of hanging it
    # (stop() below kills the child, which ends such a send)
    sender = threading.Thread(target=lambda: tickets.extend(
        side.submit(np.add, big, k) for k in range(3)), daemon=True)
    sender.start()
    sender.join(10)
    blocked = sender.is_alive()
    if blocked:
        side.stop()
    assert not blocked, "submit blocked on a child that does not read"
    assert all(t.get() is None for t in tickets)
    assert time.perf_counter() - t0 < 30
    side.stop()
    assert not multiprocessing.active_children()


@pytest.mark.slow
def test_forked_helpers_run_opencascade_serially():
    """In a forked helper OpenCascade's thread pool is the parent's (its threads are not in the
    child): ``_serial_occ`` makes the Booleans build123d asks to run in parallel run on the
    calling thread, as it does for the tessellation (a fresh interpreter: it patches globally)."""
    code = ("from designlab.predict.side import _serial_occ\n"
            "from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse\n"
            "from OCP.BOPAlgo import BOPAlgo_Builder\n"
            "ops = [c() for c in (BRepAlgoAPI_Fuse, BRepAlgoAPI_Cut, BOPAlgo_Builder)]\n"
            "for op in ops: op.SetRunParallel(True)\n"
            "before = [op.RunParallel() for op in ops]\n"
            "_serial_occ()\n"
            "for op in ops: op.SetRunParallel(True)\n"
            "print(before, [op.RunParallel() for op in ops])\n")
    assert _fresh_python(code) == "[True, True, True] [False, False, False]"


@pytest.mark.slow
def test_meshing_leaves_sigpipe_ignored():
    """gmsh's initialize sets SIGPIPE back to its default (the process ends at a write to a
    pipe whose reader is gone, as a job sent to a helper that was just killed); after a mesh the
    process ignores it again, as Python does (an xdist worker died of it in the suite). A fresh
    interpreter, read from the kernel's own record of the process."""
    code = ("from designlab.geometry.fingertip import CantileverFingertip\n"
            "from designlab.sensors.fingertip.virtual import FingertipModelSettings, mesh_fingertip\n"
            "mesh_fingertip(CantileverFingertip(), FingertipModelSettings(edge_length=5.0))\n"
            "ign = [l for l in open('/proc/self/status') if l.startswith('SigIgn')][0]\n"
            "print((int(ign.split()[1], 16) >> 12) & 1)\n")
    assert _fresh_python(code).splitlines()[-1] == "1"        # bit 13 - 1: SIGPIPE ignored


def _fresh_python(code: str) -> str:
    """What ``code`` prints in a new interpreter (which must exit 0)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()
