"""Figures off the critical path: plot jobs drawn in one forked worker process while this one computes.

A :class:`FigureRenderer` forks its worker when it is created (``fork`` start method, where the platform
has it). The worker imports matplotlib (Agg) and the plot modules named in ``preload`` at once, so that
their import, about half a second, is paid while this process goes on; it then runs the jobs of
:meth:`FigureRenderer.submit` one after the other, in submission order::

    with FigureRenderer(preload=("robotcal.plots.montecarlo",)) as renderer:
        result = run_monte_carlo(...)                # the worker imports matplotlib meanwhile
        job = renderer.submit("robotcal.plots.montecarlo:write_histograms", result, folder)  # returns at once
        write_uncertainty_csv(folder / "parameters.csv", result)     # while the worker draws
        paths = job.result()                         # the job's value, or its error

A job is a module-level function, given as the function or by its name ``"package.module:function"``
(imported where the job runs: naming a plot function does not import matplotlib here), with picklable
arguments (numpy arrays, dataclasses, paths); an unpicklable one is refused by ``submit``. The arguments
are pickled in ``submit`` with their arrays out of band (pickle protocol 5): a thread of this process,
running only while there is something to send, writes the arrays from their own memory to the worker,
so ``submit`` neither copies them nor waits for the worker. The worker holds one copy of a job's
arguments while the job runs (the Monte Carlo draws: 8 bytes per draw and parameter, 24 MB for 10^5
draws of 30 parameters; the sorted copy of the statistics, which the memory check counts, is freed by
then). The figure functions write their files themselves, atomically (:mod:`robotcal.io.atomic`), and
return small values (paths).

Errors. A job's exception is raised in this process by :meth:`RenderJob.result` and by
:meth:`FigureRenderer.wait` (the first failed job's, in submission order): the same exception type (an
:class:`~robotcal.errors.InputError` stays one), with a note naming the job and, as its ``__cause__``, the
worker's traceback text (also in ``RenderJob.traceback_text``). A worker that dies (killed, out of memory)
fails its unfinished jobs with :class:`FigureWorkerError`, never a hang.

Stopping. Leaving the ``with`` block normally waits for every job (and raises the first error, even one
already seen through :meth:`RenderJob.result`: :meth:`~FigureRenderer.wait` reports every failure); leaving it
by an exception (an error, Ctrl-C, SIGTERM turned into an exception by the CLI) stops the worker at once,
whatever it does. The worker ignores SIGINT (Ctrl-C reaches the whole process group: only
the parent decides) and turns SIGTERM into ``SystemExit``, so that an atomic write in progress removes its
temporary file and a forked helper of the job (the histograms draw in two processes) is stopped too; it
gets SIGTERM when the parent dies (Linux), exits when it sees that its parent changed, and is stopped at
the interpreter's exit; a process a job forks gets SIGTERM when the worker dies, even by SIGKILL (Linux). The
worker never outlives the parent and, once :meth:`~FigureRenderer.cancel` or :meth:`~FigureRenderer.wait` has
returned or raised, no job writes any more. A single :class:`RenderJob` cannot be cancelled (its ``cancel``
returns False): :meth:`FigureRenderer.cancel` stops every unfinished job. Only a worker killed outright
(SIGKILL, the out-of-memory killer) can leave an atomic write's hidden temporary file (``.NAME.*.tmp``) beside
its figure; the figure itself is never half written.

Where ``fork`` is not available, with ``workers=0``, or when no process can be started (inside a daemonic
process), the jobs run synchronously in :meth:`~FigureRenderer.submit`, with the same results and errors.
The files are the same either way: a job draws the same figure in the worker as here.

Below the pipeline: imports matplotlib only in the worker (and in the synchronous mode, when a job runs),
never the pipeline, the report or the CLI.
"""

from __future__ import annotations

import atexit
import collections
import importlib
import multiprocessing
import multiprocessing.connection
import multiprocessing.util  # noqa: F401  (its exit hook is registered before ours: ours runs first)
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError, Future
from concurrent.futures import TimeoutError as FutureTimeoutError

