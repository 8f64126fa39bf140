"""``robotcal joints CAPTURE.csv --scenario S --out DIR``: backlash and eccentricity per joint (ch. 4.6)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from robotcal.cli._common import Force, app_command, command_app, console, error_console, read_scenario_capture
from robotcal.cli._tables import Column, FittedTable
from robotcal.io.results.output import result_folder

if TYPE_CHECKING:  # numpy and the diagnostics load in the command: a fast --help
    from robotcal.diagnostics import JointDiagnostics

app = command_app()


def _table(diagnostics: JointDiagnostics) -> FittedTable:
    headers = ("axial RMS", "radial RMS", "backlash max", "min", "mean", "angle (deg)")
    table = FittedTable(
        "Joint diagnostics (µm; backlash over matched pairs, turnarounds excluded)",
        [
            Column("joint", "name", justify="right"),
            Column("points"),
            Column("pairs", narrow=1),
            *(Column(header) for header in headers),
        ],
        elsewhere="summary.csv",
    )

    def um(value):
        return "-" if not math.isfinite(value) else f"{value * 1000:.2f}"

    def degrees(value):
        return "-" if not math.isfinite(value) else f"{math.degrees(value):+.5f}"

    for s in diagnostics.summary():
        table.add_row(
            f"J{s.joint}", str(s.points), str(s.pairs), um(s.plane_rms), um(s.circle_rms),
            um(s.backlash_max), um(s.backlash_min), um(s.backlash_mean), degrees(s.backlash_angle_mean),
        )  # fmt: skip
    return table


@app_command(app)
def joints(
    capture: Annotated[
        Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z), ideally bidirectional.")
    ],
    scenario: Annotated[
        str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot (joint count) and circle fit.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write.")],
    order: Annotated[int, typer.Option(min=1, help="Highest harmonic K of the harmonic model.")] = 2,
    backlash: Annotated[
        bool, typer.Option("--backlash/--no-backlash", help="Analyse backlash (needs both sweep directions).")
    ] = True,
    scale: Annotated[float, typer.Option(min=0.0, help="Arrow scale of backlash_vectors.png (thesis: 500).")] = 500.0,
    match_tolerance_deg: Annotated[
        float, typer.Option(min=0.0, help="Largest reading difference of a forward/return pair [deg].")
    ] = 1e-3,
    force: Force = False,
) -> None:
    """Backlash and axial/radial eccentricity per joint (thesis ch. 4.6), with a harmonic model."""
    from robotcal import api
    from robotcal.io.results.joints_files import write_joints_folder

    loaded, measured, inputs = read_scenario_capture(capture, scenario, out, force=force, folder=True)
    analysis = api.diagnose_joints(
        measured, loaded, order=order, backlash=backlash, match_tolerance_deg=match_tolerance_deg
    )
    diagnostics, model = analysis.diagnostics, analysis.harmonics
    with result_folder(out, inputs=inputs, force=force, command="robotcal joints") as folder:
        files = list(write_joints_folder(folder, diagnostics, model, capture=capture, scenario=loaded))
        from robotcal.plots.joints import write_joint_figures

        files += [path.name for path in write_joint_figures(diagnostics, folder, model=model, scale=scale)]
    console.print(_table(diagnostics))
    for note in (*diagnostics.messages, *model.messages):
        error_console.print(f"note: {note}", highlight=False)
    console.print(f"wrote {out}: {', '.join(files)}", highlight=False, soft_wrap=True)
