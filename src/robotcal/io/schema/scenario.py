"""Scenario TOML: robot, instrument, capture plan and identification options (docs/results.md).

Every key is documented in ``docs/scenario.md``. Lengths in mm, angles in degrees, instrument terms
in micrometres (``a_um``, ``b_um_per_m``); unknown keys are errors, so a typo never goes unnoticed.

The tables are frozen pydantic models and every default is defined once, here, in the table
definitions. :class:`Scenario` turns the robot, instrument, capture plan and identification options
into core objects (mm, rad); the run-option tables (:class:`MonteCarloTable`, :class:`TruthTable`,
:class:`ValidationTable`, :class:`TCPTable`) stay typed, in the file's units that their key names
state (``_mm``, ``_deg``): ``scenario.montecarlo.iterations``, ``(scenario.truth or TruthTable()).seed``.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, NoReturn, cast

import numpy as np
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, Field, model_validator

from robotcal.errors import InputError, RigidTransformWarning
from robotcal.geometry.transforms import check_rigid_transform, nearest_rotation
from robotcal.identification.cpa import CPAOptions
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema._validation import XYZ, Matrix4, TomlBool, TomlFloat, TomlInt, XYZList, validate_model
from robotcal.io.schema.builtins import builtin_names, data_path, read_toml
from robotcal.io.schema.instruments import InstrumentTable, make_instrument
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.joint_model import MAX_HARMONIC_ORDER
from robotcal.kinematics.model import ReflectorMount, RobotModel
from robotcal.simulation.generator import ERROR_TERMS, JointErrorModel
from robotcal.simulation.plan import CapturePlan

__all__ = [
    "Scenario",
    "MissingTable",
    "MonteCarloTable",
    "TruthTable",
    "ValidationTable",
    "PayloadTable",
    "CalibrationPosesTable",
    "POSES_TARGET",
    "JointModelTable",
    "TCPTable",
    "load_scenario",
    "list_scenarios",
    "scenario_from_dict",
]

#: Largest deviation from orthonormal that is repaired (with a warning) instead of refused: a
#: matrix printed to 5 significant digits, like the thesis's Table 5.4, deviates by ~1e-5.
REPAIRABLE_DEVIATION = 1e-3
_IDENTITY = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


class _Strict(BaseModel):
    """A scenario table: unknown keys refused, frozen once validated (a loaded scenario is a value)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class _RunTable(_Strict):
    """A run-option table kept typed on :class:`Scenario` (read its attributes: no defaults restated)."""


class ErrorTerm(_Strict):
    amplitude: TomlFloat = 0.0
    period_deg: TomlFloat = Field(default=360.0, gt=0)
    phase_deg: TomlFloat = 0.0
    noise_sd: TomlFloat = Field(default=0.0, ge=0)


class JointErrorTable(_Strict):
    joint: TomlInt = Field(ge=1)
    dx: ErrorTerm = ErrorTerm()
    dy: ErrorTerm = ErrorTerm()
    dz: ErrorTerm = ErrorTerm()
    ex: ErrorTerm = ErrorTerm()
    ey: ErrorTerm = ErrorTerm()
    backlash_deg: TomlFloat = Field(default=0.0, ge=0)
    lash_mm: XYZ = (0.0, 0.0, 0.0)


class CaptureTable(_Strict):
    start_deg: list[TomlFloat] | list[list[TomlFloat]] | None = None
    sweep_deg: list[TomlFloat] | None = None
    points: list[TomlInt] | None = None
    reflector_mm: list[XYZList] | None = None  # one per joint (their count: the robot's)
    flange_reflector_mm: XYZList | None = None
    bidirectional: TomlBool = False
    joint_limits: Literal["warn", "error", "ignore"] = "warn"
    seed: TomlInt | None = Field(default=None, ge=0)
    joint_errors: list[JointErrorTable] = []

    @model_validator(mode="after")
    def _one_reflector(self) -> CaptureTable:
        if self.reflector_mm is not None and self.flange_reflector_mm is not None:
            raise ValueError("give exactly one of `reflector_mm` (per circle) and `flange_reflector_mm`")
        plan = [key for key in PLAN_KEYS if getattr(self, key) is not None]
        if plan and len(plan) != len(PLAN_KEYS):
            missing = ", ".join(f"`capture.{key}`" for key in PLAN_KEYS if key not in plan)
            raise ValueError(f"a capture plan needs `start_deg`, `sweep_deg` and `points`: {missing} missing")
        return self