from robotcal.errors import InputError, RobotcalError

__all__ = ["FigureRenderer", "RenderJob", "FigureWorkerError", "DEFAULT_PRELOAD"]

#: Modules the worker imports as soon as it starts: matplotlib with the Agg backend and the figure plumbing.
DEFAULT_PRELOAD = ("robotcal.plots.figures",)

#: Seconds a stopped worker is given to finish (SIGTERM: remove its temporary file) before SIGKILL.
STOP_TIMEOUT_S = 5.0

#: Seconds between two checks of the idle worker that its parent is still the one that started it.
_PARENT_CHECK_S = 1.0

#: First message of a job (followed by its 8-byte index and the 8-byte sizes of its buffers, then come the pickle
#: and the buffers' raw bytes), and the message that stops the worker.
_JOB, _STOP = b"J", b"S"


class FigureWorkerError(RobotcalError):
    """The figure worker stopped before a job finished (killed, out of memory), or a job's outcome could
    not be brought back (an exception or value that does not pickle)."""


class _RemoteTraceback(Exception):
    """The worker's traceback text, attached as ``__cause__`` of the error raised here (as
    :mod:`concurrent.futures` does for its process pools)."""

    def __init__(self, text: str):
        super().__init__(text)
        self.text = text

    def __str__(self) -> str:
        return f"\n\"\"\"\n{self.text}\"\"\""


class RenderJob(Future):
    """A submitted plot job: a :class:`concurrent.futures.Future` whose :meth:`result` and :meth:`exception`
    collect what the worker sent back (no thread of this process waits on the worker).

    Attributes
    ----------
    name : str
        ``"<module>.<function> (job <n>)"``, used in error messages.
    index : int
        Submission number, from 1.
    traceback_text : str or None
        The job's traceback as the worker (or the synchronous call) formatted it, when it failed.
    """

    def __init__(self, renderer: FigureRenderer | None, index: int, name: str):
        super().__init__()
        self._renderer = renderer
        self.index = index
        self.name = name
        self.traceback_text: str | None = None

    def cancel(self) -> bool:
        """False: one job cannot be cancelled (the worker may be drawing it); :meth:`FigureRenderer.cancel`
        stops every unfinished job."""
        return False

    def _cancel_here(self) -> None:
        """Mark the job cancelled (the renderer stopped it)."""
        super().cancel()

    def result(self, timeout: float | None = None):
        self._collect(timeout)
        return super().result(timeout=0)

    def exception(self, timeout: float | None = None):
        self._collect(timeout)
        return super().exception(timeout=0)

    def _collect(self, timeout: float | None) -> None:
        if not self.done() and self._renderer is not None:
            self._renderer._collect(until=self, timeout=timeout)
        if not self.done():
            raise FutureTimeoutError(f"figure job {self.name} not finished after {timeout} s")

    def _fail(self, error: BaseException, traceback_text: str | None, where: str) -> None:
        self.traceback_text = traceback_text
        try:
            error.add_note(f"(figure job {self.name}, {where})")
        except AttributeError:  # pragma: no cover - every exception has add_note on Python >= 3.11
            pass
        if traceback_text and error.__cause__ is None:
            error.__cause__ = _RemoteTraceback(traceback_text)
        self.set_exception(error)


def _job_name(function: Callable | str, index: int) -> str:
    if isinstance(function, str):
        return f"{function.replace(':', '.')} (job {index})"
    module = getattr(function, "__module__", None) or "?"
    qualified = getattr(function, "__qualname__", None) or repr(function)
    return f"{module}.{qualified} (job {index})"


# --------------------------------------------------------------------------------------------------- worker


#: Set in the worker (and its helpers) by SIGTERM: the ``SystemExit`` that follows is a stop, not a job's failure.
_STOPPING = False

#: True in the worker while a job runs (and so in the processes a job forks).
_IN_JOB = False


