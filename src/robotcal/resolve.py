"""How the front door (:mod:`robotcal.api`) resolves its arguments, once, before it calls the core.

A call takes explicit objects or a :class:`~robotcal.io.schema.scenario.Scenario` in place of the robot; these functions
turn what was given into what the core takes: the robot and the scenario of a ``robot`` argument, a capture from a
Capture or a CSV path, parameters from a ParameterSet, a result or a JSON path, an ``rng`` into an int seed, and a
scenario's tables into the targets, the masses and the TCP poses (``[tcp]``) its captures and stages need. Numbers
given in degrees are converted here; what leaves is in the core's units, mm and radians.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar, cast

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture, join_captures
from robotcal.errors import InputError, JointLimitWarning
from robotcal.identification.settings import ModelChoiceSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.formats.trajectory_csv import builtin_trajectories, load_trajectory
from robotcal.io.schema.robots import load_robot
from robotcal.io.schema.scenario import CalibrationPosesTable, JointModelTable, Scenario, TCPTable, ValidationTable
from robotcal.kinematics.model import LinkMasses, ParameterSet, ReflectorMount, RobotModel
from robotcal.limits import SEED_BOUND
from robotcal.uncertainty.tcp import check_readings

if TYPE_CHECKING:
    from robotcal.identification.cpa import CPAResult
    from robotcal.identification.records import RefinementResult
    from robotcal.kinematics.joint_model import JointModel
    from robotcal.programs.filter import FilteredProgram
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

__all__ = [
    "DEFAULT_TRAJECTORY",
    "KUKA_CONTROLLER_ROBOT",
    "TABLE_5_8_READINGS_DEG",
    "ParameterSource",
    "TCPTargets",
    "as_capture",
    "as_parameters",
    "calibrated_parameters",
    "calibration_capture",
    "capture_targets",
    "compensation_targets",
    "convert_readings",
    "free_pose_table",
    "link_masses",
    "monte_carlo_settings",
    "needed",
    "parameter_draws",
    "program_tcp_uncertainty",
    "refinement_targets",
    "scenario_instrument",
    "simulation_inputs",
    "seed_from",
    "split_robot",
    "target_name",
    "tcp_targets",
    "true_offsets",
    "validation_target",
]

T = TypeVar("T")

#: What a ``parameters`` (or ``start``) argument takes: a ParameterSet, a CPA or refinement result holding one, the
#: path of a parameter JSON, or None (the nominal parameters; where the argument may be None).
ParameterSource: TypeAlias = "ParameterSet | CPAResult | RefinementResult | str | os.PathLike[str] | None"

#: Robot whose readings are KUKA controller angles; the thesis's Table 5.8 pose and the built-in
#: trajectories are given in its readings.
KUKA_CONTROLLER_ROBOT = "kuka-kr5-sixx-r650-krc"
#: Thesis Table 5.8 pose, KUKA controller readings A1..A6 [deg] (the text's "68" is a misprint: docs/conventions.md).
TABLE_5_8_READINGS_DEG = (60.0, 80.0, -45.0, 200.0, 125.0, 280.0)
#: Built-in 75-pose trajectory of the TCP stage (docs/tcp.md), KUKA controller readings.
DEFAULT_TRAJECTORY = "kr5-sweep-75"


def seed_from(rng: np.random.Generator | int | None, default: int | None = None) -> int:
    """The int seed a core function takes, from an ``rng`` argument.

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        None: ``default`` when given (a seed the scenario records), else fresh entropy; an int: that
        seed; a Generator: ``rng.integers(2**63)`` (the Generator advances, so two calls with one
        Generator give two different, reproducible seeds).
    default : int, optional

    Returns
    -------
    int
        A seed in ``[0, 2**63)``, to record with the result.

    Examples
    --------
    >>> import numpy as np
    >>> from robotcal.api import seed_from
    >>> seed_from(7)
    7
    >>> seed_from(None, default=3)
    3
    >>> a = seed_from(np.random.default_rng(1))
    >>> a == seed_from(np.random.default_rng(1))
    True
    """
    if rng is None:
        if default is not None:
            return seed_from(default)
        return int(cast(int, np.random.SeedSequence().entropy) % SEED_BOUND)
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(SEED_BOUND))
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer):
        raise InputError(f"`rng` must be None, an int seed or a numpy.random.Generator; got {type(rng).__name__}")
    if not 0 <= int(rng) < SEED_BOUND:
        raise InputError(f"`rng` seed must be in [0, 2**63); got {rng}")
    return int(rng)


def split_robot(robot: RobotModel | Scenario) -> tuple[RobotModel, Scenario | None]:
    """The robot and the scenario (None) of a ``robot`` argument: a RobotModel or a Scenario."""
    if isinstance(robot, Scenario):
        return robot.robot, robot
    if isinstance(robot, RobotModel):
        return robot, None
    raise InputError(
        "`robot` must be a RobotModel (robotcal.load_robot) or a Scenario (robotcal.load_scenario); "
        f"got {type(robot).__name__}"
    )


def needed(value: T | None, name: str, scenario: Scenario | None, what: Callable[[Scenario], T]) -> T:
    """``value``, else the scenario's ``what`` (a callable of the scenario), else an error naming ``name``."""
    if value is not None:
        return value
    if scenario is None:
        raise InputError(f"`{name}` is needed (or give a Scenario in place of the robot)")
    return what(scenario)


