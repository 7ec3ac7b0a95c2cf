"""The forked helper processes of a prediction: :class:`_Side` runs a function and then jobs
in a forked child (pickled through pipes, killed when stalled or when the caller stops it),
:class:`_Pictures` holds ``designlab predict --out``'s painter and coarse-mesh process, and
:func:`_use_parallel` decides whether to fork at all. What the children compute is the
caller's (:mod:`designlab.predict.run`, :mod:`designlab.predict.record`)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable


def _two_cpus(parallel: bool | None) -> bool:
    """``parallel`` resolved: None -> at least two CPUs free to this process and a process that
    may have children (not a daemonic pool worker)."""
    import multiprocessing as mp
    import os

    if parallel is not None:
        return bool(parallel)
    if mp.current_process().daemon:
        return False
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except AttributeError:                  # not Linux
        return (os.cpu_count() or 1) >= 2


def _use_parallel(parallel: bool | None, fem_cache) -> bool:
    """``predict``'s ``parallel`` resolved: never once gmsh ran in this process; True -> yes;
    None -> two CPUs (:func:`_two_cpus`) and no ``fem_cache`` (a sweep: its workers use the
    cores)."""
    import sys

    if "gmsh" in sys.modules or parallel is False:
        # gmsh's thread pool does not survive a fork (the child's mesher would wait for
        # threads it does not have): the first predict of a process forks before any meshing
        return False
    if parallel:
        return True
    return fem_cache is None and _two_cpus(None)


def _warm_pictures() -> None:
    """The painter's first job (:func:`~designlab.predict.run.predict_and_write`): the drawing
    libraries (VTK/pyvista, matplotlib) imported while the caller imports and builds the CAD."""
    _warm_matplotlib()
    import pyvista.plotting  # noqa: F401


def _warm_matplotlib() -> None:
    """The coarse mesh's process, once done (:func:`~designlab.predict.run.predict_and_write`):
    matplotlib imported for the plots it will draw."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


@dataclass
class _Pictures:
    """:func:`~designlab.predict.run.predict_and_write`'s forked helpers: the ``painter``
    (drawing libraries imported first thing; design.png, deformed.png) and the coarse mesh's
    process (``side``, set by :func:`~designlab.predict.run.predict`; the plots), or the
    painter alone."""

    painter: _Side
    side: _Side | None = None
    #: where the plots are drawn before the output is staged (beside ``--out``: one file
    #: system), and their job, sent as soon as the report is complete (before the stress)
    plot_dir: Path | None = None
    #: [(the group of plots (None: all), its job)]
    plots: "list[tuple[tuple[str, ...] | None, _Ticket]] | None" = None
    #: deformed.png's job, sent as soon as the run is done (into ``plot_dir``)
    deformed: "_Ticket | None" = None

    @property
    def plotter(self) -> _Side:
        return self.side if self.side is not None and not self.side._dead else self.painter

    def stop(self) -> None:
        for p in (self.painter, self.side):
            if p is not None:
                p.stop()


def _serial_occ() -> None:
    """In a forked child: OpenCascade's thread pool is the parent's (its threads are not in the
    child), so a parallel ``BRepMesh`` or Boolean would wait for ever; tessellate and run the
    Booleans on the calling thread (the same triangles and shapes). build123d asks every
    Boolean to run in parallel (``SetRunParallel(True)``): the setter itself is made to ask for
    the serial algorithm. Once per process."""
    global _OCC_SERIAL
    if _OCC_SERIAL:
        return
    _OCC_SERIAL = True
    try:
        import OCP.BRepMesh as brepmesh
        from OCP.BOPAlgo import BOPAlgo_Options
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Algo
    except ImportError:
        return
    cls = brepmesh.BRepMesh_IncrementalMesh

    def serial(shape, *args):
        if len(args) >= 4:
            args = (*args[:3], False, *args[4:])
        return cls(shape, *args)

    brepmesh.BRepMesh_IncrementalMesh = serial
    for owner in (BRepAlgoAPI_Algo, BOPAlgo_Options):
        setter = owner.SetRunParallel
        owner.SetRunParallel = (lambda set_: lambda self, flag: set_(self, False))(setter)


_OCC_SERIAL = False


