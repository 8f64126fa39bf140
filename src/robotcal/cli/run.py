"""``robotcal run SCENARIO --out DIR``: the whole calibration pipeline into one run folder.

Stages (docs/results.md): simulate (truth, calibration and validation captures), identify (CPA),
refine (points and distances criteria), evaluate, joints, uncertainty (Monte Carlo, draws kept),
tcp (Table 5.8 pose, trajectory, workspace), report. Each stage calls the same functions as its
stand-alone command and writes the same files, its folder built with
:func:`robotcal.io.atomic.atomic_directory`; ``run.json`` is rewritten (atomically) after every
stage, so a failed stage leaves the earlier stages' outputs and a record of what failed and why.

Everything that can be checked is checked by :func:`prepare_run` before any computation.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import shutil
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from robotcal.capture import Capture
from robotcal.cli import app
from robotcal.cli._common import (
    BYTES_PER_POSE,
    FORCE_HELP,
    SEED_BOUND,
    Terminated,
    check_memory,
    console,
    error_console,
    handle_errors,
    monte_carlo_bytes,
    pairs_bytes,
)
from robotcal.cli.evaluate import evaluation_document, write_evaluation_folder
from robotcal.cli.joints import compute_joints, write_joints_folder
from robotcal.cli.tcp import compute_tcp, write_tcp_folder
from robotcal.cli.uncertainty import compute_uncertainty, write_uncertainty_folder
from robotcal.errors import InputError, RobotcalError
from robotcal.io import load_scenario, read_capture, write_capture, write_parameters
from robotcal.io.atomic import atomic_directory, atomic_write_text
from robotcal.io.output import check_output_folder, existing_inputs, output_lock, write_marker
from robotcal.io.scenario import Scenario
from robotcal.kinematics.model import ParameterSet
from robotcal.uncertainty.montecarlo import MonteCarloSettings
from robotcal.workflow import (
    TCPTargets,
    cpa_provenance,
    evaluate_scenario,
    identify_scenario,
    refine_provenance,
    refine_scenario,
    resolve_seed,
    scenario_truth,
    simulate_scenario,
    simulate_validation,
    tcp_targets,
    validation_consistency,
    validation_reflector,
    versions,
)

__all__ = ["RunPlan", "STAGES", "prepare_run", "execute_run", "run", "run_with_display"]

#: Stages in order (the names of ``run.json`` ``stages`` and of the report's stage table).
STAGES = ("simulate", "identify", "refine", "evaluate", "joints", "uncertainty", "tcp", "plan", "report")
#: What each stage writes under the run folder.
OUTPUTS = {
    "simulate": ("truth.json", "capture.csv", "validation.csv"),
    "identify": ("cpa",),
    "refine": ("refine",),
    "evaluate": ("evaluation",),
    "joints": ("joints",),
    "uncertainty": ("uncertainty", "uncertainty-refined"),
    "tcp": ("tcp",),
    "plan": ("plan",),
    "report": ("report.html",),
}
#: Steps per stage for the progress display (the Monte Carlo counts draws instead).
STEPS = {"simulate": 3, "identify": 1, "refine": 2, "evaluate": 1, "joints": 1, "tcp": 3, "plan": 2, "report": 1}
#: The plan stage's sensitivity study (thesis Fig. 5.15): the angle joint 4 covers, Monte Carlo draws per case.
PLAN_SENSITIVITY_KEY = "capture.sweep_deg.4"
PLAN_SENSITIVITY_VALUES = (15.0, 50.0, 90.0, 180.0)
PLAN_SENSITIVITY_DRAWS = 2_000
#: Refined-model Monte Carlo draws of a run unless ``--refined-draws`` says otherwise (at most the CPA
#: Monte Carlo's): each refined draw costs about 20 CPA draws (docs/uncertainty.md).
REFINED_DRAWS = 20_000
#: Offsets of the seeds derived from ``--seed N``: every random part of the run gets its own.
SEED_OFFSETS = {"capture": 0, "truth": 1, "validation": 2, "montecarlo": 3, "workspace": 4}

StageProgress = Callable[[str, int, int | None, str], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class RunPlan:
    """A checked run: the scenario, the output folder, the seeds and the stage settings."""

    scenario: Scenario
    out: Path
    seeds: dict
    montecarlo: MonteCarloSettings
    refined_montecarlo: MonteCarloSettings
    tcp: TCPTargets
    backlash: bool
    command: str
    force: bool = False
    inputs: tuple = ()


def prepare_run(
    scenario: str,
    out: Path,
    *,
    seed: int | None = None,
    draws: int | None = None,
    workspace: int | None = None,
    workers: int | None = None,
    refined_draws: int | None = None,
    command: str = "robotcal run",
    force: bool = False,
) -> RunPlan:
    """Load and check everything a run needs, before any computation; nothing is written.

    Raises :class:`InputError` naming the file and key (scenario keys, validation target, TCP pose and
    trajectory, Monte Carlo settings, seeds, the memory each stage needs, output folder: the output
    policy of :mod:`robotcal.io.output`).
    """
    inputs = existing_inputs(scenario)
    out = Path(out)
    check_output_folder(out, inputs=inputs, force=force, keeps_other_files=True)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    check_output_folder(out, inputs=inputs, force=force, keeps_other_files=True)
    robot = loaded.robot
    validation_reflector(loaded)  # a validation capture needs a flange target
    table = loaded.validation or {"margin_deg": 5.0}
    if not np.all(np.isfinite(robot.limits)):
        raise InputError(
            f"{loaded.source}: robot {robot.name!r} needs finite `limits_deg` on every joint for the random "
            "validation poses"
        )
    if np.any(robot.limits[:, 1] - robot.limits[:, 0] <= 2 * np.deg2rad(table["margin_deg"])):
        raise InputError(f"{loaded.source}: key `validation.margin_deg` leaves no room within the joint limits")
    if seed is not None:
        seeds = {name: seed + offset for name, offset in SEED_OFFSETS.items()}
    else:
        seeds = {
            "capture": resolve_seed(loaded.seed),
            "truth": resolve_seed((loaded.truth or {}).get("seed")),
            "validation": resolve_seed((loaded.validation or {}).get("seed")),
            "montecarlo": resolve_seed(loaded.montecarlo.get("seed")),
            "workspace": None,
        }
    if loaded.truth is None:
        seeds["truth"] = None
    for name, value in seeds.items():
        if value is not None and not 0 <= value < SEED_BOUND:
            raise InputError(f"{loaded.source}: the {name} seed {value} is outside [0, 2^63)")
    targets = tcp_targets(loaded)
    if seeds["workspace"] is None:
        seeds["workspace"] = targets.workspace_seed
    if workspace is not None:
        if workspace < 1:
            raise InputError(f"--workspace must be a positive number of poses; got {workspace}")
        targets = _replace_workspace(targets, workspace)
    iterations = int(loaded.montecarlo["iterations"]) if draws is None else draws
    try:
        settings = MonteCarloSettings(
            iterations=iterations,
            coverage=float(loaded.montecarlo["coverage"]),
            workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        )
    except InputError as exc:
        raise InputError(f"{loaded.source}: Monte Carlo settings: {exc}") from None
    if refined_draws is not None and not 1 <= refined_draws <= iterations:
        raise InputError(
            f"--refined-draws must be between 1 and the Monte Carlo draws ({iterations:,}); got {refined_draws}"
        )
    try:
        refined_settings = dataclasses.replace(
            settings, iterations=min(iterations, REFINED_DRAWS) if refined_draws is None else refined_draws
        )
    except InputError as exc:
        raise InputError(f"--refined-draws: {exc}") from None
    _check_tcp(loaded, targets, settings)
    _check_memory(loaded, targets, settings, table)  # the refined Monte Carlo has at most as many draws
    return RunPlan(
        scenario=loaded,
        out=out,
        seeds=seeds,
        montecarlo=settings,
        refined_montecarlo=refined_settings,
        tcp=targets,
        backlash=bool(loaded.plan.bidirectional),
        command=command,
        force=force,
        inputs=tuple(inputs),
    )


def _check_tcp(loaded: Scenario, targets: TCPTargets, settings: MonteCarloSettings) -> None:
    """The ``[tcp]`` stage's settings, checked before the run starts."""
    if targets.tool_mm is not None and not np.all(np.isfinite(targets.tool_mm)):
        raise InputError(
            f"{loaded.source}: key `tcp.tool_mm` must hold 3 finite numbers [mm]; got {targets.tool_mm.tolist()}"
        )
    smallest = int(np.ceil(1.0 / (1.0 - settings.coverage))) + 1
    used = settings.iterations if targets.workspace_draws is None else min(targets.workspace_draws, settings.iterations)
    if used < smallest:
        raise InputError(
            f"{loaded.source}: key `tcp.workspace_draws` = {targets.workspace_draws} is too few for a "
            f"{settings.coverage:g} coverage interval: at least {smallest}"
        )


