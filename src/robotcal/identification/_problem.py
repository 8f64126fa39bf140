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
from robotcal.geometry.transforms import rot_x, rot_y, rot_z
from robotcal.identification.health import repeatability_sigma
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.kinematics.forward import forward_kinematics, target_positions
from robotcal.kinematics.jacobian import target_jacobian
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ANGLE_COLUMNS, ParameterSet, ReflectorMount

__all__ = [
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
BASE_NAMES = ("base.tx", "base.ty", "base.tz", "base.rx", "base.ry", "base.rz")
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
    (:func:`robotcal.io.parameters_json.parameters_to_dict`) and the tables of ``identify`` and ``refine``.
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
        jac = np.zeros((n_points, 3, 5 * n + m + 3 * len(self.unknown)))
        groups = [(np.arange(n_points), self.reflector, None)] if not self.targets else self._groups(state.offsets)
        for rows, mount, slot in groups:
            group_points, group_jac, by_joint = target_jacobian(
                state.values, q[rows], self.turning[rows], mount, joint_variables=True
            )
            points[rows] = group_points
            jac[rows, :, : 5 * n] = group_jac.reshape(rows.size, 3, -1)
            if m:  # d p / d extras = sum_i d p / d q_i C_i
                jac[rows, :, 5 * n : 5 * n + m] = by_joint @ self.joint_columns[rows]
            if slot is not None:  # d (F_n r) / d r = the flange rotation
                column = 5 * n + m + 3 * slot
                jac[rows, :, column : column + 3] = forward_kinematics(state.values, q[rows])[:, :3, :3]
        return points, jac

    def tracker(self, x_base) -> np.ndarray:
        rotation, shift, _ = base_correction(x_base)
        delta = np.eye(4)
        delta[:3, :3] = rotation
        delta[:3, 3] = shift
        return self.base_start @ delta

    def raw_residuals(self, x) -> np.ndarray:
        """Unweighted residuals [mm]: ``T p - m`` per coordinate, or ``|p_i - p_j| - |m_i - m_j|``."""
        state = self.unpack_all(x)
        points = self.base_points(state)
        if self.criterion == "distances":
            return pdist(points)[self.pair_keep] - self.measured_distances
        tracker = self.tracker(state.x_base)
        return (points @ tracker[:3, :3].T + tracker[:3, 3] - self.measured).ravel()

    def _row_weights(self) -> np.ndarray | None:
        if self.criterion == "distances":
            return self.pair_weight
        return None if self.point_weight is None else np.repeat(self.point_weight, 3)

    def residuals(self, x) -> np.ndarray:
        residuals = self.raw_residuals(x)
        weights = self._row_weights()
        return residuals if weights is None else residuals * weights

    def point_jacobian(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """Tracker-frame (points criterion) or base-frame (distances) points ``(n_points, 3)`` and
        ``d points / d x`` ``(n_points, 3, n_x)``."""
        points, jac = self.base_jacobian(state)
        jac = jac[:, :, np.r_[self.free.ravel(), self.extra_free, self.offset_free]]
        if self.criterion == "distances":
            return points, jac
        rotation, shift, derivatives = base_correction(state.x_base)
        r0 = self.base_start[:3, :3]
        total = r0 @ rotation
        columns = [np.einsum("ij,pjk->pik", total, jac)]
        base = [np.broadcast_to(r0[:, axis], points.shape) for axis in range(3)]
        base += [points @ (r0 @ derivative).T for derivative in derivatives]
        chosen = [base[k] for k in np.flatnonzero(self.base_free)]
        if chosen:
            columns.append(np.stack(chosen, axis=-1))
        tracker_points = points @ total.T + r0 @ shift + self.base_start[:3, 3]
        return tracker_points, np.concatenate(columns, axis=-1)

    def evaluate(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(m,)`` and Jacobian ``(m, n_x)`` at x (weighted where weights are given)."""
        points, jac = self.point_jacobian(self.unpack_all(x))
        if self.criterion == "points":
            residuals, jacobian = (points - self.measured).ravel(), jac.reshape(-1, jac.shape[-1])
        else:
            residuals = pdist(points)[self.pair_keep] - self.measured_distances
            jacobian = _pair_jacobian(points, jac, self.pair_i, self.pair_j)
        weights = self._row_weights()
        if weights is None:
            return residuals, jacobian
        return residuals * weights, jacobian * weights[:, None]

    def jacobian_sample(self, x, rows: int) -> np.ndarray:
        """Jacobian at x on about ``rows`` evenly strided residuals (every pair, or point, k-th)."""
        points, jac = self.point_jacobian(self.unpack_all(x))
        if self.criterion == "points":
            return jac.reshape(-1, jac.shape[-1])
        stride = max(1, self.pair_i.size // rows)
        return _pair_jacobian(points, jac, self.pair_i[::stride], self.pair_j[::stride])

    def noise_map(self, x) -> scipy.sparse.csr_matrix | None:
        """``G = d residuals / d measured points`` ``(m, 3 n_points)`` for distances; None = identity."""
        if self.criterion == "points":
            return None
        points = self.base_points(self.unpack_all(x))
        unit = _unit(points[self.pair_i] - points[self.pair_j])
        if self.pair_weight is not None:  # G = diag(w_pair) dr/dm diag(sigma_k / sigma_ref): isotropic noise again
            unit = unit * self.pair_weight[:, None]
            unit_i = unit / self.point_weight[self.pair_i, None]
            unit_j = unit / self.point_weight[self.pair_j, None]
        else:
            unit_i = unit_j = unit
        m = self.pair_i.size
        rows = np.repeat(np.arange(m), 6)
        cols = np.concatenate(
            [3 * self.pair_i[:, None] + np.arange(3), 3 * self.pair_j[:, None] + np.arange(3)], axis=1
        ).ravel()
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
