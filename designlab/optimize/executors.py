"""Executors that run one function over many tasks and yield results as they finish.

``LocalExecutor``: a process pool on this machine (all cores by default). ``DaskExecutor``: a
Dask distributed cluster (``tcp://HOST:PORT``), for sweeps on a cluster. Both yield
``(index, result, error)`` with ``error`` the one-line text of an exception, so a failing
design never stops the sweep.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any, Callable, Iterator, Sequence

Result = tuple[int, Any, str | None]


def _guarded(fn: Callable[[Any], Any], task: Any) -> tuple[Any, str | None]:
    try:
        return fn(task), None
    except Exception as exc:  # recorded per design, the sweep goes on
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        return None, f"{type(exc).__name__}: {msg}" if msg else traceback.format_exc(limit=1)


def _worker_init(parent_pid: int) -> None:
    """Pool worker initializer: the worker dies with the process that started the pool
    (kill -9 of the sweep included), instead of computing on for nobody."""
    from designlab.atomic import die_with_parent

    die_with_parent(parent_pid)


MAX_WORKERS = 512


class LocalExecutor:
    """Process pool (``spawn`` start method: OCP and VTK are not fork-safe). Its workers end
    with the process that started them, however that one ends (Linux parent-death signal)."""

    def __init__(self, workers: int | None = None):
        from designlab.errors import ParameterError

        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or not 1 <= workers <= MAX_WORKERS):
            raise ParameterError("--workers", workers, f"an integer, 1 <= value <= {MAX_WORKERS}")
        self.workers = workers or os.cpu_count() or 1

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Result]:
        if self.workers == 1:
            for i, t in enumerate(tasks):
                yield (i, *_guarded(fn, t))
            return
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx,
                                 initializer=_worker_init, initargs=(os.getpid(),)) as pool:
            pending = {pool.submit(_guarded, fn, t): i for i, t in enumerate(tasks)}
            try:
                while pending:
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for f in done:
                        i = pending.pop(f)
                        yield (i, *f.result())
            except BaseException:
                for f in pending:
                    f.cancel()
                raise


class DaskExecutor:
    """Tasks on a Dask distributed scheduler at ``address`` (e.g. ``tcp://10.0.0.5:8786``)."""

    def __init__(self, address: str):
        self.address = address

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Result]:
        from designlab.errors import ParameterError

        try:
            from distributed import Client, as_completed
        except ImportError:
            raise ParameterError("--scheduler", self.address,
                                 "Dask installed: pip install 'designlab[cluster]'") from None

        try:
            client = Client(self.address, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise ParameterError("--scheduler", self.address,
                                 f"the address of a reachable Dask scheduler ({exc})") from None
        try:
            futures = {client.submit(_guarded, fn, t, pure=False): i for i, t in enumerate(tasks)}
            for fut in as_completed(futures):
                yield (futures[fut], *fut.result())
        finally:
            client.close()
