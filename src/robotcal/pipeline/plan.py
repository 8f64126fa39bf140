"""Plan a calibration run: load and check everything it needs before any computation (nothing is written).

:func:`plan_run` is the one place that turns a scenario and the run options (``robotcal run``'s) into a
:class:`RunPlan`; the constants that shape a run (stages, their outputs, derived seeds, the refined Monte
Carlo's draws, the plan stage's sensitivity study) live here.
"""

from __future__ import annotations

import dataclasses
import operator
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robotcal.errors import InputError
from robotcal.io.results.output import check_output_folder, existing_inputs
from robotcal.io.results.run_folder import OUTPUTS, RUN_RECORD, STAGES
from robotcal.io.schema.scenario import Scenario, ValidationTable, load_scenario
from robotcal.limits import (
    BYTES_PER_POSE,
    REFINED_DRAWS,
    SEED_BOUND,
    SEED_OFFSETS,
    check_memory,
    monte_carlo_bytes,
    pairs_bytes,
)
from robotcal.resolve import TCPTargets, seed_from, tcp_targets, validation_target
from robotcal.uncertainty.montecarlo import MonteCarloSettings

__all__ = [
    "OUTPUTS",
    "PLAN_SENSITIVITY_DRAWS",
    "PLAN_SENSITIVITY_KEY",
    "PLAN_SENSITIVITY_VALUES",
    "REFINED_DRAWS",
    "RUN_RECORD",
    "SEED_OFFSETS",
    "STAGES",
    "STEPS",
    "RunPlan",
    "TCPTargets",
    "plan_run",
    "tcp_targets",
]

#: Steps per stage for a progress display (the Monte Carlo counts draws instead).
STEPS = {"simulate": 4, "identify": 1, "joints": 1, "refine": 2, "evaluate": 1, "tcp": 3, "plan": 2, "iso9283": 1, "report": 1}
#: The plan stage's sensitivity study (thesis Fig. 5.15): the angle joint 4 covers, Monte Carlo draws per case.
PLAN_SENSITIVITY_KEY = "capture.sweep_deg.4"
PLAN_SENSITIVITY_VALUES = (15.0, 50.0, 90.0, 180.0)
PLAN_SENSITIVITY_DRAWS = 2_000


@dataclass(frozen=True, slots=True, kw_only=True)
class RunPlan:
    """A checked run: the scenario, the output folder, the seeds and the stage settings.

    Attributes
    ----------
    scenario : Scenario
    out : Path or None
        The run folder; None for a plan only studied (:func:`robotcal.pipeline.run_calibration` refuses it).
    seeds : dict
        ``capture``, ``truth`` (None without a ``[truth]`` table), ``validation``, ``montecarlo``, ``workspace``.
    montecarlo, refined_montecarlo : MonteCarloSettings
        The CPA-model and the refined-model Monte Carlo.
    tcp : TCPTargets
        Where the TCP uncertainty is stated (pose, trajectory, workspace) [rad, mm].
    backlash : bool
        Whether the joints stage analyses backlash (a bidirectional capture plan).
    command : str
        The command line recorded in ``run.json``.
    force : bool
        Replace an output folder robotcal did not write (:mod:`robotcal.io.results.output`).
    inputs : tuple of Path
        The files the run reads (the scenario and the robot it names): never replaced by its output.
    """

    scenario: Scenario
    out: Path | None
    seeds: dict
    montecarlo: MonteCarloSettings
    refined_montecarlo: MonteCarloSettings
    tcp: TCPTargets
    backlash: bool
    command: str
    force: bool = False
    inputs: tuple = ()


