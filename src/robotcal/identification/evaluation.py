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

Measurement sessions (issue 29): the points view registers each session of a capture on its own (a session is a
tracker station); the absolute view takes, for a session that a parameter set recorded a frame for
(``bases[set]`` a mapping of session name to frame), that frame, else the set's first frame. A capture (or
session) whose absolute error is far above its registered one (:func:`station_moved`: the RMS above
``STATION_RATIO`` times the registered RMS plus ``STATION_FLOOR_MM``) was measured from another station than the
recorded frame when every parameter set with a base frame shows it (a moved station moves them all; a set whose own
model is off, e.g. an uncalibrated J1, moves only its own): the capture's absolute rows carry ``station`` =
``"moved"`` and a :class:`StationMovedWarning` says so.

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
from robotcal.identification.targets import Target, resolve_targets, split_by_session
from robotcal.kinematics.forward import probe_rotations, target_positions
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
    "tracker_points",
    "evaluate_parameters",
    "guessed_targets",
    "GuessedOffsetWarning",
    "StationMovedWarning",
    "STATION_RATIO",
    "STATION_FLOOR_MM",
    "station_moved",
    "fitted_targets",
    "fit_frames",
    "OrientationRow",
    "orientation_errors",
    "evaluate_orientation",
]

#: A capture's absolute RMS error above ``STATION_RATIO`` times its registered RMS error plus ``STATION_FLOOR_MM``
#: is not the model's: the tracker stood elsewhere than the recorded base frame says (:func:`station_moved`).
STATION_RATIO = 3.0
STATION_FLOOR_MM = 0.1

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
    station: str = ""  # absolute view: "moved" when the capture's station is not the recorded base frame


class StationMovedWarning(RobotcalWarning):
    """A capture evaluated in the absolute view was measured from another tracker station than the base frame
    used: its absolute errors measure the station, not the parameter set (:func:`station_moved`)."""


class GuessedOffsetWarning(RobotcalWarning):
    """Points on a target declared with an unknown offset are evaluated at its guess (``guess_mm``): the parameter
    set did not estimate that offset, so the errors of those points measure the guess, not the set."""


def guessed_targets(capture: Capture, reflector, offsets: Mapping[str, tuple]) -> tuple[str, ...]:
    """Names of the targets with an unknown offset that points of ``capture`` lie on and that ``offsets`` (a set's
    estimated offsets, name -> (x, y, z) [mm]) does not give: those points are predicted at the target's guess.
    ``reflector`` as for :func:`predicted_points` (a :class:`ReflectorMount` is always known)."""
    if isinstance(reflector, ReflectorMount):
        return ()
    given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
    targets, _ = resolve_targets(*split_by_session(capture, given))
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


def _warn_moved(capture_name: str, set_names, sessions) -> None:
    which = "" if sessions == [None] else f" (session{'s' if len(sessions) > 1 else ''} {', '.join(sessions)})"
    sets = ", ".join(repr(name) for name in set_names)
    warnings.warn(
        f"capture {capture_name!r}{which} was measured from another tracker station than the base frame of "
        f"{sets}: its absolute error is far above its error after registration for every set, so the absolute view "
        "measures the station, not the parameters; give the capture a session the refinement estimated, or read "
        "the points view (each session registered on its own)",
        StationMovedWarning,
        stacklevel=4,
    )


def predicted_points(capture: Capture, parameters: ParameterSet, reflector, *, joint_errors=None) -> np.ndarray:
    """Predicted base-frame points; ``reflector`` a :class:`ReflectorMount` or :class:`Target` object(s);
    ``joint_errors`` the error transforms ``(n_points, n_joints, 4, 4)`` of a simulated robot
    (:func:`robotcal.kinematics.forward.target_positions`), none by default."""
    robot = parameters.robot
    if capture.n_joints != robot.n_joints:
        raise InputError(
            f"{capture.source}: {capture.n_joints} joint readings per point; robot {robot.name!r} has {robot.n_joints}"
        )
    q = parameters.model_joint_variables(capture.readings)
    if isinstance(reflector, ReflectorMount):
        turning = capture_turning_joints(capture, reflector)
        return target_positions(parameters.values, q, turning, reflector, joint_errors=joint_errors)
    given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
    targets, index = resolve_targets(*split_by_session(capture, given))
    turning = np.maximum(capture.circle - 1, 0)
    points = np.empty((capture.n_points, 3))
    for t, target in enumerate(targets):
        rows = np.flatnonzero(index == t)
        if target.frame == "joint" and np.any(capture.circle[rows] == 0):
            raise InputError(f"{capture.source}: free poses (circle = 0) on the per-joint target {target.name!r}")
        errors = None if joint_errors is None else joint_errors[rows]
        points[rows] = target_positions(parameters.values, q[rows], turning[rows], target.mount, joint_errors=errors)
    return points


