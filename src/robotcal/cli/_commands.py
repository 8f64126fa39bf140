"""The registry of ``robotcal``'s commands (:data:`COMMANDS`) and their lazy loading (:func:`load_command`): what
both the package's ``__init__`` and the Typer application (:mod:`robotcal.cli._app`) read, in a module of its own so
that neither imports the other."""

from __future__ import annotations

import functools
from importlib import import_module
from typing import NamedTuple

__all__ = ["COMMANDS", "CommandEntry", "load_command"]


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
    module = import_module(f"robotcal.cli.{entry.module}")
    command = typer.main.get_command(module.app)
    if isinstance(command, TyperGroup) and name in command.commands:
        return command.commands[name]
    if command.name == name:
        return command
    raise LookupError(f"robotcal.cli.{entry.module}.app defines no command {name!r}")