def as_capture(capture: Capture | str | os.PathLike, robot: RobotModel, name: str = "capture") -> Capture:
    """A Capture from a Capture or a capture CSV path (read with the robot's joint count)."""
    if isinstance(capture, Capture):
        return capture
    if isinstance(capture, str | os.PathLike):
        from robotcal.io.formats.capture_csv import read_capture

        return read_capture(capture, n_joints=robot.n_joints)
    raise InputError(f"`{name}` must be a Capture or the path of a capture CSV; got {type(capture).__name__}")


def as_parameters(parameters: ParameterSource, robot: RobotModel, name: str = "parameters") -> ParameterSet:
    """A ParameterSet from a ParameterSet, a result holding one, a parameter JSON path, or None (nominal)."""
    if parameters is None:
        return ParameterSet.nominal(robot)
    held = getattr(parameters, "parameters", None)
    if isinstance(held, ParameterSet):  # CPAResult, RefinementResult
        parameters = held
    elif isinstance(parameters, str | os.PathLike):
        from robotcal.io.formats.parameters_json import read_parameters

        return read_parameters(parameters, robot)
    if not isinstance(parameters, ParameterSet):
        raise InputError(
            f"`{name}` must be a ParameterSet, a CPA or refinement result, or the path of a parameter JSON; "
            f"got {type(parameters).__name__}"
        )
    if parameters.robot.n_joints != robot.n_joints:
        raise InputError(
            f"`{name}` belong to robot {parameters.robot.name!r} ({parameters.robot.n_joints} joints); "
            f"the robot {robot.name!r} has {robot.n_joints}"
        )
    return parameters


def scenario_instrument(instrument: Instrument | None, scenario: Scenario | None) -> Instrument | None:
    """``instrument``, else the scenario's when it declares one."""
    if instrument is not None or scenario is None:
        return instrument
    return scenario.instrument if scenario.has_instrument else None


def calibrated_parameters(parameters: ParameterSource, robot: RobotModel | Scenario | None) -> ParameterSet:
    """The calibrated model of ``compensate`` and ``filter_program``: a ParameterSet, a result holding one, or a
    parameter JSON path read for ``robot`` (a RobotModel or a Scenario)."""
    if robot is None:
        held = getattr(parameters, "parameters", parameters)
        if not isinstance(held, ParameterSet):
            raise InputError("`parameters` must be a ParameterSet or a result holding one (a JSON path needs `robot`)")
        robot = held.robot
    else:
        robot, _ = split_robot(robot)
    return as_parameters(parameters, robot, "parameters")


