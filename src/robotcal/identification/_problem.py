"""The least-squares problem of a refinement (thesis ch. 4.5.7, eqs 4-101 and 4-102): its unknowns, residuals and
exact Jacobian as pure functions of the unknowns, with the helpers the other modules share (pairs of distinct
measurements, base-frame corrections, angle wrapping).

:class:`Problem` holds the immutable data of one fit; :class:`Setup` what a refinement fixes before its first fit
(:func:`robotcal.identification.refine.refine_parameters` builds it). The module notes of
:mod:`robotcal.identification.refine` describe the objectives, the scaling and the weights.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.geometry.rotations import inverse_right_jacobian, rotation_vectors, vee
from robotcal.geometry.transforms import rot_x, rot_y, rot_z
from robotcal.identification.health import repeatability_sigma
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.kinematics.forward import forward_kinematics, probe_rotations, target_positions
from robotcal.kinematics.jacobian import target_jacobian
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ANGLE_COLUMNS, ParameterSet, ReflectorMount

__all__ = [
    "BASE_AXES",
    "BASE_NAMES",
    "Problem",
    "State",
    "Setup",
    "pdist",
    "least_squares",
    "wrap_angles",
    "point_sigmas",
    "capture_turning_joints",
    "capture_target_index",
    "measurement_pairs",
    "base_correction",
]

if TYPE_CHECKING:
    import scipy.sparse

#: Names of the six ``tracker_from_base`` corrections (points criterion): translation [mm], then
#: rotation angles [rad] of ``Rz(rz) Ry(ry) Rx(rx)``, applied on the base side of the start transform.
BASE_AXES = ("tx", "ty", "tz", "rx", "ry", "rz")
BASE_NAMES = tuple(f"base.{axis}" for axis in BASE_AXES)
_PAIR_CHUNK = 32768


def pdist(points):
    """:func:`scipy.spatial.distance.pdist`, imported on first use (scipy is slow to import: a command
    that never refines must not pay it)."""
    from scipy.spatial.distance import pdist as condensed_distances

    return condensed_distances(points)


def least_squares(*args, **kwargs):
    """:func:`scipy.optimize.least_squares`, imported on first use (see :func:`pdist`)."""
    from scipy.optimize import least_squares as solve

    return solve(*args, **kwargs)



def wrap_angles(values, nominal=None) -> np.ndarray:
    """Parameters ``(..., n_joints, 5)`` with theta, alpha, beta wrapped into ``(c - pi, c + pi]`` [rad],
    ``c`` = the ``nominal`` values (the robot's nominal parameters), or 0 without them.

    A turn of 2 pi leaves every transform unchanged; only values outside the interval are touched,
    so that values already inside keep every bit. Wrapping about the nominal keeps every estimate, truth
    and Monte Carlo statistic of an angle in one branch, that of its nominal value (a J5.theta of nominal
    180 deg stays near 180, never -179.9): their differences are then the errors. The fits keep their
    values continuous with the start; every output wraps them: the parameter JSON
    (:func:`robotcal.io.formats.parameters_json.parameters_to_dict`) and the tables of ``identify`` and ``refine``.
    """
    values = np.array(values, dtype=float)
    columns = list(ANGLE_COLUMNS)
    centre = 0.0 if nominal is None else np.broadcast_to(np.asarray(nominal, dtype=float), values.shape)[..., columns]
    offset = values[..., columns] - centre
    wrapped = np.pi - np.mod(np.pi - offset, 2.0 * np.pi)
    values[..., columns] = np.where((offset > np.pi) | (offset <= -np.pi), centre + wrapped, values[..., columns])
    return values


def point_sigmas(capture: Capture, repeatability_mm: float | None = None) -> np.ndarray | None:
    """Standard uncertainty per coordinate of every point [mm] from its U(95): ``U / 2`` (k = 2, normal), with the
    robot's pose scatter added in quadrature when its ISO 9283 repeatability RP is stated (the noise budget,
    ``u^2 = u_instrument^2 + sigma_r^2``, :func:`robotcal.identification.health.repeatability_sigma`); None when the
    capture has no ``u95_mm`` column (the points are then weighted equally, as the same scatter adds to each)."""
    if capture.u95 is None:
        return None
    return np.hypot(np.asarray(capture.u95, dtype=float) / 2.0, repeatability_sigma(repeatability_mm))


def capture_turning_joints(capture: Capture, reflector: ReflectorMount) -> np.ndarray:
    """0-based joint whose circle each point belongs to (circle - 1); checked against the reflector.

    Points on no circle (``circle = 0``, free poses such as a validation capture) need a flange
    reflector: a per-joint reflector is defined only for circle points.
    """
    if reflector.frame == "joint":
        free_poses = np.flatnonzero(capture.circle == 0)
        if free_poses.size:
            raise InputError(
                f"{capture.source}: {free_poses.size} points have circle = 0 (free poses, first at point "
                f"{free_poses[0] + 1}); a per-joint reflector is defined only on circles, use a flange reflector"
            )
    return np.maximum(capture.circle - 1, 0)


def base_correction(x_base: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """Rotation ``Rz Ry Rx``, translation, and the three rotation derivatives of the correction.

    ``x_base (..., 6)``: one correction or a batch (the refined-model Monte Carlo); every output has the
    batch's leading shape, ``(..., 3, 3)`` and ``(..., 3)``.
    """
    x_base = np.asarray(x_base, dtype=float)
    r_x, r_y, r_z = (rot(x_base[..., 3 + k])[..., :3, :3] for k, rot in enumerate((rot_x, rot_y, rot_z)))
    k_x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    k_y = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    k_z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    rotation = r_z @ r_y @ r_x
    derivatives = (r_z @ r_y @ r_x @ k_x, r_z @ r_y @ k_y @ r_x, r_z @ k_z @ r_y @ r_x)
    return rotation, x_base[..., :3].copy(), derivatives


def _corrected(start: np.ndarray, correction) -> np.ndarray:
    """``start @ [R(correction) | t]``: a base frame with its six corrections applied on the base side."""
    rotation, shift, _ = base_correction(correction)
    delta = np.eye(4)
    delta[:3, :3] = rotation
    delta[:3, 3] = shift
    return start @ delta


def _unit(diff: np.ndarray) -> np.ndarray:
    """Rows of ``diff (m, 3)`` normalised; 0 where a model distance is 0 (|x| has no derivative there)."""
    norm = np.linalg.norm(diff, axis=1, keepdims=True)
    return np.divide(diff, norm, out=np.zeros_like(diff), where=norm > 0.0)


def _pair_jacobian(points, jac, pair_i, pair_j) -> np.ndarray:
    """``d |p_i - p_j| / d x`` ``(n_pairs, n_x)`` from the points and their Jacobian ``(n_points, 3, n_x)``."""
    out = np.empty((pair_i.size, jac.shape[-1]))
    for start in range(0, pair_i.size, _PAIR_CHUNK):
        i = pair_i[start : start + _PAIR_CHUNK]
        j = pair_j[start : start + _PAIR_CHUNK]
        unit = _unit(points[i] - points[j])
        out[start : start + i.size] = np.einsum("pc,pck->pk", unit, jac[i]) - np.einsum("pc,pck->pk", unit, jac[j])
    return out


def _empty_offsets() -> np.ndarray:
    return np.zeros((0, 3))


def _no_flags() -> np.ndarray:
    return np.zeros(0, dtype=bool)


class State(NamedTuple):
    """The quantities a point of the search stands for: parameters ``(n, 5)``, joint-model values ``(m,)``,
    unknown offsets ``(k, 3)`` and base corrections ``(6,)``."""

    values: np.ndarray
    extras: np.ndarray
    offsets: np.ndarray
    x_base: np.ndarray


@dataclass(frozen=True, slots=True, kw_only=True)
class Problem:
    """Immutable data of one refinement; residuals and Jacobian are pure functions of x.

    ``x`` holds the free parameters, then the free joint-model values (``joint_columns`` ``C(q)``: the joint
    variables are ``q + C(q) extras``, :mod:`robotcal.kinematics.joint_model`), then the free components of the
    unknown flange offsets (``targets[unknown[u]]``, 3 each), then the free base corrections. Without ``targets``
    every point is on ``reflector`` (the historical single-target problem).
    """

    start: np.ndarray
    free: np.ndarray  # (n, 5) bool
    base_start: np.ndarray | None  # (4, 4)
    base_free: np.ndarray  # (6,) bool
    q: np.ndarray
    turning: np.ndarray
    reflector: ReflectorMount
    measured: np.ndarray
    criterion: str
    pair_i: np.ndarray | None
    pair_j: np.ndarray | None
    pair_keep: np.ndarray | None
    measured_distances: np.ndarray | None
    targets: tuple[Target, ...] = ()
    target_index: np.ndarray | None = None
    unknown: tuple[int, ...] = ()
    offset_start: np.ndarray = field(default_factory=_empty_offsets)
    offset_free: np.ndarray = field(default_factory=_no_flags)
    point_weight: np.ndarray | None = None
    pair_weight: np.ndarray | None = None
    base_offset: np.ndarray = field(default_factory=lambda: np.zeros(6))  # base corrections at x0 (held: kept)
    joint_columns: np.ndarray | None = None  # (n_points, n, m)
    extra_start: np.ndarray = field(default_factory=lambda: np.zeros(0))
    extra_free: np.ndarray = field(default_factory=_no_flags)
    # measurement sessions (points criterion, issue 29): the session of each point (None: one session), the start
    # transforms of sessions 2..S, whose corrections follow the unknown offsets in the offsets block (a translation
    # row [mm], then a rotation row [rad] times ``rotation_length`` [mm], so that a unit of either moves the
    # points by about 1 mm)
    session_index: np.ndarray | None = None
    session_starts: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    rotation_length: float = 1.0
    # a 6-DoF probe (points criterion, issue 29): the points with a measured orientation, their rotations (probe to
    # tracker), the weight of their residuals [mm/rad], and the start of the probe's rotation in the flange frame,
    # whose correction is the last row of the offsets block (angles times ``rotation_length``)
    oriented: np.ndarray | None = None
    measured_rotations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    orientation_weight: np.ndarray = field(default_factory=lambda: np.zeros(0))
    probe_start: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def n_kinematic(self) -> int:
        return int(self.free.sum())

    @property
    def n_extra(self) -> int:
        return int(self.extra_free.sum())

    @property
    def n_offsets(self) -> int:
        return int(self.offset_free.sum())

    def x0(self) -> np.ndarray:
        return self.pack(State(self.start, self.extra_start, self.offset_start, self.base_offset))

    def unpack_all(self, x) -> State:
        """The parameters, joint-model values, unknown offsets and base corrections at x."""
        bounds = np.cumsum([self.n_kinematic, self.n_extra, self.n_offsets])
        values = self.start.copy()
        values[self.free] = x[: bounds[0]]
        extras = self.extra_start.copy()
        extras[self.extra_free] = x[bounds[0] : bounds[1]]
        offsets = self.offset_start.copy().ravel()
        offsets[self.offset_free] = x[bounds[1] : bounds[2]]
        x_base = self.base_offset.copy()
        x_base[self.base_free] = x[bounds[2] :]
        return State(values, extras, offsets.reshape(-1, 3), x_base)

    def pack(self, state: State) -> np.ndarray:
        """The unknowns x of a state."""
        return np.concatenate(
            [
                state.values[self.free],
                np.asarray(state.extras)[self.extra_free],
                np.asarray(state.offsets).ravel()[self.offset_free],
                np.asarray(state.x_base)[self.base_free],
            ]
        )

    @property
    def n_sessions(self) -> int:
        return 1 + self.session_starts.shape[0]

    def session_rows(self) -> list[np.ndarray]:
        """The points of each session (every point for one session)."""
        if self.session_index is None:
            return [np.arange(self.q.shape[0])]
        return [np.flatnonzero(self.session_index == s) for s in range(self.n_sessions)]

    def session_correction(self, state: State, session: int) -> np.ndarray:
        """The six corrections ``(tx, ty, tz [mm], rx, ry, rz [rad])`` of a session's base frame (0: ``x_base``)."""
        if session == 0:
            return np.asarray(state.x_base, dtype=float)
        row = len(self.unknown) + 2 * (session - 1)
        return np.r_[state.offsets[row], state.offsets[row + 1] / self.rotation_length]

    def session_start(self, session: int) -> np.ndarray:
        """The start frame of a session (points criterion: the first session's is ``base_start``)."""
        start = self.base_start if session == 0 else self.session_starts[session - 1]
        if start is None:
            raise InputError("the distances criterion has no base frame")
        return start

    def trackers(self, state: State) -> np.ndarray:
        """``tracker_from_base`` of every session ``(n_sessions, 4, 4)``."""
        return np.stack(
            [_corrected(self.session_start(s), self.session_correction(state, s)) for s in range(self.n_sessions)]
        )

    def probe_rotation(self, state: State) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """The probe's rotation in the flange frame ``R_P = R_P0 C(u)``, the correction ``C`` and its three
        derivatives (``u`` the last offsets row over ``rotation_length``)."""
        angles = np.asarray(state.offsets[-1], dtype=float) / self.rotation_length
        correction, _, derivatives = base_correction(np.r_[0.0, 0.0, 0.0, angles])
        return self.probe_start @ correction, correction, derivatives

    def orientation_part(self, state: State, jacobian: bool = True):
        """Unweighted orientation residuals ``log(R_m^T R_T F R_P)`` ``(m, 3)`` [rad] of the oriented points and,
        with ``jacobian``, their derivatives ``(m, 3, n_x)`` in the columns of :meth:`point_jacobian`."""
        rows = np.arange(0) if self.oriented is None else self.oriented
        q = self.joint_variables(state.extras)[rows]
        trackers = self.trackers(state)
        session = np.zeros(rows.size, dtype=int) if self.session_index is None else self.session_index[rows]
        probe, correction, probe_derivatives = self.probe_rotation(state)
        model = probe_rotations(state.values, q, probe, trackers[session])
        error = rotation_vectors(np.einsum("pji,pjk->pik", self.measured_rotations, model))
        if not jacobian:
            return error, None
        flange = forward_kinematics(state.values, q)[:, :3, :3]
        n, m = state.values.shape[0], self.extra_free.size
        width = 5 * n + m + self.offset_start.size
        body = np.zeros((rows.size, 3, width))
        # the flange's body-frame turn per parameter: dF e_j = d(F e_j)/dx - d(F 0)/dx, then vee(F^T dF)
        moves = [self._flange_point_jacobian(state, q, rows, offset) for offset in np.eye(4, 3, -1)]
        d_flange = np.stack([moves[j + 1] - moves[0] for j in range(3)], axis=2)  # (m, 3, 3, 5 n + m)
        turn = vee(np.einsum("pji,pjkc->pikc", flange, d_flange).transpose(0, 3, 1, 2))  # (m, 5 n + m, 3)
        body[:, :, : 5 * n + m] = np.einsum("ji,pcj->pic", probe, turn)
        after = flange @ probe  # what a base turn is seen through
        base = np.zeros((rows.size, 3, 6))
        for s in range(self.n_sessions):
            chosen = np.flatnonzero(session == s)
            rotation, _, derivatives = base_correction(self.session_correction(state, s))
            turns = np.stack([vee(rotation.T @ d) for d in derivatives], axis=-1)  # (3, 3)
            seen = np.einsum("pji,jk->pik", after[chosen], turns)
            if s == 0:
                base[chosen, :, 3:] = seen
            else:
                column = 5 * n + m + 3 * len(self.unknown) + 6 * (s - 1) + 3
                body[chosen, :, column : column + 3] = seen / self.rotation_length
        probe_turns = np.stack([vee(correction.T @ d) for d in probe_derivatives], axis=-1)
        body[:, :, width - 3 :] = probe_turns / self.rotation_length
        inverse = inverse_right_jacobian(error)
        body = np.einsum("pij,pjk->pik", inverse, body)
        base = np.einsum("pij,pjk->pik", inverse, base)
        use = np.r_[self.free.ravel(), self.extra_free, self.offset_free]
        columns = [body[:, :, use]] + ([base[:, :, self.base_free]] if self.base_free.any() else [])
        return error, np.concatenate(columns, axis=-1)

    def _flange_point_jacobian(self, state: State, q, rows, offset) -> np.ndarray:
        """``d (F r) / d (parameters, joint-model values)`` ``(m, 3, 5 n + m)`` of a flange point ``r``."""
        n = state.values.shape[0]
        mount = ReflectorMount(frame="flange", positions=offset)
        _, group_jac, by_joint = target_jacobian(
            state.values, q, np.full(rows.size, n - 1), mount, joint_variables=True
        )
        out = group_jac.reshape(rows.size, 3, -1)
        if self.extra_free.size:
            assert self.joint_columns is not None  # joint-model values only with a joint model's columns
            out = np.concatenate([out, by_joint @ self.joint_columns[rows]], axis=-1)
        return out

    def _stacked(self, state: State, residuals, jacobian=None):
        """Position rows followed by the orientation rows of a 6-DoF capture (points criterion)."""
        if self.oriented is None or self.criterion != "points":
            return residuals, jacobian
        error, turn = self.orientation_part(state, jacobian is not None)
        residuals = np.concatenate([residuals, error.ravel()])
        if jacobian is None:
            return residuals, None
        return residuals, np.concatenate([jacobian, turn.reshape(-1, turn.shape[-1])])

    def joint_variables(self, extras) -> np.ndarray:
        """``q + C(q) extras`` [rad] (``q`` itself for the geometric model)."""
        if self.joint_columns is None:
            return self.q
        return self.q + self.joint_columns @ np.asarray(extras, dtype=float)

    def _groups(self, offsets):
        """``(rows, mount, unknown slot or None)`` per target."""
        for t, target in enumerate(self.targets):
            rows = np.flatnonzero(self.target_index == t)
            if rows.size == 0:
                continue
            slot = self.unknown.index(t) if t in self.unknown else None
            mount = target.mount if slot is None else ReflectorMount(frame="flange", positions=offsets[slot])
            yield rows, mount, slot

    def base_points(self, state: State) -> np.ndarray:
        """Target positions in the base frame ``(n_points, 3)`` [mm]."""
        q = self.joint_variables(state.extras)
        if not self.targets:
            return target_positions(state.values, q, self.turning, self.reflector)
        points = np.empty((q.shape[0], 3))
        for rows, mount, _ in self._groups(state.offsets):
            points[rows] = target_positions(state.values, q[rows], self.turning[rows], mount)
        return points

    def base_jacobian(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """Base-frame points and ``d points / d (parameters, joint-model values, every unknown offset)``
        ``(n_points, 3, 5 n + m + 3 k)``."""
        q = self.joint_variables(state.extras)
        n_points, n = q.shape
        m = self.extra_free.size
        points = np.empty((n_points, 3))
        jac = np.zeros((n_points, 3, 5 * n + m + self.offset_start.size))  # session columns: point_jacobian
        groups = [(np.arange(n_points), self.reflector, None)] if not self.targets else self._groups(state.offsets)
        for rows, mount, slot in groups:
            group_points, group_jac, by_joint = target_jacobian(
                state.values, q[rows], self.turning[rows], mount, joint_variables=True
            )
            points[rows] = group_points
            jac[rows, :, : 5 * n] = group_jac.reshape(rows.size, 3, -1)
            if m:  # d p / d extras = sum_i d p / d q_i C_i
                assert self.joint_columns is not None  # m > 0 only with a joint model's columns
                jac[rows, :, 5 * n : 5 * n + m] = by_joint @ self.joint_columns[rows]
            if slot is not None:  # d (F_n r) / d r = the flange rotation
                column = 5 * n + m + 3 * slot
                jac[rows, :, column : column + 3] = forward_kinematics(state.values, q[rows])[:, :3, :3]
        return points, jac

    def tracker(self, x_base) -> np.ndarray:
        """``tracker_from_base`` of the first session at the corrections ``x_base``."""
        return _corrected(self.session_start(0), x_base)

    def raw_residuals(self, x) -> np.ndarray:
        """Unweighted residuals [mm]: ``T p - m`` per coordinate (``T`` the point's session's), or
        ``|p_i - p_j| - |m_i - m_j|``."""
        state = self.unpack_all(x)
        points = self.base_points(state)
        if self.criterion == "distances":
            return pdist(points)[self.pair_keep] - self.measured_distances
        trackers = self.trackers(state)
        in_tracker = np.empty_like(points)
        for s, rows in enumerate(self.session_rows()):
            in_tracker[rows] = points[rows] @ trackers[s, :3, :3].T + trackers[s, :3, 3]
        return (in_tracker - self.measured).ravel()

    def _pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The distances criterion's point pairs ``(pair_i, pair_j)``."""
        assert self.pair_i is not None and self.pair_j is not None  # set whenever the criterion is distances
        return self.pair_i, self.pair_j

    def _row_weights(self) -> np.ndarray | None:
        if self.criterion == "distances":
            return self.pair_weight
        weights = None if self.point_weight is None else np.repeat(self.point_weight, 3)
        if self.oriented is None:
            return weights
        position = np.ones(3 * self.q.shape[0]) if weights is None else weights
        return np.concatenate([position, np.repeat(self.orientation_weight, 3)])

    def residuals(self, x) -> np.ndarray:
        residuals = self.raw_residuals(x)
        if self.oriented is not None and self.criterion == "points":
            residuals, _ = self._stacked(self.unpack_all(x), residuals)
        weights = self._row_weights()
        return residuals if weights is None else residuals * weights

    def point_jacobian(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """Tracker-frame (points criterion) or base-frame (distances) points ``(n_points, 3)`` and
        ``d points / d x`` ``(n_points, 3, n_x)``."""
        points, jac = self.base_jacobian(state)
        use = np.r_[self.free.ravel(), self.extra_free, self.offset_free]
        if self.criterion == "distances":
            return points, jac[:, :, use]
        own = jac.shape[-1] - self.offset_start.size + 3 * len(self.unknown)  # the first session column
        tracker_points = np.empty_like(points)
        base = np.zeros(points.shape + (6,))
        for s, rows in enumerate(self.session_rows()):
            start = self.session_start(s)
            rotation, shift, derivatives = base_correction(self.session_correction(state, s))
            r0 = start[:3, :3]
            total = r0 @ rotation
            jac[rows] = np.einsum("ij,pjk->pik", total, jac[rows])
            fields = [np.broadcast_to(r0[:, axis], (rows.size, 3)) for axis in range(3)]
            fields += [points[rows] @ (r0 @ derivative).T for derivative in derivatives]
            if s == 0:
                base[rows] = np.stack(fields, axis=-1)
            else:  # the session's translation, then its rotation per unit of rotation_length
                column = own + 6 * (s - 1)
                jac[rows, :, column : column + 3] = np.stack(fields[:3], axis=-1)
                jac[rows, :, column + 3 : column + 6] = np.stack(fields[3:], axis=-1) / self.rotation_length
            tracker_points[rows] = points[rows] @ total.T + r0 @ shift + start[:3, 3]
        columns = [jac[:, :, use]]
        if self.base_free.any():
            columns.append(base[:, :, self.base_free])
        return tracker_points, np.concatenate(columns, axis=-1)

    def evaluate(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(m,)`` and Jacobian ``(m, n_x)`` at x (weighted where weights are given)."""
        state = self.unpack_all(x)
        points, jac = self.point_jacobian(state)
        if self.criterion == "points":
            residuals, jacobian = (points - self.measured).ravel(), jac.reshape(-1, jac.shape[-1])
            residuals, jacobian = self._stacked(state, residuals, jacobian)
        else:
            residuals = pdist(points)[self.pair_keep] - self.measured_distances
            jacobian = _pair_jacobian(points, jac, *self._pairs())
        weights = self._row_weights()
        if weights is None:
            return residuals, jacobian
        return residuals * weights, jacobian * weights[:, None]

    def jacobian_sample(self, x, rows: int) -> np.ndarray:
        """Jacobian at x on about ``rows`` evenly strided residuals (every pair, or point, k-th)."""
        state = self.unpack_all(x)
        points, jac = self.point_jacobian(state)
        if self.criterion == "points":
            return self._stacked(state, points.ravel(), jac.reshape(-1, jac.shape[-1]))[1]
        assert self.pair_i is not None and self.pair_j is not None  # the distances criterion has its pairs
        stride = max(1, self.pair_i.size // rows)
        return _pair_jacobian(points, jac, self.pair_i[::stride], self.pair_j[::stride])

    def noise_map(self, x) -> scipy.sparse.csr_matrix | None:
        """``G = d residuals / d measured points`` ``(m, 3 n_points)`` for distances; None = identity."""
        if self.criterion == "points":
            return None
        points = self.base_points(self.unpack_all(x))
        pair_i, pair_j = self._pairs()
        unit = _unit(points[pair_i] - points[pair_j])
        if self.pair_weight is not None:  # G = diag(w_pair) dr/dm diag(sigma_k / sigma_ref): isotropic noise again
            assert self.point_weight is not None  # pair weights are built from the point weights
            unit = unit * self.pair_weight[:, None]
            unit_i = unit / self.point_weight[pair_i, None]
            unit_j = unit / self.point_weight[pair_j, None]
        else:
            unit_i = unit_j = unit
        m = pair_i.size
        rows = np.repeat(np.arange(m), 6)
        cols = np.concatenate([3 * pair_i[:, None] + np.arange(3), 3 * pair_j[:, None] + np.arange(3)], axis=1).ravel()
        data = np.concatenate([unit_i, -unit_j], axis=1).ravel()
        from scipy import sparse

        return sparse.csr_matrix((data, (rows, cols)), shape=(m, 3 * points.shape[0]))


def measurement_pairs(readings, targets=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs i < j of points that are not the same measurement, in :func:`scipy.spatial.distance.pdist` order.

    Two points at the same readings *and* on the same target (the forward and return sweeps of a
    bidirectional capture share their readings; readings 360 deg apart are the same pose too) have
    model distance 0 for any parameters: such a pair carries no information about the parameters
    and is left out (its distance has no derivative at 0). With per-joint reflectors
    (``ReflectorMount(frame="joint")``) every circle has its own target, so two points of different
    circles at the same readings are different targets and their pair is kept.

    Parameters
    ----------
    readings : array_like, shape (n_points, n_joints)
        Joint readings [rad].
    targets : array_like of int, shape (n_points,), optional
        Which target each point is on (the turning joint for per-joint reflectors, see
        :func:`capture_target_index`); None: one target for all points (flange reflector).

    Returns
    -------
    pair_i, pair_j : ndarray of int, shape (n_pairs,)
        The kept pairs.
    keep : ndarray of bool, shape (n_points (n_points - 1) / 2,)
        Which entries of ``pdist`` order are kept.
    """
    readings = np.asarray(readings, dtype=float)
    n = readings.shape[0]
    # one pose: the same joint angles modulo 360 deg (a sweep over -360..360 visits every pose twice),
    # compared on a 1e-7 deg grid so that 360 deg computed in floating point matches exactly
    turns = np.mod(np.round(np.rad2deg(readings) * 1e7).astype(np.int64), 3_600_000_000)
    key = turns if targets is None else np.column_stack([turns, np.asarray(targets, dtype=np.int64)])
    _, pose = np.unique(key, axis=0, return_inverse=True)
    pose = pose.ravel()
    pair_i, pair_j = np.triu_indices(n, k=1)
    keep = pose[pair_i] != pose[pair_j]
    return pair_i[keep], pair_j[keep], keep


def capture_target_index(capture: Capture, reflector: ReflectorMount) -> np.ndarray | None:
    """Target of each point for :func:`measurement_pairs`: the circle for per-joint reflectors, else None."""
    return capture_turning_joints(capture, reflector) if reflector.frame == "joint" else None



@dataclass(frozen=True, slots=True, kw_only=True)
class Setup:
    """What a refinement fixes before its first fit: the problem with every candidate free (``probe``, the
    unknown offsets at their start), the candidates, the scales, the names and the settings."""

    capture: Capture
    start: ParameterSet
    settings: RefinementSettings
    probe: Problem
    candidates: np.ndarray  # (5 n + m,) bool: parameters, then joint-model values
    all_scale: np.ndarray  # (5 n + m + 6,): parameters, joint-model values, then base corrections
    offset_start: np.ndarray  # (k, 3)
    offset_names: tuple[str, ...]
    joint_model: JointModel | None
    use_base: bool
    still: tuple[str, ...]
    weighted: bool
    n_residuals: int
    session_names: tuple[str, ...] = ()  # points criterion, several sessions: their names (the first: the reference)

    @property
    def criterion(self) -> str:
        return self.probe.criterion

    @property
    def explicit(self) -> bool:
        """Whether the caller gave the free set."""
        return self.settings.free is not None

    @property
    def strict(self) -> bool:
        return self.settings.strict

    @property
    def extra_names(self) -> tuple[str, ...]:
        return () if self.joint_model is None else self.joint_model.names