class TargetTable(_Strict):
    """One measured target (``[[targets]]``): per-joint reflectors or a flange target, known or unknown."""

    name: str = Field(min_length=1)
    flange_mm: list[TomlFloat] | Literal["unknown"] | None = None  # [x, y, z]: its length checked when read
    guess_mm: list[TomlFloat] | None = None
    reflector_mm: list[XYZList] | None = None  # one per joint (their count: the robot's)
    per_session: bool = False  # an unknown offset re-seated between measurement sessions: one offset per session

    @model_validator(mode="after")
    def _one_position(self) -> TargetTable:
        if (self.flange_mm is None) == (self.reflector_mm is None):
            raise ValueError("give exactly one of `flange_mm` (a flange target) and `reflector_mm` (per joint)")
        if self.guess_mm is not None and self.flange_mm != "unknown":
            raise ValueError('`guess_mm` is the start of an unknown offset: it needs `flange_mm = "unknown"`')
        if self.per_session and self.flange_mm != "unknown":
            raise ValueError('`per_session` re-seats an unknown offset: it needs `flange_mm = "unknown"`')
        return self


class IdentificationTable(_Strict):
    circle_fit: Literal["geometric", "algebraic"] = "geometric"
    base_frame: Literal["given", "registered"] = "given"
    base_axis: Literal["registration", "circle1"] = "registration"
    near_parallel_deg: TomlFloat = Field(default=5.0, ge=0, le=45)
    still_tolerance_deg: TomlFloat = Field(default=1e-6, ge=0)


class MonteCarloTable(_RunTable):
    """``[montecarlo]``: the GUM-S1 Monte Carlo of the CPA parameters (always present: defaults when absent).

    Attributes
    ----------
    iterations : int
        Draws (``robotcal uncertainty -n`` and ``robotcal run --draws`` override it).
    seed : int or None
        Seed of the draws; None: fresh entropy, recorded.
    coverage : float
        Coverage probability of the intervals (0.95: 95 %).
    refined_iterations : int or None
        Draws of a run's refined-model Monte Carlo (at most ``iterations``; ``robotcal run --refined-draws``
        overrides it); None: the run's default, ``robotcal.limits.REFINED_DRAWS``.
    """

    iterations: TomlInt = Field(default=100_000, ge=1)
    seed: TomlInt | None = Field(default=None, ge=0)
    coverage: TomlFloat = Field(default=0.95, gt=0, lt=1)
    refined_iterations: TomlInt | None = Field(default=None, ge=1)


class TruthTable(_RunTable):
    """``[truth]``, synthetic runs: how far the "true" robot deviates from nominal (simulation.perturb).

    In the file's units [mm, deg]. ``Scenario.truth`` is None when the file has no ``[truth]``
    table (a run then simulates the nominal robot); ``TruthTable()`` holds the defaults.
    ``compliance_rad_per_nm``: one compliance per joint [rad/(N m)], 0 where rigid: the true robot sags under
    gravity (link masses of the robot file, the ``[payload]``), a joint model in its truth JSON.
    """

    length_sd_mm: TomlFloat = Field(default=0.2, ge=0)
    angle_sd_deg: TomlFloat = Field(default=0.05, ge=0)
    include_base: TomlBool = False
    seed: TomlInt | None = Field(default=None, ge=0)
    compliance_rad_per_nm: tuple[Annotated[TomlFloat, Field(ge=0)], ...] | None = None  # one per joint


class ValidationTable(_RunTable):
    """``[validation]``: a capture at random reachable poses with a flange target (simulation.poses).

    In the file's units [mm, deg]. ``Scenario.validation`` is None when the file has no
    ``[validation]`` table (the flange target then comes from ``[capture]`` or ``[[targets]]``);
    ``ValidationTable()`` holds the defaults.
    """

    poses: TomlInt = Field(default=100, ge=4)
    seed: TomlInt | None = Field(default=None, ge=0)
    flange_reflector_mm: XYZ = (60.0, 40.0, 30.0)
    margin_deg: TomlFloat = Field(default=5.0, ge=0)
    min_height_mm: TomlFloat | None = None


