"""The stages of a calibration run, one plain function each (docs/pipeline.md).

Every stage calls the front door (:mod:`robotcal.api`) with the run's scenario and the results of earlier
stages, writes its files through :mod:`robotcal.io` and returns a :class:`StageOutput`: its typed result, the
documents it wrote (keyed by their path relative to the run folder, :mod:`robotcal.io.results.run_folder`) and a
one-line detail for the progress display. A stage's folder is built with
:func:`robotcal.io.atomic.atomic_directory`: it appears whole or not at all (``tcp/``: one folder per mode;
``plan/`` then ``plan/sensitivity/``); its figures are then asked of ``figures``
(:class:`~robotcal.pipeline.figures.FigureJobs`) and drawn into the final folder while the next stages
compute. The stand-alone commands (``robotcal identify``, ``refine``, ``evaluate``, ``joints``,
``uncertainty``, ``tcp``, ``plan``) call the same functions and write the same files.

``step(done, total, detail)`` reports progress inside a stage (``total`` None: the stage's step count).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np

from robotcal import api
from robotcal.capture import Capture
from robotcal.diagnostics.iso9283 import ISO_CYCLES, simulate_iso_study
from robotcal.identification.records import RefinementResult
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.io.atomic import atomic_directory
from robotcal.io.formats.capture_csv import capture_to_csv, read_capture_text
from robotcal.io.formats.parameters_json import parameters_to_dict, refined_targets
from robotcal.io.results.evaluation_files import convergence_of, evaluation_document, write_evaluation_folder
from robotcal.io.results.iso9283_files import iso_to_csv
from robotcal.io.results.joints_files import write_joints_folder
from robotcal.io.results.provenance import cpa_provenance, refine_provenance, scenario_echo, versions
from robotcal.io.results.run_folder import Document, read_document, write_csv, write_json
from robotcal.io.results.tcp_results import write_tcp_folder
from robotcal.io.results.uncertainty_files import write_uncertainty_folder
from robotcal.io.schema.scenario import Scenario, repeatability_of
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.figures import FigureJobs
from robotcal.pipeline.plan import PLAN_SENSITIVITY_DRAWS, PLAN_SENSITIVITY_KEY, PLAN_SENSITIVITY_VALUES, TCPTargets
from robotcal.resolve import refinement_targets
from robotcal.simulation.generator import JointErrorModel
from robotcal.uncertainty.joint_errors import CalibrationFit, MeasuredJointErrors, measured_joint_errors
from robotcal.uncertainty.montecarlo import MonteCarloResult, MonteCarloSettings

__all__ = [
    "CRITERIA_RUN",
    "DEPLOYED",
    "DEPLOYED_FILE",
    "JOINT_ERRORS_FILE",
    "ISO_TARGETS_MM",
    "Simulated",
    "StageOutput",
    "evaluate_stage",
    "identify_stage",
    "iso9283_stage",
    "joints_stage",
    "plan_stage",
    "refine_stage",
    "simulate_stage",
    "tcp_stage",
    "uncertainty_stage",
    "calibration_fit",
]

#: The refinement criteria a run computes, the deployed one (the recommended model) first.
CRITERIA_RUN: tuple[Literal["points", "distances"], ...] = ("points", "distances")
#: The deployed model's criterion: its Monte Carlo, TCP figures and consistency check.
DEPLOYED: Literal["points"] = "points"
#: The geometric fit of the deployed criterion, written beside an extended deployed model for the comparison.
GEOMETRIC_FILE = f"{DEPLOYED}-geometric.json"
#: The deployed values (the refinement's estimate corrected for the Monte Carlo's bias), in ``uncertainty-refined/``.
DEPLOYED_FILE = "deployed.json"
#: The joint errors the calibration's Monte Carlo simulated (what the capture measured), beside its draws.
JOINT_ERRORS_FILE = "joint_errors.json"
DEPLOYED_METHOD = (
    "the deployed values: the refinement's estimate (estimate_file) minus the bias its Monte Carlo measures "
    "(uncertainty-refined/parameters.csv, column bias; GUM correction for recognised systematic effects: the joint "
    "errors the joints stage measured and the estimator's non-linearity), the centre of the stated intervals"
)
#: Three flange targets (a typical adapter plate) measured at each ISO 9283 test pose, so that the orientation
#: characteristics are measured too [mm].
ISO_TARGETS_MM = {"A": (60.0, 40.0, 30.0), "B": (-50.0, 30.0, 20.0), "C": (0.0, -60.0, 40.0)}

Step = Callable[[int, int | None, str], None]


def _no_step(done: int, total: int | None, detail: str = "") -> None:
    return None


@dataclass(frozen=True, slots=True)
class StageOutput:
    """What a stage produced: its typed result, its documents (path relative to the run folder) and a detail."""

    value: Any
    documents: dict[str, Document] = field(default_factory=dict)
    detail: str = ""


@dataclass(frozen=True, slots=True, kw_only=True)
class Simulated:
    """The simulate stage: the "true" robot, the calibration and the validation captures (as written)."""

    truth: ParameterSet
    capture: Capture
    validation: Capture
    poses: Capture | None = None  # the [calibration_poses], refined with the circles


def _in(prefix: str, documents: dict[str, Document], final: Path) -> dict[str, Document]:
    """Documents written into a stage's temporary folder, keyed and located as in the final run folder."""
    return {
        f"{prefix}/{name}": (final / name if isinstance(document, Path) else document)
        for name, document in documents.items()
    }


