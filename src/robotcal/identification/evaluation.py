"""Before/after evaluation of parameter sets on measured captures (thesis Tables 4.10 and 4.11).

Two views of the error, one per criterion of ch. 4.5.7:

``"points"`` (Table 4.10)
    each parameter set's predicted target positions (base frame) are registered onto the measured
    points (tracker frame) by Horn's method, and the error of a point is its distance after
    registration ``|T p_k - m_k|``.
``"distances"`` (Table 4.11)
    the error of a pair i < j of distinct measurements (different poses or, with per-joint
    reflectors, different targets) is ``| |p_i - p_j| - |m_i - m_j| |``,
    over all such pairs (no registration).

``"absolute"`` (issue 14, ``evaluate --absolute``)
    the error of a point is ``|T p_k - m_k|`` with the *given* base frame ``T`` (the scenario's
    ``tracker_from_base`` or the one a refinement estimated), no re-registration: the held-out error a
    user of the calibrated model sees. A parameter set without a base frame (the distances criterion
    estimates none) is evaluated with the scenario's, and the caller says so.

Captures with a ``target`` column are evaluated point by point on their own targets (each capture may
name its own); the unknown offsets are the ones the evaluated parameter set estimated. Where a set did not
estimate the offset of a target that points lie on, those points are predicted at the target's guess: a
:class:`GuessedOffsetWarning` names the set, the targets and the captures (their errors measure the guess).

The improvement of a set is ``100 (1 - mean / mean_reference)`` [%], the reference being the
first set given (normally the nominal parameters), per view and capture, as in the tables'
"Mejora promedio" columns (e.g. test 2, CPA: 1 - 0.6498/1.0015 = 35.12 %).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import InputError, RobotcalWarning
from robotcal.geometry.registration import register_points
from robotcal.identification._problem import capture_target_index, capture_turning_joints, measurement_pairs, pdist
from robotcal.identification.targets import Target, resolve_targets
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount

__all__ = [
    "VIEWS",
    "ALL_VIEWS",
    "EvaluationRow",
    "point_errors",
    "predicted_points",
    "distinct_pairs",
    "distance_errors",
    "absolute_errors",
    "evaluate_parameters",
    "guessed_targets",
    "GuessedOffsetWarning",
]

#: Evaluation views (Tables 4.10, 4.11).
VIEWS = ("points", "distances")
#: Every view: ``"absolute"`` needs a base frame per parameter set.
ALL_VIEWS = ("points", "distances", "absolute")


@dataclass(frozen=True, slots=True, kw_only=True)
class EvaluationRow:
    """Errors of one parameter set on one capture under one view [mm]."""

    parameter_set: str
    view: str
    capture: str
    n_errors: int
    mean_error_mm: float
    max_error_mm: float
    rms_error_mm: float
    improvement_pct: float


class GuessedOffsetWarning(RobotcalWarning):
    """Points on a target declared with an unknown offset are evaluated at its guess (``guess_mm``): the parameter
    set did not estimate that offset, so the errors of those points measure the guess, not the set."""


def guessed_targets(capture: Capture, reflector, offsets: Mapping[str, tuple]) -> tuple[str, ...]:
    """Names of the targets with an unknown offset that points of ``capture`` lie on and that ``offsets`` (a set's
    estimated offsets, name -> (x, y, z) [mm]) does not give: those points are predicted at the target's guess.
    ``reflector`` as for :func:`predicted_points` (a :class:`ReflectorMount` is always known)."""
    if isinstance(reflector, ReflectorMount):
        return ()
    targets, _ = resolve_targets(capture, (reflector,) if isinstance(reflector, Target) else tuple(reflector))
    return tuple(t.name for t in targets if t.frame == "flange" and not t.known and t.name not in offsets)


def _warn_guessed(captures, parameter_sets, reflectors, set_targets) -> None:
    """One :class:`GuessedOffsetWarning` per parameter set that leaves targets of the captures at their guess."""
    for set_name in parameter_sets:
        offsets = (set_targets or {}).get(set_name) or {}
        guessed: dict[str, list[str]] = {}
        for capture_name, capture in captures.items():
            reflector = reflectors if isinstance(reflectors, ReflectorMount) else reflectors.get(capture_name)
            if reflector is None:
                continue  # refused below, naming the capture
            for target in guessed_targets(capture, reflector, offsets):
                guessed.setdefault(target, []).append(repr(capture_name))
        if not guessed:
            continue
        names = ", ".join(guessed)
        which = sorted({name for names_of in guessed.values() for name in names_of})
        warnings.warn(
            f"parameter set {set_name!r} estimated no offset for target{'s' if len(guessed) > 1 else ''} {names} "
            f"(declared unknown): {'its' if len(guessed) == 1 else 'their'} points in capture{'s' if len(which) > 1 else ''} "
            f"{', '.join(which)} are predicted at the guess (guess_mm), so their errors measure the guess, not the "
            "set; evaluate a parameter set that estimated the offset",
            GuessedOffsetWarning,
            stacklevel=3,
        )


def predicted_points(capture: Capture, parameters: ParameterSet, reflector) -> np.ndarray:
    """Predicted base-frame points; ``reflector`` a :class:`ReflectorMount` or :class:`Target` object(s)."""
    robot = parameters.robot
    if capture.n_joints != robot.n_joints:
        raise InputError(
            f"{capture.source}: {capture.n_joints} joint readings per point; robot {robot.name!r} has {robot.n_joints}"
        )
    q = parameters.model_joint_variables(capture.readings)
    if isinstance(reflector, ReflectorMount):
        turning = capture_turning_joints(capture, reflector)
        return target_positions(parameters.values, q, turning, reflector)
    targets, index = resolve_targets(capture, (reflector,) if isinstance(reflector, Target) else tuple(reflector))
    turning = np.maximum(capture.circle - 1, 0)
    points = np.empty((capture.n_points, 3))
    for t, target in enumerate(targets):
        rows = np.flatnonzero(index == t)
        if target.frame == "joint" and np.any(capture.circle[rows] == 0):
            raise InputError(f"{capture.source}: free poses (circle = 0) on the per-joint target {target.name!r}")
        points[rows] = target_positions(parameters.values, q[rows], turning[rows], target.mount)
    return points


def distinct_pairs(capture: Capture, reflector, n_joints: int) -> np.ndarray:
    """Which pairs of :func:`scipy.spatial.distance.pdist` order are distinct measurements (as the refinement's
    distances criterion takes them), ``(n_points (n_points - 1) / 2,)`` bool."""
    if isinstance(reflector, ReflectorMount):
        key = capture_target_index(capture, reflector)
    else:
        targets, index = resolve_targets(capture, (reflector,) if isinstance(reflector, Target) else tuple(reflector))
        is_joint = np.array([target.frame == "joint" for target in targets])
        key = index * (n_joints + 1) + np.where(is_joint[index], np.maximum(capture.circle - 1, 0) + 1, 0)
    return measurement_pairs(capture.readings, key)[2]


def absolute_errors(capture: Capture, parameters: ParameterSet, reflector, tracker_from_base) -> np.ndarray:
    """``|T p_k - m_k|`` with the given base frame ``T`` (no registration), ``(n_points,)`` [mm]."""
    predicted = predicted_points(capture, parameters, reflector)
    transform = np.asarray(tracker_from_base, dtype=float)
    in_tracker = predicted @ transform[:3, :3].T + transform[:3, 3]
    return np.linalg.norm(in_tracker - capture.points, axis=1)


def point_errors(capture: Capture, parameters: ParameterSet, reflector) -> np.ndarray:
    """Per-point distance after registering the predicted points onto the measured ones, ``(n_points,)`` [mm]."""
    predicted = predicted_points(capture, parameters, reflector)
    return register_points(predicted, capture.points).residuals


def distance_errors(capture: Capture, parameters: ParameterSet, reflector) -> np.ndarray:
    """``| |p_i - p_j| - |m_i - m_j| |`` over pairs of distinct measurements, ``(n_pairs,)`` [mm].

    A pair at the same readings on the same target (bidirectional twins) is left out; with per-joint
    reflectors points of different circles are different targets (see
    :func:`robotcal.identification.refine.measurement_pairs`).
    """
    predicted = predicted_points(capture, parameters, reflector)
    keep = distinct_pairs(capture, reflector, parameters.robot.n_joints)
    return np.abs(pdist(predicted) - pdist(capture.points))[keep]


def evaluate_parameters(
    captures: Mapping[str, Capture],
    parameter_sets: Mapping[str, ParameterSet],
    reflectors: Mapping[str, ReflectorMount] | ReflectorMount,
    *,
    views=VIEWS,
    bases: Mapping[str, np.ndarray] | None = None,
    set_targets: Mapping[str, Mapping[str, tuple]] | None = None,
) -> tuple[EvaluationRow, ...]:
    """Mean, max and RMS errors of every parameter set on every capture under each view.

    Parameters
    ----------
    captures : mapping of str to Capture
        E.g. ``{"calibration": ..., "validation": ...}``.
    parameter_sets : mapping of str to ParameterSet
        E.g. ``{"nominal": ..., "cpa": ..., "points": ..., "distances": ...}``; the first is the
        reference of ``improvement_pct``.
    reflectors : ReflectorMount or mapping of str to ReflectorMount
        The target of each capture (one for all, or per capture name).
    views : sequence of {"points", "distances", "absolute"}
    bases : mapping of str to ndarray (4, 4), optional
        ``"absolute"`` view: the base frame of each parameter set; a set without one (absent or None) is left out
        of that view, whose improvements are then relative to the first set that has one.
    set_targets : mapping of str to mapping of str to (x, y, z), optional
        Per parameter set, flange offsets [mm] that replace those of same-named targets (the offsets
        a refinement estimated for targets declared unknown).

    Warns
    -----
    GuessedOffsetWarning
        Once per parameter set that leaves a target with an unknown offset, which points of the captures lie on,
        at its guess (:func:`guessed_targets`), naming the set, the targets and the captures.

    Returns
    -------
    tuple of EvaluationRow
        Ordered by capture, view, parameter set.
    """
    if not captures or not parameter_sets:
        raise InputError("evaluation needs at least one capture and one parameter set")
    unknown = [view for view in views if view not in ALL_VIEWS]
    if unknown:
        raise InputError(f"unknown evaluation view(s) {unknown}; expected {ALL_VIEWS}")
    frames: Mapping[str, np.ndarray] = {} if bases is None else bases
    if "absolute" in views and not any(frames.get(name) is not None for name in parameter_sets):
        raise InputError("the absolute view needs the base frame of at least one parameter set; none was given")

    _warn_guessed(captures, parameter_sets, reflectors, set_targets)

    def errors_of(view, capture, set_name, parameters, reflector):
        offsets = (set_targets or {}).get(set_name) or {}
        if offsets and not isinstance(reflector, ReflectorMount):
            given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
            reflector = tuple(
                t.with_position(offsets[t.name]) if t.frame == "flange" and t.name in offsets else t for t in given
            )
        if view == "absolute":
            return absolute_errors(capture, parameters, reflector, frames[set_name])
        return (point_errors if view == "points" else distance_errors)(capture, parameters, reflector)

    rows = []
    for capture_name, capture in captures.items():
        reflector = reflectors if isinstance(reflectors, ReflectorMount) else reflectors.get(capture_name)
        if reflector is None:
            raise InputError(f"no reflector given for capture {capture_name!r}")
        for view in views:
            reference = None
            for set_name, parameters in parameter_sets.items():
                if view == "absolute" and frames.get(set_name) is None:
                    continue  # no base frame for this set: left out of the absolute view (the caller says why)
                errors = errors_of(view, capture, set_name, parameters, reflector)
                mean = float(errors.mean())
                reference = mean if reference is None else reference
                improvement = 100.0 * (1.0 - mean / reference) if reference > 0 else 0.0
                rows.append(
                    EvaluationRow(
                        parameter_set=set_name,
                        view=view,
                        capture=capture_name,
                        n_errors=int(errors.size),
                        mean_error_mm=mean,
                        max_error_mm=float(errors.max()),
                        rms_error_mm=float(np.sqrt(np.mean(errors**2))),
                        improvement_pct=float(improvement),
                    )
                )
    return tuple(rows)
