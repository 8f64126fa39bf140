"""The stages of a calibration run, one plain function each (docs/pipeline.md).

Every stage takes typed inputs (the scenario, the results of earlier stages, the run folder ``out``) and
returns a :class:`StageOutput`: its typed result, the documents it wrote (keyed by their path relative to
the run folder, :mod:`robotcal.pipeline.result`) and a one-line detail for the progress display. A stage's
folder is built with :func:`robotcal.io.atomic.atomic_directory`: it appears whole or not at all (``tcp/``: one
folder per mode, committed as it is computed; ``plan/`` then ``plan/sensitivity/``), and its figures are drawn
afterwards, into the final folder, through ``render`` (:mod:`robotcal.pipeline.figures`). The
stand-alone commands (``robotcal identify``, ``refine``, ``evaluate``, ``joints``, ``uncertainty``,
``tcp``, ``plan``) call the same library functions and write the same files.

``step(done, total, detail)`` reports progress inside a stage (``total`` None: the stage's step count).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robotcal.capture import Capture
from robotcal.io.atomic import atomic_directory
from robotcal.io.capture_csv import capture_to_csv
from robotcal.io.parameters_json import parameters_to_dict
from robotcal.io.scenario import Scenario
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline.evaluation import evaluation_document, write_evaluation_figures, write_evaluation_folder
from robotcal.pipeline.figures import Render, draw_now
from robotcal.pipeline.folder import read_document, write_csv, write_json
from robotcal.pipeline.iso9283 import iso9283_stage
from robotcal.pipeline.joints import compute_joints, write_joint_figure_files, write_joints_folder
from robotcal.pipeline.plan import PLAN_SENSITIVITY_DRAWS, PLAN_SENSITIVITY_KEY, PLAN_SENSITIVITY_VALUES
from robotcal.pipeline.result import Document, Table
from robotcal.pipeline.tcp import compute_tcp, write_tcp_figures, write_tcp_folder
from robotcal.pipeline.uncertainty import HISTOGRAMS, compute_uncertainty, write_uncertainty_folder
from robotcal.uncertainty.montecarlo import MonteCarloResult, MonteCarloSettings
from robotcal.workflow import (
    TCPTargets,
    cpa_provenance,
    evaluate_scenario,
    identify_scenario,
    refine_provenance,
    refine_scenario,
    scenario_truth,
    simulate_scenario,
    simulate_validation,
    validation_consistency,
    versions,
)

__all__ = [
    "CRITERIA_RUN",
    "Simulated",
    "StageOutput",
    "capture_from_table",
    "evaluate_stage",
    "identify_stage",
    "iso9283_stage",
    "joints_stage",
    "plan_stage",
    "refine_stage",
    "simulate_stage",
    "tcp_stage",
    "uncertainty_stage",
]

#: The refinement criteria a run computes, the deployed one (the recommended model) first.
CRITERIA_RUN = ("points", "distances")
#: The deployed model's criterion: its Monte Carlo, TCP figures and consistency check.
DEPLOYED = "points"

Step = Callable[[int, int | None, str], None]


def _no_step(done: int, total: int | None, detail: str = "") -> None:
    return None


@dataclass(frozen=True, slots=True)
class StageOutput:
    """What a stage produced: its typed result, its documents (path relative to the run folder), a detail,
    and its figures as ``render`` returned them (paths, or jobs of paths: :func:`~robotcal.pipeline.figures.figure_paths`)."""

    value: Any
    documents: dict[str, Document] = field(default_factory=dict)
    detail: str = ""
    figures: tuple = ()


@dataclass(frozen=True, slots=True, kw_only=True)
class Simulated:
    """The simulate stage: the "true" robot, the calibration and the validation captures (as written)."""

    truth: ParameterSet
    capture: Capture
    validation: Capture


def _folder_documents(prefix: str, documents: dict[str, Document], final: Path) -> dict[str, Document]:
    """Documents written into a stage's temporary folder, keyed and located as in the final run folder."""
    return {
        f"{prefix}/{name}": (final / name if isinstance(document, Path) else document)
        for name, document in documents.items()
    }