def _read_back(folder: Path, final: Path) -> dict[str, Document]:
    """The files another module wrote into ``folder`` (a stage's temporary folder), read back once as
    :func:`robotcal.io.results.run_folder.read_run` would: JSON and CSV as documents, others by their path in ``final``."""
    return {
        path.name: read_document(folder, path.name) if path.suffix in (".json", ".csv") else final / path.name
        for path in sorted(folder.iterdir())
        if path.is_file()
    }


def simulate_stage(scenario: Scenario, seeds: dict, out: Path, step: Step = _no_step) -> StageOutput:
    """``truth.json``, ``capture.csv``, ``validation.csv`` and, with ``[calibration_poses]``, ``poses.csv``: the "true"
    robot and its simulated captures.

    The captures the later stages use are those of the CSV files (12 decimals), read back from the text
    written: a stand-alone command reading ``capture.csv`` sees the same numbers bit for bit.
    """
    provenance: dict[str, Any] = {"scenario": scenario_echo(scenario), "versions": versions()}
    if scenario.truth is not None:
        truth = api.perturb(scenario, rng=seeds["truth"])
        provenance.update(
            method="nominal plus normal deviations of the CPA-identifiable parameters (simulation.perturb)",
            truth=scenario.truth.model_dump(),
            seed=seeds["truth"],
        )
    else:
        truth = ParameterSet.nominal(scenario.robot)
        provenance["method"] = "nominal parameters (the scenario has no [truth] table)"
    documents: dict[str, Document] = {"truth.json": write_json(out / "truth.json", parameters_to_dict(truth, provenance))}
    step(1, None, "truth")
    captures = {}
    simulated = [
        ("capture", api.simulate(scenario, rng=seeds["capture"], true_parameters=truth)),
        ("validation", api.simulate_poses(scenario, rng=seeds["validation"], true_parameters=truth)),
    ]
    if scenario.calibration_poses is not None:
        poses = api.simulate_poses(scenario, kind="calibration", rng=seeds.get("poses"), true_parameters=truth)
        simulated.append(("poses", poses))
    for name, capture in simulated:
        text = capture_to_csv(capture)
        documents[f"{name}.csv"] = write_csv(out / f"{name}.csv", text)
        captures[name] = read_capture_text(text, source=f"{name}.csv", n_joints=scenario.robot.n_joints, seed=capture.seed)
        step(len(documents), None, f"{capture.n_points} points")
    value = Simulated(
        truth=truth, capture=captures["capture"], validation=captures["validation"], poses=captures.get("poses")
    )
    counts = [value.capture.n_points] + ([value.poses.n_points] if value.poses is not None else [])
    detail = f"{' + '.join(map(str, counts))} + {value.validation.n_points} points"
    return StageOutput(value, documents, detail)


