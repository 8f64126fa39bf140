"""Shared CLI plumbing: consoles, error and warning display, signals, limits, parameter tables.

User text (paths, CSV cells, robot and scenario names, exception messages) reaches the terminal
literally: both consoles are created with ``markup=False``, so square brackets are never read as Rich
markup; styled parts are built as :class:`rich.text.Text` (:func:`styled`).

Importing this module is light (``robotcal --help`` and :func:`robotcal.cli.main` import it): Rich, numpy
and the kinematics are imported where used, and ``console`` / ``error_console`` are created on first use.
"""

from __future__ import annotations

import functools
import math
import os
import signal
import sys
import warnings
from typing import TYPE_CHECKING

import typer

from robotcal.errors import InputError, RobotcalError
from robotcal.pipeline.runtime import (  # noqa: F401  (re-exported: the commands import them from here)
    BYTES_PER_POSE,
    FALLBACK_MEMORY,
    SEED_BOUND,
    Terminated,
    available_memory,
    check_memory,
    monte_carlo_bytes,
    pairs_bytes,
)

if TYPE_CHECKING:  # imported where used: `robotcal --help` and main() stay light (docs/cli.md)
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from robotcal.kinematics.model import ParameterSet

    console: Console
    error_console: Console

#: Settings of the two consoles, created on first use (module ``__getattr__``): ``console`` for
#: results on stdout, ``error_console`` for messages on stderr (each message stays on one line).
_CONSOLES = {
    "console": {"markup": False},
    "error_console": {"stderr": True, "soft_wrap": True, "markup": False},
}


def __getattr__(name: str):
    """``console`` and ``error_console``, created on first use (``from robotcal.cli._common import console``)."""
    if name not in _CONSOLES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from rich.console import Console

    return globals().setdefault(name, Console(**_CONSOLES[name]))  # one console even if two threads race


def _error_console() -> Console:
    """``error_console`` (a test may have replaced it), created on first use."""
    replaced = globals().get("error_console")
    return __getattr__("error_console") if replaced is None else replaced

#: Help of every command's ``--force`` (docs/cli.md, "Output safety").
FORCE_HELP = (
    "Replace an existing output that robotcal did not write (never an input of the command, "
    "the home folder, / or the current folder)."
)
#: Exit status after SIGINT (Ctrl-C) and SIGTERM: 128 + the signal number, as shells report them.
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143
def command_app(**settings) -> typer.Typer:
    """A command module's Typer application, ``app = command_app()``, on which the module registers its
    command(s) (``@app.command()``); :data:`robotcal.cli.COMMANDS` names the module for each command.

    Settings shared with the ``robotcal`` group: help printed literally (no Rich markup: "[mm]" stays),
    no completion options, plain tracebacks; ``settings`` are further :class:`typer.Typer` arguments.
    """
    return typer.Typer(add_completion=False, pretty_exceptions_enable=False, rich_markup_mode=None, **settings)


def styled(text: str, style: str) -> Text:
    """``text`` (printed literally) in ``style``."""
    from rich.text import Text

    return Text(str(text), style=style)


def _line(label: str, style: str, message) -> Text:
    from rich.text import Text

    line = Text(label, style=style)
    line.append(f" {message}")
    return line


def _show_warning(message, category, filename, lineno, file=None, line=None):
    _error_console().print(_line("warning:", "yellow", message), highlight=False)


def _on_sigterm(signum, frame):
    if os.getpid() != _MAIN_PID[0]:  # a forked worker: die as the signal asks
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    # one interrupt is enough: a second signal must not break the cleanup the first one started
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated()


_MAIN_PID = [os.getpid()]


#: Thread-count variables of the BLAS / OpenMP libraries numpy and scipy may load.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def limit_blas_threads() -> None:
    """One BLAS / OpenMP thread (:data:`BLAS_THREAD_VARIABLES` set to 1) unless the user set them."""
    for variable in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(variable, "1")


def tune_numeric_runtime() -> None:
    """Process settings for the ``robotcal`` command, applied before numpy is imported.

    - One BLAS thread per process, unless the user set the variables: robotcal's parallelism is its own
      (Monte Carlo workers, the figure worker, threads over poses), and its linear algebra is small
      (3x3 fits, 40-column QRs, 500-draw blocks). On the 2-core reference machine a multi-threaded
      OpenBLAS made such calls up to 50x slower when the cores were busy (its threads spin waiting for
      each other): in one pair of demo runs under the same load, 58 s with the default threads, 32 s with one.
    - glibc's malloc keeps blocks up to 32 MiB in its heap and returns freed memory above 256 MiB only:
      the Monte Carlo batches allocate and free the same tens of megabytes thousands of times, which with
      the default (mmap above 128 KiB or a moving threshold) cost about 1 s of system time in page faults.
      Set only on Linux with glibc; other platforms are left as they are.

    Library callers are not affected: this runs in :func:`robotcal.cli.main` only.
    """
    limit_blas_threads()
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt): keep the allocator as it is
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    # 32 MiB: the largest threshold mallopt(3) documents on 64-bit (an older glibc refuses more, returning 0);
    # the trim threshold only when it was taken (setting it alone would freeze the mmap threshold at 128 KiB)
    if mallopt(m_mmap_threshold, 32 * 2**20) == 1:
        mallopt(m_trim_threshold, 256 * 2**20)


def install_signal_handlers() -> None:
    """SIGTERM raises :class:`Terminated` in the main thread (exit 143 after cleanup); SIGINT keeps
    Python's :class:`KeyboardInterrupt` (exit 130). Called by the ``robotcal`` entry point."""
    _MAIN_PID[0] = os.getpid()
    signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        return  # started in the background with SIGINT ignored: keep it so
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: The exit status of the command, once :func:`robotcal.cli.entry` has it (see :func:`end_without_teardown`).
_EXIT_STATUS: list[int] = []