class CalibrationPosesTable(ValidationTable):
    """``[calibration_poses]``: free poses measured on a flange target after the circles, refined together with
    them (issue 22): where the joints are loaded in other ways than along the circles, so that gravity compliance
    and joint errors become observable. Keys as ``[validation]``; the target is a ``[[targets]]`` flange target at
    the same offset (``Scenario.poses_target``), else a new one named ``flange`` (also when the ``[validation]``
    target has that offset: the same reflector, named for this capture).
    ``Scenario.calibration_poses`` is None without the table.
    """

    poses: TomlInt = Field(default=30, ge=4)


class TCPTable(_RunTable):
    """``[tcp]``, the TCP stage of ``robotcal run``: where the TCP uncertainty is stated (always present:
    defaults when absent).

    In the file's units [mm, deg]; :func:`robotcal.pipeline.plan.tcp_targets` resolves it into readings [rad].
    ``pose_deg`` and ``trajectory`` None: the thesis's pose and trajectory (KR 5 sixx R650 only).
    """

    pose_deg: tuple[TomlFloat, ...] | None = None
    trajectory: str | None = None
    readings_robot: str | None = None
    workspace_poses: TomlInt = Field(default=1000, ge=1)
    workspace_draws: TomlInt | None = Field(default=10_000, ge=2)
    workspace_seed: TomlInt = Field(default=0, ge=0)
    tool_mm: XYZ | None = None


class PayloadTable(_RunTable):
    """``[payload]``: a point mass on the flange, for the gravity compliance of the extended model [kg, mm].

    ``com_mm`` is its centre of mass in the flange frame (DH frame {n}). ``Scenario.payload`` is None without
    the table (no payload).
    """

    mass_kg: TomlFloat = Field(ge=0)
    com_mm: XYZ = (0.0, 0.0, 0.0)


class JointModelTable(_RunTable):
    """``[joint_model]``: which model ``refine`` fits (issue 22, :mod:`robotcal.identification.model_choice`).

    ``fit``: ``geometric`` (default, the hybrid DH / Hayati chain alone), ``compliance``, ``harmonic``,
    ``compliance+harmonic`` or ``auto`` (each fitted, chosen by cross-validation). Joints are 1-based; ``None``
    takes the defaults (compliance: the joints gravity loads; harmonic: every joint). ``folds``: the
    cross-validation by pose every fit reports (0: none); ``seed``: the deal of poses into folds.
    """

    fit: Literal["geometric", "compliance", "harmonic", "compliance+harmonic", "auto"] = "geometric"
    compliance_joints: tuple[Annotated[TomlInt, Field(ge=1)], ...] | None = None  # joints of the robot: checked
    harmonic_joints: tuple[Annotated[TomlInt, Field(ge=1)], ...] | None = None  # against it when it is loaded
    harmonic_order: TomlInt = Field(default=1, ge=1, le=MAX_HARMONIC_ORDER)
    folds: TomlInt = Field(default=5, ge=0)
    seed: TomlInt = Field(default=0, ge=0)

    @model_validator(mode="after")
    def _valid(self) -> JointModelTable:
        if self.folds == 1:
            raise ValueError("folds must be 0 (no cross-validation) or at least 2")
        for key in ("compliance_joints", "harmonic_joints"):
            joints = getattr(self, key)
            if joints is not None and len(set(joints)) != len(joints):
                raise ValueError(f"{key} must list distinct 1-based joints")
        return self


class ScenarioFile(_Strict):
    description: str = ""
    robot: str
    #: The robot's ISO 9283 pose repeatability RP [mm] (what `robotcal iso9283` measures): the noise budget's
    #: robot part (docs/scenario.md, "Noise budget").
    repeatability_mm: TomlFloat | None = Field(default=None, ge=0)
    tracker_from_base: Matrix4 = _IDENTITY
    instrument: InstrumentTable | None = None
    capture: CaptureTable | None = None
    targets: list[TargetTable] = []
    identification: IdentificationTable = Field(default_factory=IdentificationTable)
    montecarlo: MonteCarloTable = Field(default_factory=MonteCarloTable)
    truth: TruthTable | None = None
    validation: ValidationTable | None = None
    calibration_poses: CalibrationPosesTable | None = None
    tcp: TCPTable = Field(default_factory=TCPTable)
    payload: PayloadTable | None = None
    joint_model: JointModelTable = Field(default_factory=JointModelTable)


