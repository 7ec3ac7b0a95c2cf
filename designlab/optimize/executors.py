"""Executors that run one function over many tasks and yield results as they finish.

``LocalExecutor``: a process pool on this machine (all cores by default). ``DaskExecutor``: a
Dask distributed cluster (``tcp://HOST:PORT``), for sweeps on a cluster. Both yield
``(index, result, error)`` with ``error`` the one-line text of an exception, so a failing
design never stops the sweep; the text carries its kind (:mod:`designlab.optimize.failures`):
a write the file system refused (a full disk) is not the design's failure, and the sweep stops
on it instead of storing it.

A worker process that dies mid-design (killed, out of memory, a crash in native code) does not
stop the sweep either. Local pool: a death fails every task still in that pool
(``BrokenProcessPool``), so the pool is rebuilt and they are all run again (``MAX_RETRIES``
times); if the pool breaks again, the tasks left run on a one-worker pool in order, where the
design whose worker dies is known: that one is recorded failed with the reason, the others
run on. Dask: the scheduler runs a task whose worker died again (up to its own
``allowed-failures``, 3 by default, then ``KilledWorker``); each design counts its own tries
in the scheduler's metadata (which workers started it and did not finish), so it is run
``MAX_RETRIES`` times more and then recorded failed with the reason naming the workers that
died, whatever the cluster's setting (a lower ``allowed-failures`` gives the ``KilledWorker``
reason, which names the last worker).

A lost Dask scheduler is not a design's failure: the designs it had not finished are not
yielded as results but raised as :class:`LostTasks` once the finished ones are yielded (the
sweep stores nothing for them, names them, and a resume runs them).
"""

from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterator, Sequence

from designlab.optimize.failures import error_text, one_line

Result = tuple[int, Any, str | None]

#: runs of a design after the first whose worker process died (local pool and Dask alike)
MAX_RETRIES = 1


def _guarded(fn: Callable[[Any], Any], task: Any) -> tuple[Any, str | None]:
    """``(fn(task), None)``, or ``(None, error)`` with the error an
    :class:`~designlab.optimize.failures.ErrorText` that says whether it is the design's or a
    refused write's (a full disk: the caller stops the run rather than storing it)."""
    try:
        return fn(task), None
    except Exception as exc:  # recorded per design, the sweep goes on
        return None, error_text(exc)


def _worker_init(parent_pid: int) -> None:
    """Pool worker initializer: the worker dies with the process that started the pool
    (kill -9 of the sweep included), instead of computing on for nobody."""
    from designlab.atomic import die_with_parent

    die_with_parent(parent_pid)


MAX_WORKERS = 512


class LocalExecutor:
    """Process pool (``spawn`` start method: OCP and VTK are not fork-safe). Its workers end
    with the process that started them, however that one ends (Linux parent-death signal).

    ``with executor:`` keeps one pool for every :meth:`run` inside the block (the batches of
    an Optuna study): its worker processes start and import designlab once, not per batch.
    Outside such a block each :meth:`run` has a pool of its own."""

    def __init__(self, workers: int | None = None):
        from designlab.errors import ParameterError

        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or not 1 <= workers <= MAX_WORKERS):
            raise ParameterError("--workers", workers, f"an integer, 1 <= value <= {MAX_WORKERS}")
        self.workers = workers or os.cpu_count() or 1
        self._keep = 0                # depth of ``with`` blocks keeping the pool
        self._pool: ProcessPoolExecutor | None = None
        #: pools started so far (a kept pool counts once)
        self.pools_started = 0

    def __enter__(self) -> "LocalExecutor":
        self._keep += 1
        return self

    def __exit__(self, *exc) -> None:
        self._keep -= 1
        if not self._keep:
            self._close(cancel=exc[0] is not None)

    def _close(self, cancel: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=cancel)

    def _shared_pool(self, size: int) -> ProcessPoolExecutor:
        """The pool of ``size`` workers for one round of :meth:`run`: the kept one (of all the
        workers; processes start as tasks need them) inside a ``with`` block."""
        if self._keep and self._pool is not None:
            return self._pool
        self.pools_started += 1
        pool = ProcessPoolExecutor(max_workers=self.workers if self._keep else size,
                                   mp_context=mp.get_context("spawn"),
                                   initializer=_worker_init, initargs=(os.getpid(),))
        if self._keep:
            self._pool = pool
        return pool

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Result]:
        if self.workers == 1:
            for i, t in enumerate(tasks):
                yield (i, *_guarded(fn, t))
            return
        todo = list(range(len(tasks)))
        broken = 0                    # shared pools that broke so far
        while todo:
            alone = broken > MAX_RETRIES  # then one worker: the design that dies is known
            if alone:
                self.pools_started += 1
                pool = ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("spawn"),
                                           initializer=_worker_init, initargs=(os.getpid(),))
            else:
                pool = self._shared_pool(min(self.workers, len(todo)))
            pending, died, ended = {}, [], False
            try:
                pending = {pool.submit(_guarded, fn, tasks[i]): i for i in todo}
                todo = []
                while pending:
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for f in done:
                        i = pending.pop(f)
                        try:
                            res = f.result()
                        except BrokenProcessPool:
                            # a worker died: every task still in this pool fails with this
                            # error, the one that killed it among them
                            died.append(i)
                            continue
                        except Exception as exc:  # e.g. a result that cannot be pickled
                            res = (None, one_line(exc))
                        yield (i, *res)
                ended = True
            except BaseException:
                for f in pending:
                    f.cancel()
                raise
            finally:
                if pool is self._pool and not (ended and not died):
                    self._pool = None     # broken or interrupted: not kept
                if pool is not self._pool:
                    pool.shutdown(wait=True, cancel_futures=True)
            if died and alone:
                # one worker runs the tasks in order: the first that did not finish killed it
                i = min(died)
                died.remove(i)
                yield (i, None, f"worker process died while running this design (killed, out "
                                f"of memory or a crash; {broken} shared pool(s) broke with it "
                                f"pending, then it died alone)")
                broken = MAX_RETRIES  # the rest back on the shared pool; a death -> alone
            elif died:
                broken += 1
            todo = sorted(died)