def validation_target(scenario: Scenario) -> ReflectorMount:
    """The flange target of a scenario's captures at free poses: ``[validation].flange_reflector_mm``, else the
    plan's (or ``[capture]``'s) reflector when it is a flange one, else the only known flange target of
    ``[[targets]]``."""
    if scenario.validation is not None:
        return ReflectorMount(frame="flange", positions=np.asarray(scenario.validation.flange_reflector_mm))
    reflector = scenario.plan.reflector if scenario.has_plan else scenario.reflector
    if reflector is not None and reflector.frame == "flange":
        return reflector
    flange = [t for t in scenario.targets if t.frame == "flange" and t.known]
    if reflector is None and len(flange) == 1:
        return flange[0].mount
    raise InputError(
        f"{scenario.source}: a capture at free poses (circle = 0) needs a flange target: add a [validation] table "
        "with `flange_reflector_mm`, use a scenario with `capture.flange_reflector_mm`, or give the capture a "
        "`target` column naming [[targets]] entries"
    )


def capture_targets(scenario: Scenario, capture: Capture) -> ReflectorMount | Target | tuple[Target, ...]:
    """The target(s) the points of ``capture`` were measured on, as the scenario declares them.

    * a ``target`` column: the scenario's declared targets (each point names one);
    * free poses (circle = 0): the validation flange target (:func:`validation_target`), or the
      only ``[[targets]]`` entry (whose offset may be unknown);
    * circles: the plan's reflector, else ``[capture]``'s, else the only ``[[targets]]`` entry.
    """
    if capture.target is not None:
        return scenario.targets
    declared = [t for t in scenario.targets if t.name not in ("capture", "validation")]
    if np.any(capture.circle == 0):
        if len(declared) == 1 and scenario.validation is None and scenario.reflector is None:
            return declared[0]
        return validation_target(scenario)
    if scenario.has_plan:
        return scenario.plan.reflector
    if scenario.reflector is not None:
        return scenario.reflector
    if len(declared) == 1:
        return declared[0]
    raise InputError(
        f"{scenario.source}: which target was measured? declare one (`capture.flange_reflector_mm`, "
        "`capture.reflector_mm` or one [[targets]] entry) or give the capture a `target` column"
    )


def refinement_targets(
    scenario: Scenario | None, capture: Capture, targets: Any, tracker_from_base: np.ndarray | None
) -> tuple[Any, np.ndarray | None]:
    """The targets and the held base frame of a refinement of ``capture``: those given, else the scenario's (its
    :func:`capture_targets`; its ``tracker_from_base`` where ``base_frame = "given"``). InputError without targets."""
    if scenario is not None:
        targets = capture_targets(scenario, capture) if targets is None else targets
        if tracker_from_base is None and scenario.identification.base_frame == "given":
            tracker_from_base = scenario.tracker_from_base
    if targets is None:
        raise InputError("`targets` is needed: where the points were measured (a ReflectorMount or Targets)")
    return targets, tracker_from_base


def calibration_capture(
    scenario: Scenario, capture: Capture | str | os.PathLike, poses: Capture | str | os.PathLike | None = None
) -> Capture:
    """The capture a refinement fits: the circles (or any capture) and, when given, the free calibration poses
    (:func:`simulate_poses` with ``kind="calibration"``, or measured), one after the other with a ``target``
    column. A part without its own column takes the name of the scenario target it was measured on."""
    parts = [capture] if poses is None else [capture, poses]
    named = []
    for part in parts:
        part = as_capture(part, scenario.robot)
        named.append((part, None if part.target is not None else target_name(scenario, part)))
    if len(named) == 1 and named[0][1] is None:
        return named[0][0]
    return join_captures(named, source=" + ".join(part.source for part, _ in named))


def target_name(scenario: Scenario, capture: Capture) -> str:
    """The name, among the scenario's targets, of the one target of a capture without a ``target`` column."""
    target = capture_targets(scenario, capture)
    if isinstance(target, Target):
        return target.name
    target = cast(ReflectorMount, target)  # a capture without a target column has one target
    for declared in scenario.targets:
        if declared.frame == target.frame and np.array_equal(
            np.reshape(declared.positions, (-1, 3)), np.reshape(target.positions, (-1, 3))
        ):
            return declared.name
    raise InputError(f"{capture.source}: its target is none of the scenario's named targets; give it a target column")