def _written_back(folder: Path, final: Path) -> dict[str, Document]:
    """The files another module wrote into ``folder`` (a stage's temporary folder; :mod:`robotcal.plots.planning`
    writes its own), read back once as :func:`robotcal.pipeline.folder.read_run` would: JSON and CSV as
    documents, others by their path in ``final``."""
    return {
        path.name: read_document(folder, path.name) if path.suffix in (".json", ".csv") else final / path.name
        for path in sorted(folder.iterdir())
        if path.is_file()
    }


def capture_from_table(table: Table, *, source: str, seed: int | None) -> Capture:
    """The capture a capture CSV's cells describe, exactly as :func:`robotcal.io.read_capture` reads the file.

    Columns are found by name as the reader finds them (``circle, direction, q1..qN, x, y, z`` and the optional
    ``target`` and ``u95_mm``); every number goes through ``float`` and readings [deg] through ``np.deg2rad``
    as in the reader, and target names are numbered in order of first appearance as the reader numbers them,
    so the capture is bit for bit the file's (12 decimals, :func:`robotcal.io.capture_csv.capture_to_csv`).
    The table is one the pipeline wrote itself: no input checks are repeated here.
    """
    header = [cell.strip().lower() for cell in table.header]
    joints = sorted((c for c in header if c[:1] == "q" and c[1:].isdigit()), key=lambda c: int(c[1:]))
    columns = [header.index(c) for c in ("circle", "direction", *joints, "x", "y", "z")]
    data = np.array([[float(row[k]) for k in columns] for row in table.rows], dtype=float).reshape(-1, len(columns))
    n = len(joints)
    target = names = u95 = None
    if "target" in header:
        labels = [row[header.index("target")].strip() for row in table.rows]
        names = tuple(dict.fromkeys(labels))
        lookup = {name: k for k, name in enumerate(names)}
        target = np.array([lookup[label] for label in labels], dtype=int)
    if "u95_mm" in header:
        u95 = np.array([float(row[header.index("u95_mm")]) for row in table.rows], dtype=float)
    return Capture(
        circle=data[:, 0].astype(int),
        direction=data[:, 1].astype(int),
        readings=np.deg2rad(data[:, 2 : 2 + n]),
        points=data[:, 2 + n :],
        source=source,
        seed=seed,
        target=target,
        target_names=names or (),
        u95=u95,
    )


def simulate_stage(scenario: Scenario, seeds: dict, out: Path, step: Step = _no_step) -> StageOutput:
    """``truth.json``, ``capture.csv``, ``validation.csv``: the "true" robot and its two simulated captures.

    The captures the later stages use are those of the CSV files (12 decimals), kept in memory: a stand-alone
    command reading ``capture.csv`` sees the same numbers bit for bit.
    """
    robot = scenario.robot
    if scenario.truth is not None:
        truth, truth_seed = scenario_truth(scenario, seed=seeds["truth"])
        provenance = {
            "method": "nominal plus normal deviations of the CPA-identifiable parameters (simulation.perturb)",
            "scenario": {"name": scenario.name, "source": scenario.source},
            "truth": scenario.truth.model_dump(),
            "seed": truth_seed,
            "versions": versions(),
        }
    else:
        truth = ParameterSet.nominal(robot)
        provenance = {
            "method": "nominal parameters (the scenario has no [truth] table)",
            "scenario": {"name": scenario.name, "source": scenario.source},
            "versions": versions(),
        }
    documents: dict[str, Document] = {"truth.json": write_json(out / "truth.json", parameters_to_dict(truth, provenance))}
    step(1, None, "truth")
    calibration = simulate_scenario(scenario, seed=seeds["capture"], true_parameters=truth)
    documents["capture.csv"] = write_csv(out / "capture.csv", capture_to_csv(calibration.capture))
    step(2, None, f"{calibration.capture.n_points} points")
    validation = simulate_validation(scenario, seed=seeds["validation"], true_parameters=truth)
    documents["validation.csv"] = write_csv(out / "validation.csv", capture_to_csv(validation.capture))
    value = Simulated(
        truth=truth,
        capture=capture_from_table(documents["capture.csv"], source="capture.csv", seed=calibration.seed),
        validation=capture_from_table(documents["validation.csv"], source="validation.csv", seed=validation.seed),
    )
    detail = f"{calibration.capture.n_points} + {validation.capture.n_points} points"
    return StageOutput(value, documents, detail)