def identify_stage(scenario: Scenario, capture: Capture, out: Path) -> StageOutput:
    """``cpa/parameters.json``: Circle Point Analysis of the capture (thesis ch. 4.4-4.5)."""
    result = api.identify(capture, scenario)
    with atomic_directory(out / "cpa") as folder:
        document = parameters_to_dict(result.parameters, cpa_provenance(result, capture, scenario=scenario))
        documents: dict[str, Document] = {"parameters.json": write_json(folder / "parameters.json", document)}
    assert result.health is not None  # robotcal.identify always judges the fit
    detail = f"{int(result.parameters.identified.sum())} parameters, fit health {result.health.verdict}"
    return StageOutput(result, _in("cpa", documents, out / "cpa"), detail)


def refine_stage(
    scenario: Scenario,
    capture: Capture,
    start: ParameterSet,
    out: Path,
    step: Step = _no_step,
    poses: Capture | None = None,
    joints: api.JointAnalysis | None = None,
) -> StageOutput:
    """``refine/points.json``, ``refine/distances.json``: Levenberg-Marquardt refinement from the CPA result, over the
    circles and the calibration poses. The deployed criterion fits the scenario's ``[joint_model]`` (``auto``: each
    model, chosen by cross-validation); the other criterion fits the model it chose. When that is an extended model,
    ``refine/points-geometric.json`` holds the geometric fit of the same data, for the comparison. ``joints``: the
    joints stage's analysis of a bidirectional capture, whose angular backlash corrects the circle points."""
    fitted = api.calibration_capture(scenario, capture, poses)
    lash = None if joints is None or not joints.diagnostics.backlash else joints
    results: dict[str, RefinementResult] = {
        DEPLOYED: api.refine(fitted, scenario, start, criterion=DEPLOYED, backlash_deg=lash)
    }
    step(1, None, DEPLOYED)
    chosen = cast("api.ModelName", results[DEPLOYED].model)  # the name of a model fitted: one of the choices
    for criterion in CRITERIA_RUN:
        if criterion != DEPLOYED:
            results[criterion] = api.refine(fitted, scenario, start, criterion=criterion, model=chosen, backlash_deg=lash)
            step(len(results), None, criterion)
    geometric = None
    if chosen != "geometric":
        geometric = api.refine(
            fitted, scenario, start, criterion=DEPLOYED, model="geometric", health="off", backlash_deg=lash
        )
    documents: dict[str, Document] = {}
    with atomic_directory(out / "refine") as folder:
        named = [(f"{criterion}.json", result) for criterion, result in results.items()]
        if geometric is not None:
            named.append((GEOMETRIC_FILE, geometric))
        for name, result in named:
            provenance = refine_provenance(result, fitted, "cpa/parameters.json", scenario=scenario)
            document = parameters_to_dict(
                result.parameters, provenance, refined_targets(result), result.uncertainty.joint_model_uncertainty
            )
            documents[name] = write_json(folder / name, document)
    detail = ", ".join(f"{c} RMS {r.fit.rms_history[-1] * 1e3:.1f} um" for c, r in results.items()) + f", model {chosen}"
    value = dict(results)
    if geometric is not None:
        value["geometric"] = geometric
    return StageOutput(value, _in("refine", documents, out / "refine"), detail)