#: The name of the ``[calibration_poses]`` flange target in a capture's ``target`` column.
POSES_TARGET = "flange"
#: The keys of ``[capture]`` that make a capture plan (needed to simulate, not to identify).
PLAN_KEYS = ("start_deg", "sweep_deg", "points")
#: Commands that need the capture plan / the instrument (for the error of a scenario without them).
PLAN_USERS = "simulate, the Monte Carlo (uncertainty, plan) and run"
INSTRUMENT_USERS = "simulate, the Monte Carlo (uncertainty, plan), run and identify --reject-outliers"


class MissingTable:
    """Stands for a scenario table that is absent: any use raises an :class:`InputError` naming the
    file, the key and the commands that need it (identification needs neither plan nor instrument)."""

    __slots__ = ("_message",)

    def __init__(self, message: str):
        object.__setattr__(self, "_message", message)

    def __getattr__(self, name: str) -> NoReturn:
        if name.startswith("__"):
            raise AttributeError(name)
        raise InputError(self._message)

    def __bool__(self) -> bool:
        return False

    def __repr__(self) -> str:
        return f"MissingTable({self._message!r})"

    def __reduce__(self) -> tuple[type[MissingTable], tuple[str]]:
        return (MissingTable, (self._message,))


@dataclass(frozen=True, slots=True, kw_only=True)
class Scenario:
    """A loaded, validated scenario: core objects in core units (mm, rad).

    ``plan`` and ``instrument`` are :class:`MissingTable` when the file has no capture plan / no
    ``[instrument]`` (a scenario for a real capture): using them raises an :class:`InputError` that
    names the key; :attr:`has_plan` / :attr:`has_instrument` test for them.

    ``montecarlo``, ``truth``, ``validation`` and ``tcp`` are the validated tables, typed and frozen, in
    the file's units (their key names say which: ``_mm``, ``_deg``); ``truth`` and ``validation`` are
    None when the file has no such table. ``settings`` is the whole validated file as a plain dict: the
    echo recorded in ``run.json``, a document, not for computing.
    """

    name: str
    source: str
    description: str
    robot: RobotModel
    instrument: Instrument
    plan: CapturePlan
    tracker_from_base: np.ndarray
    joint_errors: JointErrorModel | None
    joint_limits: str
    identification: CPAOptions
    seed: int | None
    montecarlo: MonteCarloTable = field(default_factory=MonteCarloTable)
    settings: dict = field(default_factory=dict)
    truth: TruthTable | None = None
    validation: ValidationTable | None = None
    calibration_poses: CalibrationPosesTable | None = None
    tcp: TCPTable = field(default_factory=TCPTable)
    #: The target the ``[calibration_poses]`` are measured on: a ``[[targets]]`` flange target at their offset,
    #: else ``flange``; None without the table.
    poses_target: str | None = None
    #: ``[payload]`` (None: no payload) and ``[joint_model]``: the extended model's inputs and choice.
    payload: PayloadTable | None = None
    joint_model: JointModelTable = field(default_factory=JointModelTable)
    #: Files the scenario was read from (the TOML and a robot TOML it names): inputs that an output
    #: of the same command must never replace.
    files: tuple[str, ...] = ()
    #: Declared targets: ``[[targets]]``, then (under the names ``capture``, ``validation`` and ``flange``, where
    #: those names are free) the ``[capture]`` reflector, the ``[validation]`` and ``[calibration_poses]`` flange
    #: targets.
    targets: tuple[Target, ...] = ()
    #: The ``[capture]`` reflector (``reflector_mm`` / ``flange_reflector_mm``), plan or not; None if absent.
    reflector: ReflectorMount | None = None
    #: Whether the file gives ``tracker_from_base`` (else it is the identity, a placeholder: a result that
    #: needs the real base frame, such as an absolute error, must not use it).
    gives_tracker_from_base: bool = True
    #: The robot's ISO 9283 pose repeatability RP [mm] (``repeatability_mm``), None when not stated: added to the
    #: instrument's noise in the fit health, the refinement's weights and the Monte Carlo (the noise budget).
    repeatability_mm: float | None = None

    @property
    def has_plan(self) -> bool:
        return not isinstance(self.plan, MissingTable)

    @property
    def has_instrument(self) -> bool:
        return not isinstance(self.instrument, MissingTable)

    def target(self, name: str) -> Target:
        """The declared target ``name``; an :class:`InputError` lists the declared ones otherwise."""
        for target in self.targets:
            if target.name == name:
                return target
        declared = ", ".join(t.name for t in self.targets) or "none"
        raise InputError(f"{self.source}: no target named {name!r} (declared: {declared}); see [[targets]]")


