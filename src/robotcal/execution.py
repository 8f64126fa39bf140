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
whole process group) and, on Linux, are killed when the parent dies. They are started with the interrupt signals
held back in the parent (:func:`robotcal.errors.interrupts_held`): a signal that arrives as a worker is forked is
raised in the parent once the fork is done, not dropped in a fork handler, and never reaches the new worker before
it ignores it. When the parent leaves the pool's ``with`` block by an exception (a task's error, Ctrl-C, SIGTERM
turned into an exception by the CLI) it cancels the tasks not started and writes to the pool's stop pipe. Each
worker then interrupts the task it runs: a thread of the worker, waiting on the pipe, signals the worker's main
thread (SIGUSR1), whose handler raises :class:`StopRequested` in the task's code; the task's ``finally`` blocks run
(a figure's temporary file is removed) and it ends at once, whatever it computes (a figure being drawn, a Monte
Carlo block), on a busy machine too. A task that has not started ends at its start; :func:`check_stop`, called
between the steps of long tasks, ends them where there is no such signal. A worker is never killed, and the
exception is never raised once the task has returned, while the worker sends its result: a message cut short would
leave the pool's manager thread waiting for the rest of it for ever. The stop is a pipe, not a
:class:`multiprocessing.Event`, because nothing it involves takes a lock shared between processes: an exception
raised in a worker as it holds such a lock (an event's) would keep it held, and the waiter of an event in a worker
that has died makes the event's ``set`` wait for ever.

In the parent, :func:`check_stop` raises an interrupt the process received whose exception Python dropped
(:func:`robotcal.errors.check_interrupt`): it is called when a pool has started its workers and as each result
comes back, so that the work stops even then.
"""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import sys
import threading
import time
import weakref
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

from robotcal.errors import INTERRUPT_SIGNALS, InputError, check_count, check_interrupt, interrupts_held

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
            return _serial_results(function, items)
        if self.kind == "processes":
            futures = [self._pool.submit(function, item) for item in items]
        else:
            futures = self._client.map(function, items, pure=False)
        return _results(futures)


def _serial_results(function: Callable, items: list) -> Iterator:
    for item in items:
        check_stop()
        yield function(item)


def _results(futures: list) -> Iterator:
    """The futures' results in order, each after a :func:`check_stop`."""
    for future in futures:
        result = future.result()
        check_stop()
        yield result


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
    """Raised in a pool worker's task when its pool is being shut down (by :func:`check_stop`, or by the signal the
    worker's stop watcher sends, module docstring)."""


#: In a pool worker: the read end of the pool's stop pipe, readable once the pool stops (None elsewhere).
_STOP = None
#: In a pool worker: whether a task is running (:func:`_task`), so that the pool's stop may interrupt it.
_RUNNING = False
#: The signal by which a pool worker's stop watcher interrupts its running task (None: no such signal here).
_STOP_SIGNAL = getattr(signal, "SIGUSR1", None) if hasattr(signal, "pthread_kill") else None
#: Seconds between two such signals while the worker lives (a task that caught the first one still ends).
_STOP_REPEAT_S = 0.5


def check_stop() -> None:
    """In a pool worker whose pool is shutting down, raise :class:`StopRequested`; in the main process, raise an
    interrupt it received whose exception was dropped (:func:`robotcal.errors.check_interrupt`); else nothing.

    Long tasks call it between their steps so that an interrupt of the parent ends them within a step.
    """
    if _STOP is not None:
        if _STOP.poll():
            raise StopRequested("the pool is shutting down")
        return
    check_interrupt()


def _task(function: Callable, /, *args, **kwargs):
    """A pool task: ``function(*args, **kwargs)``, interrupted by the pool's stop (:func:`_stop_task`)."""
    global _RUNNING
    check_stop()
    _RUNNING = True
    try:
        return _call(function, args, kwargs)
    finally:
        _RUNNING = False


def _call(function: Callable, args: tuple, kwargs: dict):
    # a frame of its own under _task, also for a function written in C (time.sleep): _stop_task raises there
    return function(*args, **kwargs)


def _stop_task(signum, frame) -> None:
    """In a pool worker, the handler of :data:`_STOP_SIGNAL`: raise :class:`StopRequested` in the running task's code
    (never in :func:`_task` itself, which has returned or is returning, nor between tasks, nor in a weak-reference
    callback or finaliser that the garbage collector runs in the task's stack: Python prints and drops an exception
    raised there; the watcher signals again :data:`_STOP_REPEAT_S` later, in the task's own code)."""
    if not _RUNNING or frame is None or frame.f_code is _task.__code__:
        return
    if frame.f_code.co_name == "__del__" or frame.f_code.co_filename == weakref.__file__:
        return
    raise StopRequested("the pool is shutting down")


def _watch_stop(stop, thread: int) -> None:
    """In a pool worker, a daemon thread: once the pool's ``stop`` pipe is readable, signal the worker's main thread
    ``thread``, again every :data:`_STOP_REPEAT_S` while the worker lives."""
    assert _STOP_SIGNAL is not None  # started only where the platform has the signal (_start_worker)
    stop.poll(None)
    while True:
        signal.pthread_kill(thread, _STOP_SIGNAL)
        time.sleep(_STOP_REPEAT_S)


def _start_worker(stop) -> None:
    """Pool initializer: signals are the parent's business, the pool's stop pipe (its read end) and its watcher, one
    BLAS thread for the worker's life, and (Linux) death with the parent."""
    global _STOP
    _STOP = stop
    for name in INTERRUPT_SIGNALS:
        signal.signal(getattr(signal, name), signal.SIG_IGN)
    if _STOP_SIGNAL is not None:
        signal.signal(_STOP_SIGNAL, _stop_task)
        watcher = threading.Thread(target=_watch_stop, args=(stop, threading.get_ident()), daemon=True)
        watcher.start()
    threadpool_limits(limits=1, user_api="blas")
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG: a worker never outlives a parent killed outright
        except OSError:  # pragma: no cover - not glibc: the pool still stops its workers
            pass


def _check(workers, scheduler) -> tuple[int, str | None]:
    workers = check_count(workers, "workers")
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


class _StoppablePool(ProcessPoolExecutor):
    """A :class:`~concurrent.futures.ProcessPoolExecutor` whose tasks its stop interrupts (:func:`_task`) and whose
    workers start with the interrupt signals held back (module docstring)."""

    def submit(self, fn: Callable, /, *args, **kwargs) -> Future:
        with interrupts_held():  # the workers are forked here (at the first task, for the fork start method)
            future = super().submit(_task, fn, *args, **kwargs)
        check_stop()
        return future


@contextmanager
def process_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A local :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` processes for a ``with`` block
    (module docstring: start method, signals, stopping). Leaving the block normally waits for every task;
    leaving it by an exception cancels the tasks not started and stops the running ones at once."""
    context = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    stop, stopping = context.Pipe(duplex=False)
    try:
        pool = _StoppablePool(max_workers=workers, mp_context=context, initializer=_start_worker, initargs=(stop,))
        try:
            yield pool
            check_stop()  # an interrupt whose exception was dropped in the block
        except BaseException:
            stopping.send_bytes(b"stop")  # each worker interrupts its running task; one not started ends at its start
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    finally:
        stop.close()
        stopping.close()