def evaluate_stage(
    scenario: Scenario,
    *,
    cpa: ParameterSet,
    refined: dict,
    capture: Capture,
    validation: Capture,
    out: Path,
    figures: FigureJobs,
) -> StageOutput:
    """``evaluation/``: nominal, CPA and refined parameters on the validation and calibration captures."""
    sets = {"nominal": ParameterSet.nominal(scenario.robot), "cpa": cpa, **{c: r.parameters for c, r in refined.items()}}
    rows = api.evaluate({"validation": validation, "capture": capture}, sets, scenario)
    histories = {
        c: {"criterion": r.criterion, "cost_mm2": r.fit.cost_history.tolist(), "rms_mm": r.fit.rms_history.tolist()}
        for c, r in refined.items()
    }
    document = evaluation_document(
        rows,
        scenario,
        parameter_files={
            "cpa": "cpa/parameters.json",
            **{c: f"refine/{GEOMETRIC_FILE if c == 'geometric' else c + '.json'}" for c in refined},
        },
        capture_files={"validation": "validation.csv", "capture": "capture.csv"},
        reference="nominal",
        histories=histories,
        headline_after=DEPLOYED,
    )
    with atomic_directory(out / "evaluation") as folder:
        documents = write_evaluation_folder(folder, rows, document)
    figures.draw("robotcal.plots.refine:plot_convergence", convergence_of(document), out / "evaluation" / "convergence.png")
    headline = document["headline"]
    detail = f"{headline['before_mean_mm']:.3f} -> {headline['after_mean_mm']:.4f} mm" if headline else ""
    return StageOutput(rows, _in("evaluation", documents, out / "evaluation"), detail)


def joints_stage(scenario: Scenario, capture: Capture, *, backlash: bool, out: Path, figures: FigureJobs) -> StageOutput:
    """``joints/``: backlash and eccentricity per joint with their harmonic model (thesis ch. 4.6)."""
    analysis = api.diagnose_joints(capture, scenario, backlash=backlash)
    with atomic_directory(out / "joints") as folder:
        documents = write_joints_folder(
            folder, analysis.diagnostics, analysis.harmonics, capture="capture.csv", scenario=scenario
        )
    figures.draw(
        "robotcal.plots.joints:write_joint_figures", analysis.diagnostics, out / "joints", model=analysis.harmonics
    )
    detail = "backlash and eccentricity" if backlash else "eccentricity (one sweep direction)"
    return StageOutput(analysis, _in("joints", documents, out / "joints"), detail)


def uncertainty_stage(
    scenario: Scenario,
    *,
    montecarlo: MonteCarloSettings,
    refined_montecarlo: MonteCarloSettings,
    seed: int,
    cpa: ParameterSet,
    deployed: ParameterSet,
    out: Path,
    figures: FigureJobs,
    step: Step = _no_step,
    poses: Capture | None = None,
    joints: api.JointAnalysis | None = None,
    capture: Capture | None = None,
    refined: RefinementResult | None = None,
) -> StageOutput:
    """``uncertainty/`` (CPA model, thesis ch. 5.2.3) and ``uncertainty-refined/`` (the deployed model: its joint
    model, if extended, fitted in every draw, and the calibration ``poses`` refined with the circles).

    Both Monte Carlos use the same seed, so they see the same instrument noise draw for draw, and simulate the
    joint errors the capture's own joints stage measured (``joints``: its backlash and eccentricity,
    :func:`robotcal.uncertainty.joint_errors.measured_joint_errors`; none without it), with the eccentricity no
    circle shows fitted to the deployed refinement's residuals at the calibration poses (the circles ``capture``
    and the deployed ``refined`` result: :func:`calibration_fit`), never the scenario's simulation settings. The refined Monte Carlo's bias corrects the refinement's estimate: the
    deployed values,
    ``uncertainty-refined/deployed.json`` (docs/uncertainty.md, "The measurand"). Both folders are written only
    once both are computed (a failure or an interrupt while computing leaves neither).
    Result: ``{"cpa": MonteCarloResult, "refined": MonteCarloResult, "deployed": ParameterSet, "joint_errors":
    MeasuredJointErrors}``.
    """
    calibration = None
    if joints is not None and capture is not None and refined is not None:
        calibration = calibration_fit(scenario, capture, poses, cpa, refined)
    measured = measured_errors(scenario, joints, deployed, calibration)
    total = montecarlo.iterations + refined_montecarlo.iterations
    results = {}
    runs: tuple[tuple[Literal["cpa", "refined"], MonteCarloSettings, ParameterSet, int], ...] = (
        ("cpa", montecarlo, cpa, 0),
        ("refined", refined_montecarlo, deployed, montecarlo.iterations),
    )
    for model, settings, parameters, done in runs:

        def progress(count: int, expected: int | None, done: int = done) -> None:
            step(done + count, total, "draws")

        results[model] = api.monte_carlo(
            scenario,
            settings=settings,
            parameters=parameters,
            model=model,
            criterion=DEPLOYED,
            rng=seed,
            joint_errors=measured,
            progress=progress,
            poses=poses if model == "refined" else None,
        )
    corrected = results["refined"].corrected(deployed)
    documents: dict[str, Document] = {}
    for name, result in (("uncertainty", results["cpa"]), ("uncertainty-refined", results["refined"])):
        with atomic_directory(out / name) as folder:
            written = write_uncertainty_folder(
                folder, result, scenario=scenario, save_draws=True, deployed=corrected if name != "uncertainty" else None
            )
            if name == "uncertainty-refined":
                provenance = {"method": DEPLOYED_METHOD, "estimate_file": f"refine/{DEPLOYED}.json", "versions": versions()}
                document = parameters_to_dict(corrected, provenance)
                written[DEPLOYED_FILE] = write_json(folder / DEPLOYED_FILE, document)
                written[JOINT_ERRORS_FILE] = write_json(folder / JOINT_ERRORS_FILE, joint_errors_document(measured))
        documents.update(_in(name, written, out / name))
        deployed_values = {} if name == "uncertainty" else {"deployed": corrected}
        figures.draw("robotcal.plots.montecarlo:write_histograms", result, out / name, **deployed_values)
    rates = [r.n_draws / max(r.timings_s.get("draws", 0.0), 1e-9) for r in results.values()]
    detail = (
        f"CPA {results['cpa'].n_draws:,} draws ({rates[0]:,.0f}/s), "
        f"refined {results['refined'].n_draws:,} draws ({rates[1]:,.0f}/s), deployed = estimate - bias"
    )
    return StageOutput({**results, "deployed": corrected, "joint_errors": measured}, documents, detail)