def _rigid(matrix: ArrayLike, source: str) -> np.ndarray:
    """``tracker_from_base`` (a 4x4 matrix by its type) as a rigid transform; a near-rotation repaired with a warning."""
    array = np.asarray(matrix, dtype=float)
    rotation = array[:3, :3]
    deviation = float(np.max(np.abs(rotation.T @ rotation - np.eye(3))))
    if 1e-6 < deviation <= REPAIRABLE_DEVIATION and np.linalg.det(rotation) > 0:
        array = array.copy()
        array[:3, :3] = nearest_rotation(rotation)
        warnings.warn(
            f"{source}: `tracker_from_base` deviates from a rotation by {deviation:.2g}; using its nearest rotation",
            RigidTransformWarning,
            stacklevel=4,
        )
    try:
        return check_rigid_transform(array, "tracker_from_base")
    except InputError as exc:
        raise InputError(f"{source}: key {exc}") from None


def _joint_errors(tables: list[JointErrorTable], n_joints: int, source: str) -> JointErrorModel | None:
    if not tables:
        return None
    model = JointErrorModel.zeros(n_joints)
    amplitude, period, phase, noise = (
        np.array(a) for a in (model.amplitude, model.period, model.phase, model.noise_sd)
    )
    backlash, lash = np.zeros(n_joints), np.zeros((n_joints, 3))
    seen = set()
    for table in tables:
        if table.joint > n_joints or table.joint in seen:
            raise InputError(
                f"{source}: key `capture.joint_errors`: joint {table.joint} is out of range 1..{n_joints} or repeated"
            )
        seen.add(table.joint)
        for column, term_name in enumerate(ERROR_TERMS):
            term: ErrorTerm = getattr(table, term_name)
            to_core = 1.0 if term_name.startswith("d") else np.pi / 180.0  # mm stay mm, deg -> rad
            amplitude[table.joint - 1, column] = term.amplitude * to_core
            noise[table.joint - 1, column] = term.noise_sd * to_core
            period[table.joint - 1, column] = np.deg2rad(term.period_deg)
            phase[table.joint - 1, column] = np.deg2rad(term.phase_deg)
        backlash[table.joint - 1] = np.deg2rad(table.backlash_deg)
        lash[table.joint - 1] = table.lash_mm
    return JointErrorModel(
        amplitude=amplitude, period=period, phase=phase, noise_sd=noise, backlash=backlash, lash=lash
    )


def repeatability_of(scenario: Scenario | None) -> float | None:
    """The robot's ISO 9283 repeatability RP a scenario states [mm] (``repeatability_mm``); None without one."""
    return None if scenario is None else scenario.repeatability_mm