def _check_memory(loaded: Scenario, targets: TCPTargets, settings: MonteCarloSettings, validation: dict) -> None:
    """Estimate the memory of the large stages up front (:func:`robotcal.cli._common.check_memory`)."""
    robot = loaded.robot
    n_points = int(loaded.plan.points.sum()) * (2 if loaded.plan.bidirectional else 1)
    check_memory(
        f"a Monte Carlo of {settings.iterations:,} draws",
        monte_carlo_bytes(
            settings.iterations, robot.n_joints, n_points, batch_size=settings.batch_size, workers=settings.workers
        ),
        "use fewer --draws",
    )
    check_memory(
        f"a workspace map of {targets.workspace_poses:,} poses",
        targets.workspace_poses * float(BYTES_PER_POSE),
        "use fewer --workspace poses (tcp.workspace_poses)",
    )
    poses = int(validation.get("poses", 100))
    check_memory(
        f"a validation capture of {poses:,} poses (with its distances view)",
        poses * float(BYTES_PER_POSE) + pairs_bytes(poses),
        "lower `validation.poses` in the scenario",
    )
    check_memory(
        f"the distances criterion on {n_points:,} points",
        pairs_bytes(n_points, 5 * robot.n_joints),
        "use fewer points per circle in the scenario's capture plan",
    )


