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
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.identification.evaluation import distinct_pairs, predicted_points
from robotcal.identification.refine import pdist
from robotcal.identification.targets import Target
from robotcal.kinematics.joint_model import GRAVITY_MPS2, JointModel, gravity_torques
from robotcal.kinematics.model import LinkMasses, RobotModel

__all__ = [
    "MODELS",
    "MODEL_CHOICES",
    "DEFAULT_FOLDS",
    "COMPLIANCE_TORQUE_FRACTION",
    "CrossValidation",
    "ModelChoice",
    "default_compliance_joints",
    "joint_model_for",
    "pose_folds",
    "cross_validate",
    "choose_model",
]

#: The models, simplest first.
MODELS = ("geometric", "compliance", "harmonic", "compliance+harmonic")
#: What ``refine --model`` accepts.
MODEL_CHOICES = (*MODELS, "auto")
#: Folds of the cross-validation by pose.
DEFAULT_FOLDS = 5
#: A joint is compliant by default when its largest gravity torque over the workspace reaches this fraction of
#: the largest joint's (on a floor-mounted KR 5: J2 and J3; J1's axis is vertical, the wrist joints carry little).
COMPLIANCE_TORQUE_FRACTION = 0.1


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


@dataclass(frozen=True, slots=True, kw_only=True)
class CrossValidation:
    """k-fold cross-validation by pose of one model (module notes) [mm, mm^2].

    Attributes
    ----------
    model : str
    unknowns : int
        Free unknowns of the full fit (parameters, joint-model values, offsets, base corrections).
    folds : int
    seed : int
        Seed of the deal of poses into folds.
    calibration_rms_mm : float
        The full fit's residual RMS on its own data.
    cv_rms_mm : float
        RMS of every held-out residual over the folds.
    fold_mse_mm2 : ndarray, shape (folds,)
        Mean squared held-out residual of each fold.
    se_mm2 : float
        Standard error of the CV mean squared error, ``sd(fold_mse) / sqrt(folds)``.
    failed_folds : int
        Folds whose refit did not converge (their held-out residuals still count: a model that cannot be refitted
        on part of the data predicts it badly).
    """

    model: str
    unknowns: int
    folds: int
    seed: int
    calibration_rms_mm: float
    cv_rms_mm: float
    fold_mse_mm2: np.ndarray
    se_mm2: float
    failed_folds: int = 0

    @property
    def cv_mse_mm2(self) -> float:
        return self.cv_rms_mm**2

    def to_dict(self) -> dict:
        return {
            "model": self.model,
            "unknowns": self.unknowns,
            "folds": self.folds,
            "seed": self.seed,
            "calibration_rms_mm": self.calibration_rms_mm,
            "cv_rms_mm": self.cv_rms_mm,
            "fold_rms_mm": [float(v) for v in np.sqrt(self.fold_mse_mm2)],
            "cv_se_mm2": self.se_mm2,
            "failed_folds": self.failed_folds,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class ModelChoice:
    """The candidates of ``auto`` with their cross-validation, the chosen model and why."""

    candidates: tuple[CrossValidation, ...]
    chosen: str
    reason: str

    def to_dict(self) -> dict:
        return {
            "rule": "fewest unknowns within one standard error of the smallest CV mean squared error",
            "chosen": self.chosen,
            "reason": self.reason,
            "candidates": [candidate.to_dict() for candidate in self.candidates],
        }


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
    if fit.targets:  # the fold's estimated offsets, by name
        estimated = {target.name: target for target in fit.targets}
        targets = tuple(
            estimated.get(target.name, target) for target in ((targets,) if isinstance(targets, Target) else targets)
        )
    if fit.criterion == "points":
        part = capture.select(held)
        predicted = predicted_points(part, fit.parameters, targets)
        tracker = np.asarray(fit.tracker_from_base, dtype=float)
        return np.linalg.norm(predicted @ tracker[:3, :3].T + tracker[:3, 3] - part.points, axis=1)
    predicted = predicted_points(capture, fit.parameters, targets)
    keep = distinct_pairs(capture, targets, capture.n_joints)
    pair_i, pair_j = np.triu_indices(capture.n_points, k=1)
    mask = np.zeros(capture.n_points, dtype=bool)
    mask[held] = True
    involved = (mask[pair_i] | mask[pair_j])[keep]
    return (pdist(predicted) - pdist(capture.points))[keep][involved]


def cross_validate(
    capture: Capture,
    fit: Callable[[Capture], object],
    full,
    targets,
    *,
    model: str,
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> CrossValidation:
    """k-fold cross-validation by pose (module notes) of the refinement ``fit(capture) -> RefinementResult``.

    Parameters
    ----------
    capture : Capture
    fit : callable
        Refines a part of the capture with the model's options, from the same start as ``full`` (warnings about
        quantities a fold cannot determine are silenced: the full fit reports them).
    full : RefinementResult
        The fit on the whole capture (its residual RMS is the calibration error).
    targets : ReflectorMount, Target or sequence of Target
        As given to the refinement.
    model : str
        The model's name, recorded.
    """
    fold_of = pose_folds(capture, folds, seed)
    squares, fold_mse, failed = [], np.zeros(folds), 0
    for fold in range(folds):
        held = np.flatnonzero(fold_of == fold)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            result = fit(capture.select(np.flatnonzero(fold_of != fold)))
        failed += int(not result.success)
        residuals = _held_out_residuals(capture, held, result, targets)
        squares.append(residuals**2)
        fold_mse[fold] = float(np.mean(residuals**2))
        if progress is not None:
            progress(fold + 1, folds)
    pooled = np.concatenate(squares)
    return CrossValidation(
        model=model,
        unknowns=len(full.free_names),
        folds=folds,
        seed=int(seed),
        calibration_rms_mm=float(full.residual_rms),
        cv_rms_mm=float(np.sqrt(pooled.mean())),
        fold_mse_mm2=_frozen(fold_mse),
        se_mm2=float(fold_mse.std(ddof=1) / np.sqrt(folds)),
        failed_folds=failed,
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