def end_without_teardown() -> bool:
    """Let the process end as soon as the command is done, without the interpreter's teardown.

    After the last ``atexit`` handler Python frees every module and object one by one (~0.1 s for the
    ~960 modules of ``robotcal run``, 0.2-0.3 s more for the results a run keeps): work nobody waits
    for, since the kernel reclaims the memory at once. This registers an ``atexit`` handler that flushes
    stdout and stderr and calls ``os._exit`` with the status :func:`record_exit_status` recorded.
    Handlers run last-registered first, so registered before any other this one runs after all
    of them (the multiprocessing, concurrent.futures and logging clean-ups, temporary files'
    finalizers, a coverage tool's...); threads have been joined before any handler runs. It is not
    registered (False) when some handler is already there, since that one would be skipped; nor
    where the interpreter cannot tell (no ``atexit._ncallbacks``). Only the ``robotcal`` console script
    (:func:`robotcal.cli.entry`) calls it: Python callers of :func:`robotcal.cli.main` keep their normal exit.
    ``os._exit`` also skips C-level exit handlers and C stdio buffers (robotcal's dependencies have none).
    """
    import atexit

    count = getattr(atexit, "_ncallbacks", None)
    if count is None or count() != 0:
        return False
    atexit.register(_exit_now, os.getpid())
    return True


def record_exit_status(code) -> None:
    """The status the command's ``SystemExit`` carries (None: 0). Anything else (a message, a bool, an integer
    beyond a C int, which ``os._exit`` refuses) is left to Python's own exit."""
    if code is None:
        code = 0
    if isinstance(code, int) and not isinstance(code, bool) and -(2**31) <= code < 2**31:
        _EXIT_STATUS[:] = [code]


def _exit_now(pid: int) -> None:
    """The handler of :func:`end_without_teardown`: in the process that registered it, once a status is
    recorded and the standard streams are flushed (a failed flush, e.g. a closed pipe, is left to Python,
    which reports it), end the process with that status."""
    if os.getpid() != pid or not _EXIT_STATUS:
        return
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except Exception:  # noqa: BLE001 - Python's own exit reports it
        return
    os._exit(_EXIT_STATUS[0])


def handle_errors(function):
    """Run a command: robotcal errors become a one-line message and exit status 2, never a traceback;
    an interrupt exits 130 (Ctrl-C) or 143 (SIGTERM) after the cleanup has run."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        previous = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            return function(*args, **kwargs)
        except RobotcalError as exc:
            _error_console().print(_line("error:", "red", exc), highlight=False)
            raise typer.Exit(code=2) from None
        except MemoryError:
            _error_console().print(
                _line("error:", "red", "out of memory; use fewer draws, poses or points (or --batch-size)"),
                highlight=False,
            )
            raise typer.Exit(code=2) from None
        except KeyboardInterrupt as exc:
            terminated = isinstance(exc, Terminated)
            _error_console().print(styled("terminated" if terminated else "interrupted", "red"))
            sys.exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED)
        finally:
            warnings.showwarning = previous

    return wrapper


def seed_option_check(seed: int | None, option: str = "--seed", *, headroom: int = 0) -> None:
    """Seeds are integers in ``[0, SEED_BOUND - headroom)``."""
    if seed is not None and not 0 <= seed < SEED_BOUND - headroom:
        raise InputError(f"{option} must be an integer in [0, {SEED_BOUND - headroom}); got {seed}")


def _display(kind: str, value: float) -> float:
    from robotcal.kinematics.model import ANGLE_KINDS

    return math.degrees(float(value)) if kind in ANGLE_KINDS else float(value)


def parameter_table(nominal: ParameterSet, identified: ParameterSet, title: str) -> Table:
    """Nominal / identified / difference per parameter, in mm and degrees."""
    from rich.table import Table

    from robotcal.kinematics.model import KIND_UNITS, PARAMETER_KINDS

    table = Table(title=title, title_justify="left")
    table.add_column("parameter")
    table.add_column("unit")
    table.add_column("nominal", justify="right")
    table.add_column("identified", justify="right")
    table.add_column("difference", justify="right")
    difference = identified.difference(nominal)
    robot = nominal.robot
    for i in range(robot.n_joints):
        for k, kind in enumerate(PARAMETER_KINDS):
            if robot.structurally_fixed[i, k]:
                continue
            unit = KIND_UNITS[kind]
            if identified.identified[i, k]:
                shown, diff = (
                    f"{_display(kind, identified.values[i, k]):.6f}",
                    f"{_display(kind, difference[i, k]):+.3e}",
                )
            else:
                shown, diff = styled("nominal", "dim"), ""
            table.add_row(f"J{i + 1}.{kind}", unit, f"{_display(kind, nominal.values[i, k]):.6f}", shown, diff)
    return table


def circle_table(result) -> Table:
    """Per-circle fit residuals of a CPA result."""
    from rich.table import Table

    table = Table(title="Circle fits", title_justify="left")
    for column in ("circle", "points", "radius (mm)", "plane RMS (mm)", "circle RMS (mm)"):
        table.add_column(column, justify="right")
    for joint, fit in enumerate(result.circle_fits):
        table.add_row(
            str(joint + 1),
            str(fit.plane_residuals.shape[-1]),
            f"{float(fit.radius):.4f}",
            f"{float(fit.plane_rms):.2e}",
            f"{float(fit.circle_rms):.2e}",
        )
    return table
