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
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
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
from robotcal.kinematics.joint_model import GRAVITY_MPS2, JointModel, gravity_torques
from robotcal.kinematics.model import LinkMasses, ParameterSet, RobotModel

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
    compliance, harmonic = (), ()
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
    if isinstance(folds, bool) or not isinstance(folds, int | np.integer) or folds < 2:
        raise InputError(f"cross-validation needs at least 2 folds; got {folds!r}")
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
    targets: object
    settings: RefinementSettings
    tracker_from_base: np.ndarray | None
    joint_model: JointModel | None
    instrument: object = None
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


def _tasks(capture, start, targets, settings, choice, tracker_from_base, structures, instrument) -> list[FitTask]:
    """Every candidate's full fit followed by its folds, in that order (the order of the progress and the warnings)."""
    fold_of = pose_folds(capture, choice.folds, choice.seed) if choice.folds else None
    tasks = []
    for name in choice.candidates:
        common = dict(
            model=name, capture=capture, start=start.geometric(), targets=targets, settings=settings,
            tracker_from_base=tracker_from_base, joint_model=structures[name],
        )  # fmt: skip
        tasks.append(FitTask(**common, instrument=instrument))
        tasks.extend(FitTask(**common, fold=fold, fold_of=fold_of) for fold in range(choice.folds))
    return tasks


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
        Of the compliance terms (payload included); None: the robot's, else the lumped form.
    backlash : ndarray, shape (n_joints,), optional
        Angular lash of every joint [rad], a fixed correction of the circle points (``backlash_source`` says
        where it comes from).
    instrument : Instrument, optional
        The stated noise of the fit health.
    workers : int
        Processes running the fits (1: in this process); the result does not depend on it.
    progress : callable, optional
        ``progress(done, total, what)`` after every fit, in the order of the fits.

    Returns
    -------
    RefinementResult
        The chosen model's fit with its ``health``, ``cross_validation`` (None without folds) and, for ``auto``,
        ``model_choice``. Its warnings, and those alone, are re-emitted here.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"`workers` must be a positive integer; got {workers!r}")
    lash = dict(masses=masses, backlash=backlash, backlash_source=backlash_source)
    structures = {name: candidate_joint_model(name, start, choice, **lash) for name in choice.candidates}
    tasks = _tasks(capture, start, targets, settings, choice, tracker_from_base, structures, instrument)
    fits, held_out, emitted = {}, {name: [] for name in choice.candidates}, {}
    with open_executor(workers=min(workers, len(tasks))) as executor:
        for done, (task, outcome) in enumerate(zip(tasks, executor.map(run_fit, tasks), strict=True), start=1):
            if isinstance(outcome, _Refused):
                raise IdentifiabilityError(outcome.message, parameters=outcome.parameters)
            if task.fold is None:
                fits[task.model] = _read_only(outcome.result)
                emitted[task.model] = list(outcome.warnings)
            else:
                held_out[task.model].append((outcome.success, outcome.held_out))
                for found in outcome.warnings:  # what a fold raises besides what it cannot determine, as it comes
                    warnings.warn_explicit(*found)
            if progress is not None:
                progress(done, len(tasks), task.model if task.fold is None else f"{task.model} CV")
    validations = {
        name: _validation(name, fits[name], held_out[name], choice) for name in choice.candidates if choice.folds
    }
    model_choice = choose_model(tuple(validations.values())) if choice.model == "auto" else None
    chosen = model_choice.chosen if model_choice is not None else choice.model
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
