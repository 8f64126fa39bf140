"""``robotcal refine CAPTURE.csv --scenario S --start PARAMS.json --criterion points|distances --out REFINED.json``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from robotcal.cli import app
from robotcal.cli._common import console, handle_errors, parameter_table
from robotcal.io import load_scenario, read_capture, read_parameters, write_parameters
from robotcal.kinematics.model import ParameterSet
from robotcal.workflow import refine_provenance, refine_scenario


@app.command()
@handle_errors
def refine(
    capture: Annotated[Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z).")],
    scenario: Annotated[
        str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot, target, base frame.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Parameter JSON to write.")],
    start: Annotated[
        Path | None,
        typer.Option("--start", help="Parameter JSON to start from (e.g. the CPA result; default nominal)."),
    ] = None,
    criterion: Annotated[
        str, typer.Option("--criterion", "-c", help="points (eq. 4-101) or distances (eq. 4-102).")
    ] = "points",
    strict: Annotated[
        bool, typer.Option("--strict", help="Fail instead of holding parameters the data cannot determine.")
    ] = False,
) -> None:
    """Refine the parameters by Levenberg-Marquardt over all measured points (thesis ch. 4.5.7)."""
    if criterion not in ("points", "distances"):
        raise typer.BadParameter(f"must be 'points' or 'distances'; got {criterion!r}", param_hint="--criterion")
    loaded = load_scenario(scenario)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    initial = read_parameters(start, loaded.robot) if start is not None else ParameterSet.nominal(loaded.robot)
    result = refine_scenario(
        measured, loaded, initial, criterion=criterion, on_unidentifiable="raise" if strict else "fix"
    )
    source = str(start) if start is not None else "nominal"
    write_parameters(out, result.parameters, refine_provenance(result, measured, loaded, source))
    console.print(parameter_table(initial, result.parameters, f"Refined parameters ({criterion}) vs start"))
    summary = Table(title="Refinement", title_justify="left", show_header=False)
    summary.add_row("criterion", criterion)
    summary.add_row("solver", f"least_squares, method={result.method}")
    summary.add_row("status", f"{'converged' if result.success else 'NOT converged'}: {result.message}")
    summary.add_row("iterations (Jacobian evaluations)", str(result.njev))
    summary.add_row("residual evaluations", str(result.nfev))
    summary.add_row("residuals", str(result.n_residuals))
    summary.add_row("RMS residual start -> end [mm]", f"{result.rms_history[0]:.4g} -> {result.rms_history[-1]:.4g}")
    summary.add_row("mean / max residual [mm]", f"{result.residual_mean:.4g} / {result.residual_max:.4g}")
    summary.add_row("noise per coordinate sigma [mm]", f"{result.sigma:.3g}")
    summary.add_row("condition number (scaled)", f"{result.condition_number:.4g}")
    summary.add_row("held (gauge)", ", ".join(result.gauge) or "-")
    summary.add_row("held (not determined)", ", ".join(result.held) or "-")
    summary.add_row("time [s]", f"{result.wall_time_s:.2f}")
    console.print(summary)
    console.print(f"wrote {out}", highlight=False)