#: the scheduler metadata under which a Dask run counts its designs' unfinished tries
TRIES_KEY = "designlab-tries"


def _dask_try(fn: Callable[[Any], Any], task: Any, key: list[str]) -> tuple[Any, str | None]:
    """One try of a design on a Dask worker: the worker's address is added to the design's
    list of unfinished tries (scheduler metadata ``key``) before it runs and removed when it
    returns. A design that finds more than ``MAX_RETRIES`` unfinished tries (their workers died
    while running it) is not run again: it is recorded failed, naming those workers."""
    try:
        from distributed import get_client, get_worker

        client, me = get_client(), get_worker().address
        died = list(client.get_metadata(key, default=None) or [])
    except Exception:  # no bookkeeping (an old scheduler): the scheduler's own limit applies
        return _guarded(fn, task)
    if len(died) > MAX_RETRIES:
        return None, (f"the Dask worker(s) running this design died {len(died)} times "
                      f"({', '.join(died)}: killed, out of memory or a crash); not run again")
    client.set_metadata(key, died + [me])
    out = _guarded(fn, task)
    try:
        client.set_metadata(key, died)
    except Exception:
        pass
    return out


class LostTasks(Exception):
    """Raised by an executor after it yielded every result it got: the tasks ``indices`` were
    not run, or their results never came back, for a reason outside them (the Dask scheduler
    was lost). They are not results: nothing is recorded for them, a resume runs them."""

    def __init__(self, indices: list[int], reason: str):
        self.indices, self.reason = sorted(indices), reason
        super().__init__(f"{len(self.indices)} task(s) not run: {reason}")


#: the start of the error text of a design Dask could not run (stored in its row)
DASK_FAILED = "Dask could not run this design: "
#: error texts of a lost cluster rather than of the design (rows stored with them are run
#: again by a plain resume)
LOST_MARKERS = ("CancelledError", "CommClosedError", "scheduler-connection-lost")


def cluster_lost(error: str | None) -> bool:
    """Whether a stored design's ``error`` says the cluster was lost (not the design's own
    failure): such a design is run again by a resume."""
    return bool(error) and error.startswith(DASK_FAILED) and any(m in error
                                                                  for m in LOST_MARKERS)


def _is_lost(exc: BaseException, client) -> bool:
    """A future's exception that is the cluster's, not the design's: it was cancelled (the
    client lost its scheduler cancels every future), its connection closed, or the client is
    no longer running. A ``KilledWorker`` (a design that kills its workers) is the design's."""
    from concurrent.futures import CancelledError

    if isinstance(exc, (CancelledError, OSError, TimeoutError)):
        return True
    return getattr(client, "status", "running") != "running"


class DaskExecutor:
    """Tasks on a Dask distributed scheduler at ``address`` (e.g. ``tcp://10.0.0.5:8786``).

    ``with executor:`` keeps one client for every :meth:`run` inside the block, and
    ``workers`` is then the cluster's number of worker threads (an Optuna study asks that
    many trials at a time). A lost scheduler ends :meth:`run` with :class:`LostTasks` for the
    designs it did not finish (each finished one was yielded)."""

    def __init__(self, address: str):
        self.address = address
        self._keep = 0
        self._client = None

    @property
    def workers(self) -> int | None:
        """Worker threads of the cluster (None outside a ``with`` block)."""
        if self._client is None:
            return None
        try:
            return sum(self._client.nthreads().values()) or None
        except Exception:
            return None

    def __enter__(self) -> "DaskExecutor":
        self._keep += 1
        if self._client is None:
            self._client = self._connect()
        return self

    def __exit__(self, *exc) -> None:
        self._keep -= 1
        if not self._keep:
            client, self._client = self._client, None
            if client is not None:
                client.close()

    def _connect(self):
        from designlab.errors import ParameterError

        try:
            from distributed import Client
        except ImportError:
            raise ParameterError("--scheduler", self.address,
                                 "Dask installed: pip install 'designlab[cluster]'") from None
        try:
            return Client(self.address, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise ParameterError("--scheduler", self.address,
                                 f"the address of a reachable Dask scheduler ({exc})") from None

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Result]:
        import uuid

        client = self._client if self._client is not None else self._connect()
        from distributed import as_completed

        run = uuid.uuid4().hex
        lost, reason = [], ""
        try:
            futures = {client.submit(_dask_try, fn, t, [TRIES_KEY, run, str(i)], pure=False): i
                       for i, t in enumerate(tasks)}
            for fut in as_completed(futures):
                try:
                    res = fut.result()
                except (KeyboardInterrupt, SystemExit, GeneratorExit):
                    raise
                except BaseException as exc:  # KilledWorker (after the retry), cancelled, lost
                    if _is_lost(exc, client):
                        lost.append(futures[fut])
                        reason = reason or one_line(exc)
                        continue
                    yield (futures[fut], None, DASK_FAILED + one_line(exc))
                    continue
                yield (futures[fut], *res)
        finally:
            if not lost:
                try:
                    client.set_metadata([TRIES_KEY, run], None)   # this run's bookkeeping
                except Exception:
                    pass
            if client is not self._client or lost:
                if client is self._client:
                    self._client = None
                client.close()
        if lost:
            raise LostTasks(lost, f"the Dask scheduler at {self.address} was lost ({reason})")
