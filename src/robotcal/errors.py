"""One exception hierarchy and the warning classes of robotcal.

Library functions raise these and never print or exit; the CLI turns them into one-line messages.
"""

from __future__ import annotations

__all__ = [
    "RobotcalError",
    "InputError",
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
]


class RobotcalError(Exception):
    """Base class of every error robotcal raises on purpose."""


class InputError(RobotcalError, ValueError):
    """Input that robotcal cannot use: wrong shape, NaN, missing key, unknown name, bad file."""


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