def scenario_from_dict(
    data: dict, *, name: str = "scenario", source: str = "scenario", base_dir: Path | None = None
) -> Scenario:
    """Validate a parsed scenario and build its core objects; errors name ``source`` and the key."""
    spec: ScenarioFile = validate_model(ScenarioFile, data, source)
    try:
        robot = load_robot(spec.robot, relative_to=base_dir)
    except InputError as exc:
        raise InputError(f"{source}: key `robot`: {exc}") from None
    n = robot.n_joints
    capture = spec.capture
    declared = _targets(spec.targets, n, source)
    reflector = None if capture is None else _capture_reflector(capture, n, source)
    plan: CapturePlan | MissingTable = MissingTable(
        f"{source}: key `capture.start_deg` (with `sweep_deg` and `points`) is missing: the capture plan is needed "
        f"by {PLAN_USERS}; identify, refine and evaluate work without it"
    )
    if capture is not None and capture.start_deg is not None:
        plan = _plan(capture, reflector, declared, robot, source)
    instrument: Instrument | MissingTable = MissingTable(
        f"{source}: key `instrument` is missing: the instrument is needed by {INSTRUMENT_USERS} (identify and refine "
        "work without it, comparing their residual with the points' u95_mm when the capture has it)"
    )
    if spec.instrument is not None:
        instrument = make_instrument(**spec.instrument.model_dump())
    validation = spec.validation
    targets = list(declared)
    taken = {target.name for target in targets}
    if reflector is not None and "capture" not in taken:
        targets.append(Target.from_mount(reflector, "capture"))
    if validation is not None and "validation" not in taken:
        targets.append(Target(name="validation", frame="flange", positions=np.asarray(validation.flange_reflector_mm)))
    poses_target = None
    if spec.calibration_poses is not None:  # measured on a [[targets]] flange target at that offset, else on "flange"
        offset = np.asarray(spec.calibration_poses.flange_reflector_mm, dtype=float)
        # not the [validation] one: a target is named for its capture (the same reflector is "flange" here)
        same = [t.name for t in declared if t.frame == "flange" and t.known and np.array_equal(t.positions, offset)]
        if same:
            poses_target = same[0]
        elif POSES_TARGET not in {t.name for t in targets}:
            targets.append(Target(name=POSES_TARGET, frame="flange", positions=offset))
            poses_target = POSES_TARGET
        else:
            raise InputError(
                f"{source}: key `calibration_poses.flange_reflector_mm`: the target {POSES_TARGET!r} is declared at "
                "another offset; give the calibration poses the offset of a declared flange target"
            )
    ident = spec.identification
    return Scenario(
        name=name,
        source=source,
        description=spec.description,
        robot=robot,
        # a MissingTable stands in for an absent table: any use of it raises an InputError naming the key
        instrument=cast(Instrument, instrument),
        plan=cast(CapturePlan, plan),
        tracker_from_base=_rigid(spec.tracker_from_base, source),
        joint_errors=_joint_errors([] if capture is None else capture.joint_errors, n, source),
        joint_limits="warn" if capture is None else capture.joint_limits,
        identification=CPAOptions(**ident.model_dump()),
        seed=None if capture is None else capture.seed,
        montecarlo=spec.montecarlo,
        settings=spec.model_dump(),
        truth=spec.truth,
        validation=validation,
        calibration_poses=spec.calibration_poses,
        poses_target=poses_target,
        tcp=spec.tcp,
        payload=spec.payload,
        joint_model=_joint_model_table(spec.joint_model, spec.truth, robot, source),
        files=(source, *_robot_file(spec.robot, base_dir)),
        targets=tuple(targets),
        reflector=reflector,
        gives_tracker_from_base="tracker_from_base" in data,
        repeatability_mm=spec.repeatability_mm,
    )


def _joint_model_table(
    table: JointModelTable, truth: TruthTable | None, robot: RobotModel, source: str
) -> JointModelTable:
    """``[joint_model]`` checked against the robot (and ``[truth] compliance_rad_per_nm``)."""
    n = robot.n_joints
    for key in ("compliance_joints", "harmonic_joints"):
        joints = getattr(table, key)
        if joints is not None and max(joints, default=0) > n:
            raise InputError(f"{source}: key `joint_model.{key}`: joint {max(joints)} of a {n}-joint robot")
    if truth is not None and truth.compliance_rad_per_nm is not None:
        values = truth.compliance_rad_per_nm
        if len(values) != n:
            raise InputError(f"{source}: key `truth.compliance_rad_per_nm` must be {n} compliances; got {len(values)}")
    return table


def _capture_reflector(capture: CaptureTable, n: int, source: str) -> ReflectorMount | None:
    """The ``[capture]`` reflector (per joint or flange), None when the table gives neither."""
    if capture.reflector_mm is not None:
        if len(capture.reflector_mm) != n:
            raise InputError(
                f"{source}: key `capture.reflector_mm` must be {n} positions [x, y, z] (one per joint); "
                f"got {len(capture.reflector_mm)}"
            )
        return ReflectorMount(frame="joint", positions=np.asarray(capture.reflector_mm, dtype=float))
    if capture.flange_reflector_mm is not None:
        return ReflectorMount(frame="flange", positions=np.asarray(capture.flange_reflector_mm, dtype=float))
    return None


