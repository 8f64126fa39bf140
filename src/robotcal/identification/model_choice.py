"""Which model to deploy: the geometric chain alone, or with gravity compliance and harmonic joint errors (issue 22).

A real robot is not purely geometric: its joints sag under gravity and their angles carry errors periodic in the
joint's own variable (thesis ch. 4.6, eqs 5-2..5-4; its future work, ch. 6.2). The extended model of
:mod:`robotcal.kinematics.joint_model` adds those as named parameter groups; this module says which of four models
the data support:

``geometric``            the hybrid DH / Hayati chain (thesis ch. 3.4-3.5), today's model
``compliance``           + ``k_i tau_i(q)`` on the joints gravity loads (:func:`default_compliance_joints`)
``harmonic``             + ``a_i sin q_i + b_i cos q_i`` on every joint (order 1; higher on request)
``compliance+harmonic``  both

**Cross-validation by pose.** Every fit is judged on data it did not see: the capture's poses (points at the same
readings: every target measured there, both sweep directions) are dealt into ``folds`` (5) seeded groups; each
group is held out in turn, the model refitted on the others from the same start, and the held-out points
predicted with the fold's parameters, base frame and target offsets. The CV error is the RMS of those held-out
residuals: per point ``|T p - m|`` for the points criterion, the pairs that include a held-out point for the
distances criterion; the calibration error is the same statistic of the full fit on its own data.

**Choice (``auto``).** Each model is fitted and cross-validated; the chosen one is the model with the fewest
unknowns whose CV mean squared error is within one standard error of the smallest (the "one-standard-error rule"
of Hastie, Tibshirani and Friedman, *The Elements of Statistical Learning*, 2nd ed., 2009, sec. 7.10): a model
with more parameters must earn them by more than the folds' own scatter. The standard error is that of the mean
of the fold MSEs, ``sd / sqrt(folds)``.

**Lumped compliance.** Where the robot file gives no link masses the compliance is lumped
(:func:`robotcal.kinematics.joint_model.lumped_terms`): 10 torque shapes for J2 and 8 for J3 of a 6R arm, most of
which a capture cannot tell apart. :func:`smallest_lumped` starts from the largest shape of every compliant joint
and adds the next shapes only while the data support them: with folds, while the CV error falls by more than one
standard error, then the one-standard-error choice among the sets tried; without, while an F test of the residual
against the previous set says the new terms explain more than noise (:data:`LUMPED_F_TEST_ALPHA`). The set used
is announced (:class:`~robotcal.errors.IdentifiabilityWarning`). On the kr5-demo capture refined without masses
both rules keep 2 shapes per joint (4 terms of 18).

**Running the fits.** :func:`refine_model` is the whole of it: every candidate's fit on all points and its
``folds`` fold fits (``auto``: 4 models x (1 + 5 folds) = 24 fits) are independent, each described by a picklable
:class:`FitTask`, and run in the process pool of :mod:`robotcal.execution` (``workers``); the results do not depend
on the number of workers. Only the chosen model's warnings reach the caller, as if it alone had been fitted.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields, is_dataclass, replace

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError, check_count
from robotcal.execution import open_executor
from robotcal.identification._problem import pdist
from robotcal.identification.evaluation import (
    absolute_errors,
    distinct_pairs,
    fit_frames,
    fitted_targets,
    predicted_points,
)
from robotcal.identification.records import CrossValidation, ModelChoice, RefinementResult
from robotcal.identification.refine import refine_parameters
from robotcal.identification.settings import (
    DEFAULT_FOLDS,
    MODEL_CHOICES,
    MODELS,
    ModelChoiceSettings,
    RefinementSettings,
)
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.kinematics.joint_model import GRAVITY_MPS2, JointModel, gravity_torques, lumped_levels
from robotcal.kinematics.model import LinkMasses, ParameterSet, ReflectorMount, RobotModel

__all__ = [
    "MODELS",
    "MODEL_CHOICES",
    "DEFAULT_FOLDS",
    "COMPLIANCE_TORQUE_FRACTION",
    "CrossValidation",
    "ModelChoice",
    "ModelChoiceSettings",
    "FitTask",
    "default_compliance_joints",
    "joint_model_for",
    "candidate_joint_model",
    "pose_folds",
    "run_fit",
    "refine_model",
    "choose_model",
]

#: A joint is compliant by default when its largest gravity torque over the workspace reaches this fraction of
#: the largest joint's (on a floor-mounted KR 5: J2 and J3; J1's axis is vertical, the wrist joints carry little).
COMPLIANCE_TORQUE_FRACTION = 0.1
_DEFAULT_SETTINGS = RefinementSettings()
_DEFAULT_CHOICE = ModelChoiceSettings()


def _proxy_masses(robot: RobotModel) -> LinkMasses:
    """Unit masses at the link frame origins: the lever arms of the structure, where its masses are unknown."""
    return LinkMasses(mass_kg=np.ones(robot.n_joints), com_mm=np.zeros((robot.n_joints, 3)), source="unit proxy")


def default_compliance_joints(
    robot: RobotModel, masses: LinkMasses | None = None, gravity=GRAVITY_MPS2, *, poses: int = 400, seed: int = 0
) -> tuple[int, ...]:
    """The 0-based joints whose largest gravity torque over ``poses`` seeded poses within the limits reaches
    :data:`COMPLIANCE_TORQUE_FRACTION` of the largest joint's, with ``masses`` (default the robot's; where it has
    none, unit masses at the link frame origins stand in for the lever arms)."""
    masses = masses if masses is not None else robot.masses if robot.masses is not None else _proxy_masses(robot)
    limits = np.where(np.isfinite(robot.limits), robot.limits, np.array([-np.pi, np.pi]))
    readings = np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(poses, robot.n_joints))
    torque = np.abs(gravity_torques(robot.nominal, robot.model_joint_variables(readings), masses, gravity)).max(axis=0)
    if not np.any(torque > 0.0):
        return ()
    return tuple(int(j) for j in np.flatnonzero(torque >= COMPLIANCE_TORQUE_FRACTION * torque.max()))


def joint_model_for(
    model: str,
    robot: RobotModel,
    *,
    masses: LinkMasses | None = None,
    compliance_joints: Sequence[int] | None = None,
    harmonic_joints: Sequence[int] | None = None,
    harmonic_order: int = 1,
    gravity=GRAVITY_MPS2,
) -> JointModel | None:
    """The joint model (every value 0) of one of :data:`MODELS`; None for ``geometric``.

    ``masses``: the links' (default the robot's, payload included by the caller); without any, the compliance is
    the lumped form (:func:`robotcal.kinematics.joint_model.lumped_terms`). ``compliance_joints`` default to
    :func:`default_compliance_joints`, ``harmonic_joints`` to every joint (0-based).
    """
    if model not in MODELS:
        raise InputError(f"unknown model {model!r}; expected one of {', '.join(MODEL_CHOICES)}")
    if model == "geometric":
        return None
    masses = robot.masses if masses is None else masses
    compliance: Sequence[int] = ()
    harmonic: Sequence[int] = ()
    if "compliance" in model:
        compliance = (
            default_compliance_joints(robot, masses, gravity) if compliance_joints is None else compliance_joints
        )
        if not len(compliance):
            raise InputError(f"robot {robot.name!r}: no joint carries a gravity torque; the compliance model is empty")
    if "harmonic" in model:
        harmonic = range(robot.n_joints) if harmonic_joints is None else harmonic_joints
    return JointModel.build(
        robot,
        compliance_joints=compliance,
        masses=masses,
        harmonic_joints=harmonic,
        harmonic_order=harmonic_order,
        gravity=gravity,
    )


def pose_folds(capture: Capture, folds: int, seed: int) -> np.ndarray:
    """The fold ``(n_points,)`` of every point: poses (the same readings, on a 1e-7 deg grid) dealt at random
    (seeded) into ``folds`` groups as equal as the number of poses allows."""
    check_count(folds, "folds", minimum=2)  # cross-validation needs at least 2 folds
    turns = np.round(np.rad2deg(np.asarray(capture.readings, dtype=float)) * 1e7).astype(np.int64)
    _, pose = np.unique(turns, axis=0, return_inverse=True)
    pose = pose.ravel()
    n_poses = int(pose.max()) + 1
    if n_poses < folds:
        raise InputError(f"{capture.source}: {n_poses} distinct poses; {folds}-fold cross-validation needs {folds}")
    deal = np.random.default_rng(seed).permutation(n_poses) % folds
    return deal[pose]


def _held_out_residuals(capture: Capture, held: np.ndarray, fit, targets) -> np.ndarray:
    """The fold fit's residuals on the points it did not see [mm]: per point (points criterion) or per pair with
    at least one held-out point (distances)."""
    capture, targets = fitted_targets(capture, targets, fit)  # the fold's estimated offsets (issue 29: per session)
    if fit.criterion == "points":  # each session in its own estimated frame
        return absolute_errors(capture.select(held), fit.parameters, targets, fit_frames(fit))
    predicted = predicted_points(capture, fit.parameters, targets)
    keep = distinct_pairs(capture, targets, capture.n_joints)
    pair_i, pair_j = np.triu_indices(capture.n_points, k=1)
    mask = np.zeros(capture.n_points, dtype=bool)
    mask[held] = True
    involved = (mask[pair_i] | mask[pair_j])[keep]
    return (pdist(predicted) - pdist(capture.points))[keep][involved]


def candidate_joint_model(
    model: str,
    start: ParameterSet,
    choice: ModelChoiceSettings,
    *,
    masses: LinkMasses | None = None,
    backlash=None,
    backlash_source: str = "",
) -> JointModel | None:
    """The joint model a candidate ``model`` is fitted with: :func:`joint_model_for` with ``choice``'s joints and
    order (every value 0), or the start's own joint model when it has the same parameters (its values are then the
    start); with ``backlash`` [rad] (n_joints,) the lash correction of the circles, whatever the model."""
    robot = start.robot
    structure = joint_model_for(
        model, robot, masses=masses, compliance_joints=choice.compliance_joints,
        harmonic_joints=choice.harmonic_joints, harmonic_order=choice.harmonic_order,
    )  # fmt: skip
    if structure is not None and start.joint_model is not None and start.joint_model.names == structure.names:
        structure = start.joint_model
    if backlash is not None:
        structure = (structure or JointModel.build(robot)).with_backlash(backlash, backlash_source)
    return structure


@dataclass(frozen=True, slots=True, kw_only=True)
class FitTask:
    """One fit of :func:`refine_model`, everything it needs and nothing else (picklable: it may run in a worker).

    ``fold`` None: the fit on the whole capture (its result comes back); else the fit on the points whose
    ``fold_of`` is not ``fold``, predicting those that are (its held-out residuals come back).
    """

    model: str
    capture: Capture
    start: ParameterSet
    targets: ReflectorMount | Target | Sequence[Target]
    settings: RefinementSettings
    tracker_from_base: np.ndarray | None
    joint_model: JointModel | None
    instrument: Instrument | None = None
    fold: int | None = None
    fold_of: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class _Refused:
    """An :class:`~robotcal.errors.IdentifiabilityError` of a task, carried back whole (its ``parameters`` would not
    survive the pickling of the exception)."""

    message: str
    parameters: tuple[str, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class _Outcome:
    """What a task sends back: the full fit's result, or a fold's success and held-out residuals [mm]; the warnings
    it raised, as ``(message, category, filename, lineno)``, for the parent to re-emit."""

    result: RefinementResult | None = None
    success: bool = True
    held_out: np.ndarray | None = None
    warnings: tuple = ()


def run_fit(task: FitTask) -> _Outcome | _Refused:
    """Run one :class:`FitTask` (module notes), recording its warnings; a fold's quantities the fold cannot determine
    are not reported (the full fit reports them)."""
    capture = task.capture if task.fold is None else task.capture.select(np.flatnonzero(task.fold_of != task.fold))
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = refine_parameters(
                capture, task.start, task.targets, settings=task.settings, tracker_from_base=task.tracker_from_base,
                joint_model=task.joint_model, instrument=task.instrument,
            )  # fmt: skip
    except IdentifiabilityError as error:
        return _Refused(str(error), tuple(error.parameters))
    if task.fold is not None:
        caught = [found for found in caught if not issubclass(found.category, IdentifiabilityWarning)]
    found = tuple((w.message, w.category, w.filename, w.lineno) for w in caught)
    if task.fold is None:
        return _Outcome(result=result, warnings=found)
    held = np.flatnonzero(task.fold_of == task.fold)
    residuals = _held_out_residuals(task.capture, held, result, task.targets)
    return _Outcome(success=bool(result.success), held_out=residuals, warnings=found)


def _fit_tasks(model: str, joint_model: JointModel | None, common: dict, choice: ModelChoiceSettings, fold_of, instrument):
    """The fit of ``model`` with ``joint_model`` on the whole capture followed by its folds' fits."""
    tasks = [FitTask(model=model, joint_model=joint_model, **common, instrument=instrument)]
    tasks += [
        FitTask(model=model, joint_model=joint_model, **common, fold=fold, fold_of=fold_of) for fold in range(choice.folds)
    ]
    return tasks