def _on_sigterm_in_worker(signum, frame):
    """SIGTERM in the worker (or a process it forked): stop its own forked helpers, then unwind with
    ``SystemExit`` so that ``finally`` blocks run (an atomic write removes its temporary file).

    Outside a job there is nothing to unwind, and the worker exits at once: a ``SystemExit`` raised while the
    handler happens to run inside a weakref callback or a ``__del__`` is printed and swallowed ("Exception
    ignored in ..."), and the idle worker then waited for its SIGKILL (5 s; about one stop in ten of a run).
    Inside a job, the same swallowing lets the job go on; the worker exits as soon as the job returns."""
    global _STOPPING
    _STOPPING = True
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # one is enough: the unwinding must not be interrupted
    for child in multiprocessing.active_children():
        child.terminate()
    if not _IN_JOB:
        os._exit(128 + signum)
    raise SystemExit(128 + signum)


def _die_with_parent() -> None:
    """SIGTERM to this process when its parent dies (Linux ``PR_SET_PDEATHSIG``; elsewhere nothing)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
        except OSError:  # pragma: no cover - no libc: the parent check of the idle loop remains
            pass


def _helper_dies_with_worker(worker_pid: int) -> None:
    """In a process a job forks (the histograms draw in helpers): SIGTERM when the worker dies, even by SIGKILL,
    so that no helper outlives it, holds its pipes or writes a figure after it was stopped."""
    _die_with_parent()
    if os.getppid() != worker_pid:  # the worker died before PR_SET_PDEATHSIG took effect
        os._exit(128 + signal.SIGTERM)


def _set_up_worker(parent_pid: int) -> None:
    """Signals (SIGINT ignored, SIGTERM unwinds, SIGTERM when the parent dies on Linux, and so for the processes
    its jobs fork) and one BLAS thread."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_sigterm_in_worker)
    _die_with_parent()
    if os.getppid() != parent_pid:  # the parent died before PR_SET_PDEATHSIG took effect
        raise SystemExit(0)
    worker_pid = os.getpid()
    if hasattr(os, "register_at_fork"):
        os.register_at_fork(after_in_child=lambda: _helper_dies_with_worker(worker_pid))
    # the figures need no BLAS threads; a process started from here (none is) would read these
    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[variable] = "1"
    try:  # the BLAS numpy already loaded (inherited by the fork) is limited only through threadpoolctl
        from threadpoolctl import threadpool_limits
    except ImportError:
        pass
    else:
        threadpool_limits(1)


def _worker_main(jobs, results, unused, preload: tuple[str, ...], parent_pid: int) -> None:
    """The worker: preload, then run jobs until the stop message, a closed pipe or a new parent."""
    global _IN_JOB
    for connection in unused:
        connection.close()
    _set_up_worker(parent_pid)
    for name in preload:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001, S112 - a job that needs the module raises the error itself, reported
            pass
    while True:
        if not jobs.poll(_PARENT_CHECK_S):
            if os.getppid() != parent_pid:
                return
            continue
        try:
            start = jobs.recv_bytes()
            if start[:1] != _JOB:  # _STOP
                return
            index = int.from_bytes(start[1:9], "little")  # the outcome names it even if the pickle fails to load
            sizes = [int.from_bytes(start[i : i + 8], "little") for i in range(9, len(start), 8)]
            header = jobs.recv_bytes()
            buffers = [bytearray(size) for size in sizes]  # writable: the arrays arrive as they were
            for buffer in buffers:
                _read_exactly(jobs.fileno(), buffer)
        except (EOFError, OSError):
            return
        _IN_JOB = True
        outcome = _run_job(index, header, buffers)
        _IN_JOB = False
        if _STOPPING:  # stopped during the job, whose SystemExit was swallowed (see _on_sigterm_in_worker)
            os._exit(128 + signal.SIGTERM)
        del header, buffers  # the job's arguments are not kept while the worker waits for the next one
        results.send_bytes(outcome)


def _read_exactly(fd: int, buffer: bytearray) -> None:
    """Fill ``buffer`` from the pipe, reading straight into it (one copy, no intermediate)."""
    view, done = memoryview(buffer), 0
    while done < len(buffer):
        count = os.readv(fd, [view[done:]])
        if count == 0:
            raise EOFError("the job pipe closed in the middle of a job")
        done += count


