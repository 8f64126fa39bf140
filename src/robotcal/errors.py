"""One exception hierarchy and the warning classes of robotcal, and how a signal becomes an interrupt.

Library functions raise these and never print or exit; the CLI turns them into one-line messages.

Interrupts. The command line installs :func:`install_interrupt_handlers` first thing: SIGINT raises
:class:`KeyboardInterrupt`, SIGTERM and SIGHUP :class:`Terminated`, in the main thread, so that every cleanup runs.
Python drops an exception raised where it cannot propagate (a fork handler: "Exception ignored in ...
_releaseLock", a ``__del__`` method), so the handler also records the interrupt: :func:`check_interrupt` raises it
again, and the places where work goes on or a result is kept call it (a pool's start and each of its results,
:func:`robotcal.execution.check_stop`, a run's stages, a result folder before it is renamed into place).
:func:`interrupts_held` holds the exception for a block where it would be dropped (a pool starting its workers).
"""

from __future__ import annotations

import numbers
import os
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = [
    "RobotcalError",
    "InputError",
    "check_count",
    "DegenerateGeometryError",
    "IdentifiabilityError",
    "RobotcalWarning",
    "JointLimitWarning",
    "RigidTransformWarning",
    "IdentifiabilityWarning",
    "FitHealthWarning",
    "FitHealthError",
    "Terminated",
    "interrupt_behind",
    "install_interrupt_handlers",
    "interrupt_received",
    "check_interrupt",
    "interrupts_held",
    "INTERRUPT_SIGNALS",
]


class RobotcalError(Exception):
    """Base class of every error robotcal raises on purpose."""


class InputError(RobotcalError, ValueError):
    """Input that robotcal cannot use: wrong shape, NaN, missing key, unknown name, bad file."""


def check_count(value: object, name: str, *, minimum: int = 1) -> int:
    """``value`` as an ``int``, checked to be a whole number (Python's or numpy's, never a bool) ``>= minimum``.

    Raises :class:`InputError` naming ``name`` and the value as written: "`workers` must be a positive
    integer; got 0", "`seed` must be a non-negative integer; got -1", "`folds` must be an integer >= 2; got True".
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        what = {1: "a positive integer", 0: "a non-negative integer"}.get(minimum, f"an integer >= {minimum}")
        raise InputError(f"`{name}` must be {what}; got {value!r}")
    return int(value)


class DegenerateGeometryError(InputError):
    """Points that do not define the geometry asked for (collinear circle, zero sweep, ...)."""


class FitHealthError(RobotcalError):
    """``--strict``: a fit failed the fit-health test (:class:`FitHealthWarning`'s cases,
    :mod:`robotcal.identification.health`)."""


class IdentifiabilityError(RobotcalError):
    """The data cannot determine some parameters; ``parameters`` lists their names."""

    def __init__(self, message: str, parameters: list[str] | tuple[str, ...] = ()):
        super().__init__(message)
        self.parameters = tuple(parameters)


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by the command line's SIGTERM (and SIGHUP) handler, so that every cleanup
    (``finally``, context managers, pool shutdown) runs as for Ctrl-C; a :class:`KeyboardInterrupt` so code
    that handles an interrupt handles this too."""

    def __init__(self, signal_name: str = "SIGTERM"):
        super().__init__(signal_name)
        self.signal_name = signal_name