def joint_errors_document(errors: JointErrorModel) -> dict[str, Any]:
    """``uncertainty-refined/joint_errors.json``: per joint the backlash [deg] and each translation term's sinusoid
    ``A sin(2 pi / T q + phi)`` (amplitude [mm], period and phase [deg]) the Monte Carlo simulated, a measured
    order-3 eccentricity's under ``order_3`` (the same terms, added to those), and how many uncertainty sources its
    bias correction propagated (docs/uncertainty.md, "Where the bias comes from")."""

    def sinusoids(model: JointErrorModel, joint: int) -> dict[str, Any]:
        return {
            name: {
                "amplitude_mm": float(model.amplitude[joint, k]),
                "period_deg": float(np.rad2deg(model.period[joint, k])),
                "phase_deg": float(np.rad2deg(model.phase[joint, k])),
            }
            for k, name in enumerate(("dx", "dy", "dz"))
            if model.amplitude[joint, k] != 0.0
        }

    lobes = getattr(errors, "lobes", None)
    joints = []
    for joint in range(errors.n_joints):
        entry = {"joint": joint + 1, "backlash_deg": float(np.rad2deg(errors.backlash[joint])), **sinusoids(errors, joint)}
        if lobes is not None and np.any(lobes.amplitude[joint] != 0.0):
            entry["order_3"] = sinusoids(lobes, joint)
        joints.append(entry)
    return {
        "method": "measured by the capture: the joints stage (backlash, the eccentricity the circles show) and the "
        "deployed refinement's residuals at the calibration poses (the eccentricity no circle shows)",
        "joints": joints,
        "uncertainty_sources": len(getattr(errors, "sources", ())),
        "versions": versions(),
    }