def _write_all(fd: int, buffer) -> None:
    """Write an array's memory to the pipe as it is (no copy)."""
    view, done = memoryview(buffer).cast("B"), 0
    while done < len(view):
        done += os.write(fd, view[done:])


def _widen(connection) -> None:
    """A 1 MiB pipe buffer where Linux allows it (64 KiB by default): fewer switches between the processes
    while the draws go through."""
    try:
        import fcntl

        fcntl.fcntl(connection.fileno(), fcntl.F_SETPIPE_SZ, 1 << 20)
    except (ImportError, AttributeError, OSError):  # not Linux, or above /proc/sys/fs/pipe-max-size
        pass


def _resolve(function: Callable | str) -> Callable:
    """A function, or ``"package.module:function"`` imported here."""
    if not isinstance(function, str):
        return function
    module, _, name = function.partition(":")
    return getattr(importlib.import_module(module), name)


def _run_job(index: int, header: bytes, buffers: list[bytearray]) -> bytes:
    """Run job ``index`` from its pickle; the pickled ``(index, ok, traceback_text, pickled value or exception)``.

    A job that cannot be loaded here (its function defined in ``__main__`` after the fork, say) fails like
    one that raises. One that raises ``SystemExit`` or ``KeyboardInterrupt`` itself fails with a
    :class:`FigureWorkerError` (raising those in the parent would end it), with its traceback; the
    ``SystemExit`` of a SIGTERM is not caught (the worker is being stopped: it unwinds)."""
    try:
        function, args, kwargs = pickle.loads(header, buffers=buffers)
        value = _resolve(function)(*args, **kwargs)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        if _STOPPING:
            raise
        text = "".join(traceback.format_exception(exc))
        if not isinstance(exc, Exception):
            exc = FigureWorkerError(f"the job raised {type(exc).__qualname__}({exc})")
        try:
            payload = pickle.dumps(exc, protocol=pickle.HIGHEST_PROTOCOL)
            pickle.loads(payload)  # an exception that pickles but does not unpickle is caught here
        except Exception:  # noqa: BLE001
            payload = pickle.dumps(FigureWorkerError(f"{type(exc).__qualname__}: {exc}"))
        return pickle.dumps((index, False, text, payload), protocol=pickle.HIGHEST_PROTOCOL)
    try:
        payload = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # noqa: BLE001
        error = FigureWorkerError(f"its value ({type(value).__qualname__}) cannot be sent back: {exc}")
        return pickle.dumps((index, False, None, pickle.dumps(error)), protocol=pickle.HIGHEST_PROTOCOL)
    return pickle.dumps((index, True, None, payload), protocol=pickle.HIGHEST_PROTOCOL)