def distinct_pairs(capture: Capture, reflector, n_joints: int) -> np.ndarray:
    """Which pairs of :func:`scipy.spatial.distance.pdist` order are distinct measurements (as the refinement's
    distances criterion takes them: of one session), ``(n_points (n_points - 1) / 2,)`` bool."""
    if isinstance(reflector, ReflectorMount):
        key = capture_target_index(capture, reflector)
    else:
        given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
        targets, index = resolve_targets(*split_by_session(capture, given))
        is_joint = np.array([target.frame == "joint" for target in targets])
        key = index * (n_joints + 1) + np.where(is_joint[index], np.maximum(capture.circle - 1, 0) + 1, 0)
    keep = measurement_pairs(capture.readings, key)[2]
    if capture.session is not None:  # a distance between two stations (sessions) is no measurement
        pair_i, pair_j = np.triu_indices(capture.n_points, k=1)
        keep &= capture.session[pair_i] == capture.session[pair_j]
    return keep


def _session_groups(capture: Capture) -> list[tuple[str | None, np.ndarray]]:
    """``(session name, rows)`` of each session of the capture; one group ``(None, every row)`` without sessions."""
    if capture.session is None:
        return [(None, np.arange(capture.n_points))]
    groups = [(name, np.flatnonzero(capture.session == k)) for k, name in enumerate(capture.session_names)]
    return [(name, rows) for name, rows in groups if rows.size]


def _frame_of(tracker_from_base, session: str | None) -> np.ndarray:
    """The base frame for a session: ``tracker_from_base`` one (4, 4) frame, or a mapping of session name to frame
    (a refinement over sessions), whose first frame serves a session it does not name."""
    if isinstance(tracker_from_base, Mapping):
        frames = list(tracker_from_base.values())
        return np.asarray(tracker_from_base.get(session, frames[0]) if session is not None else frames[0], dtype=float)
    return np.asarray(tracker_from_base, dtype=float)


def absolute_errors(capture: Capture, parameters: ParameterSet, reflector, tracker_from_base) -> np.ndarray:
    """``|T p_k - m_k|`` with the given base frame ``T`` (no registration), ``(n_points,)`` [mm].

    ``tracker_from_base``: one (4, 4) frame, or a mapping of session name to frame (each point in its session's
    frame; a session the mapping does not name in its first frame)."""
    return np.linalg.norm(tracker_points(capture, parameters, reflector, tracker_from_base) - capture.points, axis=1)


def tracker_points(
    capture: Capture, parameters: ParameterSet, reflector, tracker_from_base, *, joint_errors=None
) -> np.ndarray:
    """The predicted points in the tracker frame ``(n_points, 3)`` [mm] (:func:`predicted_points`), each in its
    session's frame (``tracker_from_base`` as for :func:`absolute_errors`)."""
    predicted = predicted_points(capture, parameters, reflector, joint_errors=joint_errors)
    for session, rows in _session_groups(capture):
        transform = _frame_of(tracker_from_base, session)
        predicted[rows] = predicted[rows] @ transform[:3, :3].T + transform[:3, 3]
    return predicted


def point_errors(capture: Capture, parameters: ParameterSet, reflector) -> np.ndarray:
    """Per-point distance after registering the predicted points onto the measured ones, ``(n_points,)`` [mm];
    each session of a capture with a ``session`` column registered on its own (its own tracker station)."""
    predicted = predicted_points(capture, parameters, reflector)
    errors = np.empty(capture.n_points)
    for _, rows in _session_groups(capture):
        errors[rows] = register_points(predicted[rows], capture.points[rows]).residuals
    return errors


