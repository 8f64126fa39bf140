"""Joint error diagnostics from a Circle Point capture: backlash and axial/radial eccentricity.

Thesis ch. 4.6 (Figs 4.26-4.30, Tables 4.12-4.17). Each circle is swept forward (``direction = +1``)
and back (``-1``) over the same readings of its turning joint. Per circle:

- one plane and circle are fitted to the points of both directions together
  (:func:`robotcal.geometry.fits.fit_circle_3d`); the normal is oriented so that a growing reading
  turns the target right-handed about it;
- **axial eccentricity** of a point: its signed distance to the plane along that normal;
- **radial eccentricity**: signed distance of its projection to the fitted circle, outward positive;
- **backlash** at a commanded angle: the vector from the forward point to the return point at the
  same reading, ``b = p_return - p_forward`` (Fig. 4.26 draws it from the positive-rotation point
  to the negative-rotation one), its magnitude (Fig. 4.28, Tables 4.12-4.17), and its components
  along the axis, the radial and the tangential direction at the pair's mid-point, with the signed
  angle from the forward to the return point about the axis.

**Noise floor**: instrument noise alone gives every pair a backlash vector too. With independent noise
of standard deviation ``sigma`` per coordinate (isotropic, as the instrument models of
:mod:`robotcal.instruments`), the difference of two points has ``2 sigma^2`` per component and its
length follows a Maxwell distribution of mean ``2 sqrt(2) sigma sqrt(2/pi) = 4 sigma / sqrt(pi)``
(:attr:`CircleDiagnostics.backlash_noise_floor`). ``sigma`` is estimated from the axial and radial
components of the pair differences, which the joint's systematic errors cancel (same reading) and a
rotational backlash hardly reaches (it turns the point along the tangent); without pairs, from the fit
residuals. A joint's backlash is told apart from noise when its mean magnitude exceeds the floor by
three standard deviations of a noise-only mean (:attr:`JointSummary.backlash_exceeds_noise`).

Lengths in mm, angles in radians, points in the tracker frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.geometry.fits import fit_circle_3d

__all__ = [
    "CircleDiagnostics",
    "JointSummary",
    "JointDiagnostics",
    "analyze_joints",
    "lash_state",
    "local_frame",
    "DEFAULT_MATCH_TOLERANCE",
    "MAXWELL_MEAN_PER_SIGMA",
]

#: Largest difference between a forward and a return reading that still counts as the same
#: commanded angle [rad] (1e-3 deg: controllers and CSV exports round readings to ~1e-4 deg).
DEFAULT_MATCH_TOLERANCE = float(np.deg2rad(1e-3))
#: Mean length of the difference of two points with isotropic noise, per unit point standard deviation:
#: ``|e_r - e_f|`` is Maxwell distributed with scale ``sqrt(2) sigma``, mean ``sqrt(2) sigma 2 sqrt(2/pi)``.
MAXWELL_MEAN_PER_SIGMA = 4.0 / math.sqrt(math.pi)
#: Coefficient of variation of a Maxwell variable, ``sqrt(3 pi / 8 - 1)`` (std / mean).
MAXWELL_CV = math.sqrt(3.0 * math.pi / 8.0 - 1.0)
#: Circle fit parameters absorbed by the residuals (plane: 3, circle in the plane: 3).
_FIT_DOF = 6


@dataclass(frozen=True, slots=True, kw_only=True)
class CircleDiagnostics:
    """Backlash and eccentricity of one circle (one joint turning).

    Attributes
    ----------
    joint : int
        1-based joint turned in the circle.
    centre : ndarray, shape (3,)
        Fitted circle centre, tracker frame [mm].
    normal : ndarray, shape (3,)
        Unit axis direction, oriented so that a growing reading turns the target right-handed.
    radius : float
        Fitted radius [mm].
    rows : ndarray of int, shape (n_points,)
        Rows of the capture that belong to the circle, in capture order.
    points : ndarray, shape (n_points, 3)
        Those points, tracker frame [mm].
    reading : ndarray, shape (n_points,)
        Reading of the turning joint at each point [rad].
    direction : ndarray of int, shape (n_points,)
        Sweep label of each point (+1 forward, -1 return).
    state : ndarray of int, shape (n_points,)
        Lash state (:func:`lash_state`): the sweep by which the joint reached the point.
    axial, radial : ndarray, shape (n_points,)
        Signed axial and radial eccentricity [mm] (Figs 4.29, 4.30).
    plane_rms, circle_rms : float
        RMS of ``axial`` and ``radial`` [mm] (fit residual RMS).
    pair_forward, pair_return : ndarray of int, shape (n_pairs,)
        Capture rows of the matched forward and return points, by increasing reading.
    pair_reading : ndarray, shape (n_pairs,)
        Commanded reading of each pair (mean of the two) [rad].
    backlash : ndarray, shape (n_pairs, 3)
        ``p_return - p_forward`` in the tracker frame [mm] (Figs 4.26, 4.27).
    backlash_local : ndarray, shape (n_pairs, 3)
        The same along the axis, the radial and the tangential direction at the pair's mid-point
        (tangent = normal x radial) [mm].
    backlash_angle : ndarray, shape (n_pairs,)
        Signed angle from the forward to the return point about the oriented axis [rad].
    turnaround : ndarray of bool, shape (n_pairs,)
        The return point directly follows the forward point in the capture with the same readings:
        the robot did not move between them, so the pair measures repeatability, not backlash.
    unmatched : ndarray of int, shape (n_unmatched,)
        Capture rows left without a partner at the same reading (empty without backlash analysis).
    """

    joint: int
    centre: np.ndarray
    normal: np.ndarray
    radius: float
    rows: np.ndarray
    points: np.ndarray
    reading: np.ndarray
    direction: np.ndarray
    state: np.ndarray
    axial: np.ndarray
    radial: np.ndarray
    plane_rms: float
    circle_rms: float
    pair_forward: np.ndarray
    pair_return: np.ndarray
    pair_reading: np.ndarray
    backlash: np.ndarray
    backlash_local: np.ndarray
    backlash_angle: np.ndarray
    turnaround: np.ndarray
    unmatched: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.rows.size)

    @property
    def n_pairs(self) -> int:
        return int(self.pair_forward.size)

    @property
    def backlash_magnitude(self) -> np.ndarray:
        """Euclidean length of each backlash vector [mm] (Fig. 4.28)."""
        return np.linalg.norm(self.backlash, axis=-1)

    def local_frame(self, points) -> np.ndarray:
        """Axial, radial and tangential unit vectors at ``points (..., 3)``: shape ``(..., 3, 3)``."""
        return local_frame(self.centre, self.normal, points, joint=self.joint)

    @property
    def noise_sigma(self) -> float:
        """Estimated instrument noise per coordinate of one point [mm] (standard deviation).

        From the matched pairs (turnarounds included: they repeat one pose): each axial and radial
        component of ``p_return - p_forward`` has variance ``2 sigma^2`` whatever the joint's
        eccentricity, so ``sigma^2 = sum(axial^2 + radial^2) / (4 n_pairs)``. Without pairs, from
        the fit residuals, ``sigma^2 = sum(axial^2 + radial^2) / (2 n_points - 6)``, which the
        joint's eccentricity inflates. NaN when neither is available.
        """
        if self.n_pairs:
            parts = self.backlash_local[:, :2]
            return float(np.sqrt(np.sum(parts**2) / (4.0 * self.n_pairs)))
        dof = 2 * self.n_points - _FIT_DOF
        if dof <= 0:
            return float("nan")
        return float(np.sqrt((np.sum(self.axial**2) + np.sum(self.radial**2)) / dof))

    @property
    def backlash_noise_floor(self) -> float:
        """Backlash magnitude expected from the instrument noise alone [mm]: ``4 sigma / sqrt(pi)``.

        The mean length of the difference of two noisy measurements of one point (Maxwell mean of a
        3-D vector with ``2 sigma^2`` per component, :attr:`noise_sigma`).
        """
        return MAXWELL_MEAN_PER_SIGMA * self.noise_sigma


@dataclass(frozen=True, slots=True, kw_only=True)
class JointSummary:
    """Per-joint summary (Tables 4.12-4.17 give max, min and mean of the backlash magnitude).

    Backlash statistics use the matched pairs that are not turnarounds; they are NaN when the joint
    has none. Lengths in mm, angles in rad.
    """

    joint: int
    points: int
    pairs: int
    radius: float
    plane_rms: float
    circle_rms: float
    axial_min: float
    axial_max: float
    radial_min: float
    radial_max: float
    backlash_max: float
    backlash_min: float
    backlash_mean: float
    backlash_std: float
    backlash_angle_mean: float
    noise_sigma: float = float("nan")
    backlash_noise_floor: float = float("nan")

    @property
    def backlash_exceeds_noise(self) -> bool:
        """The mean backlash magnitude lies above the noise floor by more than three standard deviations
        of a noise-only mean: ``mean > floor (1 + 3 sqrt(CV^2 + 1/4) / sqrt(n))`` over ``n`` pairs, with
        ``CV^2 / n`` the relative variance of a mean of ``n`` Maxwell lengths (CV = 0.42) and ``1 / (4 n)``
        that of the floor, whose ``sigma^2`` comes from ``2 n`` squared components. False without pairs."""
        n = self.pairs
        if n == 0 or not math.isfinite(self.backlash_mean) or not math.isfinite(self.backlash_noise_floor):
            return False
        spread = math.sqrt(MAXWELL_CV**2 + 0.25) / math.sqrt(n)
        return self.backlash_mean > self.backlash_noise_floor * (1.0 + 3.0 * spread)


@dataclass(frozen=True, slots=True, kw_only=True)
class JointDiagnostics:
    """Backlash and eccentricity of every circle of a capture.

    Attributes
    ----------
    circles : tuple of CircleDiagnostics
        One per circle present in the capture, by joint.
    n_joints : int
    backlash : bool
        Whether backlash was analysed (all circles swept both ways).
    match_tolerance : float
        Reading tolerance of the forward/return matching [rad].
    ignored_points : int
        Points not on a circle (``circle = 0``: free poses) that were left out.
    messages : tuple of str
        Notes for the user: ignored points, unmatched readings.
    source : str
    """

    circles: tuple[CircleDiagnostics, ...]
    n_joints: int
    backlash: bool
    match_tolerance: float
    ignored_points: int
    messages: tuple[str, ...]
    source: str

    def circle(self, joint: int) -> CircleDiagnostics:
        """The diagnostics of the circle of ``joint`` (1-based)."""
        for item in self.circles:
            if item.joint == joint:
                return item
        raise InputError(f"{self.source}: the capture has no circle for joint J{joint}")

    def lash_correction(self) -> np.ndarray:
        """The angular lash ``(n_joints,)`` [rad] a refinement corrects the circles for: the mean backlash angle of
        the joints whose backlash exceeds the noise (:attr:`JointSummary.backlash_exceeds_noise`), 0 elsewhere."""
        lash = np.zeros(self.n_joints)
        for joint in self.summary():
            if joint.backlash_exceeds_noise:
                lash[joint.joint - 1] = joint.backlash_angle_mean
        return lash

    def summary(self) -> tuple[JointSummary, ...]:
        """Per-joint summary rows (max, min, mean of the backlash magnitude as Tables 4.12-4.17)."""
        rows = []
        for c in self.circles:
            keep = ~c.turnaround
            magnitude = c.backlash_magnitude[keep]
            angle = c.backlash_angle[keep]
            has = magnitude.size > 0

            def stat(function, values, has=has):
                return float(function(values)) if has else float("nan")

            rows.append(
                JointSummary(
                    joint=c.joint,
                    points=c.n_points,
                    pairs=int(keep.sum()),
                    radius=float(c.radius),
                    plane_rms=c.plane_rms,
                    circle_rms=c.circle_rms,
                    axial_min=float(c.axial.min()),
                    axial_max=float(c.axial.max()),
                    radial_min=float(c.radial.min()),
                    radial_max=float(c.radial.max()),
                    backlash_max=stat(np.max, magnitude),
                    backlash_min=stat(np.min, magnitude),
                    backlash_mean=stat(np.mean, magnitude),
                    backlash_std=float(np.std(magnitude, ddof=1)) if magnitude.size > 1 else float("nan"),
                    backlash_angle_mean=stat(np.mean, angle),
                    noise_sigma=c.noise_sigma,
                    backlash_noise_floor=c.backlash_noise_floor if c.n_pairs else float("nan"),
                )
            )
        return tuple(rows)


def local_frame(centre: np.ndarray, normal: np.ndarray, points: ArrayLike, *, joint: int = 0) -> np.ndarray:
    """Rows ``(axis, radial, tangent)`` of unit vectors at ``points (..., 3)`` about an axis.

    ``axis`` is the unit ``normal``, ``radial`` points from the axis to the point's projection on
    the plane through ``centre``, ``tangent = axis x radial``. Shape ``(..., 3, 3)``.
    """
    points = np.asarray(points, dtype=float)
    offset = points - centre
    in_plane = offset - (offset @ normal)[..., None] * normal
    length = np.linalg.norm(in_plane, axis=-1, keepdims=True)
    if np.any(length <= 1e-9):
        raise InputError(f"circle {joint}: a point lies on the fitted axis; its radial direction is undefined")
    radial = in_plane / length
    tangent = np.cross(normal, radial)
    axis = np.broadcast_to(normal, radial.shape)
    return np.stack([axis, radial, tangent], axis=-2)


def lash_state(readings: ArrayLike, direction: ArrayLike) -> np.ndarray:
    """The sweep by which the turning joint reached each point of one circle.

    Parameters
    ----------
    readings : array_like, shape (n_points, n_joints)
        All joint readings of the circle's points, in capture order [rad].
    direction : array_like of int, shape (n_points,)
        Sweep labels (+1 / -1).

    Returns
    -------
    ndarray of int, shape (n_points,)
        The label of the point, except that a point with exactly the readings of the point before it
        (the robot did not move: the turnaround of a bidirectional sweep) keeps that point's state.
        This is the ``s`` of the generator's backlash term when the circle's forward sweep turns the
        joint towards larger readings.
    """
    readings = np.asarray(readings, dtype=float)
    state = np.asarray(direction, dtype=int).copy()
    for k in range(1, state.size):
        if np.array_equal(readings[k], readings[k - 1]):
            state[k] = state[k - 1]
    return state


def _check_capture(capture) -> Capture:
    if not isinstance(capture, Capture):
        raise InputError(f"`capture` must be a Capture; got {type(capture).__name__}")
    return capture


def _orient(normal: np.ndarray, centre: np.ndarray, points: np.ndarray, reading: np.ndarray) -> np.ndarray:
    """Flip ``normal`` unless growing readings turn the points right-handed about it."""
    offsets = points - centre
    turn = np.einsum("ki,i->k", np.cross(offsets[:-1], offsets[1:]), normal)
    vote = float(np.sum(np.sign(np.diff(reading)) * turn))
    return -normal if vote < 0 else normal


def _match(reading: np.ndarray, direction: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (forward index, return index) at the same reading: closest first, one partner each."""
    forward = np.flatnonzero(direction == 1)
    back = np.flatnonzero(direction == -1)
    gap = np.abs(reading[forward][:, None] - reading[back][None, :])
    candidates = np.argwhere(gap <= tolerance)
    order = np.argsort(gap[candidates[:, 0], candidates[:, 1]], kind="stable")
    used_f, used_b, pairs = set(), set(), []
    for i, j in candidates[order]:
        if i in used_f or j in used_b:
            continue
        used_f.add(i)
        used_b.add(j)
        pairs.append((forward[i], back[j]))
    pairs.sort(key=lambda pair: reading[pair[0]])
    pairs_array = np.array(pairs, dtype=int).reshape(-1, 2)
    return pairs_array[:, 0], pairs_array[:, 1]