def identify_stage(scenario: Scenario, capture: Capture, out: Path) -> StageOutput:
    """``cpa/parameters.json``: Circle Point Analysis of the capture (thesis ch. 3)."""
    result = identify_scenario(capture, scenario)
    with atomic_directory(out / "cpa") as folder:
        document = parameters_to_dict(result.parameters, cpa_provenance(result, capture, scenario))
        documents = {"parameters.json": write_json(folder / "parameters.json", document)}
    return StageOutput(result, _folder_documents("cpa", documents, out / "cpa"), f"{int(result.parameters.identified.sum())} parameters")


def refine_stage(scenario: Scenario, capture: Capture, start: ParameterSet, out: Path, step: Step = _no_step) -> StageOutput:
    """``refine/points.json``, ``refine/distances.json``: Levenberg-Marquardt refinement from the CPA result."""
    results = {}
    for k, criterion in enumerate(CRITERIA_RUN):
        results[criterion] = refine_scenario(capture, scenario, start, criterion=criterion)
        step(k + 1, None, criterion)
    documents = {}
    with atomic_directory(out / "refine") as folder:
        for criterion, result in results.items():
            provenance = refine_provenance(result, capture, scenario, "cpa/parameters.json")
            documents[f"{criterion}.json"] = write_json(
                folder / f"{criterion}.json", parameters_to_dict(result.parameters, provenance)
            )
    detail = ", ".join(f"{c} RMS {r.rms_history[-1] * 1e3:.1f} um" for c, r in results.items())
    return StageOutput(results, _folder_documents("refine", documents, out / "refine"), detail)


def convergence_histories(refined: dict) -> dict:
    """The RMS and cost per iteration of each refinement (``evaluation.json`` ``convergence``) [mm, mm^2]."""
    return {
        criterion: {"criterion": criterion, "cost_mm2": result.cost_history.tolist(), "rms_mm": result.rms_history.tolist()}
        for criterion, result in refined.items()
    }


def evaluate_stage(
    scenario: Scenario,
    *,
    cpa: ParameterSet,
    refined: dict,
    capture: Capture,
    validation: Capture,
    out: Path,
    render: Render = draw_now,
) -> StageOutput:
    """``evaluation/``: nominal, CPA and refined parameters on the validation and calibration captures."""
    sets = {"nominal": ParameterSet.nominal(scenario.robot), "cpa": cpa, **{c: r.parameters for c, r in refined.items()}}
    rows = evaluate_scenario(scenario, {"validation": validation, "capture": capture}, sets)
    document = evaluation_document(
        rows,
        scenario,
        parameter_files={"cpa": "cpa/parameters.json", **{c: f"refine/{c}.json" for c in refined}},
        capture_files={"validation": "validation.csv", "capture": "capture.csv"},
        reference="nominal",
        histories=convergence_histories(refined),
        headline_after=DEPLOYED,
    )
    with atomic_directory(out / "evaluation") as folder:
        documents = write_evaluation_folder(folder, rows, document, figures=False)
    drawn = write_evaluation_figures(out / "evaluation", document, render=render)
    headline = document["headline"]
    detail = f"{headline['before_mean_mm']:.3f} -> {headline['after_mean_mm']:.4f} mm" if headline else ""
    return StageOutput(rows, _folder_documents("evaluation", documents, out / "evaluation"), detail, tuple(drawn))


def joints_stage(
    scenario: Scenario, capture: Capture, *, backlash: bool, out: Path, render: Render = draw_now
) -> StageOutput:
    """``joints/``: backlash and eccentricity per joint with their harmonic model (thesis ch. 4.6)."""
    diagnostics, model = compute_joints(capture, scenario, backlash=backlash)
    with atomic_directory(out / "joints") as folder:
        documents = write_joints_folder(
            folder, diagnostics, model, capture="capture.csv", scenario=scenario, figures=False
        )
    drawn = write_joint_figure_files(out / "joints", diagnostics, model, render=render)
    detail = "backlash and eccentricity" if backlash else "eccentricity (one sweep direction)"
    return StageOutput((diagnostics, model), _folder_documents("joints", documents, out / "joints"), detail, (drawn,))