class _Worker:
    """The forked process, its two pipes and the thread that sends the jobs."""

    def __init__(self, preload: tuple[str, ...]):
        context = multiprocessing.get_context("fork")
        job_reader, self.jobs = context.Pipe(duplex=False)
        self.results, result_writer = context.Pipe(duplex=False)
        _widen(self.jobs)
        self.process = context.Process(
            target=_worker_main,
            args=(job_reader, result_writer, (self.jobs, self.results), preload, os.getpid()),
            name="robotcal-figures",
            daemon=False,  # a daemonic process may not fork; the jobs may (the histograms draw in two processes)
        )
        try:
            self.process.start()
        except BaseException:
            self.jobs.close()
            self.results.close()
            raise
        finally:
            job_reader.close()
            result_writer.close()
        self.owner = os.getpid()
        # Jobs wait here for the sending thread, which runs only while there is something to send (no thread
        # of ours lives on while this process forks other workers, e.g. the Monte Carlo's).
        self.outbox: collections.deque = collections.deque()
        self.lock = threading.Lock()
        self.sender: threading.Thread | None = None
        atexit.register(self.terminate)  # after multiprocessing's exit hook, so before it joins its children

    def send(self, item: tuple[int, bytes, list] | None) -> None:
        """Queue a job (index, pickle and buffers) or the stop message (None), in order; returns at once."""
        with self.lock:
            self.outbox.append(item)
            if self.sender is None:
                self.sender = threading.Thread(target=self._send_queued, name="robotcal-figure-jobs", daemon=True)
                self.sender.start()

    def _send_queued(self) -> None:
        """Send each job as: the sizes of its buffers, the pickle, the buffers (the arrays' memory, not copied)."""
        while True:
            with self.lock:
                if not self.outbox:
                    self.sender = None
                    return
                item = self.outbox.popleft()
            try:
                if item is None:
                    self.jobs.send_bytes(_STOP)
                    continue
                index, header, buffers = item
                sizes = b"".join(buffer.nbytes.to_bytes(8, "little") for buffer in buffers)
                self.jobs.send_bytes(_JOB + index.to_bytes(8, "little") + sizes)
                self.jobs.send_bytes(header)
                for buffer in buffers:  # raw, after the two framed messages: the worker reads exactly nbytes
                    _write_all(self.jobs.fileno(), buffer)
            except (OSError, ValueError):  # the worker is gone: the collecting side reports it
                with self.lock:
                    self.outbox.clear()
                    self.sender = None
                return

    def stop(self) -> None:
        """Let the worker finish what it was sent, then exit; reap it."""
        self.send(None)
        sender = self.sender
        if sender is not None:
            sender.join(timeout=STOP_TIMEOUT_S)
        self.process.join(timeout=STOP_TIMEOUT_S)
        self.terminate()
        self.release()

    def terminate(self) -> None:
        """Stop the worker now: SIGTERM (its atomic writes clean up), SIGKILL if it does not exit in time."""
        atexit.unregister(self.terminate)
        if os.getpid() != self.owner:  # a process forked from the parent exits: not its worker
            return
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout=STOP_TIMEOUT_S)
            if self.process.is_alive():  # pragma: no cover - stuck in uninterruptible C code
                self.process.kill()
                self.process.join(timeout=STOP_TIMEOUT_S)
        self.process.join(timeout=0)
        with self.lock:
            self.outbox.clear()  # a sender blocked on a full pipe fails now that the reader is gone

    def release(self) -> None:
        """Close this side's pipe ends (after :meth:`terminate` or :meth:`stop`, once the outcomes are read)."""
        for connection in (self.jobs, self.results):
            try:
                connection.close()
            except OSError:  # pragma: no cover
                pass

    def describe_exit(self) -> str:
        code = self.process.exitcode
        if code is None:
            return "the figure worker stopped answering"
        if code < 0:
            try:
                return f"the figure worker was killed by {signal.Signals(-code).name}"
            except ValueError:  # pragma: no cover
                return f"the figure worker was killed by signal {-code}"
        return f"the figure worker exited with status {code}"


# ------------------------------------------------------------------------------------------------- renderer