def interrupt_behind(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The interrupt (Ctrl-C, or :class:`Terminated`) behind ``exc``: ``exc`` itself, or one that ``exc`` was raised
    from or while handling (its ``__cause__`` / ``__context__`` chain); None if there is none.

    An error of the cleanup after an interrupt (a write to the terminal a SIGHUP closed, a full disk) and an error
    the interrupt caused (a C extension whose import it broke: "ImportError: initialization failed") are that
    interrupt, for the record and the exit status.
    """
    seen = set()
    pending = [exc]
    while pending:
        exc = pending.pop()
        if exc is None or id(exc) in seen:
            continue
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        pending += [exc.__cause__, exc.__context__]
    return None


#: The signals that interrupt a command (where the platform has them).
INTERRUPT_SIGNALS = tuple(name for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))

#: The signals received through :func:`_on_signal` (names, in order) since the handlers were installed.
_RECEIVED: list[str] = []
#: The process whose main thread the handlers interrupt (a forked child inherits the handlers, not the role).
_MAIN_PID = [os.getpid()]


def _interrupt(signal_name: str) -> KeyboardInterrupt:
    return KeyboardInterrupt() if signal_name == "SIGINT" else Terminated(signal_name)


def _on_signal(signum: int, frame: FrameType | None) -> None:
    """The command line's handler of :data:`INTERRUPT_SIGNALS` (:func:`install_interrupt_handlers`).

    In the main process: record the signal, and raise its interrupt for the first one only (a second signal must not
    break the cleanup the first one started; it is recorded). In a forked child that has not set handlers of its
    own: end as the signal asks (the pool's workers set theirs, and start with the signals held back,
    :func:`interrupts_held`).
    """
    if os.getpid() != _MAIN_PID[0]:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    name = signal.Signals(signum).name
    _RECEIVED.append(name)
    if len(_RECEIVED) == 1:
        raise _interrupt(name)


def install_interrupt_handlers() -> None:
    """SIGINT raises :class:`KeyboardInterrupt`, SIGTERM and SIGHUP (a closed terminal or ssh session)
    :class:`Terminated`, in the main thread, and each is recorded for :func:`check_interrupt`. A signal ignored when
    the process started stays ignored (``nohup``, a background job of a shell without job control). Called first
    thing by :func:`robotcal.cli.main`; a library caller keeps its own handlers."""
    _MAIN_PID[0] = os.getpid()
    _RECEIVED.clear()
    for name in INTERRUPT_SIGNALS:
        number = getattr(signal, name)
        if signal.getsignal(number) is not signal.SIG_IGN:
            signal.signal(number, _on_signal)


def interrupt_received() -> KeyboardInterrupt | None:
    """The interrupt of the first signal :func:`install_interrupt_handlers`'s handlers received (a new exception of
    its kind), or None."""
    if not _RECEIVED or os.getpid() != _MAIN_PID[0]:
        return None
    return _interrupt(_RECEIVED[0])


def check_interrupt() -> None:
    """Raise the interrupt of a signal this process received, if any (its first exception may have been dropped
    where Python cannot propagate one). Called where work goes on or a result is kept; never in a cleanup."""
    interrupt = interrupt_received()
    if interrupt is not None:
        raise interrupt


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold back the exception of an interrupt signal during the block and raise it when the block ends.

    For a block in which Python would drop it: :func:`os.fork` runs its handlers (logging's ``_releaseLock``) in
    the parent and in the child, where an exception is printed and forgotten ("Exception ignored in ...") and the
    child, a pool worker, would die of it before it sets its own handlers. In the main thread only (elsewhere the
    handlers never run); a handler other than Python's or robotcal's (SIG_IGN, SIG_DFL, a caller's) is left alone.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {}
    for name in INTERRUPT_SIGNALS:
        number = getattr(signal, name)
        handler = signal.getsignal(number)
        if handler in (signal.default_int_handler, _on_signal):
            previous[number] = handler
            signal.signal(number, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    for number in held[:1]:  # the first signal, as its own handler would have met it
        previous[number](number, None)


class RobotcalWarning(UserWarning):
    """Base class of robotcal's warnings."""


class JointLimitWarning(RobotcalWarning):
    """A joint reading lies outside the robot file's software limits."""


class RigidTransformWarning(RobotcalWarning):
    """A nearly rigid 4x4 matrix was replaced by its nearest rigid transform."""


class IdentifiabilityWarning(RobotcalWarning):
    """A parameter was held at its nominal value because the data cannot determine it."""


class FitHealthWarning(RobotcalWarning):
    """A fit does not explain the data, is ill-conditioned, or rests on circles too small for the noise
    (:mod:`robotcal.identification.health`)."""