def measured_errors(
    scenario: Scenario,
    joints: api.JointAnalysis | None,
    estimate: ParameterSet,
    calibration: CalibrationFit | None = None,
) -> MeasuredJointErrors:
    """The joint errors a calibration's Monte Carlo simulates: those the joints stage measured from the capture,
    and those no circle shows from the deployed refinement's residuals (``calibration``), with their uncertainty
    (:func:`robotcal.uncertainty.joint_errors.measured_joint_errors`); none without a joints analysis."""
    if joints is None:
        zeros = JointErrorModel.zeros(scenario.robot.n_joints)
        return MeasuredJointErrors(amplitude=zeros.amplitude, period=zeros.period, phase=zeros.phase, noise_sd=zeros.noise_sd)
    return measured_joint_errors(
        joints.diagnostics, estimate, scenario.plan, scenario.tracker_from_base,
        circle_fit=scenario.identification.circle_fit, calibration=calibration,
    )  # fmt: skip


def calibration_fit(
    scenario: Scenario, capture: Capture, poses: Capture | None, start: ParameterSet, refined: RefinementResult
) -> CalibrationFit:
    """The deployed refinement as :func:`measured_errors` refits it: the circles and calibration poses as
    :func:`refine_stage` fitted them, from the same ``start``, with the settings, targets and base of the scenario
    and the deployed result's own joint model (its structure and lash, started at its values: no model choice, no
    cross-validation; only the estimate is used)."""
    fitted = api.calibration_capture(scenario, capture, poses)
    targets, tracker_from_base = refinement_targets(scenario, fitted, None, None)
    settings = RefinementSettings(criterion=DEPLOYED, repeatability_mm=repeatability_of(scenario))
    joint_model = refined.parameters.joint_model

    def refit(moved: Capture) -> RefinementResult:
        with warnings.catch_warnings():  # the deployed fit's warnings, said once by the refine stage
            warnings.simplefilter("ignore")
            return refine_parameters(
                moved, start, targets, settings=settings, tracker_from_base=tracker_from_base, joint_model=joint_model
            )

    return CalibrationFit(capture=fitted, targets=refined.targets, result=refined, refit=refit)


def _estimate_errors(
    validation: Capture, estimate: ParameterSet, scenario: Scenario, expected_rms_mm: float
) -> dict[str, Any]:
    """The uncorrected estimate's observed errors at the validation poses, against the deployed values' expected RMS
    (the Monte Carlo's covariance there does not depend on which of the two is deployed: computed once)."""
    from robotcal.uncertainty.consistency import observed_errors

    given = scenario.tracker_from_base if scenario.identification.base_frame == "given" else None
    _, observed, _ = observed_errors(validation, estimate, api.validation_target(scenario), given)
    rms = float(np.sqrt(np.mean(observed**2)))
    return {
        "observed_rms_mm": rms,
        "observed_mean_mm": float(observed.mean()),
        "ratio": rms / expected_rms_mm if expected_rms_mm > 0 else None,
    }


def _deployed_label(draws: MonteCarloResult) -> str:
    """``refined (CPA + points refinement)``, with the extended model's name when the draws carry one."""
    extended = ""
    if draws.joint_model is not None:  # extended
        groups = draws.joint_model.groups
        extended = ", " + "+".join(group for group in ("compliance", "harmonic") if group in groups) + " model"
    return f"refined (CPA + {DEPLOYED} refinement{extended})"


