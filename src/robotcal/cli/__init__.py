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

import os
import sys
from typing import TYPE_CHECKING, NoReturn

from robotcal.cli._commands import COMMANDS as COMMANDS
from robotcal.cli._commands import CommandEntry as CommandEntry
from robotcal.cli._commands import load_command as load_command

if TYPE_CHECKING:
    import typer

    app: typer.Typer


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
    ending.robotcal_reported = True  # type: ignore[attr-defined]  # a mark on the exception, read by main() with getattr
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