def link_masses(robot: RobotModel | Scenario, scenario: Scenario | None = None) -> LinkMasses | None:
    """The link masses of the extended model: the robot file's, with the scenario's ``[payload]`` on the flange
    (None when the robot file gives no masses: the compliance is then the lumped form)."""
    model, scenario = split_robot(robot) if scenario is None else (cast(RobotModel, robot), scenario)
    masses = model.masses
    payload = None if scenario is None else scenario.payload
    if masses is None or payload is None:
        return masses
    return masses.with_payload(payload.mass_kg, payload.com_mm)


def parameter_draws(
    draws: Any, robot: RobotModel, limit: int | None = None
) -> tuple[np.ndarray, JointModel | None, np.ndarray | None]:
    """Parameter draws (n_draws, n_joints, 5) [mm, rad] from a result, a draws file or an array, with an extended
    model's joint model and its values in every draw ``(n_draws, m)`` (None, None for the geometric model);
    ``limit``: the first draws only.

    Draws that name their robot (a Monte Carlo result, a draws file) must be of ``robot``'s model (same
    joint types and nominal parameters; its reading map may differ, e.g. controller readings).
    """
    source = getattr(draws, "robot", None)
    joint_model = extras = None
    if isinstance(draws, str | os.PathLike):
        from robotcal.io.formats.draws_npz import read_draws

        read = read_draws(draws)
        values, source, joint_model, extras = read.values, read.robot, read.joint_model, read.extras
    elif hasattr(draws, "draws") and hasattr(draws, "summary"):  # a MonteCarloResult
        if draws.draws is None:
            raise InputError("`draws`: this Monte Carlo result kept no draws; run monte_carlo(..., keep_draws=True)")
        values = draws.draws
        if draws.is_extended:
            joint_model, extras = draws.joint_model, draws.extra_draws
    else:
        values = getattr(draws, "values", draws)  # a ParameterDraws, or an array
    values = np.asarray(values, dtype=float)
    if values.ndim != 3 or values.shape[1:] != (robot.n_joints, 5):
        raise InputError(
            f"`draws` must be a MonteCarloResult, a draws.npz path or an array of shape (n_draws, "
            f"{robot.n_joints}, 5) [mm, rad]; got shape {values.shape}"
        )
    if isinstance(source, RobotModel) and not (
        np.array_equal(source.hayati, robot.hayati) and np.allclose(source.nominal, robot.nominal, rtol=0, atol=1e-9)
    ):
        raise InputError(
            f"`draws` are parameters of robot {source.name!r}, whose model differs from robot {robot.name!r}'s"
        )
    if extras is not None and extras.shape[0] != values.shape[0]:
        raise InputError(f"`draws`: {extras.shape[0]} joint-model draws for {values.shape[0]} parameter draws")
    if limit is not None:
        values = values[:limit]
        extras = None if extras is None else extras[:limit]
    return values, joint_model, extras


def program_tcp_uncertainty(
    result: FilteredProgram, robot: RobotModel, controller: RobotModel, draws: Any, frames: dict | None
) -> FilteredProgram:
    """``result`` with every written point's tool position uncertainty at its command, from ``draws``; points are
    grouped by their tool point in the model's flange frame (the propagation takes one tool point per call)."""
    from robotcal.uncertainty.tcp import propagate_to_tcp

    values, joint_model, extras = parameter_draws(draws, robot)
    flange = np.eye(4) if controller.flange_frame is None else controller.flange_frame
    known = {**result.program.frames, **(frames or {})}
    groups: dict[tuple, list[int]] = {}
    for index, record in enumerate(result.points):
        if record.written:
            tool = flange @ (np.eye(4) if record.point.tool not in known else known[record.point.tool])
            groups.setdefault(tuple(np.round(tool[:3, 3], 9)), []).append(index)
    points = list(result.points)
    for tool_mm, members in groups.items():
        commands = np.deg2rad([points[k].command_deg for k in members])
        readings = robot.readings_from_model(controller.model_joint_variables(commands))
        tcp = propagate_to_tcp(
            robot, values, readings, tool=np.array(tool_mm), joint_model=joint_model, extra_draws=extras
        )
        for k, u in zip(members, tcp.position_uncertainty, strict=True):
            points[k] = dataclasses.replace(points[k], tcp_u_mm=float(u))
    return dataclasses.replace(result, points=points)