def uncertainty_stage(
    scenario: Scenario,
    *,
    montecarlo: MonteCarloSettings,
    refined_montecarlo: MonteCarloSettings,
    seed: int,
    cpa: ParameterSet,
    deployed: ParameterSet,
    out: Path,
    step: Step = _no_step,
    render: Render = draw_now,
) -> StageOutput:
    """``uncertainty/`` (CPA model, thesis ch. 5.2.3) and ``uncertainty-refined/`` (the deployed model).

    Both Monte Carlos use the same seed, so they see the same instrument noise draw for draw; both folders
    are written only once both are computed (a failure or an interrupt while computing leaves neither).
    Result: ``{"cpa": MonteCarloResult, "refined": MonteCarloResult}``.
    """
    total = montecarlo.iterations + refined_montecarlo.iterations

    def cpa_done(done: int, expected: int | None) -> None:
        step(done, total, "draws")

    def refined_done(done: int, expected: int | None) -> None:
        step(montecarlo.iterations + done, total, "draws")

    drawn: list = []  # the histogram pages are prepared by the figure worker while the draws run

    def prepare(function, *args, **kwargs):
        drawn.append(render(function, *args, **kwargs))

    result = compute_uncertainty(
        scenario, montecarlo, seed=seed, true_parameters=cpa, progress=cpa_done, render=prepare
    )
    refined = compute_uncertainty(
        scenario,
        refined_montecarlo,
        seed=seed,
        true_parameters=deployed,
        progress=refined_done,
        model="refined",
        criterion=DEPLOYED,
    )
    documents: dict[str, Document] = {}
    for name, value in (("uncertainty", result), ("uncertainty-refined", refined)):
        with atomic_directory(out / name) as folder:
            written = write_uncertainty_folder(folder, value, scenario, save_draws=True, figures=False)
        documents.update(_folder_documents(name, written, out / name))
        drawn.append(render(HISTOGRAMS, value, out / name))
    rates = [r.n_draws / max(r.timings_s.get("draws", 0.0), 1e-9) for r in (result, refined)]
    detail = f"CPA {result.n_draws:,} draws ({rates[0]:,.0f}/s), refined {refined.n_draws:,} draws ({rates[1]:,.0f}/s)"
    return StageOutput({"cpa": result, "refined": refined}, documents, detail, tuple(drawn))