def tcp_stage(
    scenario: Scenario,
    *,
    targets: TCPTargets,
    draws: MonteCarloResult,
    validation: Capture,
    deployed: ParameterSet,
    workspace_seed: int,
    estimate: ParameterSet | None = None,
    joint_errors: JointErrorModel | None = None,
    out: Path,
    figures: FigureJobs,
    step: Step = _no_step,
) -> StageOutput:
    """``tcp/``: TCP uncertainty of the deployed (refined) model at the pose, along the trajectory, over the
    workspace (thesis ch. 5.3), and ``tcp/consistency.json``, the check against the validation capture (with the
    measured ``joint_errors`` the deployed model does not represent in the expected error).

    Result: ``{mode: TCPUncertainty}`` plus ``"workspace_map"`` (WorkspaceUncertainty) and ``"consistency"``.
    """
    base = {
        "model": f"{_deployed_label(draws)}, Monte Carlo",
        "draws_file": "uncertainty-refined/draws.npz",
        "draws_seed": draws.seed,
        "draws_in_file": draws.n_draws,
        "versions": versions(),
    }
    folder = out / "tcp"
    folder.mkdir(exist_ok=True)
    written: dict[str, Document] = {}
    value: dict = {}

    def commit(mode: str, result, provenance: dict, workspace=None) -> None:
        """One folder per mode, whole or not at all, committed as soon as it is computed."""
        with atomic_directory(folder / mode) as partial:
            files = write_tcp_folder(partial, result, workspace=workspace, provenance=provenance)
        written.update(_in(mode, files, folder / mode))
        figures.draw("robotcal.plots.tcp:write_tcp_figures", result, folder / mode, mode, workspace=workspace)
        value[mode] = result
        step(len(value), None, mode)

    tool = targets.tool_mm
    for mode, readings, source in (
        ("pose", targets.pose, targets.pose_source),
        ("trajectory", targets.trajectory, targets.trajectory_source),
    ):
        if readings is None:
            continue
        started = time.perf_counter()
        result = api.tcp_uncertainty(scenario, draws, np.rad2deg(readings), tool_mm=tool, keep_draws=mode == "pose")
        commit(mode, result, {**base, mode: source, "mode": mode, "seconds": round(time.perf_counter() - started, 3)})
    started = time.perf_counter()
    used = draws.n_draws if targets.workspace_draws is None else min(targets.workspace_draws, draws.n_draws)
    workspace = api.workspace_uncertainty(
        scenario, draws, targets.workspace_poses, tool_mm=tool, rng=workspace_seed, draws_used=used
    )
    provenance = {**base, "mode": "workspace", "seconds": round(time.perf_counter() - started, 3)}
    if used < draws.n_draws:
        provenance["draws_used"] = int(used)
    commit("workspace", workspace.tcp, provenance, workspace=workspace)
    consistency = api.validation_consistency(
        validation, deployed, draws, scenario, model=_deployed_label(draws), joint_errors=joint_errors
    )
    consistency.update(draws_file="uncertainty-refined/draws.npz", validation_file="validation.csv")
    if estimate is not None and estimate is not deployed:
        consistency["deployed"] = "the refinement's estimate corrected for its Monte Carlo's bias (uncertainty-refined/deployed.json)"
        consistency["estimate"] = _estimate_errors(validation, estimate, scenario, consistency["expected_rms_mm"])
    written["consistency.json"] = write_json(folder / "consistency.json", consistency)
    documents = {
        f"tcp/{name}": (folder / document if isinstance(document, Path) else document)
        for name, document in written.items()
    }
    detail = ", ".join(value)
    value.update(workspace_map=workspace, consistency=consistency)
    return StageOutput(value, documents, detail)