@dataclass(frozen=True, slots=True, kw_only=True)
class TCPTargets:
    """Where ``robotcal run`` states the TCP uncertainty: readings of the scenario's robot [rad].

    ``pose`` (1, n) and ``trajectory`` (m, n) are ``None`` when the stage part is skipped (the reason
    is in ``notes``); ``*_source`` say where the readings come from.
    """

    pose: np.ndarray | None
    pose_source: str
    trajectory: np.ndarray | None
    trajectory_source: str
    workspace_poses: int
    workspace_draws: int | None
    workspace_seed: int
    tool_mm: np.ndarray | None
    notes: tuple[str, ...] = ()


def _same_geometry(a: RobotModel, b: RobotModel) -> bool:
    return (
        a.n_joints == b.n_joints
        and bool(np.all(a.hayati == b.hayati))
        and np.allclose(a.nominal, b.nominal, rtol=0.0, atol=1e-9)
    )


def convert_readings(readings: np.ndarray, from_robot: RobotModel, to_robot: RobotModel) -> np.ndarray:
    """Readings of ``from_robot`` [rad] as readings of ``to_robot`` [rad], through the model joint
    variables (``q = sign * reading + offset`` of each robot file); both must share the same model."""
    if not _same_geometry(from_robot, to_robot):
        raise InputError(
            f"readings of robot {from_robot.name!r} cannot be used on robot {to_robot.name!r}: "
            "their joint count, joint types or nominal parameters differ"
        )
    return to_robot.readings_from_model(from_robot.model_joint_variables(readings))


