"""The measurement frames of a refinement (issue 29): the sessions of a capture (a base frame per tracker station)
and a 6-DoF probe's rotation on the flange; their starts, the orientation residuals' weights, and the records
:class:`~robotcal.identification.records.SessionFrame` and :class:`~robotcal.identification.records.ProbeFrame`
of a solution. The notes of docs/refinement.md (measurement sessions, 6-DoF probes) describe the choices.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import nearest_rotation
from robotcal.identification._problem import Problem, Setup, State, point_sigmas
from robotcal.identification.health import repeatability_sigma
from robotcal.identification.records import ProbeFrame, SessionFrame
from robotcal.kinematics.forward import probe_rotations

__all__ = ["PROBE_NAMES", "capture_sessions", "session_starts", "with_probe", "session_frames", "probe_frame"]

#: Names of the three corrections of a 6-DoF probe's rotation in the flange frame (``R_P = R_P0 Rz Ry Rx``).
PROBE_NAMES = ("probe.rx", "probe.ry", "probe.rz")


def capture_sessions(capture: Capture) -> tuple[tuple[str, ...], np.ndarray | None]:
    """The sessions the capture's points use (in order of first appearance) and each point's index into them;
    ``((), None)`` for one session (no ``session`` column, or a single name in it)."""
    if capture.session is None:
        return (), None
    used, first, index = np.unique(capture.session, return_index=True, return_inverse=True)
    if used.size < 2:
        return (), None
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return tuple(capture.session_names[used[k]] for k in order), rank[index.ravel()]


def session_starts(probe: Problem, values, offset_start, source: str, names) -> Problem:
    """The start frames of a capture of several sessions: each session's points registered (Horn) onto the start
    model's; the first session's frame stays the given one when there is one."""
    start = State(values, probe.extra_start, offset_start, np.zeros(6))
    points = probe.base_points(start)
    frames = []
    for s in range(len(names)):
        rows = np.flatnonzero(probe.session_index == s)
        if rows.size < 3:
            raise InputError(f"{source}: session {names[s]!r} has {rows.size} points; its base frame needs at least 3")
        frames.append(register_points(points[rows], probe.measured[rows]).transform)
    base_start = frames[0] if probe.base_start is None else probe.base_start
    return replace(probe, base_start=base_start, session_starts=np.stack(frames[1:]))


def _orientation_sigmas(
    capture: Capture, instrument, repeatability_mm: float | None = None
) -> tuple[np.ndarray, float]:
    """Standard uncertainty of each point's orientation [rad] and the points' reference position u [mm]: what
    weighs an orientation residual against a position one (``u_position / u_angle`` [mm/rad]); the position u holds
    the robot's pose scatter when its repeatability is stated, as the position weights do."""
    if capture.orientation_u95 is not None:
        angle = np.asarray(capture.orientation_u95, dtype=float) / 2.0
    elif instrument is not None and instrument.orientation_standard_uncertainty:
        angle = np.full(capture.n_points, instrument.orientation_standard_uncertainty)
    else:
        raise InputError(
            f"{capture.source}: the capture has orientations but no stated orientation uncertainty: give a "
            "`u95_deg` column or an instrument with an orientation term (e.g. preset 6dof-probe)"
        )
    sigmas = point_sigmas(capture, repeatability_mm)
    if sigmas is None and instrument is not None and not instrument.is_noise_free:
        sigmas = np.hypot(instrument.standard_uncertainty(capture.points), repeatability_sigma(repeatability_mm))
    if sigmas is None:
        raise InputError(
            f"{capture.source}: weighing orientation against position needs the positions' uncertainty too: give "
            "a `u95_mm` column or the scenario's [instrument]"
        )
    return angle, float(np.sqrt(np.mean(np.square(sigmas))))


def with_probe(
    probe: Problem, capture: Capture, instrument, start: State, repeatability_mm: float | None = None
) -> Problem:
    """The problem with the orientation residuals of a 6-DoF capture (points criterion): every point oriented,
    weights ``u_position / u_angle``, the probe's rotation started at the chordal mean of ``(T F)^T R_m``."""
    measured = capture.orientation
    if measured is None:
        raise InputError(f"{capture.source}: no orientations (a position-only capture)")
    angle, reference = _orientation_sigmas(capture, instrument, repeatability_mm)
    oriented = replace(probe, oriented=np.arange(capture.n_points), measured_rotations=measured,
                       orientation_weight=reference / angle)  # fmt: skip
    q = oriented.joint_variables(start.extras)
    trackers = oriented.trackers(start)
    session = np.zeros(capture.n_points, dtype=int) if probe.session_index is None else probe.session_index
    seen = probe_rotations(start.values, q, np.eye(3), trackers[session])  # R_T F: the probe's rotation left out
    return replace(oriented, probe_start=nearest_rotation(np.einsum("pji,pjk->ik", seen, measured)))


def session_frames(setup: Setup, problem: Problem, selection, solved: State, covariance) -> tuple[SessionFrame, ...]:
    """The base frame of every session with the standard uncertainties of its corrections (empty for one
    session); the first session's are the ``base.*`` corrections, the others' follow the unknown offsets."""
    if not setup.session_names:
        return ()
    offset_sd = np.full(problem.offset_start.size, np.nan)
    base_sd = np.full(6, np.nan)
    if covariance is not None:
        diagonal = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
        bounds = np.cumsum([problem.n_kinematic, problem.n_extra, problem.n_offsets])
        offset_sd[selection.offset_free] = diagonal[bounds[1] : bounds[2]]
        base_sd[selection.base_free] = diagonal[bounds[2] :]
    trackers = problem.trackers(solved)
    frames = []
    for s, name in enumerate(setup.session_names):
        sd = base_sd
        if s > 0:
            first = 3 * len(problem.unknown) + 6 * (s - 1)
            sd = offset_sd[first : first + 6].copy()
            sd[3:] /= problem.rotation_length
        frames.append(SessionFrame(name=name, tracker_from_base=_frozen(trackers[s]), standard_uncertainty=_frozen(sd)))
    return tuple(frames)


def probe_frame(problem: Problem, selection, solved: State, covariance) -> ProbeFrame | None:
    """The 6-DoF probe's rotation with the standard uncertainties of its corrections (the last offsets row)."""
    if problem.oriented is None:
        return None
    sd = np.full(3, np.nan)
    if covariance is not None:
        bounds = np.cumsum([problem.n_kinematic, problem.n_extra, problem.n_offsets])
        offset_sd = np.full(problem.offset_start.size, np.nan)
        offset_sd[selection.offset_free] = np.sqrt(np.clip(np.diag(covariance), 0.0, None))[bounds[1] : bounds[2]]
        sd = offset_sd[-3:] / problem.rotation_length
    error, _ = problem.orientation_part(solved, jacobian=False)
    rms = float(np.rad2deg(np.sqrt(np.mean(np.sum(error**2, axis=1)))))
    rotation = problem.probe_rotation(solved)[0]
    return ProbeFrame(rotation=_frozen(rotation), standard_uncertainty=_frozen(sd), orientation_rms_deg=rms)