def plan_stage(
    scenario: Scenario, *, seed: int, draws: int, out: Path, figures: FigureJobs, step: Step = _no_step
) -> StageOutput:
    """``plan/``: the capture plan checked in the cell (thesis 4.5.2) and how its J4 sweep drives the
    uncertainty (ch. 5.2.4, Fig. 5.15), a sensitivity study of at most :data:`PLAN_SENSITIVITY_DRAWS` draws per
    case. Result: ``{"check": PlanCheck, "study": SensitivityStudy, "notes": [...]}``.
    """
    from robotcal.planning.files import check_document, write_check_files, write_sensitivity_files
    from robotcal.planning.scenario import cell_from_scenario, scenario_document
    from robotcal.planning.sensitivity import run_sensitivity, study_rows

    cell, notes = cell_from_scenario(scenario)
    check = api.check_plan(scenario, cell=cell)
    step(1, None, "cell check")
    with atomic_directory(out / "plan") as folder:
        check_json = check_document(check, scenario=scenario.source, cell=cell, notes=notes)
        write_check_files(folder, check, check_json)
        documents = _read_back(folder, out / "plan")
    acceptance = check_json["cell"]["acceptance_deg"]
    figures.draw("robotcal.plots.planning:plot_check", check, out / "plan" / "plan_check.png", acceptance_deg=acceptance)
    document, base_dir, name, source = scenario_document(scenario.source)
    study = run_sensitivity(
        document,
        base_dir,
        name,
        source,
        [(PLAN_SENSITIVITY_KEY, list(PLAN_SENSITIVITY_VALUES))],
        seed=seed,
        iterations=min(PLAN_SENSITIVITY_DRAWS, draws),
    )
    rows = study_rows(study)
    with atomic_directory(out / "plan" / "sensitivity") as folder:
        summary = {
            "scenario": scenario.source,
            "keys": list(study.keys),
            "seed": seed,
            "length_limit_mm": study.length_limit_mm,
            "angle_limit_deg": study.angle_limit_deg,
            "cases": [dict(case.values, draws=case.n_draws) for case in study.cases],
            "model": "CPA (thesis ch. 5.2.4)",
        }
        write_sensitivity_files(folder, rows, summary)
        documents.update(
            {f"sensitivity/{key}": value for key, value in _read_back(folder, out / "plan" / "sensitivity").items()}
        )
    figures.draw("robotcal.plots.planning:plot_sensitivity", rows, study.keys, out / "plan" / "sensitivity")
    bad = int((~check.ok).sum())
    verdict = "feasible in the cell" if bad == 0 else f"{bad} of {check.ok.size} points fail a cell check"
    detail = f"{verdict}; sensitivity to the J4 sweep, {len(study.cases)} cases"
    return StageOutput(
        {"check": check, "study": study, "notes": notes},
        {f"plan/{name}": document for name, document in documents.items()},
        detail,
    )


def iso9283_stage(
    scenario: Scenario, *, truth: ParameterSet, models: dict, seed: int, out: Path, figures: FigureJobs
) -> StageOutput:
    """``iso9283/``: ``iso9283.csv`` (the ``robotcal iso9283`` columns), ``study.json`` (cube, start, cycles,
    targets, seed, models) and ``iso9283.png``: a simulated ISO 9283 pose test of the true robot, evaluated with
    every model. Result: the :class:`~robotcal.diagnostics.iso9283.IsoStudy`."""
    study = simulate_iso_study(
        scenario.robot,
        models,
        true_parameters=truth,
        tracker_from_base=scenario.tracker_from_base,
        joint_errors=scenario.joint_errors,
        instrument=scenario.instrument if scenario.has_instrument else None,
        targets_mm=ISO_TARGETS_MM,
        cycles=ISO_CYCLES,
        seed=seed,
    )
    summary = {
        "method": (
            "simulated ISO 9283 pose test: the scenario's true robot with its joint error model and instrument "
            "noise visits P1..P5 (one unmeasured warm-up cycle); each model's commanded pose is its forward "
            "kinematics at the commanded readings (docs/iso9283.md)"
        ),
        "models": list(models),
        "cycles": ISO_CYCLES,
        "seed": seed,
        "cube": {"center_mm": study.center_mm.tolist(), "side_mm": float(study.side_mm)},
        "start_deg": np.rad2deg(study.start_readings).tolist(),
        "point_mm": study.point_mm.tolist(),
        "targets_mm": {name: np.asarray(value, dtype=float).tolist() for name, value in study.targets_mm.items()},
        "units": {"AP, RP, AD, RD, l_bar, S_l": "mm", "APa..c, RPa..c": "deg"},
    }
    with atomic_directory(out / "iso9283") as folder:
        documents: dict[str, Document] = {
            "iso9283/iso9283.csv": write_csv(folder / "iso9283.csv", iso_to_csv(study.results)),
            "iso9283/study.json": write_json(folder / "study.json", summary),
        }
    figures.draw("robotcal.plots.iso9283:plot_iso_results", study.results, out / "iso9283" / "iso9283.png")
    worst = {model: float(np.max(r.ap)) * 1e3 for model, r in study.results.items()}
    detail = "max AP " + ", ".join(f"{model} {value:.0f} um" for model, value in worst.items())
    return StageOutput(study, documents, detail)