class _Runner:
    """Runs :class:`FitTask` lists in an executor, each distinct fit once (a lumped level's fits are those of the
    model that keeps it), reporting ``progress(done, total, what)`` over every fit run."""

    def __init__(self, executor, progress):
        self.executor, self.progress, self.done, self.cache = executor, progress, 0, {}

    @staticmethod
    def key(task: FitTask) -> tuple:
        return task.model, None if task.joint_model is None else task.joint_model.names, task.fold

    def run(self, tasks: list[FitTask]) -> list[_Outcome]:
        todo = [task for task in tasks if self.key(task) not in self.cache]
        for ran, (task, outcome) in enumerate(zip(todo, self.executor.map(run_fit, todo), strict=True), start=1):
            if isinstance(outcome, _Refused):
                raise IdentifiabilityError(outcome.message, parameters=outcome.parameters)
            self.cache[self.key(task)] = outcome
            self.done += 1
            if self.progress is not None:
                total = self.done + len(todo) - ran
                self.progress(self.done, total, task.model if task.fold is None else f"{task.model} CV")
        return [self.cache[self.key(task)] for task in tasks]


#: Significance of the F test that adds a level of lumped compliance terms when there are no folds to hold out.
LUMPED_F_TEST_ALPHA = 0.01


def smallest_lumped(
    model: str, structure: JointModel, robot: RobotModel, runner: _Runner, tasks_of, choice: ModelChoiceSettings
) -> tuple[JointModel, str]:
    """The smallest lumped compliance set of ``structure`` the data support, and the sentence that announces it.

    The levels of :func:`robotcal.kinematics.joint_model.lumped_levels` (1, 2, ... terms per compliant joint, the
    largest torque shapes first) are fitted in turn. With folds, each is cross-validated and the next is tried
    while the last lowered the CV mean squared error by more than one standard error of the best so far; the set
    is then the one-standard-error choice among those tried (:func:`choose_model`). Without folds, a level is
    kept while the F test of its residual against the previous level's rejects "no improvement" at
    :data:`LUMPED_F_TEST_ALPHA`.
    """
    levels = lumped_levels(structure, robot)
    records, fits, chosen, why = [], [], len(levels) - 1, "every further term lowered the residual"
    for index, level in enumerate(levels):
        outcomes = runner.run(tasks_of(model, level))
        full = outcomes[0].result
        assert full is not None  # a whole-capture fit's outcome carries its result (run_fit)
        fits.append(full)
        if choice.folds:
            folds = [(outcome.success, outcome.held_out) for outcome in outcomes[1:]]
            records.append(_validation(f"{index + 1} per joint", fits[-1], folds, choice))
            best = min(records[:-1], key=lambda record: record.cv_mse_mm2, default=None)
            if best is not None and not records[-1].cv_mse_mm2 < best.cv_mse_mm2 - best.se_mm2:
                break
        elif index and (p_value := _f_test(fits[-2], fits[-1])) > LUMPED_F_TEST_ALPHA:
            chosen = index - 1
            why = f"{index + 1} per joint did not lower the residual significantly (F test, p = {p_value:.2g})"
            break
    if choice.folds:
        picked = choose_model(records)
        chosen = [record.model for record in records].index(picked.chosen)
        why = f"cross-validation chose them ({picked.reason})" if len(records) > 1 else why
    kept = [name for name in levels[chosen].names if name in structure.lumped]
    counts = ", ".join(
        f"{joint}: {sum(name.startswith(joint + '.') for name in kept)} of "
        f"{sum(name.startswith(joint + '.') for name in structure.lumped)}"
        for joint in dict.fromkeys(name.split(".")[0] for name in structure.lumped)
    )
    note = (
        f"model {model}: the robot file gives no link masses, so the compliance is lumped; the terms the data "
        f"support are {', '.join(kept)} ({counts} torque shapes): {why}; give the link masses (mass_kg, com_mm) "
        "for one compliance per joint"
    )
    return levels[chosen], note