def tcp_targets(scenario: Scenario) -> TCPTargets:
    """Resolve and check the ``[tcp]`` table (defaults when absent) before any computation.

    Defaults: the Table 5.8 pose and the trajectory ``kr5-sweep-75``, both KUKA controller readings
    (robot ``kuka-kr5-sixx-r650-krc``), converted to the scenario robot's readings when it has the
    same model (e.g. ``kuka-kr5-sixx-r650``, model q = (-60, -80, 45, -200, 125, -280) deg); for
    another robot without ``pose_deg``/``trajectory`` that part is skipped, with a note. Readings
    outside the limits are noted (the thesis's pose is outside them), not refused.
    """
    table: TCPTable = scenario.tcp
    robot = scenario.robot
    where = f"{scenario.source}: key `tcp"
    notes: list[str] = []
    kuka = load_robot(KUKA_CONTROLLER_ROBOT)
    kuka_compatible = _same_geometry(kuka, robot)
    readings_robot = robot
    if table.readings_robot:
        try:
            readings_robot = load_robot(table.readings_robot)
        except InputError as exc:
            raise InputError(f"{where}.readings_robot`: {exc}") from None
        if not _same_geometry(readings_robot, robot):
            raise InputError(
                f"{where}.readings_robot`: robot {readings_robot.name!r} does not share the model of {robot.name!r}"
            )

    def checked(values: ArrayLike, key: str, source_robot: RobotModel) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if values.ndim != 2 or values.shape[1] != robot.n_joints:
            raise InputError(
                f"{where}.{key}`: {values.shape[-1]} joint readings; robot {robot.name!r} has {robot.n_joints}"
            )
        values = convert_readings(values, source_robot, robot)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", JointLimitWarning)
            try:
                values = check_readings(robot, values, name=f"tcp.{key}")
            except InputError as exc:
                raise InputError(f"{scenario.source}: key {exc}") from None
        notes.extend(str(w.message) for w in caught if issubclass(w.category, JointLimitWarning))
        return values

    pose = trajectory = None
    pose_source = trajectory_source = "skipped"
    if table.pose_deg is not None:
        pose = checked(np.deg2rad([table.pose_deg]), "pose_deg", readings_robot)
        pose_source = f"tcp.pose_deg = {list(table.pose_deg)} (readings of {readings_robot.name})"
    elif kuka_compatible:
        pose = checked(np.deg2rad([TABLE_5_8_READINGS_DEG]), "pose_deg", kuka)
        shown = ", ".join(f"{v:g}" for v in np.rad2deg(pose[0]))
        pose_source = (
            f"thesis Table 5.8 pose, KUKA readings {', '.join(f'{v:g}' for v in TABLE_5_8_READINGS_DEG)} deg "
            f"({KUKA_CONTROLLER_ROBOT}) = readings {shown} deg of {robot.name}"
        )
    else:
        notes.append("no TCP pose: give `tcp.pose_deg` (the Table 5.8 default is for the KR 5 sixx R650)")
    name = table.trajectory
    builtin = name is None or name in builtin_trajectories()
    if name is None and not kuka_compatible:
        notes.append(
            f"no trajectory: give `tcp.trajectory` (the {DEFAULT_TRAJECTORY} default is for the KR 5 sixx R650)"
        )
    else:
        try:
            values, path = load_trajectory(DEFAULT_TRAJECTORY if name is None else name, n_joints=robot.n_joints)
        except InputError as exc:
            raise InputError(f"{where}.trajectory`: {exc}") from None
        trajectory = checked(values, "trajectory", kuka if builtin else readings_robot)
        trajectory_source = (
            f"built-in {DEFAULT_TRAJECTORY if name is None else name} ({path}), KUKA readings converted to {robot.name}"
            if builtin
            else path
        )
    return TCPTargets(
        pose=pose,
        pose_source=pose_source,
        trajectory=trajectory,
        trajectory_source=trajectory_source,
        workspace_poses=table.workspace_poses,
        workspace_draws=table.workspace_draws,
        workspace_seed=table.workspace_seed,
        tool_mm=None if table.tool_mm is None else np.asarray(table.tool_mm, dtype=float),
        notes=tuple(notes),
    )