def _circle(
    capture: Capture,
    joint: int,
    rows: np.ndarray,
    backlash: bool,
    tolerance: float,
    method: Literal["geometric", "algebraic"],
):
    points = capture.points[rows]
    reading = capture.readings[rows, joint - 1]
    direction = capture.direction[rows]
    try:
        fit = fit_circle_3d(points, method=method)
    except InputError as exc:
        raise InputError(f"{capture.source}: circle {joint}: {exc}") from None
    centre = np.asarray(fit.centre)
    normal = _orient(np.asarray(fit.normal), centre, points, reading)
    axial = (points - centre) @ normal
    radial = np.asarray(fit.radial_residuals)
    forward_idx, return_idx = (np.zeros(0, dtype=int),) * 2
    if backlash:
        forward_idx, return_idx = _match(reading, direction, tolerance)
    b = points[return_idx] - points[forward_idx]
    state = lash_state(capture.readings[rows], direction)
    partial = CircleDiagnostics(
        joint=joint,
        centre=_frozen(centre),
        normal=_frozen(normal),
        radius=float(fit.radius),
        rows=_frozen(rows, int),
        points=_frozen(points),
        reading=_frozen(reading),
        direction=_frozen(direction, int),
        state=_frozen(state, int),
        axial=_frozen(axial),
        radial=_frozen(radial),
        plane_rms=float(np.sqrt(np.mean(axial**2))),
        circle_rms=float(np.sqrt(np.mean(radial**2))),
        pair_forward=_frozen(rows[forward_idx], int),
        pair_return=_frozen(rows[return_idx], int),
        pair_reading=_frozen(0.5 * (reading[forward_idx] + reading[return_idx])),
        backlash=_frozen(b.reshape(-1, 3)),
        backlash_local=_frozen(np.zeros((forward_idx.size, 3))),
        backlash_angle=_frozen(np.zeros(forward_idx.size)),
        turnaround=_frozen(np.zeros(forward_idx.size), bool),
        unmatched=_frozen(np.setdiff1d(rows, np.r_[rows[forward_idx], rows[return_idx]]) if backlash else [], int),
    )
    if forward_idx.size == 0:
        return partial
    # local components at the mid-point, and the signed turn about the axis
    mid = 0.5 * (points[forward_idx] + points[return_idx])
    frames = partial.local_frame(mid)
    local = np.einsum("kij,kj->ki", frames, b)
    a = points[forward_idx] - centre
    c = points[return_idx] - centre
    a = a - (a @ normal)[:, None] * normal
    c = c - (c @ normal)[:, None] * normal
    angle = np.arctan2(np.cross(a, c) @ normal, np.einsum("ki,ki->k", a, c))
    # consecutive rows with different readings are a turn only in name: the robot moved
    still = np.all(capture.readings[rows[return_idx]] == capture.readings[rows[forward_idx]], axis=1)
    turnaround = (rows[return_idx] == rows[forward_idx] + 1) & still
    return CircleDiagnostics(
        **{
            name: getattr(partial, name)
            for name in CircleDiagnostics.__dataclass_fields__
            if name not in ("backlash_local", "backlash_angle", "turnaround")
        },
        backlash_local=_frozen(local),
        backlash_angle=_frozen(angle),
        turnaround=_frozen(turnaround, bool),
    )