def _f_test(smaller: RefinementResult, larger: RefinementResult) -> float:
    """p-value of the F test that ``larger``'s extra free unknowns lower the residual sum of squares by no more
    than noise would (1 when they add no free unknown or no degree of freedom is left)."""
    sizes = [len(fit.identifiability.free_names) for fit in (smaller, larger)]
    dof = [fit.fit.n_residuals - size for fit, size in zip((smaller, larger), sizes, strict=True)]
    added = sizes[1] - sizes[0]
    sigmas = [float(fit.uncertainty.sigma) for fit in (smaller, larger)]
    if added <= 0 or dof[1] <= 0 or not all(np.isfinite(sigmas)) or sigmas[1] <= 0.0:
        return 1.0
    statistic = (sigmas[0] ** 2 * dof[0] - sigmas[1] ** 2 * dof[1]) / added / sigmas[1] ** 2
    from scipy.special import fdtrc  # the F distribution's survival function (scipy.stats.f.sf), imported on use

    return float(fdtrc(added, dof[1], statistic))


def refine_model(
    capture: Capture,
    start: ParameterSet,
    targets,
    *,
    settings: RefinementSettings = _DEFAULT_SETTINGS,
    choice: ModelChoiceSettings = _DEFAULT_CHOICE,
    tracker_from_base=None,
    masses: LinkMasses | None = None,
    backlash=None,
    backlash_source: str = "",
    instrument=None,
    workers: int = 1,
    progress: Callable[[int, int, str], None] | None = None,
) -> RefinementResult:
    """Refine with the model ``choice`` names (``auto``: each candidate, the one cross-validation chooses), every
    fit cross-validated by pose; module notes.

    Parameters
    ----------
    capture, start, targets, tracker_from_base
        As for :func:`robotcal.identification.refine.refine_parameters` (every fit starts from ``start``'s
        geometry; its joint model, if any, is the start of a candidate with the same parameters).
    settings : RefinementSettings
        Of every fit.
    choice : ModelChoiceSettings
        The model, the folds and their seed, the joint-model structure.
    masses : LinkMasses, optional
        Of the compliance terms (payload included); None: the robot's, else the lumped form, whose smallest set
        of terms the data support is chosen first (:func:`smallest_lumped`, announced by an
        :class:`~robotcal.errors.IdentifiabilityWarning`).
    backlash : ndarray, shape (n_joints,), optional
        Angular lash of every joint [rad], a fixed correction of the circle points (``backlash_source`` says
        where it comes from).
    instrument : Instrument, optional
        The stated noise of the fit health.
    workers : int
        Processes running the fits (1: in this process); the result does not depend on it.
    progress : callable, optional
        ``progress(done, total, what)`` after every fit, in the order of the fits (``total`` grows while the
        lumped terms are chosen).

    Returns
    -------
    RefinementResult
        The chosen model's fit with its ``health``, ``cross_validation`` (None without folds) and, for ``auto``,
        ``model_choice``. Its warnings, and those alone, are re-emitted here.
    """
    check_count(workers, "workers")
    lash = dict(masses=masses, backlash=backlash, backlash_source=backlash_source)
    structures = {name: candidate_joint_model(name, start, choice, **lash) for name in choice.candidates}
    fold_of = pose_folds(capture, choice.folds, choice.seed) if choice.folds else None
    common = dict(
        capture=capture, start=start.geometric(), targets=targets, settings=settings,
        tracker_from_base=tracker_from_base,
    )  # fmt: skip

    def tasks_of(model: str, joint_model: JointModel | None) -> list[FitTask]:
        return _fit_tasks(model, joint_model, common, choice, fold_of, instrument)

    announced = {}
    with open_executor(workers=workers) as executor:
        runner = _Runner(executor, progress)
        for name, structure in structures.items():
            if structure is not None and structure.lumped:
                structures[name], announced[name] = smallest_lumped(name, structure, start.robot, runner, tasks_of, choice)
        tasks = [task for name in choice.candidates for task in tasks_of(name, structures[name])]
        outcomes = runner.run(tasks)
    fits: dict[str, RefinementResult] = {}
    held_out: dict[str, list[tuple[bool, np.ndarray]]] = {name: [] for name in choice.candidates}
    emitted: dict[str, list] = {}
    for task, outcome in zip(tasks, outcomes, strict=True):
        if task.fold is None:
            fits[task.model] = _read_only(outcome.result)
            emitted[task.model] = list(outcome.warnings)
        else:
            assert outcome.held_out is not None  # a fold's outcome carries its held-out residuals (run_fit)
            held_out[task.model].append((outcome.success, outcome.held_out))
            for found in outcome.warnings:  # what a fold raises besides what it cannot determine
                warnings.warn_explicit(*found)
    validations = {
        name: _validation(name, fits[name], held_out[name], choice) for name in choice.candidates if choice.folds
    }
    model_choice = choose_model(tuple(validations.values())) if choice.model == "auto" else None
    chosen = model_choice.chosen if model_choice is not None else choice.model
    if chosen in announced:
        warnings.warn(announced[chosen], IdentifiabilityWarning, stacklevel=2)
    for found in emitted[chosen]:  # only the chosen model's warnings are shown
        warnings.warn_explicit(*found)
    return replace(fits[chosen], cross_validation=validations.get(chosen), model_choice=model_choice)