def _replace_workspace(targets: TCPTargets, poses: int) -> TCPTargets:
    from dataclasses import replace

    return replace(targets, workspace_poses=poses)


def _scenario_echo(plan: RunPlan) -> dict:
    scenario = plan.scenario
    instrument = scenario.instrument
    return {
        "name": scenario.name,
        "source": scenario.source,
        "description": scenario.description,
        "robot": scenario.robot.name,
        "instrument": {
            "name": instrument.name,
            "a_um": instrument.a_mm * 1e3,
            "b_um_per_m": instrument.b_mm_per_m * 1e3,
            "noise": instrument.noise,
        },
        "settings": scenario.settings,
    }


class _Record:
    """``run.json``: scenario echo, seeds, versions, per-stage status and time; written after each stage."""

    def __init__(self, plan: RunPlan):
        self.path = plan.out / "run.json"
        self.data = {
            "command": plan.command,
            "scenario": _scenario_echo(plan),
            "robot": plan.scenario.robot.name,
            "seed": plan.seeds["capture"],
            "seeds": plan.seeds,
            "montecarlo": {
                "draws": plan.montecarlo.iterations,
                "coverage": plan.montecarlo.coverage,
                "workers": plan.montecarlo.workers,
                "simulated_robot": "the CPA result (cpa/parameters.json)",
            },
            "montecarlo_refined": {
                "draws": plan.refined_montecarlo.iterations,
                "model": "refined",
                "criterion": "points",
                "simulated_robot": "the refined result (refine/points.json)",
                "seed": "the same as montecarlo",
            },
            "tcp": {
                "pose": plan.tcp.pose_source,
                "trajectory": plan.tcp.trajectory_source,
                "workspace_poses": plan.tcp.workspace_poses,
                "workspace_draws": plan.tcp.workspace_draws,
                "workspace_seed": plan.seeds["workspace"],
                "tool_mm": None if plan.tcp.tool_mm is None else plan.tcp.tool_mm.tolist(),
            },
            "notes": list(plan.tcp.notes),
            "versions": versions(),
            "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "status": "running",
            "stages": {name: {"status": "pending", "seconds": None} for name in STAGES},
        }

    def stage(self, name: str, **entries) -> None:
        self.data["stages"][name].update(entries)

    def write(self) -> None:
        atomic_write_text(self.path, json.dumps(self.data, indent=2, allow_nan=False, default=str) + "\n")


def _clear_previous(out: Path) -> None:
    """Remove the outputs of an earlier run into ``out`` (only the names a run writes)."""
    for names in OUTPUTS.values():
        for name in names:
            path = out / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            elif path.exists() or path.is_symlink():
                path.unlink()
    (out / "run.json").unlink(missing_ok=True)


