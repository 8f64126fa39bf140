"""Command-line interface (Typer): thin commands over library calls, one module per command.

The commands load lazily. :data:`COMMANDS` names every command with the module that defines it and the
one line that ``robotcal --help`` prints, so the top-level help and the dispatch import no command
module (nor numpy, scipy or matplotlib); a command's module is imported only when that command runs or
its own ``--help`` is asked for (:func:`load_command`).

A command module defines its own Typer application, ``app = command_app()``
(:func:`robotcal.cli._common.command_app`), and registers its command(s) on it with ``@app.command()``;
a command with sub-commands (``plan check|optimise``) is added with ``app.add_typer(sub_app, name=...)``.
No command module imports :data:`app` from this package. docs/cli.md ("Adding a command") has the recipe.

Importing this package imports neither Typer nor Click: :func:`main` installs the interrupt handlers before them,
and ``app`` (the ``robotcal`` group, :mod:`robotcal.cli._app`) loads on first use.
"""

from __future__ import annotations

import functools
import os
import sys
from importlib import import_module
from typing import TYPE_CHECKING, NamedTuple, NoReturn

if TYPE_CHECKING:
    import typer

    app: typer.Typer


class CommandEntry(NamedTuple):
    """Where a command lives and how ``robotcal --help`` describes it."""

    module: str  #: module under ``robotcal.cli`` whose ``app`` holds the command
    help: str  #: one line (about 60 characters) for the command list of ``robotcal --help``


#: Every command of ``robotcal``, in the order ``robotcal --help`` lists them.
COMMANDS: dict[str, CommandEntry] = {
    # the pipeline
    "run": CommandEntry("run", "The whole pipeline into one run folder, with report.html."),
    "demo": CommandEntry("demo", "`robotcal run` on a simulated, perturbed KUKA KR 5 sixx."),
    "report": CommandEntry("report", "Rebuild the HTML report of a run folder from its files."),
    # its stages
    "simulate": CommandEntry("simulate", "Simulate a scenario's capture (or validation) CSV."),
    "import": CommandEntry("import_", "Convert a tracker export into a capture CSV."),
    "identify": CommandEntry("identify", "Identify the parameters by Circle Point Analysis."),
    "refine": CommandEntry("refine", "Refine the parameters by Levenberg-Marquardt."),
    "evaluate": CommandEntry("evaluate", "Mean/max errors of parameter sets on captures."),
    "joints": CommandEntry("joints", "Backlash and eccentricity per joint, harmonic model."),
    "uncertainty": CommandEntry("uncertainty", "Monte Carlo (GUM S1) uncertainty of the parameters."),
    "tcp": CommandEntry("tcp", "TCP position and orientation uncertainty from draws."),
    "sensitivity": CommandEntry("sensitivity", "Parameter u and Cpk against the capture conditions."),
    # planning the capture
    "plan": CommandEntry("plan", "Capture planning: check a plan in the cell, optimise it."),
    "program": CommandEntry("program", "The capture plan as a KRL, RAPID or URScript program."),
    # using the calibrated model
    "predict": CommandEntry("predict", "Forward kinematics with the calibrated model."),
    "compensate": CommandEntry("compensate", "Joint commands that reach the taught poses, calibrated."),
    "filter": CommandEntry("filter", "A KRL, RAPID or URScript program compensated, numbers only."),
    "export": CommandEntry("export", "The calibrated model as JSON, URDF, UR YAML, DH or MDH."),
    "iso9283": CommandEntry("iso9283", "ISO 9283 pose accuracy/repeatability (AP, RP, AD, RD, APa..)."),
    "iso9283-plan": CommandEntry("iso9283", "ISO 9283 test poses P1..P5: pose CSV and robot program."),
    # what ships with robotcal
    "robots": CommandEntry("catalog", "List the built-in robots."),
    "instruments": CommandEntry("catalog", "List the instrument presets, U(L) = A + B*L."),
    "scenarios": CommandEntry("catalog", "List the built-in scenarios."),
}