def station_moved(absolute: np.ndarray, registered: np.ndarray) -> bool:
    """Whether a capture's absolute errors (``|T p - m|`` in a recorded base frame) say the tracker stood elsewhere:
    their RMS above ``STATION_RATIO`` times the RMS after the capture's own registration plus ``STATION_FLOOR_MM``.
    A registration takes up the station (6 degrees of freedom) and nothing of the model's error beyond them, so on
    the recorded station the two are of one size; a moved station adds its displacement (hundreds of mm for a
    tracker moved between days) to the absolute one only."""
    rms_absolute = float(np.sqrt(np.mean(np.square(absolute))))
    rms_registered = float(np.sqrt(np.mean(np.square(registered))))
    return rms_absolute > STATION_RATIO * rms_registered + STATION_FLOOR_MM


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
    bases : mapping of str to ndarray (4, 4) or to a mapping of session name to ndarray (4, 4), optional
        ``"absolute"`` view: the base frame of each parameter set (per session for a refinement over sessions);
        a set without one (absent or None) is left out of that view, whose improvements are then relative to the
        first set that has one.
    set_targets : mapping of str to mapping of str to (x, y, z), optional
        Per parameter set, flange offsets [mm] that replace those of same-named targets (the offsets
        a refinement estimated for targets declared unknown).

    Warns
    -----
    StationMovedWarning
        A capture (or session) of the absolute view measured from another station than the base frame used
        (:func:`station_moved`); its rows carry ``station="moved"``.
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
        capture, reflector = _with_set_offsets(capture, reflector, (set_targets or {}).get(set_name))
        if view == "absolute":
            errors = absolute_errors(capture, parameters, reflector, frames[set_name])
            registered = point_errors(capture, parameters, reflector)
            moved = [name for name, rows in _session_groups(capture) if station_moved(errors[rows], registered[rows])]
            return errors, moved
        return (point_errors if view == "points" else distance_errors)(capture, parameters, reflector), []

    rows = []
    for capture_name, capture in captures.items():
        reflector = reflectors if isinstance(reflectors, ReflectorMount) else reflectors.get(capture_name)
        if reflector is None:
            raise InputError(f"no reflector given for capture {capture_name!r}")
        for view in views:
            reference = None
            outcomes = {
                set_name: errors_of(view, capture, set_name, parameters, reflector)
                for set_name, parameters in parameter_sets.items()
                if view != "absolute" or frames.get(set_name) is not None  # no base frame: left out (the caller says)
            }
            # a moved station moves every set's absolute errors; a set whose own model is off moves only its own
            moved = sorted(set.intersection(*(set(m) for _, m in outcomes.values())), key=str) if outcomes else []
            if moved:
                _warn_moved(capture_name, list(outcomes), moved)
            for set_name, (errors, _) in outcomes.items():
                mean = float(errors.mean())
                reference = mean if reference is None else reference
                improvement = 100.0 * (1.0 - mean / reference) if reference > 0 else 0.0
                rows.append(
                    EvaluationRow(
                        parameter_set=set_name, view=view, capture=capture_name, n_errors=int(errors.size),
                        mean_error_mm=mean, max_error_mm=float(errors.max()),
                        rms_error_mm=float(np.sqrt(np.mean(errors**2))), improvement_pct=float(improvement),
                        station="moved" if moved else "",
                    )  # fmt: skip
                )
    return tuple(rows)


def _with_set_offsets(capture: Capture, reflector, offsets):
    """The capture and targets with the flange offsets a parameter set estimated (``offsets``: name -> xyz [mm])
    in place of same-named targets' (a re-seated target split per session first)."""
    if not offsets or isinstance(reflector, ReflectorMount):
        return capture, reflector
    capture, given = split_by_session(capture, (reflector,) if isinstance(reflector, Target) else reflector)
    moved = tuple(t.with_position(offsets[t.name]) if t.frame == "flange" and t.name in offsets else t for t in given)
    return capture, moved


