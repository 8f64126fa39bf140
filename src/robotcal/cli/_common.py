"""Shared CLI plumbing: consoles, error and warning display, parameter tables."""

from __future__ import annotations

import functools
import sys
import warnings

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from robotcal.errors import RobotcalError
from robotcal.kinematics.model import PARAMETER_KINDS, ParameterSet

console = Console()
error_console = Console(stderr=True, soft_wrap=True)  # messages stay on one line


def _show_warning(message, category, filename, lineno, file=None, line=None):
    error_console.print(f"[yellow]warning:[/yellow] {message}", highlight=False)


def handle_errors(function):
    """Run a command: robotcal errors become a one-line message and exit status 2, never a traceback."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        previous = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            return function(*args, **kwargs)
        except RobotcalError as exc:
            error_console.print(f"[red]error:[/red] {exc}", highlight=False)
            raise typer.Exit(code=2) from None
        except KeyboardInterrupt:
            error_console.print("[red]interrupted[/red]")
            sys.exit(130)
        finally:
            warnings.showwarning = previous

    return wrapper


def _display(kind: str, value: float) -> float:
    return float(np.rad2deg(value)) if kind in ("theta", "alpha", "beta") else float(value)


def parameter_table(nominal: ParameterSet, identified: ParameterSet, title: str) -> Table:
    """Nominal / identified / difference per parameter, in mm and degrees."""
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
            unit = "deg" if kind in ("theta", "alpha", "beta") else "mm"
            if identified.identified[i, k]:
                shown, diff = (
                    f"{_display(kind, identified.values[i, k]):.6f}",
                    f"{_display(kind, difference[i, k]):+.3e}",
                )
            else:
                shown, diff = "[dim]nominal[/dim]", ""
            table.add_row(f"J{i + 1}.{kind}", unit, f"{_display(kind, nominal.values[i, k]):.6f}", shown, diff)
    return table


def circle_table(result) -> Table:
    """Per-circle fit residuals of a CPA result."""
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