def tcp_stage(
    scenario: Scenario,
    *,
    targets: TCPTargets,
    draws: MonteCarloResult,
    validation: Capture,
    deployed: ParameterSet,
    workspace_seed: int,
    out: Path,
    step: Step = _no_step,
    render: Render = draw_now,
) -> StageOutput:
    """``tcp/``: TCP uncertainty of the deployed (refined) model at the pose, along the trajectory, over the
    workspace (thesis ch. 5.3), and ``tcp/consistency.json``, the check against the validation capture.

    Result: ``{mode: TCPUncertainty}`` plus ``"workspace_map"`` (WorkspaceUncertainty) and ``"consistency"``.
    """
    robot = scenario.robot
    base = {
        "model": "refined (CPA + points refinement), Monte Carlo",
        "draws_file": "uncertainty-refined/draws.npz",
        "draws_seed": draws.seed,
        "draws_in_file": draws.n_draws,
        "versions": versions(),
    }
    # one folder per mode, each whole or not at all and committed as soon as it is computed, so that its
    # figures are drawn while the next mode computes; consistency.json last
    folder = out / "tcp"
    folder.mkdir(exist_ok=True)
    written: dict[str, Document] = {}
    drawn: list = []
    value: dict = {}

    def commit(mode: str, result, workspace_map, provenance: dict) -> None:
        with atomic_directory(folder / mode) as partial:
            files = write_tcp_folder(partial, result, mode, workspace=workspace_map, provenance=provenance, figures=False)
        written.update(_folder_documents(mode, files, Path(mode)))
        drawn.extend(write_tcp_figures(folder / mode, result, mode, workspace=workspace_map, render=render))
        value[mode] = result

    for mode, readings, source in (
        ("pose", targets.pose, targets.pose_source),
        ("trajectory", targets.trajectory, targets.trajectory_source),
    ):
        if readings is None:
            continue
        started = time.perf_counter()
        tcp, _ = compute_tcp(robot, draws.draws, mode, readings=readings, tool_mm=targets.tool_mm)
        commit(mode, tcp, None, {**base, mode: source, "mode": mode, "seconds": round(time.perf_counter() - started, 3)})
        step(len(value), None, mode)
    started = time.perf_counter()
    values = draws.draws if targets.workspace_draws is None else draws.draws[: targets.workspace_draws]
    tcp, ws = compute_tcp(
        robot, values, "workspace", n_poses=targets.workspace_poses, seed=workspace_seed, tool_mm=targets.tool_mm
    )
    provenance = {**base, "mode": "workspace", "seconds": round(time.perf_counter() - started, 3)}
    if values.shape[0] < draws.n_draws:
        provenance["draws_used"] = int(values.shape[0])
    commit("workspace", tcp, ws, provenance)
    step(len(value), None, "workspace")
    consistency = validation_consistency(
        scenario, validation, deployed, draws.draws, model="refined (CPA + points refinement)"
    )
    consistency["draws_file"] = "uncertainty-refined/draws.npz"
    consistency["validation_file"] = "validation.csv"
    written["consistency.json"] = write_json(folder / "consistency.json", consistency)
    documents = {
        f"tcp/{name}": (folder / document if isinstance(document, Path) else document)
        for name, document in written.items()
    }
    detail = ", ".join(value)
    value["workspace_map"] = ws
    value["consistency"] = consistency
    return StageOutput(value, documents, detail, tuple(drawn))


def plan_stage(
    scenario: Scenario, *, seed: int, draws: int, out: Path, step: Step = _no_step, render: Render = draw_now
) -> StageOutput:
    """``plan/``: the capture plan checked in the cell (thesis 4.5.2) and how its J4 sweep drives the
    uncertainty (ch. 5.2.4, Fig. 5.15), a sensitivity study of at most :data:`PLAN_SENSITIVITY_DRAWS` draws per case.

    Result: ``{"check": PlanCheck, "study": SensitivityStudy, "notes": [...]}``.
    """
    from robotcal.planning.cell import check_plan
    from robotcal.planning.scenario import cell_from_scenario, scenario_document
    from robotcal.planning.sensitivity import run_sensitivity, study_rows
    from robotcal.plots.planning import check_document, write_check_files, write_sensitivity_files

    cell, notes = cell_from_scenario(scenario)
    check = check_plan(scenario.robot, scenario.plan, cell)
    step(1, None, "cell check")
    # plan/ with the cell check first, so its figure is drawn while the sensitivity study computes;
    # plan/sensitivity/ then appears whole, in its turn
    with atomic_directory(out / "plan") as folder:
        check_json = check_document(check, scenario=scenario.source, cell=cell, notes=notes)
        write_check_files(folder, check, check_json)
        documents = _written_back(folder, out / "plan")
    drawn = [
        render(
            "robotcal.plots.planning:plot_check",
            check,
            out / "plan" / "plan_check.png",
            acceptance_deg=check_json["cell"]["acceptance_deg"],
        )
    ]
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
            {f"sensitivity/{key}": value for key, value in _written_back(folder, out / "plan" / "sensitivity").items()}
        )
    drawn.append(render("robotcal.plots.planning:plot_sensitivity", rows, study.keys, out / "plan" / "sensitivity"))
    bad = int((~check.ok).sum())
    verdict = "feasible in the cell" if bad == 0 else f"{bad} of {check.ok.size} points fail a cell check"
    detail = f"{verdict}; sensitivity to the J4 sweep, {len(study.cases)} cases"
    return StageOutput(
        {"check": check, "study": study, "notes": notes},
        {f"plan/{name}": document for name, document in documents.items()},
        detail,
        tuple(drawn),
    )
