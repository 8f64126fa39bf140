"""``robotcal refine CAPTURE.csv --scenario S --start PARAMS.json --criterion points|distances --out REFINED.json
[--estimate-base] [--model geometric|compliance|harmonic|compliance+harmonic|auto] [--folds K] [--workers N]``."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, cast

import typer

from robotcal.cli._common import (
    FORCE_HELP,
    check_memory,
    command_app,
    console,
    handle_errors,
    joint_model_table,
    model_table,
    pairs_bytes,
    parameter_table,
    print_health,
)
from robotcal.cli._tables import Column, FittedTable
from robotcal.io.results.output import check_output_file, existing_inputs, result_file

if TYPE_CHECKING:  # numpy, the API and the model load in the command: a fast --help
    from robotcal.api import Criterion, ModelName
    from robotcal.identification.records import RefinementResult
    from robotcal.kinematics.model import ParameterSet

app = command_app()


def _wrapped(parameters: ParameterSet) -> ParameterSet:
    """The parameters with theta, alpha, beta in (-180, 180] deg, for display."""
    from robotcal.identification.refine import wrap_angles

    return parameters.replace(values=wrap_angles(parameters.values, parameters.robot.nominal))


def time_rows(result: RefinementResult, refinement_s: float) -> list[tuple[str, str]]:
    """The summary's time rows: the fit of the model written (``result.wall_time_s``) and, where more fits were
    made (the cross-validation's, the other candidates of ``--model auto``), the whole refinement's."""
    validation = result.cross_validation
    folds = validation.folds if validation is not None else 0
    models = len(result.model_choice.candidates) if result.model_choice is not None else 1
    fits = models * (1 + folds)
    if fits == 1:
        return [("time of the fit [s]", f"{result.wall_time_s:.2f}")]
    which = "the chosen model's fit" if models > 1 else "the fit"
    each = f"each of {models} models" if models > 1 else "the model"
    return [
        (f"time of {which} [s]", f"{result.wall_time_s:.2f}"),
        (
            "time of the whole refinement [s]",
            f"{refinement_s:.2f} ({fits} fits: {each} on all points and in {folds} cross-validation folds)",
        ),
    ]


CaptureArg = Annotated[Path, typer.Argument(help="Capture CSV (circle,direction,q1..qN,x,y,z[,target][,u95_mm]).")]
ScenarioOpt = Annotated[str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot, target, base frame.")]
OutOpt = Annotated[Path, typer.Option("--out", "-o", help="Parameter JSON to write.")]
StartOpt = Annotated[
    Path | None, typer.Option("--start", help="Parameter JSON to start from (e.g. the CPA result; default nominal).")
]
CriterionOpt = Annotated[str, typer.Option("--criterion", "-c", help="points (eq. 4-101) or distances (eq. 4-102).")]
StrictOpt = Annotated[
    bool,
    typer.Option(
        "--strict",
        help="Fail (no file written) instead of holding parameters the data cannot determine, and unless the fit "
        "health is OK or NOT CHECKED (a MODEL ERROR, residual > 3 x the stated noise, fails too).",
    ),
]
WeightsOpt = Annotated[
    str,
    typer.Option(
        "--weights",
        help="auto: weight each point by 1/u^2 from its u95_mm column (u = U(95)/2, k = 2, normal), when "
        "present; none: equal weights.",
    ),
]
EstimateBaseOpt = Annotated[
    bool,
    typer.Option(
        "--estimate-base",
        help="Points criterion: estimate tracker_from_base with the parameters even when the scenario "
        'gives it (base_frame = "given" holds it by default).',
    ),
]
ModelOpt = Annotated[
    str | None,
    typer.Option(
        "--model",
        help="geometric (the DH/Hayati chain), compliance (+ gravity sag of the loaded joints), harmonic (+ "
        "a sin q + b cos q per joint), compliance+harmonic, or auto (each fitted, chosen by cross-validation). "
        "Default: the scenario's [joint_model] fit, geometric when it has none.",
    ),
]
FoldsOpt = Annotated[
    int | None,
    typer.Option("--folds", help="k-fold cross-validation by pose reported for the fit (0: none; default 5)."),
]
PosesOpt = Annotated[
    Path | None,
    typer.Option(
        "--poses",
        help="Calibration poses (capture CSV at free poses on a flange target) refined with CAPTURE: what an "
        "extended model learns the gravity sag from.",
    ),
]
BacklashOpt = Annotated[
    Path | None,
    typer.Option(
        "--backlash",
        help="The joints stage's summary.csv (robotcal joints): the angular backlash of the joints whose backlash "
        "exceeds the noise corrects the circle points by their order of motion.",
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        min=1,
        help="Worker processes for the fits and cross-validation folds (default: CPU count, at most 4); the result "
        "does not depend on it.",
    ),
]


@app.command()
@handle_errors
def refine(
    capture: CaptureArg,
    scenario: ScenarioOpt,
    out: OutOpt,
    start: StartOpt = None,
    criterion: CriterionOpt = "points",
    strict: StrictOpt = False,
    weights: WeightsOpt = "auto",
    estimate_base: EstimateBaseOpt = False,
    model: ModelOpt = None,
    folds: FoldsOpt = None,
    poses: PosesOpt = None,
    backlash: BacklashOpt = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
    workers: WorkersOpt = None,
) -> None:
    """Refine the parameters by Levenberg-Marquardt over all measured points (thesis ch. 4.5.7), with the geometric
    or an extended model (gravity compliance, harmonic joint errors), each cross-validated by pose."""
    from robotcal import api
    from robotcal.io.formats.capture_csv import read_capture
    from robotcal.io.formats.parameters_json import (
        probe_to_dict,
        read_parameters,
        refined_sessions,
        refined_targets,
        write_parameters,
    )
    from robotcal.io.results.joints_files import read_backlash
    from robotcal.io.results.provenance import refine_provenance
    from robotcal.io.schema.scenario import load_scenario
    from robotcal.kinematics.model import ParameterSet

    _check_options(criterion, weights, estimate_base, model, folds)
    inputs = existing_inputs(capture, scenario, start, poses, backlash)
    check_output_file(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    measured = read_capture(capture, n_joints=loaded.robot.n_joints)
    if poses is not None:
        measured = api.calibration_capture(loaded, measured, read_capture(poses, n_joints=loaded.robot.n_joints))
    lash = None if backlash is None else read_backlash(backlash, loaded.robot.n_joints)
    if criterion == "distances":
        check_memory(
            f"the distances criterion on {measured.n_points} points",
            pairs_bytes(measured.n_points, 5 * loaded.robot.n_joints),
            "use the points criterion or a capture with fewer points",
        )
    initial = read_parameters(start, loaded.robot) if start is not None else ParameterSet.nominal(loaded.robot)
    began = time.perf_counter()
    # the criterion and the model: values _check_options let through
    result = api.refine(
        measured, loaded, initial, criterion=cast("Criterion", criterion), on_unidentifiable="raise" if strict else "fix",
        health="strict" if strict else "warn", weights=weights, model=cast("ModelName | None", model), folds=folds,
        backlash_deg=lash, workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        estimate_base=True if estimate_base else None,  # None: the scenario's base frame decides
    )  # fmt: skip
    refinement_s = time.perf_counter() - began
    provenance = refine_provenance(result, measured, str(start) if start is not None else "nominal", scenario=loaded)
    with result_file(out, inputs=inputs, force=force):
        joint_model_u = result.uncertainty.joint_model_uncertainty
        write_parameters(
            out, result.parameters, provenance, refined_targets(result), joint_model_u=joint_model_u,
            extensions={"sessions": refined_sessions(result), "probe": probe_to_dict(result)},
        )  # fmt: skip
    _print_result(result, initial, start is not None, provenance, refinement_s)
    assert result.health is not None  # every refinement judges its fit
    console.print(f"wrote {out}" + (" (marked FAILED)" if result.health.failed else ""), highlight=False)
    print_health(result.health)


def _check_options(criterion: str, weights: str, estimate_base: bool, model: str | None, folds: int | None) -> None:
    """The options' values, named as the command line spells them."""
    from robotcal.identification.settings import MODEL_CHOICES

    if criterion not in ("points", "distances"):
        raise typer.BadParameter(f"must be 'points' or 'distances'; got {criterion!r}", param_hint="--criterion")
    if weights not in ("auto", "none"):
        raise typer.BadParameter(f"must be 'auto' or 'none'; got {weights!r}", param_hint="--weights")
    if estimate_base and criterion != "points":
        raise typer.BadParameter("applies to the points criterion only", param_hint="--estimate-base")
    if model is not None and model not in MODEL_CHOICES:
        raise typer.BadParameter(f"must be one of {', '.join(MODEL_CHOICES)}; got {model!r}", param_hint="--model")
    if folds is not None and (folds < 0 or folds == 1):
        raise typer.BadParameter(f"must be 0 (none) or at least 2; got {folds}", param_hint="--folds")


def _print_result(result: RefinementResult, initial: ParameterSet, given: bool, provenance: dict, refinement_s) -> None:
    """The parameter table, the refinement's summary, the joint model and the model choice."""
    import numpy as np

    criterion = result.criterion
    console.print(  # angles wrapped into (-180, 180] deg, as in the JSON
        parameter_table(
            _wrapped(initial),
            _wrapped(result.parameters),
            f"Refined parameters ({criterion}) vs start",
            reference="start" if given else "start (nominal)",
        )
    )
    fit, identifiability, uncertainty = result.fit, result.identifiability, result.uncertainty
    summary = FittedTable("Refinement", [Column("", "text"), Column("", "text")], show_header=False)
    summary.add_row("criterion", criterion)
    summary.add_row("solver", f"least_squares, method={result.method}")
    ended = "met its tolerance" if result.success else "did NOT meet its tolerance"
    summary.add_row("solver end", f"{ended}: {result.message}")
    summary.add_row("weights", provenance["weights"])
    summary.add_row("iterations (Jacobian evaluations)", str(result.njev))
    summary.add_row("residual evaluations", str(result.nfev))
    summary.add_row("residuals", str(fit.n_residuals))
    summary.add_row("RMS residual start -> end [mm]", f"{fit.rms_history[0]:.4g} -> {fit.rms_history[-1]:.4g}")
    summary.add_row("mean / max residual [mm]", f"{fit.residual_mean:.4g} / {fit.residual_max:.4g}")
    summary.add_row("noise per coordinate sigma [mm]", f"{uncertainty.sigma:.3g}")
    summary.add_row("condition number (scaled)", f"{identifiability.condition_number:.4g}")
    if result.tracker_from_base is not None:
        base = "estimated" if identifiability.base_free.any() else "held (scenario's tracker_from_base)"
        summary.add_row("base frame", base)
    for frame in result.sessions:  # each measurement session's base frame: its origin and largest u
        x, y, z = frame.tracker_from_base[:3, 3]
        u = frame.standard_uncertainty
        spread = "held" if not np.isfinite(u).any() else f"u {np.nanmax(u[:3]):.3g} mm, {np.rad2deg(np.nanmax(u[3:])):.3g} deg"
        summary.add_row(f"session {frame.name} base origin [mm]", f"{x:.3f}, {y:.3f}, {z:.3f} ({spread})")
    if result.probe is not None:  # a 6-DoF probe: its rotation on the flange, and the orientation residual
        angles = np.rad2deg(result.probe.standard_uncertainty)
        summary.add_row("probe rotation u (rx, ry, rz) [deg]", ", ".join(f"{a:.3g}" for a in angles))
        summary.add_row("orientation residual RMS [deg]", f"{result.probe.orientation_rms_deg:.4g}")
    summary.add_row("held (gauge: a base motion)", ", ".join(identifiability.gauge) or "-")
    summary.add_row("held (not determined)", ", ".join(identifiability.held) or "-")
    summary.add_row("free, tied to held ones", ", ".join(identifiability.confounded) or "-")
    for k, target in enumerate(result.targets):
        if not target.known:
            assert uncertainty.target_uncertainty is not None  # estimated with every unknown offset
            u = uncertainty.target_uncertainty[k]
            shown = ", ".join(f"{v:.4f} ± {e:.4f}" for v, e in zip(target.positions, u, strict=True))
            summary.add_row(f"target {target.name} offset [mm] (± u)", shown)
    for label, value in time_rows(result, refinement_s):
        summary.add_row(label, value)
    console.print(summary)
    if result.parameters.joint_model is not None:
        console.print(joint_model_table(result.parameters.joint_model, uncertainty.joint_model_uncertainty))
    if result.cross_validation is not None:
        console.print(model_table(result))
        if result.model_choice is not None:
            console.print(f"model: {result.model_choice.reason}", highlight=False, soft_wrap=True)