def _relabel(capture: Capture, source: str, seed: int | None) -> Capture:
    return Capture(
        circle=capture.circle,
        direction=capture.direction,
        readings=capture.readings,
        points=capture.points,
        source=source,
        seed=seed,
    )


def execute_run(plan: RunPlan, *, progress: StageProgress | None = None) -> dict:
    """Run every stage of ``plan`` into ``plan.out``; returns the ``run.json`` data.

    ``progress(stage, done, total, detail)`` is called as stages advance. A stage that raises stops
    the run: ``run.json`` records the stage as failed with the message, and the exception propagates.
    """
    with output_lock(plan.out):
        # checked again under the lock: another process may have written the folder since prepare_run
        check_output_folder(plan.out, inputs=plan.inputs, force=plan.force, keeps_other_files=True)
        return _execute_locked(plan, progress)


def _execute_locked(plan: RunPlan, progress: StageProgress | None) -> dict:
    report = progress or (lambda stage, done, total, detail="": None)
    scenario, out, seeds = plan.scenario, plan.out, plan.seeds
    robot = scenario.robot
    n = robot.n_joints
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create the folder: {exc.strerror or exc}") from None
    write_marker(out, command=plan.command, files=["run.json", *(name for names in OUTPUTS.values() for name in names)])
    _clear_previous(out)
    record = _Record(plan)
    record.write()
    try:
        return _stages(plan, record, report, out, seeds, scenario, robot, n)
    except BaseException as exc:
        if record.data["status"] == "running":  # interrupted between stages
            record.data.update(status=_status(exc), error=_message(exc))
            record.write()
        raise


def _status(exc: BaseException) -> str:
    return "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"


def _message(exc: BaseException) -> str:
    if isinstance(exc, Terminated):
        return "terminated (SIGTERM)"
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted (SIGINT, Ctrl-C)"
    return str(exc) if isinstance(exc, RobotcalError) else f"{type(exc).__name__}: {exc}"