class FigureRenderer:
    """Plot jobs in one forked worker process (or synchronously), results in submission order.

    Parameters
    ----------
    workers : {1, 0}
        1: one worker process, forked now (synchronous where ``fork`` is missing or no process can be
        started); 0: every job runs synchronously in :meth:`submit`.
    preload : sequence of str
        Modules the worker imports as soon as it starts (default :data:`DEFAULT_PRELOAD`: matplotlib with
        Agg); name the plot modules the jobs will use.

    Attributes
    ----------
    kind : {"process", "synchronous"}
        Where the jobs run (``"synchronous"`` after a fallback too).

    Notes
    -----
    Create it early, once numpy is imported and before matplotlib is: the fork copies what this process
    has imported (nothing to import again), and the worker imports the rest while this process works.
    Use it from the thread that created it (that thread's exit would also stop the worker on Linux:
    ``PR_SET_PDEATHSIG``). The jobs run one after the other; a job may fork helpers of its own (the worker
    is not daemonic) and these are stopped with it. The worker holds a copy of each job's arguments while
    the job runs (the Monte Carlo draws: 8 bytes per draw and parameter).
    """

    def __init__(self, *, workers: int = 1, preload: Sequence[str] = DEFAULT_PRELOAD):
        if isinstance(workers, bool) or workers not in (0, 1):
            raise InputError(f"`workers` of a FigureRenderer must be 0 (synchronous) or 1 (one process); got {workers!r}")
        if isinstance(preload, str) or not all(isinstance(name, str) for name in preload):
            raise InputError(f"`preload` must be a sequence of module names; got {preload!r}")
        self._preload = tuple(preload)
        self._background = workers == 1 and "fork" in multiprocessing.get_all_start_methods()
        self._worker: _Worker | None = None
        self._jobs: dict[int, RenderJob] = {}  # sent to the worker, not finished
        self._unwaited: list[RenderJob] = []
        self._count = 0
        self._closed = False
        if self._background:
            self._start()

    @property
    def kind(self) -> str:
        return "process" if self._background else "synchronous"

    def _start(self) -> None:
        try:
            self._worker = _Worker(self._preload)
        except (AssertionError, OSError):  # a daemonic process may not have children; no process left
            self._worker, self._background = None, False

    # ------------------------------------------------------------------------------------------ public API

    def submit(self, function: Callable | str, /, *args, **kwargs) -> RenderJob:
        """Run ``function(*args, **kwargs)`` in the worker (synchronously without one); returns at once.

        ``function`` is a module-level function, or its name ``"package.module:function"``, imported
        where the job runs (so that naming a plot function does not import matplotlib here). The
        arguments must pickle (arrays, dataclasses, paths): refused here (``TypeError``) otherwise.
        Arrays are sent from their own memory, without a copy, after this returns: do not modify one
        before its job has finished (robotcal's results are read-only).
        """
        if self._closed:
            raise RuntimeError("this FigureRenderer is closed")
        if isinstance(function, str):
            module, colon, name = function.partition(":")
            if not (colon and module and name.isidentifier()):
                raise InputError(f"a figure job named by a string must read 'package.module:function'; got {function!r}")
        elif not callable(function):
            raise TypeError(f"a figure job must be a function or 'package.module:function'; got {function!r}")
        self._count += 1
        job = RenderJob(self, self._count, _job_name(function, self._count))
        if self._background and self._worker is None:
            self._start()  # after a cancel: a new worker
        if not self._background:
            self._unwaited.append(job)
            self._run_here(job, function, args, kwargs)
            return job
        buffers: list[pickle.PickleBuffer] = []
        try:
            header = pickle.dumps((function, args, kwargs), protocol=5, buffer_callback=buffers.append)
            raw = [buffer.raw() for buffer in buffers]
        except Exception as exc:  # noqa: BLE001 - pickling raises many types
            raise TypeError(
                f"figure job {job.name}: the function must be a module-level function and its arguments "
                f"picklable (arrays, dataclasses, paths): {exc}"
            ) from exc
        self._unwaited.append(job)
        self._jobs[job.index] = job
        self._worker.send((job.index, header, raw))
        return job

    def wait(self) -> list:
        """The values of the jobs submitted since the last :meth:`wait`, in submission order.

        Raises the first failed job's exception (in submission order), after stopping the jobs still
        running (:meth:`cancel`): when this returns or raises, no job of this renderer runs.
        """
        jobs, self._unwaited = self._unwaited, []
        try:
            for job in jobs:
                if job.cancelled():
                    raise CancelledError(f"figure job {job.name} was cancelled")
                error = job.exception()
                if error is not None:
                    raise error
        except BaseException:
            self.cancel()
            raise
        return [job.result() for job in jobs]

    def cancel(self) -> None:
        """Stop the jobs not finished: the worker is terminated (SIGTERM: an atomic write in progress removes
        its temporary file), the jobs are cancelled (and no longer waited for by :meth:`wait` or the end of a
        ``with`` block), and the next :meth:`submit` starts a new worker. Finished jobs keep their outcome;
        with no unfinished job the worker is left running."""
        if self._worker is None:
            return
        self._drain()
        if self._jobs:
            self._stop_now()
        self._unwaited = [job for job in self._unwaited if not job.cancelled()]

    def _stop_now(self) -> None:
        """Terminate the worker, whatever it does (a job, its preload, waiting), and cancel what it had."""
        if self._worker is None:
            return
        worker, self._worker = self._worker, None
        worker.terminate()
        self._drain_from(worker)  # outcomes sent before the end still count
        worker.release()
        for job in self._jobs.values():
            job._cancel_here()
        self._jobs.clear()

    def close(self) -> None:
        """Wait for the jobs already submitted (their outcomes stay in their :class:`RenderJob`), then stop
        the worker. Idempotent; :meth:`submit` is refused afterwards. An interrupt while waiting cancels."""
        if self._closed:
            return
        self._closed = True
        if self._worker is None:
            return
        try:
            self._collect(until=None, timeout=None)
        except BaseException:
            self.cancel()
            raise
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.stop()

    def __enter__(self) -> FigureRenderer:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:  # an error or an interrupt: stop at once (a preload is not waited for)
            self._stop_now()
            self.close()
            return
        try:
            self.wait()
        except BaseException:
            self.close()
            raise
        self.close()

    def __del__(self):
        worker = getattr(self, "_worker", None)
        if worker is not None:
            try:
                worker.terminate()
                worker.release()
            except Exception:  # noqa: BLE001, S110 - at interpreter exit, modules may be gone; atexit stopped it
                pass

    # --------------------------------------------------------------------------------------------- helpers

    def _run_here(self, job: RenderJob, function: Callable | str, args: tuple, kwargs: dict) -> None:
        try:
            value = _resolve(function)(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - kept in the job, raised by result() / wait()
            job._fail(exc, "".join(traceback.format_exception(exc)), "run synchronously")
        except BaseException:  # an interrupt: the job has no outcome
            job._cancel_here()
            raise
        else:
            job.set_result(value)

    def _collect(self, *, until: RenderJob | None, timeout: float | None) -> None:
        """Read outcomes until ``until`` is done (None: every job sent), the worker ended, or ``timeout``."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self._worker is not None and self._jobs and (until is None or not until.done()):
            worker = self._worker
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready = multiprocessing.connection.wait([worker.results, worker.process.sentinel], left)
            if not ready:
                return  # timeout
            if worker.results in ready:
                self._receive(worker)
            elif not worker.results.poll():  # the worker ended and sent nothing more
                self._worker_died(worker)

    def _drain(self) -> None:
        if self._worker is not None:
            self._drain_from(self._worker)

    def _drain_from(self, worker: _Worker) -> None:
        """Outcomes already sent, without waiting."""
        try:
            while self._jobs and worker.results.poll():
                if not self._receive(worker):
                    return
        except (OSError, ValueError):  # closed: nothing more to read
            return

    def _receive(self, worker: _Worker) -> bool:
        """One outcome from the worker; False if the pipe ended (the worker died)."""
        try:
            data = worker.results.recv_bytes()
        except (EOFError, OSError):
            if worker is self._worker:
                self._worker_died(worker)
            return False
        index, ok, text, payload = pickle.loads(data)
        job = self._jobs.pop(index, None)
        if job is None or job.done():  # pragma: no cover - a job cancelled in between
            return True
        try:
            value = pickle.loads(payload)
        except Exception as exc:  # noqa: BLE001
            ok, value = False, FigureWorkerError(f"its outcome cannot be read back: {exc}")
        if ok:
            job.set_result(value)
        else:
            job._fail(value, text, f"in the figure worker, pid {worker.process.pid}")
        return True

    def _worker_died(self, worker: _Worker) -> None:
        worker.terminate()
        worker.release()
        if self._worker is worker:
            self._worker = None
        reason = worker.describe_exit()
        for job in self._jobs.values():
            job._fail(FigureWorkerError(f"{reason} before figure job {job.name} finished"), None, "worker lost")
        self._jobs.clear()
