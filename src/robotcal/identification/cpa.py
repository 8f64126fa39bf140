"""Circle Point Analysis: joint axes from circles, parameters from adjacent axes (thesis ch. 4.4-4.5).

Steps (algorithms 5.2.2.1 and 5.2.2.2):

1. Per circle, an orthogonal plane fit and a circle fit give the joint axis (normal, centre) as a
   Plücker line in the tracker frame. The axis is oriented so that the target turns right-handed
   about it as the model joint variable grows, and checked against the nominal model's z axis.
2. Every axis is brought into one common *reference configuration* (joint j at the model variable
   where its own circle ended). A circle of joint k is measured with the earlier joints at the model
   variables of that circle; by the product-of-exponentials form of the kinematics, the axis in the
   reference configuration is ``D^-1 L`` with ``D = Rot(L_1, dq_1) ... Rot(L_{k-1}, dq_{k-1})``, the
   rotations about the already-referenced earlier axes by the model-variable differences. Which
   joint turns in a circle, and that the others rest, is also judged on the model variables, so a
   robot with coupled readings (a Fanuc-style J3 reading that follows J2) is handled: in a circle of
   J2 its J3 reading changes while J3's model variable rests. This is exact, so real
   captures whose circles start from their own configurations (Table 4.2) are handled, and the
   thesis generator's sequence (earlier joints resting where they ended) gives ``D = I``.
3. The base frame (``tracker_from_base``) is given or registered (Horn) against the nominal model;
   it gives the robot origin (for d1) and the base x axis (for theta1), unless the theta1 reference
   is taken from the circle-1 data (``base_axis="circle1"``, docs/conventions.md).
4. Adjacent axes (j, j+1) give the frame of joint j: skew / intersecting / parallel DH pairs by
   eqs 4-35/4-36, 4-44, 4-52, a Hayati pair by Solution 3 (4.4.4.3). Then d_j is the signed
   distance along S_j between the feet of the previous and next common normals (eq. 4-91, signed)
   and theta_j the right-handed angle from x_{j-1} to x_j about S_j (eqs 4-92, 4-93) minus the
   reference reading.
5. Joint n's d, theta, a, alpha cannot be seen by CPA and stay nominal.

Everything is vectorised over leading axes of the measured points, so a Monte Carlo batch of noisy
copies of one capture is identified in a single call (:func:`identify_cpa_batch`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import DegenerateGeometryError, IdentifiabilityWarning, InputError
from robotcal.geometry._vectors import cross as _cross
from robotcal.geometry._vectors import dot as _dot
from robotcal.geometry._vectors import unit as _unit
from robotcal.geometry.fits import CircleFit, fit_circle_3d
from robotcal.geometry.lines import PluckerLine, analyse_dh_pair, analyse_hayati_pair, signed_angle_about
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import apply_transform, check_rigid_transform, rotation_about_line
from robotcal.identification.health import FitHealth
from robotcal.kinematics.forward import joint_frames, target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount, RobotModel

__all__ = ["CPAOptions", "CPAResult", "CPABatch", "identify_cpa", "identify_cpa_batch", "prepare_cpa"]

_D, _THETA, _A, _ALPHA, _BETA = range(5)

#: Largest coordinate accepted in a capture [mm] (10 km): anything larger is a corrupt value, and
#: squares of it overflow the fits.
MAX_COORDINATE_MM = 1e7
#: A circle whose points all lie within this distance of their mean [mm] did not move.
STILL_POINTS_MM = 1e-6
#: A resting joint that moves by less than this [deg] may be the rounding of logged readings (error hint).
ROUNDING_HINT_DEG = 0.01


def point_rows(rows: np.ndarray, limit: int = 6) -> str:
    """``"points 3, 4, 9 (CSV lines 4, 5, 10)"`` for 0-based capture rows (lines assume no blank lines)."""
    rows = np.asarray(rows).ravel()
    shown = ", ".join(str(r + 1) for r in rows[:limit]) + (", ..." if rows.size > limit else "")
    lines = ", ".join(str(r + 2) for r in rows[:limit]) + (", ..." if rows.size > limit else "")
    noun = "point" if rows.size == 1 else "points"
    return f"{noun} {shown} (CSV line{'s' if rows.size > 1 else ''} {lines})"


def _check_circle_points(points: np.ndarray, rows: np.ndarray, joint: int, src: str) -> None:
    """Refuse a circle with unusable coordinates (non-finite, absurd magnitude, all points identical)."""
    circle = points[rows]
    bad = np.flatnonzero(~np.all(np.isfinite(circle), axis=-1) | np.any(np.abs(circle) > MAX_COORDINATE_MM, axis=-1))
    if bad.size:
        raise InputError(
            f"{src}: circle {joint + 1}, {point_rows(rows[bad])}: a coordinate is not finite or beyond "
            f"{MAX_COORDINATE_MM:g} mm (a corrupt value?)"
        )
    spread = np.max(np.linalg.norm(circle - circle.mean(axis=0), axis=-1))
    if spread <= STILL_POINTS_MM:
        raise DegenerateGeometryError(
            f"{src}: circle {joint + 1}: all {rows.size} points (points {rows[0] + 1}..{rows[-1] + 1}) "
            f"are the same point within {STILL_POINTS_MM:g} mm: the target did not move while J{joint + 1} turned "
            "(a target on the axis, or a copied row?)"
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class CPAOptions:
    """Choices of the CPA identification.

    Attributes
    ----------
    circle_fit : {"geometric", "algebraic"}
        In-plane circle fit (see :func:`robotcal.geometry.fit_circle_3d`).
    base_frame : {"given", "registered"}
        ``given``: use the ``tracker_from_base`` passed in; ``registered``: estimate it by Horn's
        method from all measured points and the nominal model's predictions.
    base_axis : {"registration", "circle1"}
        Reference for theta1: the x axis of ``tracker_from_base``, or the circle-1 data (fitted
        centre to the first point, turned back by that point's known angle; docs/conventions.md). With a
        per-circle reflector that angle is exact (reading plus the target's azimuth in frame {0});
        with a flange reflector it is predicted by the nominal model, so theta1 then absorbs the
        deviations of the later joints (about 1e-3 rad for 0.5 mm / 0.2 deg deviations).
    near_parallel_deg : float
        Largest angle between the axes of a Hayati joint (Solution 3); DH pairs closer than this
        are analysed exactly but flagged as ill-conditioned.
    still_tolerance_deg : float
        How much a joint other than the turning one may vary within a circle.
    """

    circle_fit: Literal["geometric", "algebraic"] = "geometric"
    base_frame: str = "given"
    base_axis: str = "registration"
    near_parallel_deg: float = 5.0
    still_tolerance_deg: float = 1e-6

    def __post_init__(self) -> None:
        choices = {
            "circle_fit": ("geometric", "algebraic"),
            "base_frame": ("given", "registered"),
            "base_axis": ("registration", "circle1"),
        }
        for name, allowed in choices.items():
            if getattr(self, name) not in allowed:
                raise InputError(
                    f"identification option `{name}` must be one of {allowed}; got {getattr(self, name)!r}"
                )
        for name in ("near_parallel_deg", "still_tolerance_deg"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise InputError(f"identification option `{name}` must be a finite number >= 0; got {value!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class _Structure:
    """What CPA needs from a capture besides the measured points (shared by a whole batch)."""

    robot: RobotModel
    reflector: ReflectorMount
    options: CPAOptions
    circle_indices: tuple[np.ndarray, ...]
    model_q: np.ndarray
    reference_readings: np.ndarray
    reference_q: np.ndarray
    transport: np.ndarray
    nominal_points: np.ndarray
    circle1_azimuth: float
    source: str


@dataclass(frozen=True, slots=True, kw_only=True)
class CPABatch:
    """Batched CPA output: leading axes ``(...)`` follow the measured points.

    Attributes
    ----------
    values : ndarray, shape (..., n_joints, 5)
        Identified ``d, theta, a, alpha, beta`` [mm, rad] (nominal where not identifiable).
    identified : ndarray of bool, shape (n_joints, 5)
    axes : PluckerLine, shape (..., n_joints)
        Joint axes in the tracker frame, reference configuration.
    circle_fits : tuple of CircleFit
        One per circle (joint), batched.
    pair_cases : tuple of str
        Line-pair case of joints 1..n-1 (of the first batch item).
    tracker_from_base : ndarray, shape (..., 4, 4)
    registration_rms : ndarray, shape (...) or None
        RMS residual [mm] of the registration when ``base_frame="registered"``.
    """

    values: np.ndarray
    identified: np.ndarray
    axes: PluckerLine
    circle_fits: tuple[CircleFit, ...]
    pair_cases: tuple[str, ...]
    tracker_from_base: np.ndarray
    registration_rms: np.ndarray | None


@dataclass(frozen=True, slots=True, kw_only=True)
class CPAResult:
    """CPA identification of one capture.

    Attributes
    ----------
    parameters : ParameterSet
        Identified parameters; ``parameters.identified`` marks the 20 (for a 6R robot) that CPA
        determines, the others are nominal.
    axes : PluckerLine, shape (n_joints,)
        Joint axes in the tracker frame at the reference configuration.
    reference_readings : ndarray, shape (n_joints,)
        Controller readings of the reference configuration [rad]; identified theta is the
        geometric angle minus this (mapped to the model variable). Uncoupled robots: reading j of
        the last point of circle j; coupled robots: ``readings_from_model`` of the model variables
        (joint j's at the last point of circle j), since one reading then mixes several joints.
    circle_fits : tuple of CircleFit
        Per circle: centre, normal, radius, residuals, ``plane_rms`` and ``circle_rms`` [mm].
    pair_cases : tuple of str
        Line-pair case of joints 1..n-1.
    tracker_from_base : ndarray, shape (4, 4)
        Base frame used (given or registered).
    registration_rms : float or None
        RMS residual of the registration [mm] (registered base frame only).
    options : CPAOptions
    success : bool
    message : str
    health : FitHealth or None
        The fit-health verdict (:mod:`robotcal.identification.health`), set by :func:`robotcal.identify`.
    """

    parameters: ParameterSet
    axes: PluckerLine
    reference_readings: np.ndarray
    circle_fits: tuple[CircleFit, ...]
    pair_cases: tuple[str, ...]
    tracker_from_base: np.ndarray
    registration_rms: float | None
    options: CPAOptions
    success: bool = True
    message: str = field(default="")
    health: FitHealth | None = None

    def __repr__(self) -> str:
        health = f", {self.health.verdict}" if self.health is not None else ""
        fitted = [float(fit.circle_rms) for fit in self.circle_fits if fit.circle_rms is not None]
        worst = max(fitted, default=float("nan"))
        return (
            f"CPAResult({len(self.circle_fits)} circles, {int(self.parameters.identified.sum())} parameters, circle RMS "
            f"<= {worst * 1e3:.3g} um{health}, success={self.success})"
        )


def prepare_cpa(
    capture: Capture, robot: RobotModel, reflector: ReflectorMount, options: CPAOptions | None = None
) -> _Structure:
    """Validate a capture against the robot and precompute what every batch item shares."""
    options = CPAOptions() if options is None else options
    n = robot.n_joints
    src = capture.source
    if capture.n_joints != n:
        raise InputError(
            f"{src}: the capture has {capture.n_joints} joint readings per point; robot {robot.name!r} has {n} joints"
        )
    if reflector.frame == "joint" and reflector.positions.shape[0] != n:
        raise InputError(f"{src}: {reflector.positions.shape[0]} per-circle reflector positions for {n} joints")
    free_poses = np.flatnonzero(capture.circle == 0)
    if free_poses.size:
        raise InputError(
            f"{src}: {free_poses.size} points have circle = 0 (free poses, first on point {free_poses[0] + 1}); "
            "CPA needs circle points only: identify from the calibration capture, use free poses for refinement "
            "or evaluation"
        )
    # Which joint turns, and that the others rest, is decided on the MODEL joint variables: on a robot
    # whose readings are coupled (docs/conventions.md), a circle of J2 changes J3's reading while J3's
    # model variable rests. Uncoupled, q = sign * reading + offset, the same test as on the readings.
    model_q = robot.model_joint_variables(capture.readings)
    still_tol = np.deg2rad(options.still_tolerance_deg) + 1e-12
    indices = []
    configs = np.zeros((n, n))
    reference_q = np.zeros(n)
    for joint in range(n):
        rows = np.flatnonzero(capture.circle == joint + 1)
        if rows.size == 0:
            raise InputError(
                f"{src}: no circle for J{joint + 1}; CPA needs one circle per joint (circle = {joint + 1})"
            )
        if rows.size < 3:
            raise InputError(f"{src}: circle {joint + 1} has {rows.size} points; a circle needs at least 3")
        circle_q = model_q[rows]
        spread = circle_q.max(axis=0) - circle_q.min(axis=0)
        if spread[joint] <= still_tol:
            raise DegenerateGeometryError(f"{src}: circle {joint + 1}: joint J{joint + 1} does not turn (zero sweep)")
        moving = [k for k in range(n) if k != joint and spread[k] > still_tol]
        if moving:
            k = moving[0]
            raise InputError(
                f"{src}: circle {joint + 1}: joint J{k + 1} moves by {np.rad2deg(spread[k]):.6g} deg while J{joint + 1} turns; "
                f"only the turning joint may move within a circle{_coupling_hint(robot, joint, k)}"
                f"{_rounding_hint(spread[k], options)}"
            )
        _check_circle_points(capture.points, rows, joint, src)
        indices.append(rows)
        # a resting joint's variable exactly (the mean of n equal numbers can miss it by an ulp, and a transport
        # angle of 1e-16 rad instead of 0 costs every batch a rotation of the axes)
        configs[joint] = np.where(spread == 0.0, circle_q[0], circle_q.mean(axis=0))
        reference_q[joint] = circle_q[-1, joint]
    last_rows = np.array([rows[-1] for rows in indices])
    if robot.is_coupled:  # the readings of the reference configuration (all model variables at once)
        reference_readings = robot.readings_from_model(reference_q)
    else:  # the readings themselves, bit for bit
        reference_readings = capture.readings[last_rows, np.arange(n)]
    transport = configs - reference_q  # row k: dq_j for j < k used to bring axis k to the reference
    nominal_points = target_positions(robot.nominal, model_q, capture.circle - 1, reflector)
    circle1_azimuth = 0.0
    if options.base_axis == "circle1":
        circle1_azimuth = _circle1_azimuth(robot, reflector, model_q[indices[0][0]], src)
    return _Structure(
        robot=robot,
        reflector=reflector,
        options=options,
        circle_indices=tuple(indices),
        model_q=model_q,
        reference_readings=reference_readings,
        reference_q=reference_q,
        transport=transport,
        nominal_points=nominal_points,
        circle1_azimuth=circle1_azimuth,
        source=src,
    )


def _circle1_azimuth(robot: RobotModel, reflector: ReflectorMount, first_q: np.ndarray, src: str) -> float:
    """Azimuth about axis 1 of the circle-1 target at J1 = 0 plus J1 of circle 1's first point [rad]
    (``base_axis="circle1"``: the base x axis points at the target of circle 1 at J1 = 0)."""
    q_zero = first_q.copy()
    q_zero[0] = 0.0
    nominal = target_positions(robot.nominal, q_zero[None, :], np.array([0]), reflector)[0]
    if np.hypot(nominal[0], nominal[1]) < 1e-6:
        raise DegenerateGeometryError(f"{src}: base_axis='circle1' needs the circle-1 target off axis 1")
    return float(first_q[0] + np.arctan2(nominal[1], nominal[0]))


def _coupling_hint(robot: RobotModel, turning: int, moving: int) -> str:
    """On a coupled robot, why a resting joint may seem to move: its model variable, not its reading, must rest."""
    if not robot.is_coupled:
        return ""
    follow = robot.reading_matrix[:, turning] / robot.reading_matrix[turning, turning]
    followers = [
        f"J{k + 1}'s by {follow[k]:g} times J{turning + 1}'s change" for k in np.flatnonzero(follow) if k != turning
    ]
    rule = f"the readings follow it ({', '.join(followers)})" if followers else "no other reading changes"
    return (
        f" (robot {robot.name!r} couples its readings and J{moving + 1} here is its model joint variable: while "
        f"J{turning + 1} turns alone {rule}; docs/conventions.md, coupled readings)"
    )


def _rounding_hint(spread: float, options: CPAOptions) -> str:
    """Where a resting joint moves by a tiny angle: the rounding of the logged readings? (coupled readings
    mix two rounded values, so their model variable jitters)."""
    if np.rad2deg(spread) > ROUNDING_HINT_DEG:
        return ""
    return (
        f"; if that is the rounding of the logged readings, raise `[identification] still_tolerance_deg` "
        f"(now {options.still_tolerance_deg:g} deg) above it"
    )


def _oriented_axis(fit: CircleFit, points: np.ndarray, q_turn: np.ndarray) -> np.ndarray:
    """Flip the fitted normal where the target does not turn right-handed as q grows.

    The turn between consecutive points is ``(r_k x r_k+1) . n`` with ``r`` from the centre; with the
    fit's in-plane coordinates ``(du, dv)`` along ``u, v`` (``u x v = n``) it is the 2-D cross product
    ``du_k dv_k+1 - dv_k du_k+1`` (the axial parts drop out). The sense is the sum of the turns weighted
    by the steps of q, two one-pass sums of triple products.
    """
    steps = np.diff(q_turn)
    if fit.in_plane is not None:
        du, dv = fit.in_plane[..., 0], fit.in_plane[..., 1]
        sense = np.einsum("...k,...k,k->...", du[..., :-1], dv[..., 1:], steps)
        sense -= np.einsum("...k,...k,k->...", dv[..., :-1], du[..., 1:], steps)
    else:
        radial = points - fit.centre[..., None, :]
        turn = _dot(_cross(radial[..., :-1, :], radial[..., 1:, :]), fit.normal[..., None, :])
        sense = np.sum(turn * steps, axis=-1)
    return np.where((sense < 0.0)[..., None], -fit.normal, fit.normal)


def _turned_about(line: PluckerLine, axis: PluckerLine, angle: float) -> PluckerLine:
    """``line`` turned right-handed by ``angle`` [rad] (one angle for the whole batch) about ``axis``.

    Rodrigues' formula on the direction and on a point relative to the axis,
    ``x cos + (S x x) sin + S (S . x)(1 - cos)``: what ``line.transformed(rotation_about_line(...))``
    computes, without building and applying a batch of 4x4 matrices.
    """
    cosine, sine = np.cos(angle), np.sin(angle)
    s = axis.direction

    def turn(x: np.ndarray) -> np.ndarray:
        return x * cosine + _cross(s, x) * sine + s * (_dot(s, x) * (1.0 - cosine))[..., None]

    anchor = axis.point
    direction = turn(line.direction)
    point = anchor + turn(line.point - anchor)
    return PluckerLine(direction=direction, moment=_cross(point, direction))


def _row_selector(rows: np.ndarray) -> slice | np.ndarray:
    """``rows`` as a slice where they are consecutive, else ``rows`` itself: a slice is a view of the
    batch, where indexing by an array copies every draw's points."""
    if rows.size and rows[-1] - rows[0] == rows.size - 1 and np.all(np.diff(rows) == 1):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows


def _circle_axes(points: np.ndarray, structure: _Structure, *, residuals: bool) -> tuple[list, list[PluckerLine]]:
    """The circle fit of every joint and its axis oriented by the turn of the readings (measured configuration)."""
    options = structure.options
    fits, lines = [], []
    for joint, rows in enumerate(structure.circle_indices):
        circle_points = points[..., _row_selector(rows), :]
        try:
            fit = fit_circle_3d(circle_points, method=options.circle_fit, residuals=residuals)
        except DegenerateGeometryError as exc:
            raise DegenerateGeometryError(f"{structure.source}: circle {joint + 1} (J{joint + 1}): {exc}") from None
        normal = _oriented_axis(fit, circle_points, structure.model_q[rows, joint])
        fits.append(fit)
        try:
            lines.append(PluckerLine.from_point_direction(fit.centre, normal))
        except InputError as exc:
            raise DegenerateGeometryError(
                f"{structure.source}: circle {joint + 1} (J{joint + 1}, {point_rows(rows)}): no axis from the "
                f"circle fit ({exc}); check these rows for repeated or corrupt points"
            ) from None
    return fits, lines


def _referenced_axes(lines: list[PluckerLine], transport: np.ndarray) -> PluckerLine:
    """Every axis brought to the reference configuration (product of exponentials), stacked ``(..., n_joints)``."""
    referenced: list[PluckerLine] = []
    for k, line in enumerate(lines):
        for j in range(k):  # D^-1 L = Rot(L_{k-1}, -dq) ... Rot(L_1, -dq) L: joint 1 acts first
            angle = transport[k, j]
            if angle != 0.0:
                line = _turned_about(line, referenced[j], -angle)
        referenced.append(line)
    axes = PluckerLine(
        direction=np.stack([line.direction for line in referenced], axis=-2),
        moment=np.stack([line.moment for line in referenced], axis=-2),
    )
    return axes


def _base_frame(
    points: np.ndarray, structure: _Structure, tracker_from_base: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """``tracker_from_base`` registered from the points (and the registration's RMS) or the given one, checked."""
    if structure.options.base_frame == "registered":
        registration = register_points(structure.nominal_points, points)
        return registration.transform, registration.rms
    if tracker_from_base is None:
        raise InputError("base_frame='given' needs `tracker_from_base`")
    return check_rigid_transform(tracker_from_base, "tracker_from_base"), None


def _wrap_angles_to_nominal(values: np.ndarray, nominal: np.ndarray) -> None:
    """Bring the angles of ``values (..., n_joints, 5)`` within +-pi of the nominal ones, in place."""
    angles = [_THETA, _ALPHA, _BETA]
    nominal_angles = nominal[:, angles]
    offsets = values[..., angles] - nominal_angles
    offsets -= 2.0 * np.pi * np.round(offsets / (2.0 * np.pi))  # exact for offsets already within +-pi
    values[..., angles] = nominal_angles + offsets


def identify_cpa_batch(points: np.ndarray, structure: _Structure, tracker_from_base: np.ndarray | None = None, *, residuals: bool = True) -> CPABatch:
    """CPA on measured points ``(..., n_points, 3)`` [mm] sharing one capture structure.

    ``tracker_from_base`` (4, 4) is required when ``structure.options.base_frame == "given"``.
    ``residuals=False`` leaves the fit residuals out of ``circle_fits`` (``fit_circle_3d(residuals=False)``):
    the parameters are the same, and a Monte Carlo draw needs nothing else.
    """
    robot, options = structure.robot, structure.options
    n = robot.n_joints
    points = np.asarray(points, dtype=float)
    batch_shape = points.shape[:-2]
    # 1. circles -> oriented axes (measured configuration); 2. every axis at the reference configuration
    fits, lines = _circle_axes(points, structure, residuals=residuals)
    axes = _referenced_axes(lines, structure.transport)
    # 3. base frame
    tracker_from_base, registration_rms = _base_frame(points, structure, tracker_from_base)
    # x axes of the nominal frames {1}..{n} at the reference configuration: the hints of the common normals
    nominal_x = joint_frames(robot.nominal, structure.reference_q[None, :])[0][:, :3, 0]
    hints = np.einsum("...ij,kj->...ki", tracker_from_base[..., :3, :3], nominal_x)
    if tracker_from_base.ndim == 2:  # one given frame for the whole batch: computed once, broadcast
        tracker_from_base = np.broadcast_to(tracker_from_base, batch_shape + (4, 4))
        hints = np.broadcast_to(hints, batch_shape + hints.shape)
    origin = tracker_from_base[..., :3, 3]
    s1 = axes.direction[..., 0, :]
    if options.base_axis == "circle1":
        first = structure.circle_indices[0][0]
        radial = points[..., first, :] - fits[0].centre
        x0 = apply_transform(rotation_about_line(s1, np.zeros(3), -structure.circle1_azimuth), radial)
    else:
        x0 = tracker_from_base[..., :3, 0]
    x0 = _unit(x0 - _dot(x0, s1)[..., None] * s1)
    # 4. adjacent axes
    values = np.broadcast_to(robot.nominal, batch_shape + (n, 5)).copy()
    identified = np.zeros((n, 5), dtype=bool)
    cases = []
    previous_point = origin  # d_1 is measured from the robot origin along S_1
    previous_x = x0
    for j in range(n - 1):
        line_j, line_k = axes[..., j], axes[..., j + 1]
        s_j = line_j.direction
        hint = hints[..., j + 1, :]
        point_j = line_j.point  # a property: computed once
        foot_prev = point_j + _dot(previous_point - point_j, s_j)[..., None] * s_j
        start = foot_prev + robot.nominal[j, _D] * s_j
        angle = np.rad2deg(np.arccos(np.clip(np.abs(_dot(s_j, line_k.direction)), 0.0, 1.0)))
        if robot.hayati[j]:
            if np.any(angle > options.near_parallel_deg):
                raise DegenerateGeometryError(
                    f"{structure.source}: J{j + 1} is a Hayati joint but axes {j + 1} and {j + 2} are "
                    f"{np.max(angle):.3g} deg apart (near_parallel_deg = {options.near_parallel_deg:g})"
                )
            pair = analyse_hayati_pair(line_j, line_k, normal_hint=hint, point_j=start)
            values[..., j, _D] = 0.0
            values[..., j, _BETA] = pair.beta
            identified[j, [_THETA, _A, _ALPHA, _BETA]] = True
        else:
            pair = analyse_dh_pair(line_j, line_k, normal_hint=hint, point_j_if_parallel=start)
            values[..., j, _D] = _dot(pair.point_j - previous_point, s_j)
            parallel = np.any(pair.case == "parallel")
            identified[j, [_THETA, _A, _ALPHA]] = True
            identified[j, _D] = not parallel
        values[..., j, _A] = pair.length
        values[..., j, _ALPHA] = pair.twist
        values[..., j, _THETA] = signed_angle_about(previous_x, pair.normal, s_j) - structure.reference_q[j]
        cases.append(str(np.asarray(pair.case).reshape(-1)[0]))
        previous_point, previous_x = pair.point_k, pair.normal
    # 5. angles within +-180 deg of nominal (docs/conventions.md)
    _wrap_angles_to_nominal(values, robot.nominal)
    return CPABatch(
        values=values,
        identified=identified,
        axes=axes,
        circle_fits=tuple(fits),
        pair_cases=tuple(cases),
        tracker_from_base=tracker_from_base,
        registration_rms=registration_rms,
    )


def identify_cpa(
    capture: Capture,
    robot: RobotModel,
    reflector: ReflectorMount,
    *,
    tracker_from_base: np.ndarray | None = None,
    options: CPAOptions | None = None,
) -> CPAResult:
    """Identify the kinematic parameters of ``robot`` from one Circle Point capture.

    Parameters
    ----------
    capture : Capture
        One circle per joint (``circle`` = joint turned), all joint readings per point.
    robot : RobotModel
        Model structure, nominal values (signs and starting guesses) and the reading map.
    reflector : ReflectorMount
        Where the target sat: per circle in the turning joint's frame, or once on the flange.
    tracker_from_base : array_like, shape (4, 4), optional
        Base frame in the tracker frame; required for ``base_frame="given"``.
    options : CPAOptions, optional

    Returns
    -------
    CPAResult

    Raises
    ------
    InputError
        Capture inconsistent with the robot (joint count, missing circle, a resting joint moving).
    DegenerateGeometryError
        Fewer than 3 points, collinear points, zero sweep, axes unfit for the model.

    References
    ----------
    Thesis ch. 4.4-4.5, algorithms 5.2.2.1-5.2.2.2; docs/conventions.md.
    """
    structure = prepare_cpa(capture, robot, reflector, options)
    batch = identify_cpa_batch(capture.points, structure, tracker_from_base)
    options = structure.options
    # axis direction check against the nominal model (z_{i-1} in the tracker frame)
    nominal_frames = batch.tracker_from_base @ joint_frames(robot.nominal, structure.reference_q[None, :])[0]
    for joint in range(robot.n_joints):
        if _dot(batch.axes.direction[joint], nominal_frames[joint, :3, 2]) < 0.0:
            raise InputError(
                f"{capture.source}: circle {joint + 1}: J{joint + 1} turns the opposite way to the nominal model's "
                f"z{joint} axis as its reading grows; check `reading_sign` of J{joint + 1} in the robot file"
            )
    messages = []
    for joint, case in enumerate(batch.pair_cases):
        if case == "parallel" and not robot.hayati[joint]:
            messages.append(f"J{joint + 1}.d held at nominal: axes {joint + 1} and {joint + 2} are parallel")
            warnings.warn(
                f"axes {joint + 1} and {joint + 2} are parallel; J{joint + 1}.d cannot be identified and stays nominal "
                f"(mark J{joint + 1} as a Hayati joint in the robot file)",
                IdentifiabilityWarning,
                stacklevel=2,
            )
        elif not robot.hayati[joint]:
            cos = abs(_dot(batch.axes.direction[joint], batch.axes.direction[joint + 1]))
            if np.rad2deg(np.arccos(np.minimum(cos, 1.0))) < options.near_parallel_deg:
                messages.append(
                    f"axes {joint + 1} and {joint + 2} nearly parallel: J{joint + 1} DH parameters ill-conditioned"
                )
                warnings.warn(
                    f"axes {joint + 1} and {joint + 2} are nearly parallel; the DH parameters of J{joint + 1} are "
                    f"ill-conditioned (consider a Hayati joint)",
                    IdentifiabilityWarning,
                    stacklevel=2,
                )
    converged = all(fit.converged for fit in batch.circle_fits)
    if not converged:
        messages.append("a geometric circle fit did not meet its step tolerance")
    parameters = ParameterSet(robot=robot, values=batch.values, identified=batch.identified)
    tracker_from_base, rms = np.array(batch.tracker_from_base), None
    if batch.registration_rms is not None:
        # the base frame of the identified model: the registration above (nominal model) only located the axes
        # and the base; the identified model's points registered on the measured ones give the frame in which
        # the identified parameters predict the capture (its absolute error)
        turning = np.maximum(capture.circle - 1, 0)
        q = robot.model_joint_variables(capture.readings)
        registration = register_points(target_positions(parameters.values, q, turning, reflector), capture.points)
        tracker_from_base, rms = registration.transform, float(registration.rms)
    return CPAResult(
        parameters=parameters,
        axes=batch.axes,
        reference_readings=structure.reference_readings,
        circle_fits=batch.circle_fits,
        pair_cases=batch.pair_cases,
        tracker_from_base=tracker_from_base,
        registration_rms=rms,
        options=options,
        success=converged,
        message="; ".join(messages) if messages else "identified",
    )