@functools.cache
def load_command(name: str):
    """The click command ``name`` of :data:`COMMANDS`, importing its module (once per process).

    The module's ``app`` becomes a click command with :func:`typer.main.get_command`: a group holding
    ``name`` (a module with several commands, or a sub-application added under ``name``), or the
    command itself (a module with a single command). Raises ``KeyError`` for an unregistered name and
    ``LookupError`` when the module does not define the command it is registered for.
    """
    import typer
    from typer.core import TyperGroup

    entry = COMMANDS[name]
    module = import_module(f"{__name__}.{entry.module}")
    command = typer.main.get_command(module.app)
    if isinstance(command, TyperGroup) and name in command.commands:
        return command.commands[name]
    if command.name == name:
        return command
    raise LookupError(f"robotcal.cli.{entry.module}.app defines no command {name!r}")


def __getattr__(name: str):
    """``app`` (the ``robotcal`` Typer application) and ``LazyCommandGroup``, from :mod:`robotcal.cli._app`."""
    if name in ("app", "LazyCommandGroup"):
        from robotcal.cli import _app

        return getattr(_app, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: Exit status after an interrupt: 128 + the signal's number, as shells report a command a signal ended.
EXIT_STATUS = {"SIGINT": 130, "SIGHUP": 129, "SIGTERM": 143}


def _say_plain(line: str) -> None:
    try:
        sys.stderr.write(f"{line}\n")
        sys.stderr.flush()
    except (OSError, ValueError):  # a terminal that is gone, a closed stream
        pass


def _silence_broken_streams() -> None:
    """Point stdout and stderr at the null device where they can no longer be written (the terminal closed), so
    that Python's final flush at exit neither prints a traceback nor turns the exit status into 120."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            try:
                null = os.open(os.devnull, os.O_WRONLY)
                try:
                    os.dup2(null, stream.fileno())
                finally:
                    os.close(null)
            except (OSError, ValueError):  # no file descriptor (a test's captured stream): nothing to protect
                pass


def exit_interrupted(interrupt: KeyboardInterrupt, say=None) -> NoReturn:
    """End the command after ``interrupt`` (its cleanup done): one line on stderr, ``interrupted`` (Ctrl-C) or
    ``terminated (SIGTERM)`` / ``terminated (SIGHUP)``, printed by ``say`` (default: plain text), and exit status
    130, 143 or 129. The :class:`SystemExit` raised carries ``robotcal_reported`` (:func:`main` reports no more)."""
    name = getattr(interrupt, "signal_name", "SIGINT")
    (say or _say_plain)("interrupted" if name == "SIGINT" else f"terminated ({name})")
    _silence_broken_streams()
    ending = SystemExit(EXIT_STATUS.get(name, EXIT_STATUS["SIGINT"]))
    ending.robotcal_reported = True
    raise ending


def _end(ending: BaseException | None) -> None:
    """After the command: an interrupt not reported yet (one that came before or after the command's own error
    handling, or whose exception Python dropped) ends the process as :func:`exit_interrupted` says."""
    from robotcal.errors import interrupt_behind, interrupt_received

    if getattr(ending, "robotcal_reported", False):
        return
    interrupt = interrupt_behind(ending) or interrupt_received()
    if interrupt is not None:
        exit_interrupted(interrupt)


def main() -> None:
    """The ``robotcal`` command (the console script).

    Its first act installs the interrupt handlers (:func:`robotcal.errors.install_interrupt_handlers`), before
    Typer, Click and the command are imported: Ctrl-C, SIGTERM and SIGHUP at any moment after that, also while the
    command line loads, end the command with every cleanup run, one line on stderr and exit status 130, 143 or 129
    (:func:`exit_interrupted`), never with a traceback.
    """
    from robotcal.errors import install_interrupt_handlers

    install_interrupt_handlers()
    try:
        from robotcal.cli._app import app

        app()
    except BaseException as exc:
        _end(exc)
        raise
    _end(None)
