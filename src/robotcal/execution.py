"""One execution backend for independent tasks: Monte Carlo blocks, sweeps, plan candidates.

``open_executor`` yields an :class:`Executor` whose ``map(function, items)`` returns the results in
the order of ``items``:

* ``scheduler`` (or the environment variable ``ROBOTCAL_SCHEDULER``) set: the tasks run on a Dask
  distributed cluster (``dask.distributed.Client(scheduler)``; Dask is the optional extra
  ``robotcal[distributed]`` and is imported only here, only then);
* else ``workers > 1``: a local pool of ``workers`` processes;
* else serially in this process.

Results never depend on the backend as long as every task carries its own seed (robotcal seeds a
Monte Carlo block from ``SeedSequence(seed, spawn_key=(block,))``): the same tasks give
bit-identical results serially, in local processes and on Dask workers.

The local pool is ``concurrent.futures.ProcessPoolExecutor`` with the ``fork`` start method where the platform has
it: the workers inherit the parent's imported modules and data, so start-up costs milliseconds and
large task arguments need not be pickled at start. The tasks are pure numpy (no threads, locks or
files are shared with the parent), which is what makes forking safe here; platforms without
``fork`` (Windows, macOS by default) use ``spawn``, which needs ``function`` and ``items`` to be
picklable (they must be anyway, for Dask). Workers ignore SIGINT (Ctrl-C reaches the whole process
group; only the parent acts on it) and, on Linux, receive SIGTERM when the parent dies. The parent
terminates and joins the workers when it leaves the ``with`` block by an exception, including
``KeyboardInterrupt`` and ``SystemExit``, so that no worker outlives it.
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

from robotcal.errors import InputError

__all__ = ["Executor", "open_executor", "SCHEDULER_ENV"]

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


def _ignore_interrupts() -> None:
    """Pool initializer: Ctrl-C is the parent's business; die with the parent (Linux)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
        except OSError:  # pragma: no cover - no libc: the parent still terminates the pool
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
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=multiprocessing.get_context(method), initializer=_ignore_interrupts
    )
    try:
        yield Executor("processes", workers, pool=pool)
    except BaseException:
        _terminate(pool)  # KeyboardInterrupt, SystemExit, a task's exception: no worker survives
        raise
    pool.shutdown(wait=True, cancel_futures=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued, stop the workers now (SIGTERM, then SIGKILL) and reap them.

    ``ProcessPoolExecutor`` has no public terminate; its ``_processes`` (pid -> Process) has been
    stable since Python 3.2. A worker that died (killed, out of memory) surfaces as
    ``BrokenProcessPool`` from ``map``, never as a hang.
    """
    processes = list((getattr(pool, "_processes", None) or {}).values())
    result_queue = getattr(pool, "_result_queue", None)  # taken now: shutdown() drops the pool's reference
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=2.0)
        if process.is_alive():  # pragma: no cover - a worker stuck in uninterruptible C code
            process.kill()
            process.join(timeout=2.0)
    # A worker stopped in the middle of sending its result leaves half a message in the result pipe, and the
    # pool's manager thread then waits in recv() for the rest, for ever: the interpreter's exit joins that
    # thread, so the command hung at exit (about 1 Ctrl-C in 20 during the Monte Carlo). This process holds
    # the pipe's last write end once the workers are gone: closing it ends that recv() with EOFError, which
    # the manager thread treats as a broken pool and shuts down. (``_result_queue`` is private, as is
    # ``_processes``; without it the old behaviour remains.)
    writer = getattr(result_queue, "_writer", None)
    if writer is not None and not any(process.is_alive() for process in processes):
        try:
            writer.close()
        except OSError:  # pragma: no cover - already closed
            pass