class _Side:
    """``fn()`` in a forked child while the caller goes on; ``first.get()`` is its return
    value (pickled through a pipe), or None when the child failed or died (the caller then computes
    in-process: same result, and the error, if any, raised where it belongs). The child dies
    with the parent (``PR_SET_PDEATHSIG``) and :meth:`stop` kills it if it is still running:
    it never outlives the call. ``fn=None``: a child that only takes jobs (:meth:`submit`).

    After ``fn`` the child serves jobs: :meth:`submit` sends ``(job, args)`` (a module-level
    function and picklable arguments) and returns a :class:`_Ticket`; jobs run one after the
    other in the order sent, results come back in that order."""

    def __init__(self, fn: Callable[[], Any] | None):
        import multiprocessing as mp
        import os
        import queue
        import threading

        ctx = mp.get_context("fork")
        self._recv, send = ctx.Pipe(duplex=False)
        jobs, self._jobs = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_side_main, args=(fn, send, jobs, os.getpid()),
                                 daemon=True)
        self._proc.start()
        send.close()
        jobs.close()
        self._sent = 0 if fn is None else 1      # results the child owes, in order
        self._got: list[Any] = []                # results received (index = ticket)
        self._dead = False
        self._feed_failed = False
        self.first = _Ticket(self, 0) if fn is not None else None
        # jobs go down the pipe from a thread: a child stuck without reading (a lock copied
        # from the parent) fills the pipe, and a send from the caller would then block for ever
        # where :meth:`_wait` would have found the child stalled
        self._outbox: queue.Queue = queue.Queue()
        self._feeder = threading.Thread(target=self._feed, daemon=True)
        self._feeder.start()

    def _feed(self) -> None:
        """The feeding thread: sends the jobs in order; a failed send (the child gone) ends it.
        Only this thread writes to the job pipe, and :meth:`stop` closes it after this thread
        has ended (closed under a write in progress, its descriptor could be reused by another
        file and the rest of the job written there)."""
        while (data := self._outbox.get()) is not None:
            try:
                self._jobs.send_bytes(data)
            except Exception:  # noqa: BLE001 - the child is gone: _wait finds it and gives up
                self._feed_failed = True
                return

    #: a child whose CPU time has not moved for this long (wall s) waits on something it will
    #: never get (a lock or a thread pool copied from the parent): it is killed and the work is
    #: done in-process
    STALL_S = 20.0

    def submit(self, job: Callable[..., Any], *args: Any) -> "_Ticket":
        """Run ``job(*args)`` in the child after what it was given before."""
        from multiprocessing.reduction import ForkingPickler

        ticket = _Ticket(self, self._sent)
        self._sent += 1
        if not self._dead:
            try:
                data = bytes(ForkingPickler.dumps((job, args)))   # what Connection.send sends
            except (TypeError, AttributeError, __import__("pickle").PicklingError):
                self._give_up()
            else:
                self._outbox.put(data)
        return ticket

    def _wait(self, index: int) -> Any:
        while len(self._got) <= index and not self._dead:
            try:
                while not self._recv.poll(1.0):
                    if (not self._proc.is_alive() or self._feed_failed
                            or self._stalled()):
                        raise EOFError
                ok, value = self._recv.recv()
                self._got.append(value if ok else None)
            except (EOFError, OSError):
                self._give_up()
        return self._got[index] if index < len(self._got) else None

    def _give_up(self) -> None:
        self._dead = True
        self.stop()

    def _stalled(self) -> bool:
        """True once the child's CPU time (Linux ``/proc``) has not changed for ``STALL_S``."""
        try:
            with open(f"/proc/{self._proc.pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            cpu = int(fields[11]) + int(fields[12])          # utime + stime (ticks)
        except (OSError, IndexError, ValueError):
            return False
        now = time.monotonic()
        if getattr(self, "_cpu", None) != cpu:
            self._cpu, self._since = cpu, now
            return False
        return now - self._since > self.STALL_S

    def stop(self) -> None:
        if self._proc.is_alive():
            self._proc.kill()
        self._proc.join()
        self._outbox.put(None)          # the feeding thread ends (a send in progress fails:
        self._feeder.join(10.0)         # the reader is gone), then its pipe is closed
        self._recv.close()
        if not self._feeder.is_alive():
            self._jobs.close()
        self._dead = True


@dataclass
class _Ticket:
    """A job sent to a :class:`_Side`: :meth:`get` waits for its result (None: it failed)."""

    side: _Side
    index: int

    def get(self) -> Any:
        """The result (None: the job failed, or the child died or stalled)."""
        return self.side._wait(self.index)


def _side_main(fn, send, jobs, parent: int) -> None:
    """The child of :class:`_Side`: ``fn``, then the jobs as they come. A thread reads the
    jobs and another sends the results, so neither side's pipe can fill while the other is
    blocked writing to it (a job and a result both larger than a pipe's buffer)."""
    import queue
    import threading

    from designlab.atomic import die_with_parent

    die_with_parent(parent)
    todo: queue.Queue = queue.Queue()
    done: queue.Queue = queue.Queue()

    def read():
        while True:
            try:
                todo.put(jobs.recv())
            except (EOFError, OSError):
                todo.put(None)
                return

    def write():
        while (value := done.get()) is not None:
            try:
                send.send(value)
            except Exception as exc:  # noqa: BLE001 - e.g. not picklable: the parent recomputes
                send.send((False, f"{type(exc).__name__}: {exc}"))

    def run(call):
        try:
            return (True, call())
        except BaseException as exc:  # noqa: BLE001 - the parent recomputes and raises
            return (False, f"{type(exc).__name__}: {exc}")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        if fn is not None:
            done.put(run(fn))
        threading.Thread(target=read, daemon=True).start()
        while (item := todo.get()) is not None:
            job, args = item
            done.put(run(lambda: job(*args)))
        done.put(None)
        writer.join()
        send.close()
    finally:
        # leave at once: no flush of stdio buffers copied from the parent (its progress bar's
        # output would be written twice, or wait on a lock another parent thread held at the
        # fork)
        import os

        os._exit(0)