def _read_only(value, seen=None):
    """``value`` with every array in it, through its dataclasses and tuples, read-only again (as made: a result that
    comes back from a worker process is unpickled with writable arrays)."""
    seen = set() if seen is None else seen
    if id(value) in seen:
        return value
    seen.add(id(value))
    if isinstance(value, np.ndarray):
        value.setflags(write=False)
    elif isinstance(value, tuple | list):
        for item in value:
            _read_only(item, seen)
    elif is_dataclass(value) and not isinstance(value, type):
        for entry in fields(value):
            _read_only(getattr(value, entry.name), seen)
    return value


def _validation(model: str, full: RefinementResult, folds: list, choice: ModelChoiceSettings) -> CrossValidation:
    """The cross-validation record of ``model`` from its full fit and its folds' ``(success, held-out residuals)``."""
    fold_mse = np.array([float(np.mean(residuals**2)) for _, residuals in folds])
    pooled = np.concatenate([residuals**2 for _, residuals in folds])
    return CrossValidation(
        model=model,
        unknowns=len(full.identifiability.free_names),
        folds=choice.folds,
        seed=int(choice.seed),
        calibration_rms_mm=float(full.fit.residual_rms),
        cv_rms_mm=float(np.sqrt(pooled.mean())),
        fold_mse_mm2=_frozen(fold_mse),
        se_mm2=float(fold_mse.std(ddof=1) / np.sqrt(choice.folds)),
        failed_folds=sum(not success for success, _ in folds),
    )