def compensation_targets(
    robot: RobotModel,
    *,
    poses_deg: ArrayLike | None = None,
    cartesian: ArrayLike | None = None,
    start_deg: ArrayLike | None = None,
    tool_mm: ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool frames a compensation must reach, the readings taught for them and the tool, from joint poses taught
    on the nominal model [deg] or Cartesian targets ``x, y, z`` [mm], ``A, B, C`` [deg, KUKA] (see
    :func:`robotcal.api.compensate`).

    Returns
    -------
    targets : ndarray, shape (n_poses, 4, 4)
        ``base_from_tool`` [mm].
    taught : ndarray, shape (n_poses, n_joints)
        Readings [rad] whose branch the command keeps: the taught poses, or the nominal controller's solution
        nearest ``start_deg`` (an exact one inside the limits before any other).
    tool : ndarray, shape (4, 4)
        ``flange_from_tool`` [mm].
    """
    from robotcal.geometry.euler import matrix_from_kuka_abc
    from robotcal.kinematics.forward import check_joint_variables, forward_kinematics
    from robotcal.kinematics.inverse import nominal_solutions

    if (poses_deg is None) == (cartesian is None):
        raise InputError(
            "give the targets as joint poses (`poses_deg`) or as Cartesian targets (`cartesian`), one of them"
        )
    tool = np.eye(4)
    if tool_mm is not None:
        tool[:3, 3] = np.asarray(tool_mm, dtype=float).reshape(3)
    if poses_deg is not None:
        taught = check_joint_variables(np.deg2rad(np.asarray(poses_deg, dtype=float)), robot.n_joints, "poses_deg")
        return forward_kinematics(robot.nominal, robot.model_joint_variables(taught)) @ tool, taught, tool
    values = np.atleast_2d(np.asarray(cartesian, dtype=float))
    if values.ndim != 2 or values.shape[1] != 6 or not np.all(np.isfinite(values)):
        raise InputError(f"`cartesian` must be finite rows of x, y, z, A, B, C; got shape {values.shape}")
    targets = np.broadcast_to(np.eye(4), (values.shape[0], 4, 4)).copy()
    targets[:, :3, :3] = matrix_from_kuka_abc(np.deg2rad(values[:, 3:]))
    targets[:, :3, 3] = values[:, :3]
    middle = np.where(np.isfinite(robot.limits), robot.limits, 0.0).mean(axis=1)
    seed = middle if start_deg is None else np.deg2rad(np.asarray(start_deg, dtype=float))
    seed = np.broadcast_to(seed, (values.shape[0], robot.n_joints))
    solutions, exists = nominal_solutions(robot, targets @ np.linalg.inv(tool), reference=seed)
    # the nominal controller's solution nearest the seed: an exact one inside the limits before any other
    inside = np.all((solutions >= robot.limits[:, 0]) & (solutions <= robot.limits[:, 1]), axis=-1)
    distance = (
        np.abs(solutions - seed[:, None, :]).max(axis=-1) + np.where(exists, 0.0, 1e6) + np.where(inside, 0.0, 1e3)
    )
    return targets, solutions[np.arange(len(seed)), np.argmin(distance, axis=1)], tool


#: The keywords of :func:`robotcal.api.monte_carlo` that are fields of its MonteCarloSettings.
MONTE_CARLO_KEYWORDS = {
    "draws": "iterations",
    "coverage": "coverage",
    "interval": "interval",
    "adaptive": "adaptive",
    "workers": "workers",
    "scheduler": "scheduler",
    "keep_draws": "keep_draws",
    "batch_size": "batch_size",
}


def monte_carlo_settings(
    settings: MonteCarloSettings | None, scenario: Scenario | None, **given: Any
) -> MonteCarloSettings:
    """The one MonteCarloSettings of a Monte Carlo: ``settings`` unchanged when given (a keyword of ``given`` that
    differs from its field is an InputError naming both), else built once from the keywords (None: not given), the
    scenario's ``[montecarlo]`` table (draws, coverage; without one 10^4 draws and 0.95) and the class's defaults."""
    from robotcal.uncertainty.montecarlo import MonteCarloSettings

    if settings is not None:
        for key, value in given.items():
            field = MONTE_CARLO_KEYWORDS[key]
            if value is not None and value != getattr(settings, field):
                raise InputError(
                    f"`settings` and `{key}` disagree: settings.{field} = {getattr(settings, field)!r}, {key} = "
                    f"{value!r}; give the value in one of them"
                )
        return settings
    table = None if scenario is None else scenario.montecarlo
    values = {MONTE_CARLO_KEYWORDS[key]: value for key, value in given.items() if value is not None}
    values["iterations"] = int(values.get("iterations", table.iterations if table else 10_000))
    values["coverage"] = float(values.get("coverage", table.coverage if table else 0.95))
    return MonteCarloSettings(**values)


def free_pose_table(
    scenario: Scenario | None, kind: str, targets: ReflectorMount | Sequence[Target] | None
) -> tuple[ValidationTable | CalibrationPosesTable, ReflectorMount | Sequence[Target]]:
    """The table (poses, margin, height, seed) and the target(s) of a capture at free poses of ``kind``:
    ``"validation"`` (the scenario's ``[validation]``, else its defaults; the validation target) or
    ``"calibration"`` (the scenario's ``[calibration_poses]`` and its target)."""
    if kind == "calibration":
        if scenario is None or scenario.calibration_poses is None:
            raise InputError("calibration poses are a scenario's [calibration_poses] table: give a scenario with one")
        table: ValidationTable | CalibrationPosesTable = scenario.calibration_poses
        targets = (scenario.target(str(scenario.poses_target)),) if targets is None else targets
    elif kind == "validation":
        table = ValidationTable() if scenario is None or scenario.validation is None else scenario.validation
    else:
        raise InputError(f"`kind` must be 'validation' or 'calibration'; got {kind!r}")
    return table, cast("ReflectorMount | Sequence[Target]", needed(targets, "targets", scenario, validation_target))


def true_offsets(
    targets: ReflectorMount | Sequence[Target], offsets_mm: Mapping[str, Any] | None
) -> tuple[ReflectorMount | tuple[Target, ...], np.ndarray]:
    """The target(s) of a simulated capture at free poses and their true offsets [mm]: a ReflectorMount's positions,
    else each Target's entry of ``offsets_mm`` or its declared (known) position."""
    if isinstance(targets, ReflectorMount):
        return targets, targets.positions
    targets = tuple(targets)
    offsets = np.array([(offsets_mm or {}).get(t.name, t.positions) for t in targets], dtype=float)
    guessed = [t.name for t in targets if not t.known and t.name not in (offsets_mm or {})]
    if guessed:
        raise InputError(
            f"target(s) {', '.join(guessed)}: declared with an unknown offset, whose guess is no truth; give "
            "their true offsets (`offsets_mm`)"
        )
    return targets, offsets


def simulation_inputs(scenario: Scenario, **given: Any) -> tuple[Any, ...]:
    """The inputs of a simulated capture, in the order given: each keyword's value, else the scenario's (``plan``,
    ``instrument``, ``tracker_from_base``, ``options``: its ``[identification]``, ``joint_errors``, ``joint_limits``)."""
    fields = {"options": "identification"}
    return tuple(getattr(scenario, fields.get(key, key)) if value is None else value for key, value in given.items())


def cpa_rows(capture: Capture, target: ReflectorMount | Target | str | None) -> tuple[Capture, ReflectorMount]:
    """The rows CPA uses and their (known) target: all rows, or with a ``target`` column those of ``target``
    (a Target or a name; None: the capture's first target)."""
    if isinstance(target, ReflectorMount):
        if capture.target is not None:
            raise InputError(
                f"{capture.source}: the capture has a `target` column; give CPA's target as a Target (or its name)"
            )
        return capture, target
    if capture.target is not None:
        names = capture.target_names
        name = names[int(capture.target[0])] if target is None else getattr(target, "name", target)
        if name not in names:
            raise InputError(f"{capture.source}: no point of target {name!r} (targets: {', '.join(names)})")
        capture = capture.select(capture.target == names.index(name))
    if not isinstance(target, Target):
        raise InputError(f"`target` must be a ReflectorMount or a Target; got {type(target).__name__}")
    if not target.known:
        raise InputError(
            f"CPA needs a target of known position; the offset of target {target.name!r} is unknown (refine from "
            "the nominal parameters instead, which estimates it)"
        )
    return capture, target.mount


def scenario_cpa_target(scenario: Scenario, capture: Capture) -> ReflectorMount | Target:
    """CPA's target in a scenario: the capture's first named target, else the scenario's capture target."""
    if capture.target is not None:
        return scenario.target(capture.target_names[int(capture.target[0])])
    target = capture_targets(scenario, capture)
    return target if isinstance(target, ReflectorMount | Target) else target[0]


def model_choice_settings(scenario: Scenario | None, model: str | None, folds: int | None) -> ModelChoiceSettings:
    """The model-choice settings: the arguments, else the scenario's ``[joint_model]`` (joints made 0-based)."""
    table = scenario.joint_model if scenario is not None else JointModelTable()

    def joints(values: tuple[int, ...] | None) -> tuple[int, ...] | None:
        return None if values is None else tuple(j - 1 for j in values)

    return ModelChoiceSettings(
        model=table.fit if model is None else model, folds=table.folds if folds is None else folds, seed=table.seed,
        compliance_joints=joints(table.compliance_joints), harmonic_joints=joints(table.harmonic_joints),
        harmonic_order=table.harmonic_order,
    )  # fmt: skip