def _stages(plan, record, report, out, seeds, scenario, robot, n) -> dict:
    state: dict = {}
    run_started = time.perf_counter()

    def simulate_stage():
        if scenario.truth is not None:
            truth, truth_seed = scenario_truth(scenario, seed=seeds["truth"])
            provenance = {
                "method": "nominal plus normal deviations of the CPA-identifiable parameters (simulation.perturb)",
                "scenario": {"name": scenario.name, "source": scenario.source},
                "truth": scenario.truth,
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
        write_parameters(out / "truth.json", truth, provenance)
        report("simulate", 1, None, "truth")
        calibration = simulate_scenario(scenario, seed=seeds["capture"], true_parameters=truth)
        write_capture(out / "capture.csv", calibration.capture)
        report("simulate", 2, None, f"{calibration.capture.n_points} points")
        validation = simulate_validation(scenario, seed=seeds["validation"], true_parameters=truth)
        write_capture(out / "validation.csv", validation.capture)
        # the stages work on the files as written, exactly as the stand-alone commands read them
        state["capture"] = _relabel(read_capture(out / "capture.csv", n_joints=n), "capture.csv", calibration.seed)
        state["validation"] = _relabel(
            read_capture(out / "validation.csv", n_joints=n), "validation.csv", validation.seed
        )
        return f"{calibration.capture.n_points} + {validation.capture.n_points} points"

    def identify_stage():
        capture = state["capture"]
        result = identify_scenario(capture, scenario)
        with atomic_directory(out / "cpa") as folder:
            write_parameters(folder / "parameters.json", result.parameters, cpa_provenance(result, capture, scenario))
        state["cpa"] = result.parameters
        return f"{int(result.parameters.identified.sum())} parameters"

    def refine_stage():
        capture = state["capture"]
        results = {}
        for k, criterion in enumerate(("points", "distances")):
            results[criterion] = refine_scenario(capture, scenario, state["cpa"], criterion=criterion)
            report("refine", k + 1, None, criterion)
        with atomic_directory(out / "refine") as folder:
            for criterion, result in results.items():
                write_parameters(
                    folder / f"{criterion}.json",
                    result.parameters,
                    refine_provenance(result, capture, scenario, "cpa/parameters.json"),
                )
        state["refined"] = {criterion: result.parameters for criterion, result in results.items()}
        state["histories"] = {
            criterion: {
                "criterion": criterion,
                "cost_mm2": result.cost_history.tolist(),
                "rms_mm": result.rms_history.tolist(),
            }
            for criterion, result in results.items()
        }
        return ", ".join(f"{c} RMS {r.rms_history[-1] * 1e3:.1f} um" for c, r in results.items())

    def evaluate_stage():
        sets = {"nominal": ParameterSet.nominal(robot), "cpa": state["cpa"], **state["refined"]}
        captures = {"validation": state["validation"], "capture": state["capture"]}
        rows = evaluate_scenario(scenario, captures, sets)
        document = evaluation_document(
            rows,
            scenario,
            parameter_files={
                "cpa": "cpa/parameters.json",
                "points": "refine/points.json",
                "distances": "refine/distances.json",
            },
            capture_files={"validation": "validation.csv", "capture": "capture.csv"},
            reference="nominal",
            histories=state["histories"],
            headline_after="points",
        )
        with atomic_directory(out / "evaluation") as folder:
            write_evaluation_folder(folder, rows, document)
        state["headline"] = document["headline"]
        headline = document["headline"]
        if headline:
            return f"{headline['before_mean_mm']:.3f} -> {headline['after_mean_mm']:.4f} mm"
        return ""

    def joints_stage():
        diagnostics, model = compute_joints(state["capture"], scenario, backlash=plan.backlash)
        with atomic_directory(out / "joints") as folder:
            write_joints_folder(folder, diagnostics, model, capture="capture.csv", scenario=scenario)
        state["joint_notes"] = [*diagnostics.messages, *model.messages]
        return "backlash and eccentricity" if plan.backlash else "eccentricity (one sweep direction)"

    def uncertainty_stage():
        total = plan.montecarlo.iterations + plan.refined_montecarlo.iterations

        def cpa_done(done: int, expected: int | None) -> None:
            report("uncertainty", done, total, "draws")

        def refined_done(done: int, expected: int | None) -> None:
            report("uncertainty", plan.montecarlo.iterations + done, total, "draws")

        # the thesis's Monte Carlo (ch. 5.2.3): capture -> CPA, around the CPA estimate
        result = compute_uncertainty(
            scenario, plan.montecarlo, seed=seeds["montecarlo"], true_parameters=state["cpa"], progress=cpa_done
        )
        # the deployed model: capture -> CPA -> refinement (points), around the refined estimate; the
        # same seed, so both Monte Carlos see the same instrument noise draw for draw
        refined = compute_uncertainty(
            scenario,
            plan.refined_montecarlo,
            seed=seeds["montecarlo"],
            true_parameters=state["refined"]["points"],
            progress=refined_done,
            model="refined",
            criterion="points",
        )
        # both folders written only once both are computed: a failure or an interrupt while computing leaves neither
        with atomic_directory(out / "uncertainty") as folder:
            write_uncertainty_folder(folder, result, scenario, save_draws=True)
        with atomic_directory(out / "uncertainty-refined") as folder:
            write_uncertainty_folder(folder, refined, scenario, save_draws=True)
        state["montecarlo"] = result
        state["montecarlo_refined"] = refined
        rates = [r.n_draws / max(r.timings_s.get("draws", 0.0), 1e-9) for r in (result, refined)]
        return (
            f"CPA {result.n_draws:,} draws ({rates[0]:,.0f}/s), refined {refined.n_draws:,} draws ({rates[1]:,.0f}/s)"
        )

    def tcp_stage():
        # the TCP uncertainty of the deployed (refined) model
        result = state["montecarlo_refined"]
        targets = plan.tcp
        base = {
            "model": "refined (CPA + points refinement), Monte Carlo",
            "draws_file": "uncertainty-refined/draws.npz",
            "draws_seed": result.seed,
            "draws_in_file": result.n_draws,
            "versions": versions(),
        }
        parts = []
        for mode, readings, source in (
            ("pose", targets.pose, targets.pose_source),
            ("trajectory", targets.trajectory, targets.trajectory_source),
        ):
            if readings is None:
                parts.append((mode, None, None, None))
                continue
            started = time.perf_counter()
            tcp, _ = compute_tcp(robot, result.draws, mode, readings=readings, tool_mm=targets.tool_mm)
            provenance = {**base, mode: source, "mode": mode, "seconds": round(time.perf_counter() - started, 3)}
            parts.append((mode, tcp, None, provenance))
            report("tcp", len(parts), None, mode)
        started = time.perf_counter()
        values = result.draws if targets.workspace_draws is None else result.draws[: targets.workspace_draws]
        tcp, ws = compute_tcp(
            robot,
            values,
            "workspace",
            n_poses=targets.workspace_poses,
            seed=seeds["workspace"],
            tool_mm=targets.tool_mm,
        )
        provenance = {**base, "mode": "workspace", "seconds": round(time.perf_counter() - started, 3)}
        if values.shape[0] < result.n_draws:
            provenance["draws_used"] = int(values.shape[0])
        parts.append(("workspace", tcp, ws, provenance))
        consistency = validation_consistency(
            scenario,
            state["validation"],
            state["refined"]["points"],
            result.draws,
            model="refined (CPA + points refinement)",
        )
        consistency["draws_file"] = "uncertainty-refined/draws.npz"
        consistency["validation_file"] = "validation.csv"
        with atomic_directory(out / "tcp") as folder:
            (folder / "consistency.json").write_text(json.dumps(consistency, indent=2) + "\n", encoding="utf-8")
            for mode, tcp, ws, provenance in parts:
                if tcp is None:
                    continue
                (folder / mode).mkdir()
                write_tcp_folder(folder / mode, tcp, mode, workspace=ws, provenance=provenance)
        state["tcp"] = {mode: (tcp, ws) for mode, tcp, ws, _ in parts if tcp is not None}
        state["consistency"] = consistency
        report("tcp", 3, None, "workspace")
        return ", ".join(mode for mode, tcp, _, _ in parts if tcp is not None)

    def plan_stage():
        # the capture plan in the cell (thesis 4.5.2) and how its J4 sweep drives the uncertainty (5.2.4)
        from robotcal.planning.cell import check_plan
        from robotcal.planning.scenario import cell_from_scenario, scenario_document
        from robotcal.planning.sensitivity import run_sensitivity, study_rows
        from robotcal.report.planning import (
            check_document,
            plot_check,
            plot_sensitivity,
            write_check_files,
            write_sensitivity_files,
        )

        cell, notes = cell_from_scenario(scenario)
        check = check_plan(robot, scenario.plan, cell)
        report("plan", 1, None, "cell check")
        document, base_dir, name, source = scenario_document(scenario.source)
        study = run_sensitivity(
            document,
            base_dir,
            name,
            source,
            [(PLAN_SENSITIVITY_KEY, list(PLAN_SENSITIVITY_VALUES))],
            seed=seeds["montecarlo"],
            iterations=min(PLAN_SENSITIVITY_DRAWS, plan.montecarlo.iterations),
        )
        rows = study_rows(study)
        with atomic_directory(out / "plan") as folder:
            check_json = check_document(check, scenario=scenario.source, cell=cell, notes=notes)
            write_check_files(folder, check, check_json)
            plot_check(check, folder / "plan_check.png", acceptance_deg=check_json["cell"]["acceptance_deg"])
            (folder / "sensitivity").mkdir()
            summary = {
                "scenario": scenario.source,
                "keys": list(study.keys),
                "seed": seeds["montecarlo"],
                "length_limit_mm": study.length_limit_mm,
                "angle_limit_deg": study.angle_limit_deg,
                "cases": [dict(case.values, draws=case.n_draws) for case in study.cases],
                "model": "CPA (thesis ch. 5.2.4)",
            }
            write_sensitivity_files(folder / "sensitivity", rows, summary)
            plot_sensitivity(rows, study.keys, folder / "sensitivity")
        bad = int((~check.ok).sum())
        state["plan_notes"] = notes
        verdict = "feasible in the cell" if bad == 0 else f"{bad} of {check.ok.size} points fail a cell check"
        return f"{verdict}; sensitivity to the J4 sweep, {len(study.cases)} cases"

    def report_stage():
        from robotcal.report.html import build_report

        built = build_report(out)
        state["report"] = built
        return f"{built.figures} figures"

    functions = {
        "simulate": simulate_stage,
        "identify": identify_stage,
        "refine": refine_stage,
        "evaluate": evaluate_stage,
        "joints": joints_stage,
        "uncertainty": uncertainty_stage,
        "tcp": tcp_stage,
        "plan": plan_stage,
        "report": report_stage,
    }
    for name in STAGES:
        record.stage(name, status="running")
        record.write()
        report(name, 0, None, "running")
        started = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                detail = functions[name]()
            except BaseException as exc:
                seconds = round(time.perf_counter() - started, 3)
                message = _message(exc)
                record.stage(name, status=_status(exc), seconds=seconds, error=message)
                try:
                    exc.robotcal_stage = name  # run_and_print names the stage in its message
                except AttributeError:
                    pass
                record.data.update(
                    status=_status(exc),
                    failed_stage=name,
                    error=message,
                    seconds=round(time.perf_counter() - run_started, 3),
                )
                record.write()
                raise
        messages = list(dict.fromkeys(str(w.message) for w in caught))
        record.stage(
            name,
            status="done",
            seconds=round(time.perf_counter() - started, 3),
            outputs=[entry for entry in OUTPUTS[name] if (out / entry).exists()],
            detail=detail,
            **({"warnings": messages} if messages else {}),
        )
        if name == "report":
            record.data.update(status="done", seconds=round(time.perf_counter() - run_started, 3))
        record.write()
        report(name, -1, None, detail)
    # run.json changed after the report was built (its status and time): rebuild it so both agree
    from robotcal.report.html import build_report

    state["report"] = build_report(out)
    record.data["finished"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    return {**record.data, "_state": state}


def run_with_display(plan: RunPlan) -> dict:
    """:func:`execute_run` under one Rich progress display (a task per stage; draws for the Monte Carlo)."""
    columns = (
        SpinnerColumn(finished_text="[green]✓[/green]"),
        TextColumn("{task.fields[stage]:<12}", markup=False),
        BarColumn(bar_width=30),
        MofNCompleteColumn(),
        TextColumn("{task.fields[unit]}", markup=False),
        TimeElapsedColumn(),
        TextColumn("{task.fields[detail]}", style="dim", markup=False),
    )
    with Progress(*columns, console=console, transient=False) as display:
        tasks = {}
        for name in STAGES:
            total = (
                plan.montecarlo.iterations + plan.refined_montecarlo.iterations
                if name == "uncertainty"
                else STEPS[name]
            )
            unit = "draws" if name == "uncertainty" else "steps"
            tasks[name] = display.add_task(name, total=total, stage=name, unit=unit, detail="", start=False)

        def update(stage: str, done: int, total: int | None, detail: str = "") -> None:
            task = tasks[stage]
            if done == 0 and detail == "running":
                display.start_task(task)
                return
            if done < 0:  # stage finished
                display.update(task, completed=display.tasks[task].total, detail=detail)
                display.stop_task(task)
                return
            display.update(task, completed=done, detail=detail if stage != "uncertainty" else "")

        try:
            return execute_run(plan, progress=update)
        except BaseException:
            for task in display.tasks:
                if task.started and not task.finished:
                    display.update(task.id, detail="failed")
                    display.stop_task(task.id)
            raise


def _summary(data: dict) -> None:
    state = data["_state"]
    stages = Table(title="Stages", title_justify="left")
    for column in ("stage", "status", "time (s)", "result"):
        stages.add_column(column, justify="right" if column == "time (s)" else "left")
    for name, entry in data["stages"].items():
        stages.add_row(name, entry["status"], f"{entry['seconds']:.1f}", str(entry.get("detail") or ""))
    console.print(stages)
    warned = {message for entry in data["stages"].values() for message in entry.get("warnings", [])}
    for message in (*sorted(warned), *data.get("notes", [])):  # recorded in run.json; the run went on
        error_console.print(f"note: {message}", highlight=False)
    headline = state.get("headline")
    if headline:
        console.print(
            f"how good: mean validation error {headline['before_mean_mm']:.4f} mm (nominal) -> "
            f"{headline['after_mean_mm']:.4f} mm (refined, points criterion)",
            highlight=False,
        )
    for key, label in (("montecarlo_refined", "refined (deployed) model"), ("montecarlo", "CPA model")):
        mc = state.get(key)
        if mc is None:
            continue
        lengths = mc.identified.copy()
        lengths[:, [1, 3, 4]] = False
        angles = mc.identified & ~lengths
        console.print(
            f"how sure, {label}: largest standard uncertainty {mc.summary.std_uncertainty[lengths].max():.4f} mm "
            f"(lengths), {np.rad2deg(mc.summary.std_uncertainty[angles].max()):.4f} deg (angles); "
            f"{mc.n_draws:,} draws",
            highlight=False,
        )
    check = state.get("consistency")
    if check:
        console.print(
            f"consistency at the {check['poses']} validation poses: predicted RMS position uncertainty "
            f"{check['predicted_rms_mm']:.4f} mm, with the instrument {check['expected_rms_mm']:.4f} mm; "
            f"observed RMS error {check['observed_rms_mm']:.4f} mm",
            highlight=False,
        )
    tcp = state.get("tcp", {})
    if "pose" in tcp:
        console.print(
            f"TCP position uncertainty at the pose (refined model): {tcp['pose'][0].position_uncertainty[0]:.4f} mm",
            highlight=False,
        )
    if "workspace" in tcp:
        values = tcp["workspace"][0].position_uncertainty
        p50, p95 = np.percentile(values, [50, 95])
        console.print(
            f"where: over {values.size} workspace poses the TCP position uncertainty is {p50:.4f} mm (median), "
            f"{p95:.4f} mm (95th percentile), {values.max():.4f} mm (worst)",
            highlight=False,
        )


def _command_line(command: str, *arguments, **options) -> str:
    """The command as a user would type it, for ``run.json``."""
    parts = ["robotcal", command, *(str(a) for a in arguments if a is not None)]
    for name, value in options.items():
        if value is not None:
            parts += [f"--{name}", str(value)]
    return " ".join(parts)


def run_and_print(plan: RunPlan) -> dict:
    """The ``run``/``demo`` command body: display, summary, and the report's path and total time."""
    started = time.perf_counter()
    console.rule(f"robotcal run {plan.scenario.name}: {plan.scenario.description}")
    try:
        data = run_with_display(plan)
    except RobotcalError as exc:
        if not hasattr(exc, "robotcal_stage"):
            raise  # refused before any stage ran (output policy, lock)
        record = json.loads((plan.out / "run.json").read_text(encoding="utf-8"))
        stage = record.get("failed_stage", "?")
        done = [name for name, entry in record["stages"].items() if entry["status"] == "done"]
        raise RobotcalError(
            f"stage {stage!r} failed: {exc}. Earlier stages ({', '.join(done) or 'none'}) are intact in "
            f"{plan.out}; {plan.out / 'run.json'} records the failure"
        ) from None
    _summary(data)
    report = data["_state"]["report"]
    console.print(
        f"wrote {report.path.resolve()} (open it in a browser) in {time.perf_counter() - started:.1f} s",
        highlight=False,
        soft_wrap=True,
    )
    return data


@app.command("run")
@handle_errors
def run(
    scenario: Annotated[str, typer.Argument(help="Built-in scenario name or scenario TOML path.")],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Run folder to write (a run folder of robotcal's is replaced).")
    ],
    seed: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=SEED_BOUND - 1 - max(SEED_OFFSETS.values()),
            help="Seed of the whole run (capture N, truth N+1, validation N+2, Monte Carlo N+3, workspace N+4).",
        ),
    ] = None,
    draws: Annotated[
        int | None,
        typer.Option("--draws", min=1, help="Monte Carlo draws (default: the scenario's montecarlo.iterations)."),
    ] = None,
    workspace: Annotated[
        int | None,
        typer.Option("--workspace", min=1, help="Random workspace poses (default: tcp.workspace_poses, 1000)."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", min=1, help="Monte Carlo worker processes (default: CPU count, at most 4)."),
    ] = None,
    refined_draws: Annotated[
        int | None,
        typer.Option(
            "--refined-draws",
            min=1,
            help=f"Draws of the refined-model Monte Carlo (default: {REFINED_DRAWS:,}, at most --draws).",
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Run the whole pipeline (simulate, CPA, refine, evaluate, joints, Monte Carlo, TCP) and write DIR/report.html."""
    plan = prepare_run(
        scenario,
        out,
        seed=seed,
        draws=draws,
        workspace=workspace,
        workers=workers,
        refined_draws=refined_draws,
        command=_command_line(
            "run",
            scenario,
            out=out,
            seed=seed,
            draws=draws,
            workspace=workspace,
            workers=workers,
            refined_draws=refined_draws,
        ),
        force=force,
    )
    run_and_print(plan)