def _plan(
    capture: CaptureTable, reflector: ReflectorMount | None, declared: Sequence[Target], robot: RobotModel, source: str
) -> CapturePlan:
    """The capture plan; its target is the ``[capture]`` reflector, else the first ``[[targets]]`` entry."""
    n = robot.n_joints
    assert capture.sweep_deg is not None and capture.points is not None  # CaptureTable: the plan's keys together
    for key in ("sweep_deg", "points"):
        if len(getattr(capture, key)) != n:
            raise InputError(
                f"{source}: key `capture.{key}` has {len(getattr(capture, key))} values; robot {robot.name!r} has {n} joints"
            )
    try:
        start = np.asarray(capture.start_deg, dtype=float)
    except ValueError:  # rows of unequal length
        raise InputError(f"{source}: key `capture.start_deg` must have {n} values or {n} rows of {n}") from None
    if start.shape not in ((n,), (n, n)):
        raise InputError(
            f"{source}: key `capture.start_deg` must have {n} values or {n} rows of {n}; got shape {start.shape}"
        )
    if reflector is None:
        if not declared:
            raise InputError(
                f"{source}: key `capture`: a capture plan needs a target: give `capture.reflector_mm` or "
                "`capture.flange_reflector_mm` (or declare [[targets]])"
            )
        if not declared[0].known:
            raise InputError(
                f"{source}: key `targets[0].flange_mm`: the capture plan simulates its first target, whose offset is "
                "unknown; give `capture.flange_reflector_mm` or a known first target"
            )
        reflector = declared[0].mount
    try:
        return CapturePlan(
            start=np.deg2rad(start),
            sweep=np.deg2rad(capture.sweep_deg),
            points=np.asarray(capture.points),
            reflector=reflector,
            bidirectional=capture.bidirectional,
        )
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def _targets(tables: list[TargetTable], n: int, source: str) -> tuple[Target, ...]:
    """The ``[[targets]]`` entries as :class:`Target` objects (names distinct)."""
    targets: list[Target] = []
    for k, table in enumerate(tables):
        key = f"targets[{k}]"
        if any(t.name == table.name for t in targets):
            raise InputError(f"{source}: key `{key}.name`: target name {table.name!r} is declared twice")
        if table.reflector_mm is not None:
            if len(table.reflector_mm) != n:
                raise InputError(
                    f"{source}: key `{key}.reflector_mm` must be {n} positions [x, y, z] (one per joint); "
                    f"got {len(table.reflector_mm)}"
                )
            targets.append(
                Target(name=table.name, frame="joint", positions=np.asarray(table.reflector_mm, dtype=float))
            )
            continue
        flange = table.flange_mm
        assert flange is not None  # TargetTable: flange_mm or reflector_mm
        known = flange != "unknown"
        position = flange if isinstance(flange, list) else (table.guess_mm if table.guess_mm is not None else [0.0, 0.0, 0.0])
        if len(position) != 3:  # not by type: a union's error would name both of flange_mm's types
            what = "flange_mm" if known else "guess_mm"
            raise InputError(f"{source}: key `{key}.{what}` must be [x, y, z] mm; got {len(position)} values")
        targets.append(
            Target(name=table.name, frame="flange", positions=np.asarray(position), known=known, per_session=table.per_session)
        )
    return tuple(targets)


def _robot_file(robot: str, base_dir: Path | None) -> tuple[str, ...]:
    """The robot TOML a scenario names, as :func:`load_robot` resolves it; () for a built-in robot."""
    if robot in builtin_names("robots"):
        return ()
    path = Path(robot)
    if not path.is_absolute() and base_dir is not None and (base_dir / path).exists():
        path = base_dir / path
    return (str(path),)


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """A built-in scenario by name (``robotcal scenarios`` lists them) or a scenario TOML by path."""
    text = str(name_or_path)
    if text in builtin_names("scenarios"):
        path = data_path("scenarios", f"{text}.toml")
        name = text
    else:
        path = Path(text)
        if not path.exists():
            raise InputError(
                f"unknown scenario {text!r}: not a built-in scenario ({', '.join(builtin_names('scenarios'))}) nor an existing file"
            )
        name = path.stem
    return scenario_from_dict(read_toml(path), name=name, source=str(path), base_dir=path.parent)


def list_scenarios() -> list[Scenario]:
    """Every built-in scenario."""
    return [load_scenario(name) for name in builtin_names("scenarios")]
