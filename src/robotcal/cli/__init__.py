"""Command-line interface (Typer): thin commands over library calls, one module per command.

The commands load lazily. :data:`COMMANDS` names every command with the module that defines it and the
one line that ``robotcal --help`` prints, so the top-level help and the dispatch import no command
module (nor numpy, scipy or matplotlib); a command's module is imported only when that command runs or
its own ``--help`` is asked for (:func:`load_command`).

A command module defines its own Typer application, ``app = command_app()``
(:func:`robotcal.cli._common.command_app`), and registers its command(s) on it with ``@app.command()``;
a command with sub-commands (``plan check|optimise``) is added with ``app.add_typer(sub_app, name=...)``.
No command module imports :data:`app` from this package. docs/cli.md ("Adding a command") has the recipe.
"""

from __future__ import annotations

import functools
from importlib import import_module
from typing import Annotated, NamedTuple

import typer
from typer.core import TyperGroup


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
    entry = COMMANDS[name]
    module = import_module(f"{__name__}.{entry.module}")
    command = typer.main.get_command(module.app)
    if isinstance(command, TyperGroup) and name in command.commands:
        return command.commands[name]
    if command.name == name:
        return command
    raise LookupError(f"robotcal.cli.{entry.module}.app defines no command {name!r}")


class LazyCommandGroup(TyperGroup):
    """The ``robotcal`` group: lists :data:`COMMANDS` without importing them; loads the one invoked."""

    def list_commands(self, ctx) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx, cmd_name: str):
        return load_command(cmd_name) if cmd_name in COMMANDS else None

    def format_commands(self, ctx, formatter) -> None:
        with formatter.section("Commands"):
            formatter.write_dl([(name, entry.help) for name, entry in COMMANDS.items()])

    def resolve_command(self, ctx, args):
        if args and args[0] not in COMMANDS and not args[0].startswith("-"):
            # "Did you mean": Typer's own suggestions look at self.commands, empty here
            from difflib import get_close_matches

            matches = get_close_matches(args[0], list(COMMANDS))
            hint = f" Did you mean {', '.join(map(repr, matches))}?" if matches else ""
            ctx.fail(f"No such command {args[0]!r}.{hint}")
        return super().resolve_command(ctx, args)


app = typer.Typer(
    name="robotcal",
    cls=LazyCommandGroup,
    help="Kinematic calibration of serial robots by Circle Point Analysis, with its uncertainty.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help texts print literally: "[validation]", "[lower, upper]", "[mm]"
)


def _print_version(asked: bool) -> None:
    if asked:
        from robotcal import __version__

        typer.echo(f"robotcal {__version__}")
        raise typer.Exit()


@app.callback()
def _robotcal(
    version: Annotated[
        bool, typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    # The options of `robotcal` itself. A callback also makes Typer build a group (LazyCommandGroup)
    # although no command is registered on this application.
    pass


def main() -> None:
    """The ``robotcal`` command (the console script): SIGTERM and SIGHUP become clean interrupts (exit 143 /
    129, as SIGINT's 130), with every cleanup run (:func:`~robotcal.cli._common.install_signal_handlers`)."""
    from robotcal.cli._common import install_signal_handlers

    install_signal_handlers()
    app()