def analyze_joints(
    capture: Capture,
    *,
    backlash: bool = True,
    match_tolerance: float = DEFAULT_MATCH_TOLERANCE,
    method: Literal["geometric", "algebraic"] = "geometric",
) -> JointDiagnostics:
    """Backlash and axial/radial eccentricity of every circle of a capture (thesis ch. 4.6).

    Parameters
    ----------
    capture : Capture
        Points in the tracker frame [mm] with the readings of every joint [rad]. Points whose
        ``circle`` is 0 (free poses, not on a circle) are left out with a note.
    backlash : bool
        Analyse backlash. Every circle must then have been swept both ways.
    match_tolerance : float
        Forward and return points are the same commanded angle when the turning joint's readings
        differ by at most this much [rad]; each point gets at most one partner, closest first.
    method : {"geometric", "algebraic"}
        In-plane circle fit (:func:`robotcal.geometry.fits.fit_circle_3d`).

    Returns
    -------
    JointDiagnostics

    Raises
    ------
    InputError
        ``backlash=True`` and a circle was swept in one direction only, or none of its readings
        match between the two directions; a circle with fewer than 3 points.
    DegenerateGeometryError
        A circle's points are collinear.

    Notes
    -----
    The axial eccentricity of point k is ``(p_k - c) . n`` and the radial one
    ``|P(p_k) - c| - R`` with P the projection onto the fitted plane (thesis algorithm 5.2.2.1,
    "Calcula distancia axial / radial"). A single circle cannot separate eccentricity of order 0
    and 1 in the joint angle from the axis position, tilt and radius: the fits absorb them.
    """
    capture = _check_capture(capture)
    if method not in ("geometric", "algebraic"):
        raise InputError(f"`method` must be 'geometric' or 'algebraic'; got {method!r}")
    tolerance = float(match_tolerance)
    if not np.isfinite(tolerance) or tolerance < 0:
        raise InputError(f"`match_tolerance` must be a finite angle >= 0 [rad]; got {match_tolerance!r}")
    messages = []
    on_circle = capture.circle >= 1
    ignored = int(np.sum(~on_circle))
    if ignored:
        messages.append(f"{ignored} point(s) with circle = 0 (free poses, not on a circle) were ignored")
    joints = sorted({int(j) for j in capture.circle[on_circle]})
    if not joints:
        raise InputError(f"{capture.source}: the capture has no circle points")
    if backlash:
        one_way = [j for j in joints if np.unique(capture.direction[capture.circle == j]).size < 2]
        if one_way:
            names = ", ".join(f"J{j}" for j in one_way)
            raise InputError(
                f"{capture.source}: backlash needs forward and return points at the same readings, but the "
                f"circle(s) of {names} were swept in one direction only; capture with `bidirectional = true`, "
                "or analyse eccentricity only (backlash=False, CLI --no-backlash)"
            )
    circles = []
    for joint in joints:
        rows = np.flatnonzero(capture.circle == joint)
        if rows.size < 3:
            raise InputError(f"{capture.source}: circle {joint} has {rows.size} point(s); a circle needs at least 3")
        item = _circle(capture, joint, rows, backlash, tolerance, method)
        if backlash and item.n_pairs == 0:
            raise InputError(
                f"{capture.source}: circle {joint}: no forward reading matches a return reading within "
                f"{np.rad2deg(tolerance):g} deg, so there is no backlash to report; check the sweeps or widen "
                "the match tolerance"
            )
        if item.unmatched.size:
            shown = ", ".join(
                f"{np.rad2deg(capture.readings[r, joint - 1]):.6g} deg ({'forward' if capture.direction[r] == 1 else 'return'})"
                for r in item.unmatched[:5]
            )
            more = f" and {item.unmatched.size - 5} more" if item.unmatched.size > 5 else ""
            messages.append(f"circle {joint}: {item.unmatched.size} reading(s) without a partner: {shown}{more}")
        circles.append(item)
    return JointDiagnostics(
        circles=tuple(circles),
        n_joints=capture.n_joints,
        backlash=bool(backlash),
        match_tolerance=tolerance,
        ignored_points=ignored,
        messages=tuple(messages),
        source=capture.source,
    )