@dataclass(frozen=True, slots=True, kw_only=True)
class OrientationRow:
    """Orientation errors of one parameter set on one 6-DoF capture under one view [deg] (issue 29)."""

    parameter_set: str
    view: str
    capture: str
    n_errors: int
    mean_error_deg: float
    max_error_deg: float
    rms_error_deg: float


def orientation_errors(
    capture: Capture, parameters: ParameterSet, reflector, probe_rotation, tracker_from_base=None
) -> np.ndarray:
    """Angle of ``R_m^T R_T F R_P`` per point [deg]: the measured orientation against the model's, the probe's
    rotation ``R_P`` on the flange as a refinement estimated it. ``R_T``: the rotation of ``tracker_from_base`` (one
    frame or a mapping of session name to frame, as :func:`absolute_errors`), or, without it, that of each
    session's registration of the predicted points onto the measured ones (the points view)."""
    from robotcal.geometry.rotations import rotation_vectors

    if capture.orientation is None:
        raise InputError(f"{capture.source}: no orientation to evaluate (position-only capture)")
    predicted = predicted_points(capture, parameters, reflector)
    trackers = np.empty((capture.n_points, 4, 4))
    for session, rows in _session_groups(capture):
        if tracker_from_base is None:
            trackers[rows] = register_points(predicted[rows], capture.points[rows]).transform
        else:
            trackers[rows] = _frame_of(tracker_from_base, session)
    q = parameters.model_joint_variables(capture.readings)
    model = probe_rotations(parameters.values, q, probe_rotation, trackers)
    error = rotation_vectors(np.einsum("pji,pjk->pik", capture.orientation, model))
    return np.rad2deg(np.linalg.norm(error, axis=1))


def evaluate_orientation(
    captures: Mapping[str, Capture],
    parameter_sets: Mapping[str, ParameterSet],
    reflectors,
    probes: Mapping[str, np.ndarray],
    *,
    views=("points",),
    bases: Mapping[str, object] | None = None,
    set_targets: Mapping[str, Mapping[str, tuple]] | None = None,
) -> tuple[OrientationRow, ...]:
    """Orientation errors (:func:`orientation_errors`) of every set with a probe rotation (``probes``: set name ->
    (3, 3)) on every capture with orientations, under the ``"points"`` and ``"absolute"`` views (the latter for
    the sets ``bases`` gives a frame); the other sets and captures are left out."""
    rows = []
    for capture_name, capture in captures.items():
        if capture.orientation is None:
            continue
        reflector = reflectors if isinstance(reflectors, ReflectorMount) else reflectors[capture_name]
        for view in views:
            for set_name, parameters in parameter_sets.items():
                base = None if view == "points" else (bases or {}).get(set_name)
                if set_name not in probes or (view == "absolute" and base is None):
                    continue
                measured, targets = _with_set_offsets(capture, reflector, (set_targets or {}).get(set_name))
                errors = orientation_errors(measured, parameters, targets, probes[set_name], base)
                rows.append(
                    OrientationRow(
                        parameter_set=set_name, view=view, capture=capture_name, n_errors=int(errors.size),
                        mean_error_deg=float(errors.mean()), max_error_deg=float(errors.max()),
                        rms_error_deg=float(np.sqrt(np.mean(errors**2))),
                    )  # fmt: skip
                )
    return tuple(rows)


def fitted_targets(capture: Capture, reflector, fit) -> tuple[Capture, object]:
    """The capture and targets as a refinement ``fit`` saw them: a re-seated target split per session, and the
    offsets it estimated (its ``targets``, by name) in place of the given ones."""
    if not fit.targets or isinstance(reflector, ReflectorMount):
        return capture, reflector
    return _with_set_offsets(capture, reflector, {t.name: t.positions for t in fit.targets if not t.known})


def fit_frames(fit):
    """The base frame(s) a points-criterion refinement estimated: each session's (a mapping of session name to
    frame, as :func:`absolute_errors` takes it) or its one ``tracker_from_base``."""
    return {frame.name: frame.tracker_from_base for frame in fit.sessions} or fit.tracker_from_base