def choose_model(candidates: Sequence[CrossValidation]) -> ModelChoice:
    """The one-standard-error choice among cross-validated models (module notes), with the reason in words."""
    if not candidates:
        raise InputError("no model to choose from")
    best = min(candidates, key=lambda c: c.cv_mse_mm2)
    limit = best.cv_mse_mm2 + best.se_mm2
    eligible = [c for c in candidates if c.cv_mse_mm2 <= limit]
    chosen = min(eligible, key=lambda c: (c.unknowns, c.cv_mse_mm2))
    if chosen is best:
        reason = f"{best.model} has the smallest CV error ({best.cv_rms_mm:.4f} mm RMS)"
        simpler = [c for c in candidates if c.unknowns < best.unknowns]
        if simpler:
            runner = min(simpler, key=lambda c: c.cv_mse_mm2)
            reason += (
                f"; the best simpler model, {runner.model} ({runner.unknowns} unknowns, {runner.cv_rms_mm:.4f} mm), is "
                f"outside one standard error of it (CV MSE {runner.cv_mse_mm2:.3g} > {best.cv_mse_mm2:.3g} + "
                f"{best.se_mm2:.2g} mm^2)"
            )
    else:
        reason = (
            f"{chosen.model} ({chosen.unknowns} unknowns, CV {chosen.cv_rms_mm:.4f} mm RMS) is within one standard "
            f"error of the smallest CV error ({best.model}, {best.unknowns} unknowns, {best.cv_rms_mm:.4f} mm) and has "
            "fewer unknowns"
        )
    return ModelChoice(candidates=tuple(candidates), chosen=chosen.model, reason=reason)
