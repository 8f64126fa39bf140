"""One execution backend for independent tasks: Monte Carlo blocks, sweeps, plan candidates, figures.

``open_executor`` yields an :class:`Executor` whose ``map(function, items)`` returns the results in
the order of ``items``:

* ``scheduler`` (or the environment variable ``ROBOTCAL_SCHEDULER``) set: the tasks run on a Dask
  distributed cluster (``dask.distributed.Client(scheduler)``; Dask is the optional extra
  ``robotcal[distributed]`` and is imported only here, only then);
* else ``workers > 1``: a local pool of ``workers`` processes (:func:`process_pool`);
* else serially in this process.

Results never depend on the backend as long as every task carries its own seed (robotcal seeds a
Monte Carlo block from ``SeedSequence(seed, spawn_key=(block,))``): the same tasks give
bit-identical results serially, in local processes and on Dask workers.

The local pool (:func:`process_pool`, the one place a pool is made) is ``concurrent.futures.ProcessPoolExecutor``
with the ``fork`` start method where the platform has it: the workers inherit the parent's imported modules and
data, so start-up costs milliseconds and large task arguments need not be pickled at start. The tasks are pure
numpy (no threads, locks or files are shared with the parent), which is what makes forking safe here; platforms
without ``fork`` (Windows, macOS by default) use ``spawn``, which needs ``function`` and ``items`` to be
picklable (they must be anyway, for Dask).

Stopping. Signals are the parent's business: workers ignore SIGINT, SIGTERM and SIGHUP (Ctrl-C reaches the
whole process group) and, on Linux, are killed when the parent dies. When the parent leaves the pool's ``with``
block by an exception (a task's error, Ctrl-C, SIGTERM turned into an exception by the CLI) it cancels the
tasks not started and sets the pool's stop event; a running task sees it at its next :func:`check_stop` (the
Monte Carlo checks between batches, every few tenths of a second) and ends, so the pool shuts down within a
batch, through the public API only. A worker is never killed while it may be sending its result: that can leave
the pool's manager thread waiting for the rest of the message for ever.
"""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import sys
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

from robotcal.errors import InputError

__all__ = ["Executor", "StopRequested", "check_stop", "open_executor", "process_pool", "single_blas_thread", "SCHEDULER_ENV"]

#: Environment variable read when ``scheduler`` is None.
SCHEDULER_ENV = "ROBOTCAL_SCHEDULER"


class Executor:
    """Runs ``function`` over ``items`` and yields the results in order.

    Attributes
    ----------
    kind : {"serial", "processes", "dask"}
    workers : int
        Local processes (1 for serial; the cluster's worker count for Dask, when known).
    """

    kind: str

    def __init__(self, kind: str, workers: int = 1, *, pool=None, client=None):
        self.kind, self.workers, self._pool, self._client = kind, workers, pool, client

    def map(self, function: Callable, items: Iterable) -> Iterator:
        """``function(item)`` for every item, yielded in the order of ``items``.

        ``function`` must be a top-level (picklable) callable, e.g. a module function or a
        ``functools.partial`` of one. An exception in a task is raised here, in the parent.
        """
        items = list(items)
        if self.kind == "serial":
            return (function(item) for item in items)
        if self.kind == "processes":
            futures = [self._pool.submit(function, item) for item in items]
            return (future.result() for future in futures)
        futures = self._client.map(function, items, pure=False)
        return (future.result() for future in futures)


def single_blas_thread():
    """A context in which BLAS runs one thread (``threadpoolctl.threadpool_limits``), the limit before restored
    when it ends.

    robotcal's parallelism is its own (Monte Carlo worker processes, threads over poses) and its linear algebra
    is small (3x3 fits, 40-column QRs, blocks of a few hundred draws): a multi-threaded BLAS only adds threads
    that spin waiting for each other, which on a loaded 2-core machine made such calls up to 50 times slower
    (benchmarks/bench_refined_montecarlo.py). Library callers get this without any environment variable.
    """
    return threadpool_limits(limits=1, user_api="blas")


class StopRequested(Exception):
    """Raised in a pool worker by :func:`check_stop` when its pool is being shut down."""


#: In a pool worker: the pool's stop event (None elsewhere).
_STOP = None


def check_stop() -> None:
    """In a pool worker whose pool is shutting down, raise :class:`StopRequested`; elsewhere do nothing.

    Long tasks call it between their steps so that an interrupt of the parent ends them within a step.
    """
    if _STOP is not None and _STOP.is_set():
        raise StopRequested("the pool is shutting down")


def _start_worker(stop) -> None:
    """Pool initializer: signals are the parent's business, the pool's stop event, one BLAS thread for the
    worker's life, and (Linux) death with the parent."""
    global _STOP
    _STOP = stop
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    threadpool_limits(limits=1, user_api="blas")
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG: a worker never outlives a parent killed outright
        except OSError:  # pragma: no cover - not glibc: the pool still stops its workers
            pass


def _check(workers, scheduler) -> tuple[int, str | None]:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"`workers` must be a positive integer; got {workers!r}")
    if scheduler is None:
        scheduler = os.environ.get(SCHEDULER_ENV) or None
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise InputError(f"`scheduler` must be a Dask scheduler address such as tcp://host:8786; got {scheduler!r}")
    return workers, scheduler


@contextmanager
def open_executor(*, workers: int = 1, scheduler: str | None = None) -> Iterator[Executor]:
    """Open the execution backend for a ``with`` block.

    Parameters
    ----------
    workers : int
        Local worker processes when there is no scheduler (1: run in this process).
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``, or an in-process ``inproc://`` address);
        None reads ``ROBOTCAL_SCHEDULER``; empty or unset means local execution.

    Yields
    ------
    Executor
    """
    workers, scheduler = _check(workers, scheduler)
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError:
            raise InputError(
                f"a Dask scheduler was given ({scheduler}) but Dask is not installed: "
                "pip install 'robotcal[distributed]'"
            ) from None
        # tcp/tls/ucx://host:port, or an in-process cluster's inproc:// address
        if not (re.fullmatch(r"(tcp|tls|ucx)://[^\s/:]+:\d+", scheduler) or scheduler.startswith("inproc://")):
            raise InputError(
                f"--scheduler / ROBOTCAL_SCHEDULER: {scheduler!r} is not a Dask scheduler address "
                "(expected e.g. tcp://host:8786)"
            )
        try:
            client = Client(scheduler, set_as_default=False, timeout="10s")
        except (OSError, ValueError, TypeError) as exc:
            raise InputError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
        try:
            count = len(client.scheduler_info().get("workers", {})) or 1
            yield Executor("dask", count, client=client)
        finally:
            client.close()
        return
    if workers == 1:
        yield Executor("serial")
        return
    with process_pool(workers) as pool:
        yield Executor("processes", workers, pool=pool)


@contextmanager
def process_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A local :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` processes for a ``with`` block
    (module docstring: start method, signals, stopping). Leaving the block normally waits for every task;
    leaving it by an exception cancels the tasks not started and asks the running ones to stop."""
    context = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    stop = context.Event()
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_start_worker, initargs=(stop,))
    try:
        yield pool
    except BaseException:
        stop.set()  # running tasks end at their next check_stop
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