def plan_run(
    scenario: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
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

    Parameters
    ----------
    scenario : str or path
        Built-in scenario name or scenario TOML.
    out : path, optional
        The run folder. Checked against the output policy of :mod:`robotcal.io.results.output` (a folder robotcal
        wrote is replaced stage by stage; another is refused unless ``force``); None plans without a folder.
    seed : int, optional
        Seed of the whole run: capture ``seed``, truth ``seed + 1``, validation ``+ 2``, Monte Carlo ``+ 3``,
        workspace ``+ 4``, ISO 9283 study ``+ 5`` (:data:`SEED_OFFSETS`); default: the scenario's seeds.
    draws : int, optional
        Monte Carlo draws (default: the scenario's ``montecarlo.iterations``).
    workspace : int, optional
        Random workspace poses of the TCP stage (default: ``tcp.workspace_poses``).
    workers : int, optional
        Monte Carlo worker processes (default: the CPU count, at most 4).
    refined_draws : int, optional
        Draws of the refined-model Monte Carlo (default: the scenario's ``montecarlo.refined_iterations``, else
        :data:`REFINED_DRAWS`; at most ``draws``).
    command : str
        The command line recorded in ``run.json``.
    force : bool
        See ``out``.

    Returns
    -------
    RunPlan

    Raises
    ------
    InputError
        Naming the file and key: scenario keys, validation target, TCP pose and trajectory, Monte Carlo
        settings, seeds, the memory each stage needs, the output folder.
    """
    if not isinstance(scenario, str | os.PathLike):
        raise InputError(
            f"plan_run takes a scenario name or TOML path; got {type(scenario).__name__} (a run records and re-reads "
            "its scenario files: write a changed scenario to TOML first)"
        )
    if seed is not None:
        try:
            seed = operator.index(seed)  # an int (numpy integers too); never a float or a string
        except TypeError:
            raise InputError(f"seed must be an integer in [0, 2^63); got {seed!r}") from None
    inputs = existing_inputs(scenario)
    if out is not None:
        out = Path(out)
        check_output_folder(out, inputs=inputs, force=force, keeps_other_files=True)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    if out is not None:
        check_output_folder(out, inputs=inputs, force=force, keeps_other_files=True)
    robot = loaded.robot
    if not loaded.has_plan:  # first: any use of the missing plan raises simulate's message (`capture.start_deg`)
        _ = loaded.plan.points
    validation_target(loaded)  # a validation capture needs a flange target
    validation = loaded.validation or ValidationTable()
    if not np.all(np.isfinite(robot.limits)):
        raise InputError(
            f"{loaded.source}: robot {robot.name!r} needs finite `limits_deg` on every joint for the random "
            "validation poses"
        )
    if np.any(robot.limits[:, 1] - robot.limits[:, 0] <= 2 * np.deg2rad(validation.margin_deg)):
        raise InputError(f"{loaded.source}: key `validation.margin_deg` leaves no room within the joint limits")
    seeds = _seeds(loaded, seed, validation)
    targets = tcp_targets(loaded)
    if seeds["workspace"] is None:
        seeds["workspace"] = targets.workspace_seed
    if workspace is not None:
        if workspace < 1:
            raise InputError(f"--workspace must be a positive number of poses; got {workspace}")
        targets = dataclasses.replace(targets, workspace_poses=workspace)
    settings, refined_settings = _monte_carlo_settings(loaded, draws, workers, refined_draws)
    _check_tcp(loaded, targets, settings)
    _check_memory(loaded, targets, settings, validation)  # the refined Monte Carlo has at most as many draws
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


def _seeds(loaded: Scenario, seed: int | None, validation: ValidationTable) -> dict[str, int | None]:
    """The seed of every stage: ``seed`` plus each stage's offset (:data:`SEED_OFFSETS`), else the scenario's."""
    seeds: dict[str, int | None]
    if seed is not None:
        seeds = {name: seed + offset for name, offset in SEED_OFFSETS.items()}
    else:
        capture = seed_from(loaded.seed)
        seeds = {
            "capture": capture,
            "truth": None if loaded.truth is None else seed_from(loaded.truth.seed),
            "validation": seed_from(validation.seed),
            "montecarlo": seed_from(loaded.montecarlo.seed),
            "workspace": None,
            # the ISO 9283 study (joint errors and noise of its visits): derived from the capture seed
            "iso9283": (capture + SEED_OFFSETS["iso9283"]) % SEED_BOUND,
            "poses": None if loaded.calibration_poses is None else seed_from(loaded.calibration_poses.seed),
        }
    if loaded.truth is None:
        seeds["truth"] = None
    if loaded.calibration_poses is None:
        seeds["poses"] = None
    for name, value in seeds.items():
        if value is not None and not 0 <= value < SEED_BOUND:
            raise InputError(f"{loaded.source}: the {name} seed {value} is outside [0, 2^63)")
    return seeds


def _monte_carlo_settings(
    loaded: Scenario, draws: int | None, workers: int | None, refined_draws: int | None
) -> tuple[MonteCarloSettings, MonteCarloSettings]:
    """The settings of the CPA-model and of the refined-model Monte Carlo, built once here and passed unchanged to
    :func:`robotcal.api.monte_carlo` by the uncertainty stage; an error names the option or the scenario key."""
    iterations = loaded.montecarlo.iterations if draws is None else draws
    try:
        settings = MonteCarloSettings(
            iterations=iterations,
            coverage=loaded.montecarlo.coverage,
            workers=min(os.cpu_count() or 1, 4) if workers is None else workers,
        )
    except InputError as exc:
        where = "--draws" if draws is not None else f"{loaded.source}: Monte Carlo settings"
        raise InputError(f"{where}: {exc}") from None
    if refined_draws is not None and not 1 <= refined_draws <= iterations:
        raise InputError(
            f"--refined-draws must be between 1 and the Monte Carlo draws ({iterations:,}); got {refined_draws}"
        )
    default_refined = loaded.montecarlo.refined_iterations or REFINED_DRAWS
    try:
        refined_settings = dataclasses.replace(
            settings, iterations=min(iterations, default_refined) if refined_draws is None else refined_draws
        )
    except InputError as exc:
        where = "--refined-draws" if refined_draws is not None else f"{loaded.source}: montecarlo.refined_iterations"
        raise InputError(f"{where}: {exc}") from None
    return settings, refined_settings


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


def _check_memory(
    loaded: Scenario, targets: TCPTargets, settings: MonteCarloSettings, validation: ValidationTable
) -> None:
    """Estimate the memory of the large stages up front (:func:`robotcal.limits.check_memory`)."""
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
    poses = validation.poses
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
