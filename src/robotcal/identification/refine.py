"""Least-squares refinement of the kinematic parameters (thesis ch. 4.5.7, eqs 4-101 and 4-102).

CPA gives parameters tied to the physical joint axes; a Levenberg-Marquardt refinement then
minimises the residual over all measured points. Two objectives:

``criterion="points"`` (eq. 4-101, the classic criterion)
    residuals ``T(x_b) p_k(x) - m_k`` (x, y, z per point, vector residuals, not the distance per
    point of eq. 4-101's summand). The robot-to-tracker transform ``tracker_from_base``
    (``T = T_0 [Rz(rz) Ry(ry) Rx(rx) | t]``, 6 corrections ``base.*``) is either held at the given
    ``T_0`` (a scenario's ``base_frame = "given"``: the default when ``tracker_from_base`` is
    passed) or estimated with the parameters (``estimate_base=True``, or no ``tracker_from_base``:
    ``T_0`` from a Horn registration).
``criterion="distances"`` (eq. 4-102, the thesis's registration-free criterion)
    residuals ``|p_i(x) - p_j(x)| - |m_i - m_j|`` for every pair i < j of measured points
    (n(n-1)/2 residuals, less the pairs that are the same measurement: same readings on the same
    target, see :func:`measurement_pairs`). No tracker transform enters.

Both are solved by ``scipy.optimize.least_squares`` (``method="lm"``, MINPACK; ``"trf"`` where
there are fewer residuals than unknowns) with an explicit ``x_scale`` (1 mm for lengths and
translations, ``1/L`` rad for angles, L the RMS radius of the measured point cloud about its
centroid, so that a unit step of any variable moves the points by about 1 mm), the exact
analytic Jacobian (:func:`robotcal.kinematics.jacobian.target_jacobian`) and
``ftol = xtol = gtol = 1e-12``: on noise-free data every determined parameter is recovered to
about 1e-11 mm / 1e-11 deg in 1-4 Jacobian evaluations from the nominal or the CPA start. The
final cost is never above the start's: should the solver end higher, the start is returned with
``success=False`` and a message saying so.

Which quantities are free: decided by the data
----------------------------------------------
Nothing is held by a list. At the start, every candidate -- each parameter the model does not fix
(beta of a DH joint, d of a Hayati joint), the unknown flange offsets, plus, when the base frame is
estimated, the six ``base.*`` corrections -- enters one rank-revealing, ordered selection on the
column-scaled Jacobian of the actual residuals
(:func:`robotcal.identification.observability.select_identifiable`). The order is a documented
choice: **base corrections first**, then the unknown offsets (their guess is rough, the nominal
parameters are not), then the parameters joint by joint in the order d, theta, a, alpha, beta. Of a
group of columns that are dependent, the earlier ones stay free and the later ones are held at their
start value: a parameter that is equivalent to a base motion is held and the base correction kept
(the base frame is the instrument's pose, the parameters are the robot's; CPA fixes d1 and theta1
from the base frame).

**Decided again at the solution.** Dependencies can exist only at special values (alpha = 0, a = 0, a
target on an axis of the nominal robot) or be hidden by them: a parameter held at the start that the
truth determines leaves a residual on noise-free data, one freed at the start that the solution does
not determine wanders along the null space. So the rank test runs again at the solution (parameters,
offsets and base frame as fitted; its Jacobian also serves the statistics), with the free set in use
tested first (each part in the order above) and the held candidates after it: a free quantity is
dropped only when it is not determined there, a held one freed only when it adds to the rank. When
the free set changes, the capture is refitted from the solution with the new set, what it now holds
going back to its start value; at most ``_MAX_REFITS`` (3) refits, and a free set seen before stops
the rounds (the last fit is returned, ``message`` and the warning say the free set did not settle).
``refits`` counts the refits; the warnings report the final decision. What is held is reported:

* ``gauge``: held parameters whose whole effect on the data is a rigid motion of the point cloud
  (tested on the data: the parameter's column of ``d points / d x`` lies in the span of the six
  rigid-motion fields of the predicted points) while the criterion cannot tell a rigid motion from
  a base-frame one (base estimated, or distances).
* ``held``: the other held quantities (the data determine no combination that includes them).
* ``confounded``: free quantities that take up the effect of held ones, so that only their
  combination is determined: the support of the null space of the full candidate Jacobian at the
  solution and at a generic point near it (every candidate moved by up to one ``x_scale`` unit,
  fixed seed) because special values hide second-order couplings (a flange target at height h
  above a nominal alpha_n = 0 moves d_n by ``h (1 - cos alpha_n)`` when alpha_n is held).

The cases (thesis layout = per-joint reflectors, reflector i fixed in frame {i-1} and turned by
q_i, eq. 5-1):

* **Per-joint reflectors.** Circle 1's points ``T Rz(q1) r1`` do not depend on d1 or theta1,
  while circles 2..n move with them, so d1 and theta1 change the shape of the point cloud: they
  are **free** with every criterion and base-frame mode (given, registered/estimated, distances).
* **J6 (joint n) behind its own reflector.** Circle n's target turns with q_n in frame {n-1}:
  joint n's d, theta, a, alpha enter no point; their columns are zero and they are ``held``.
* **Flange target, base estimated (points) or distances.** d1 (a translation along z0) and
  theta1 (a rotation about z0) move every point alike: they are a ``gauge``, held at the start
  value; with the points criterion the base corrections are ``confounded`` with them.
  Also, the target is 3 numbers in frame {n} for joint n's four d, theta, a, alpha: the last,
  alpha_n, is ``held`` and d_n, theta_n, a_n are ``confounded``.
* **Base given / held (points, ``estimate_base=False``).** Nothing absorbs a rigid motion, so d1
  and theta1 are free for every target layout.
* **A joint that never moves** (``still_joints``). Its frame is rigidly attached to the previous
  one; whatever only that rotation would separate is held: e.g. J6 never turning behind a flange
  target leaves J5's alpha and J6's d, theta, a, alpha held and J5's d, theta, a confounded; behind
  per-joint targets J5's d, theta, a, alpha go too (they move circle 6 only). A still J1 behind a
  flange target with a free base makes J1's a and alpha a gauge as well, with whatever else then
  moves the whole cloud rigidly (from the nominal start, where axes 2 and 3 are parallel: J2's theta
  and J3's d).
* **Base corrections the data cannot determine** (e.g. a target on axis 6 turned by J6 alone:
  every point is the same point, no base rotation is seen) are held at the start transform and
  listed in ``held`` as ``base.*`` names.

Held quantities raise an :class:`~robotcal.errors.IdentifiabilityWarning` naming them (and any
joint whose reading never changes) when the free set is automatic (``free=None``), and an
:class:`~robotcal.errors.IdentifiabilityError` listing them (gauge first) when the caller gave
the free set explicitly or asked for ``on_unidentifiable="raise"``.

Uncertainty
-----------
The linearised covariance of the free parameters assumes independent, isotropic point noise of
one standard deviation sigma per coordinate. For the points criterion the residuals are that noise,
so ``C = s^2 (J^T J)^-1`` with ``s^2 = SSR / (m - p)``. Pair residuals share points and are
correlated: for the distances criterion the noise is propagated through ``G = d residual /
d points`` (sandwich form) ``C = sigma^2 (J^T J)^-1 J^T G G^T J (J^T J)^-1``, with sigma^2 from
``E[SSR] = sigma^2 (tr(G G^T) - tr(H G G^T))``, H the hat matrix.

When the capture leaves no degree of freedom for the noise (e.g. a 6-point flange capture: 18
residuals for 18 determinable unknowns; for distances, ``tr(G G^T) - tr(H G G^T) <= 0``) the fit
still runs and returns its parameters, but sigma cannot be estimated: the result then has
``sigma = NaN``, ``covariance = correlation = None``, ``standard_uncertainty`` all NaN, and
``message`` says so (the solver's message follows). Writers must map those NaNs to null.

References
----------
Thesis ch. 4.5.7, eqs 4-101 and 4-102, Tables 4.8-4.11, Figs 4.24-4.25.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from robotcal.execution import single_blas_thread
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import check_rigid_transform, rot_x, rot_y, rot_z
from robotcal.identification.health import FitHealth
from robotcal.identification.observability import (
    conditioning,
    correlation_from_covariance,
    select_identifiable,
    triangular_factor,
)
from robotcal.identification.targets import Target, resolve_targets
from robotcal.kinematics.forward import forward_kinematics, target_positions
from robotcal.kinematics.jacobian import target_jacobian
from robotcal.kinematics.joint_model import JOINT_MODEL_GROUPS, JointModel, lash_turns
from robotcal.kinematics.model import ANGLE_COLUMNS, LENGTH_KINDS, PARAMETER_KINDS, ParameterSet, ReflectorMount

__all__ = [
    "CRITERIA",
    "BASE_NAMES",
    "RefinementResult",
    "refine_parameters",
    "capture_turning_joints",
    "capture_target_index",
    "measurement_pairs",
    "base_correction",
    "wrap_angles",
    "point_sigmas",
]

if TYPE_CHECKING:
    import scipy.sparse

    from robotcal.identification.model_choice import CrossValidation, ModelChoice


def pdist(points):
    """:func:`scipy.spatial.distance.pdist`, imported on first use (scipy is slow to import: a command
    that never refines must not pay it)."""
    from scipy.spatial.distance import pdist as condensed_distances

    return condensed_distances(points)


def least_squares(*args, **kwargs):
    """:func:`scipy.optimize.least_squares`, imported on first use (see :func:`pdist`)."""
    from scipy.optimize import least_squares as solve

    return solve(*args, **kwargs)


#: The two objectives of thesis ch. 4.5.7.
CRITERIA = ("points", "distances")
#: Names of the six ``tracker_from_base`` corrections (points criterion): translation [mm], then
#: rotation angles [rad] of ``Rz(rz) Ry(ry) Rx(rx)``, applied on the base side of the start transform.
BASE_NAMES = ("base.tx", "base.ty", "base.tz", "base.rx", "base.ry", "base.rz")
_D, _THETA = 0, 1
_PAIR_CHUNK = 32768
_STILL_RAD = 1e-9
_SAMPLE_ROWS = 8192  # residuals sampled for the null space at the generic point
_SUPPORT = 1e-8  # a null vector's entry (unit columns) above this ties a free quantity to a held one
#: The rank test sees unknown flange offsets at their guess moved by this much in a fixed generic direction
#: [mm]: a guess on axis n (the default, the flange origin) would hide joint n's rotation from the test,
#: while the data, taken off the axis, do show it.
_GENERIC_OFFSET_MM = 50.0
#: Refits when the rank test at a solution changes the free set (module notes); a free set seen before also stops.
_MAX_REFITS = 3


def _generic_directions(count: int) -> np.ndarray:
    """``(count, 3)`` fixed unit vectors in generic directions (seeded), one per unknown offset."""
    directions = np.random.default_rng(12345).normal(size=(count, 3))
    return directions / np.linalg.norm(directions, axis=1, keepdims=True)


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinementResult:
    """Outcome of :func:`refine_parameters`, shaped like SciPy's ``OptimizeResult``.

    Attributes
    ----------
    parameters : ParameterSet
        Refined parameters [mm, rad]; ``identified`` is the start's flags or-ed with ``free``.
    tracker_from_base : ndarray, shape (4, 4) or None
        Estimated (or held) base frame for the points criterion; None for distances.
    criterion : {"points", "distances"}
    method : {"lm", "trf"}
    success : bool
        SciPy's success, and False when the solver ended above the start's cost (then the start is
        returned).
    status : int
        SciPy's termination status.
    message : str
        SciPy's message; prefixed with an explanation when sigma could not be estimated or when
        the start was returned.
    nfev, njev : int
        Residual and Jacobian evaluations, summed over the fits (``refits`` + 1).
    free : ndarray of bool, shape (n_joints, 5)
        Parameters estimated.
    base_free : ndarray of bool, shape (6,)
        ``tracker_from_base`` corrections estimated (all False for distances).
    gauge : tuple of str
        Parameters held because their effect on the data is a rigid motion of the whole point cloud,
        which the criterion cannot tell from a base-frame motion: a free base frame absorbs it (points
        criterion, ``tracker_from_base`` estimated) or pairwise distances do not see it. Found by the
        rank test at the solution, not from a list: d1 and theta1 behind a flange target with a free
        base or with distances; empty with per-joint targets or a held base (module notes).
    held : tuple of str
        Other parameters (and ``base.*`` corrections) held because the data cannot determine them:
        a joint behind its own per-joint target, one of joint n's d, theta, a, alpha behind a flange
        target, parameters tied by a joint that never moves (module notes). Disjoint from ``gauge``.
    confounded : tuple of str
        Free quantities (parameter or ``base.*`` names) whose estimate depends on the values at which
        ``gauge``/``held`` ones are held (they take up their effect): only the combination is
        determined. The free quantities not listed are determined by the data alone.
    still_joints : tuple of str
        Joints whose reading never changes in the capture.
    free_names : tuple of str
        Names of the estimated quantities, in the order of the covariance rows.
    x_scale : ndarray, shape (n_free,)
        Characteristic scale of each unknown [mm | rad].
    start_cost : float
        SciPy cost ``0.5 * sum(r^2)`` [mm^2] at the start; the final cost is never above it.
    cost_history : ndarray, shape (n_iterations + 1,)
        SciPy cost ``0.5 * sum(r^2)`` [mm^2] at the start and after every iteration (each Jacobian
        evaluation happens at an accepted iterate), ending with the final cost; after a refit it goes
        on with the refit's start (the quantities newly held back at their start values) and iterations.
    rms_history : ndarray, shape (n_iterations + 1,)
        ``sqrt(2 cost / m)`` [mm], the RMS residual along the way.
    n_residuals : int
    residual_rms, residual_mean, residual_max : float
        Of the per-point distance ``|T p - m|`` (points) or of ``|D_model - D_measured|``
        (distances) at the solution [mm].
    singular_values : ndarray, shape (n_free,)
        Of the column-scaled Jacobian at the solution.
    condition_number : float
    sigma : float
        Estimated point noise per coordinate [mm] (see module notes); NaN when the capture leaves
        no degree of freedom for it (then ``covariance`` is None and ``message`` says why).
    covariance : ndarray, shape (n_free, n_free), or None
        Linearised covariance of the free quantities [mm, rad]; None when sigma is NaN.
    correlation : ndarray, shape (n_free, n_free), or None
        None when sigma is NaN.
    standard_uncertainty : ndarray, shape (n_joints, 5)
        ``sqrt(diag(covariance))`` placed per parameter [mm, rad]; NaN where held, and everywhere
        when sigma is NaN.
    wall_time_s : float
    refits : int
        How many times the rank test at a solution changed the free set and the capture was refitted
        (module notes); 0 when the start's decision holds at the solution.
    health : FitHealth or None
        The fit-health verdict (:mod:`robotcal.identification.health`), set by :func:`robotcal.refine`.
    joint_model_uncertainty : ndarray, shape (m,), or None
        Standard uncertainty of every joint-model value (``parameters.joint_model``, core units: rad/(N m),
        rad); NaN where held or without a covariance; None for the geometric model.
    model : str
        The model fitted: ``geometric``, or the joint model's groups (``compliance``, ``harmonic``,
        ``compliance+harmonic``).
    effect : ndarray, shape (n_free,)
        RMS displacement of the points (points criterion) or change of the distances (distances) per unit of each
        free quantity, at the solution [mm per mm, rad, ...]: ``u * effect`` is what one standard uncertainty
        of the quantity alone does to the data (:func:`robotcal.identification.health.refine_health`).
    cross_validation : CrossValidation or None
        Its k-fold cross-validation by pose, set by :func:`robotcal.refine`.
    model_choice : ModelChoice or None
        With ``model="auto"``: every candidate's cross-validation and why the model was chosen.
    """

    parameters: ParameterSet
    tracker_from_base: np.ndarray | None
    criterion: str
    method: str
    success: bool
    status: int
    message: str
    nfev: int
    njev: int
    free: np.ndarray
    base_free: np.ndarray
    gauge: tuple[str, ...]
    held: tuple[str, ...]
    confounded: tuple[str, ...]
    still_joints: tuple[str, ...]
    free_names: tuple[str, ...]
    x_scale: np.ndarray
    start_cost: float
    cost_history: np.ndarray
    rms_history: np.ndarray
    n_residuals: int
    residual_rms: float
    residual_mean: float
    residual_max: float
    singular_values: np.ndarray
    condition_number: float
    sigma: float
    covariance: np.ndarray | None
    correlation: np.ndarray | None
    standard_uncertainty: np.ndarray
    wall_time_s: float
    targets: tuple[Target, ...] = ()
    target_uncertainty: np.ndarray | None = None
    weighted: bool = False
    residual_rms_coordinate: float = float("nan")
    refits: int = 0
    health: FitHealth | None = None
    joint_model_uncertainty: np.ndarray | None = None
    model: str = "geometric"
    effect: np.ndarray | None = None
    cross_validation: CrossValidation | None = None
    model_choice: ModelChoice | None = None

    def __repr__(self) -> str:
        health = f", {self.health.verdict}" if self.health is not None else ""
        cv = "" if self.cross_validation is None else f", CV {self.cross_validation.cv_rms_mm * 1e3:.3g} um"
        return (
            f"RefinementResult({self.criterion} criterion, {self.model} model, {len(self.free_names)} free, residual "
            f"RMS {self.residual_rms * 1e3:.3g} um{cv}{health}, success={self.success})"
        )


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


def point_sigmas(capture: Capture) -> np.ndarray | None:
    """Standard uncertainty per coordinate of every point [mm] from its U(95): ``U / 2`` (k = 2, normal);
    None when the capture has no ``u95_mm`` column."""
    return None if capture.u95 is None else np.asarray(capture.u95, dtype=float) / 2.0


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


class _State(NamedTuple):
    """The quantities a point of the search stands for: parameters ``(n, 5)``, joint-model values ``(m,)``,
    unknown offsets ``(k, 3)`` and base corrections ``(6,)``."""

    values: np.ndarray
    extras: np.ndarray
    offsets: np.ndarray
    x_base: np.ndarray


@dataclass(frozen=True, slots=True, kw_only=True)
class _Problem:
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
        return self.pack(_State(self.start, self.extra_start, self.offset_start, self.base_offset))

    def unpack_all(self, x) -> _State:
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
        return _State(values, extras, offsets.reshape(-1, 3), x_base)

    def pack(self, state: _State) -> np.ndarray:
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

    def base_points(self, state: _State) -> np.ndarray:
        """Target positions in the base frame ``(n_points, 3)`` [mm]."""
        q = self.joint_variables(state.extras)
        if not self.targets:
            return target_positions(state.values, q, self.turning, self.reflector)
        points = np.empty((q.shape[0], 3))
        for rows, mount, _ in self._groups(state.offsets):
            points[rows] = target_positions(state.values, q[rows], self.turning[rows], mount)
        return points

    def base_jacobian(self, state: _State) -> tuple[np.ndarray, np.ndarray]:
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

    def point_jacobian(self, state: _State) -> tuple[np.ndarray, np.ndarray]:
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


def _check_free(free, robot) -> np.ndarray | None:
    if free is None:
        return None
    if isinstance(free, (list, tuple)) and all(isinstance(name, str) for name in free):
        names = robot.parameter_names
        unknown = [name for name in free if name not in names]
        if unknown:
            raise InputError(f"`free` names unknown parameters {unknown}; expected names like 'J2.beta'")
        mask = np.array([name in free for name in names]).reshape(robot.n_joints, 5)
    else:
        mask = np.asarray(free)
        if mask.shape != (robot.n_joints, 5) or mask.dtype != bool:
            raise InputError(
                f"`free` must be None, parameter names, or a bool array of shape ({robot.n_joints}, 5); got {mask.shape}"
            )
    fixed = mask & robot.structurally_fixed
    if np.any(fixed):
        names = [n for n, flag in zip(robot.parameter_names, fixed.ravel(), strict=True) if flag]
        raise InputError(f"`free` frees parameters the model fixes at 0: {', '.join(names)}")
    return mask


def _rigid_motion_fields(points: np.ndarray, angle_scale: float) -> np.ndarray:
    """Orthonormal basis ``(3 n_points, <= 6)`` of the velocity fields of the rigid motions of ``points``.

    Translations ``e_k`` and rotations ``e_k x (p - centroid)`` (scaled by ``angle_scale``); a
    parameter whose effect on the points lies in this span moves the whole cloud rigidly.
    """
    centred = points - points.mean(axis=0)
    fields = np.zeros((points.shape[0], 3, 6))
    for k in range(3):
        axis = np.zeros(3)
        axis[k] = 1.0
        fields[:, k, k] = 1.0
        fields[:, :, 3 + k] = np.cross(axis, centred) * angle_scale
    matrix = fields.reshape(-1, 6)
    u, s, _ = np.linalg.svd(matrix, full_matrices=False)
    return u[:, s > s[0] * 1e-12]


@dataclass(frozen=True, slots=True, kw_only=True)
class _Selection:
    """Outcome of the rank test on the full candidate set (module notes)."""

    free: np.ndarray  # (n, 5) bool: parameters estimated
    extra_free: np.ndarray  # (m,) bool: joint-model values estimated
    offset_free: np.ndarray  # (3 k,) bool: unknown offset components estimated
    base_free: np.ndarray  # (6,) bool: base corrections estimated
    held: np.ndarray  # (n, 5) bool: candidate parameters held, gauge ones included
    extra_held: np.ndarray  # (m,) bool
    offset_held: np.ndarray  # (3 k,) bool
    base_held: np.ndarray  # (6,) bool: candidate base corrections held
    gauge: np.ndarray  # (n, 5) bool: held because they move the whole point cloud rigidly
    confounded: np.ndarray  # (5 n + m + 3 k + 6,) bool: free quantities tied to a held one


def _null_support(matrix: np.ndarray, dimension: int) -> np.ndarray:
    """Columns of ``matrix`` (scaled to unit norm) that enter its ``dimension`` smallest right singular vectors."""
    if dimension <= 0:
        return np.zeros(matrix.shape[1], dtype=bool)
    _, _, vt = np.linalg.svd(matrix / np.linalg.norm(matrix, axis=0), full_matrices=True)
    return np.abs(vt[-dimension:]).max(axis=0) > _SUPPORT


def _selection_key(selection: _Selection) -> bytes:
    """What a selection estimates, comparable across rank tests."""
    return np.r_[selection.free.ravel(), selection.extra_free, selection.offset_free, selection.base_free].tobytes()


def _select_free(
    probe: _Problem,
    candidates: np.ndarray,
    all_scale: np.ndarray,
    tolerance: float,
    jacobian: np.ndarray | None = None,
    preferred: _Selection | None = None,
) -> _Selection:
    """Rank test at ``probe.x0()`` (the start, or a solution) on every candidate column (parameters, joint-model
    values, unknown offsets, base corrections); ``jacobian``: ``probe``'s Jacobian there when already evaluated.

    Columns are taken base corrections first, then the unknown flange offsets, then the parameters of
    joints 1..n in the order d, theta, a, alpha, beta (:func:`select_identifiable`), then the joint-model values:
    of a dependent group the earlier ones stay free, so a parameter equivalent to a base motion is held and the
    base correction kept, a joint-model term that only repeats a geometric parameter's effect is held, and joint
    n's d, theta, a, alpha, which only move the flange frame that unknown offsets are expressed in, are held in
    favour of the offsets (the flange frame stays nominal; the offsets are estimated in it); so is a parameter of
    joints 1..n-1 that only an offset's rough guess would otherwise absorb (a target on axis n). ``preferred``
    (at a solution: the free set in use) puts its columns first, each part in that order, so that a free quantity
    is dropped only when it is not determined and a held one freed only when it adds to the rank.

    ``candidates`` ``(5 n + m,)``: the parameters and joint-model values that may be free; ``all_scale``
    ``(5 n + m + 6,)``: the column scale of the parameters, the joint-model values and the base corrections.
    """
    n = probe.free.shape[0]
    m = probe.extra_free.size
    n_off = probe.offset_free.size
    n_base = int(probe.base_free.sum())
    own = 5 * n + m  # parameter and joint-model columns
    if preferred is not None:
        preferred = np.r_[
            preferred.free.ravel(), preferred.extra_free, preferred.offset_free, preferred.base_free[probe.base_free]
        ]
    # columns: 5 n parameters, m joint-model values, 3 k offsets, then the candidate base ones
    jac_all = probe.evaluate(probe.x0())[1] if jacobian is None else jacobian
    scale = np.concatenate([all_scale[:own], np.ones(n_off), all_scale[own:][probe.base_free]])
    scaled = triangular_factor(jac_all * scale)
    chosen = np.r_[candidates, np.ones(n_off + n_base, dtype=bool)]
    order = np.r_[
        np.arange(own + n_off, own + n_off + n_base),
        np.arange(own, own + n_off),
        np.arange(5 * n),
        np.arange(5 * n, own),
    ]
    if preferred is not None:  # the free set being checked first, each part in the documented order
        order = np.r_[order[preferred[order]], order[~preferred[order]]]
    keep = np.zeros(chosen.size, dtype=bool)
    keep[order] = select_identifiable(scaled[:, order], chosen[order], tolerance=tolerance)
    held_all = chosen & ~keep

    # free quantities whose estimate depends on a held one: the support of the null space, taken at
    # a generic point near the probe's point (every candidate moved by up to one scale unit, a fixed seed):
    # at that point itself special values (alpha = 0, a target on an axis) can hide a coupling that
    # is of second order there but still moves the free parameter once the held one is off its truth
    norms = np.linalg.norm(scaled, axis=0)
    live = chosen & (norms > tolerance * max(float(norms[chosen].max(initial=0.0)), 1e-300))  # as the selection
    confounded = np.zeros(chosen.size, dtype=bool)
    n_null = int(live.sum() - keep.sum())
    if n_null > 0:
        generic = probe.x0() + np.where(chosen, np.random.default_rng(0).uniform(-1.0, 1.0, chosen.size), 0.0) * scale
        # (a strided sample of the pairs: the null space of a few thousand generic rows is that of all)
        moved = triangular_factor(probe.jacobian_sample(generic, _SAMPLE_ROWS) * scale)[:, live]
        # the generic point keeps the structural dependencies but can lose those of the probe's own geometry
        # (a fitted target on axis n): its null space is at most n_null wide, as wide as its rank says, and the
        # null space at the probe point itself is taken too
        n_generic = min(
            n_null,
            int(live.sum()) - int(select_identifiable(moved, np.ones(moved.shape[1], bool), tolerance=tolerance).sum()),
        )
        support = _null_support(moved, n_generic) | _null_support(scaled[:, live], n_null)
        confounded[np.flatnonzero(live)[support]] = True
        confounded &= keep

    # gauge: held parameters whose effect is a (non-zero) rigid motion of the whole point cloud,
    # which a free base frame absorbs and pairwise distances do not see
    gauge = np.zeros((n, 5), dtype=bool)
    held = held_all[: 5 * n].reshape(n, 5)
    if np.any(held) and (n_base or probe.criterion == "distances"):
        state = probe.unpack_all(probe.x0())
        points, point_jac = probe.base_jacobian(state)
        kind_scale = all_scale[:5]
        columns = point_jac[:, :, : 5 * n].reshape(-1, 5 * n) * all_scale[: 5 * n]
        basis = _rigid_motion_fields(points, float(kind_scale[1]))
        size = np.linalg.norm(columns, axis=0)
        outside = np.linalg.norm(columns - basis @ (basis.T @ columns), axis=0)
        rigid = (size > 1e-12 * max(float(size.max()), 1e-300)) & (outside <= tolerance * size)
        gauge = held & rigid.reshape(n, 5)
    base_keep = np.zeros(6, dtype=bool)
    base_keep[probe.base_free] = keep[own + n_off :]
    base_held = probe.base_free & ~base_keep
    base_confounded = np.zeros(6, dtype=bool)
    base_confounded[probe.base_free] = confounded[own + n_off :]
    return _Selection(
        free=keep[: 5 * n].reshape(n, 5),
        extra_free=keep[5 * n : own],
        offset_free=keep[own : own + n_off],
        base_free=base_keep,
        held=held,
        extra_held=held_all[5 * n : own],
        offset_held=held_all[own : own + n_off],
        base_held=base_held,
        gauge=gauge,
        confounded=np.r_[confounded[: own + n_off], base_confounded],
    )


def refine_parameters(
    capture: Capture,
    start: ParameterSet,
    reflector: ReflectorMount | Target | Sequence[Target],
    *,
    criterion: str = "points",
    tracker_from_base=None,
    estimate_base: bool | None = None,
    free=None,
    on_unidentifiable: str = "fix",
    method: str = "auto",
    max_nfev: int | None = None,
    tolerance: float = 1e-12,
    rank_tolerance: float = 1e-7,
    weights: str = "auto",
    joint_model: JointModel | None = None,
) -> RefinementResult:
    """Refine kinematic parameters by least squares over all measured points (thesis ch. 4.5.7).

    Parameters
    ----------
    capture : Capture
        Measured points (tracker frame) [mm] with their joint readings; circle points and free
        poses (``circle = 0``, flange reflector only) alike.
    start : ParameterSet
        Start values (the CPA result, or nominal) [mm, rad]; held parameters keep these values.
    reflector : ReflectorMount, Target or sequence of Target
        Where the target sat: one mount for every point (the historical form), or the targets a
        capture's ``target`` column names (several per pose; a flange target with ``known=False``
        has its offset estimated, reported in ``targets`` and ``target_uncertainty``).
    criterion : {"points", "distances"}
        Eq. 4-101 (point positions in the tracker frame) or eq. 4-102 (all pairwise distances);
        see the module notes.
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the base frame, held unless ``estimate_base`` (then the start of its
        estimate); registered by Horn's method from the start parameters when omitted (and then
        always estimated). Ignored by distances.
    estimate_base : bool, optional
        Points criterion: estimate the base-frame corrections (those the data determine) together
        with the parameters. None (default): estimate only when ``tracker_from_base`` is not
        given. False needs ``tracker_from_base``.
    free : None, sequence of str, or ndarray of bool, shape (n_joints, 5)
        Parameters to estimate. None: every parameter the model allows and the data determine
        (see module notes).
    on_unidentifiable : {"fix", "raise"}
        With ``free=None``: hold undeterminable parameters with a warning, or raise.
    method : {"auto", "lm", "trf"}
        ``auto``: ``"lm"`` when there are at least as many residuals as unknowns, else ``"trf"``.
    max_nfev : int, optional
        Residual-evaluation limit of each fit (default ``100 * (n_unknowns + 1)``, SciPy's for ``"lm"``); a
        refit after the rank test at the solution (at most 3) has its own, and ``nfev`` counts them all.
    tolerance : float
        ``ftol = xtol = gtol`` of ``least_squares``.
    rank_tolerance : float
        See :func:`robotcal.identification.observability.select_identifiable`.
    weights : {"auto", "none"}
        ``auto``: with a ``u95_mm`` column, weight each point by ``1 / u^2`` (u = U(95) / 2, k = 2,
        normal; module notes); ``none``: equal weights.
    joint_model : JointModel, optional
        The non-geometric joint-angle errors to fit with the geometry (gravity compliance, harmonic errors:
        :mod:`robotcal.kinematics.joint_model`), starting from its values; every one of its parameters is a
        candidate of the rank test, after the geometric ones. None: the start's joint model (none for a
        geometric start: the geometric model).

    Returns
    -------
    RefinementResult
        When the capture leaves no degree of freedom for the noise (fewer residuals, or for
        distances fewer independent ones, than free unknowns + 1) the fit is still returned, with
        ``sigma = NaN``, ``covariance = correlation = None``, ``standard_uncertainty`` all NaN and a
        ``message`` that says so with the counts (see the module notes). When the solver ends at a
        higher cost than the start, the start is returned with ``success=False``.

    Raises
    ------
    InputError
        Capture inconsistent with the robot, bad options.
    IdentifiabilityError
        An explicitly freed parameter cannot be determined (``parameters`` names them), or any
        with ``on_unidentifiable="raise"``.
    """
    with single_blas_thread():
        began = time.perf_counter()
        setup = _set_up(
            capture, start, reflector, criterion=criterion, tracker_from_base=tracker_from_base,
            estimate_base=estimate_base, free=free, on_unidentifiable=on_unidentifiable, method=method,
            max_nfev=max_nfev, tolerance=tolerance, rank_tolerance=rank_tolerance, weights=weights,
            joint_model=joint_model,
        )  # fmt: skip
        selection = _select_free(setup.probe, setup.candidates, setup.all_scale, rank_tolerance)
        verdict = _describe(setup, selection)
        if setup.strict and set(verdict.gauge + verdict.held) - set(verdict.accepted):  # refused before any fit
            _report_held(setup, verdict, strict=True, where="the start")
        # (what the layout holds anyway only warns, after the fit)
        fit = _solve(setup, selection)
        if fit.verdict.gauge or fit.verdict.held or fit.unsettled:
            _report_held(
                setup,
                fit.verdict,
                strict=setup.strict,
                where="the solution" if fit.success else "the start",
                refits=fit.refits,
                unsettled=fit.unsettled,
            )
        return _statistics(setup, fit, began)


@dataclass(frozen=True, slots=True, kw_only=True)
class _Setup:
    """What a refinement fixes before its first fit: the problem with every candidate free (``probe``, the
    unknown offsets at their start), the candidates, the scales, the names and the options."""

    capture: Capture
    start: ParameterSet
    probe: _Problem
    candidates: np.ndarray  # (5 n + m,) bool: parameters, then joint-model values
    all_scale: np.ndarray  # (5 n + m + 6,): parameters, joint-model values, then base corrections
    offset_start: np.ndarray  # (k, 3)
    offset_names: tuple[str, ...]
    joint_model: JointModel | None
    use_base: bool
    explicit: bool
    strict: bool
    still: tuple[str, ...]
    weighted: bool
    n_residuals: int
    method: str
    max_nfev: int | None
    tolerance: float
    rank_tolerance: float

    @property
    def criterion(self) -> str:
        return self.probe.criterion

    @property
    def extra_names(self) -> tuple[str, ...]:
        return () if self.joint_model is None else self.joint_model.names


def _set_up(
    capture, start, reflector, *, criterion, tracker_from_base, estimate_base, free, on_unidentifiable, method,
    max_nfev, tolerance, rank_tolerance, weights, joint_model,
) -> _Setup:  # fmt: skip
    """Check the options and the capture, resolve the targets, weights, base frame and pairs, and build the
    problem on which the free set is chosen."""
    robot = start.robot
    n = robot.n_joints
    if criterion not in CRITERIA:
        raise InputError(f"`criterion` must be one of {CRITERIA}; got {criterion!r}")
    if method not in ("auto", "lm", "trf"):
        raise InputError(f"`method` must be 'auto', 'lm' or 'trf'; got {method!r}")
    if on_unidentifiable not in ("fix", "raise"):
        raise InputError(f"`on_unidentifiable` must be 'fix' or 'raise'; got {on_unidentifiable!r}")
    if estimate_base not in (None, True, False):
        raise InputError(f"`estimate_base` must be None, True or False; got {estimate_base!r}")
    if criterion == "points" and estimate_base is False and tracker_from_base is None:
        raise InputError("`estimate_base=False` holds the base frame: give `tracker_from_base`")
    if weights not in ("auto", "none"):
        raise InputError(f"`weights` must be 'auto' or 'none'; got {weights!r}")
    if capture.n_joints != n:
        raise InputError(
            f"{capture.source}: {capture.n_joints} joint readings per point; robot {robot.name!r} has {n} joints"
        )
    minimum = 3 if criterion == "points" else 4
    if capture.n_points < minimum:
        raise InputError(f"{capture.source}: {capture.n_points} points; refinement needs at least {minimum}")
    q = robot.model_joint_variables(capture.readings)
    measured = np.asarray(capture.points, dtype=float)
    targets: tuple[Target, ...] = ()
    target_index = None
    unknown: tuple[int, ...] = ()
    if isinstance(reflector, ReflectorMount):
        turning = capture_turning_joints(capture, reflector)
        pair_key = capture_target_index(capture, reflector)
    else:
        given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
        targets, target_index = resolve_targets(capture, given)
        turning = np.maximum(capture.circle - 1, 0)
        for t, target in enumerate(targets):
            if target.frame == "joint":
                if target.positions.shape[0] != n:
                    raise InputError(f"target {target.name!r}: {target.positions.shape[0]} reflectors for {n} joints")
                rows = np.flatnonzero((target_index == t) & (capture.circle == 0))
                if rows.size:
                    raise InputError(
                        f"{capture.source}: point {rows[0] + 1} is a free pose (circle = 0) on the per-joint target "
                        f"{target.name!r}, which is defined only on circles"
                    )
        unknown = tuple(t for t, target in enumerate(targets) if not target.known)
        is_joint = np.array([target.frame == "joint" for target in targets])
        pair_key = target_index * (n + 1) + np.where(is_joint[target_index], turning + 1, 0)
        reflector = targets[0].mount  # (unused with targets; kept for the single-target code paths)
    offset_start = np.array([targets[t].positions for t in unknown], dtype=float).reshape(-1, 3)
    offset_names = tuple(f"target.{targets[t].name}.{axis}" for t in unknown for axis in "xyz")
    sigmas = point_sigmas(capture) if weights == "auto" else None
    point_weight = pair_weight = None
    if sigmas is not None:
        reference = float(np.sqrt(np.mean(sigmas**2)))
        point_weight = reference / sigmas  # relative weights: sigma keeps its meaning [mm] (module notes)
    use_base = criterion == "points" and (tracker_from_base is None if estimate_base is None else estimate_base)
    explicit_mask = _check_free(free, robot)
    joint_model = start.joint_model if joint_model is None else joint_model
    if joint_model is not None and joint_model.nominal.shape != (n, 5):
        raise InputError(f"the joint model was built for another robot than {robot.name!r}")
    commanded = q
    if joint_model is not None and joint_model.has_backlash:  # the circles' lash, a fixed correction
        q = q + lash_turns(joint_model.backlash, q, capture.circle)
    columns = None if joint_model is None or joint_model.is_empty else joint_model.columns(commanded)
    extra_start = np.zeros(0) if columns is None else np.asarray(joint_model.values, dtype=float)

    base_start = None
    if criterion == "points":
        if tracker_from_base is None:
            start_q = q if columns is None else q + columns @ extra_start
            nominal_points = target_positions(start.values, start_q, turning, reflector)
            base_start = register_points(nominal_points, measured).transform
        else:
            base_start = check_rigid_transform(tracker_from_base, "tracker_from_base")
    pair_i = pair_j = distances = pair_keep = None
    if criterion == "distances":
        pair_i, pair_j, pair_keep = measurement_pairs(commanded, pair_key)
        distances = pdist(measured)[pair_keep]
        if sigmas is not None:
            pair_weight = np.sqrt(2.0) * reference / np.hypot(sigmas[pair_i], sigmas[pair_j])
        if np.any(distances <= 0.0):
            k = int(np.flatnonzero(distances <= 0.0)[0])
            raise InputError(
                f"{capture.source}: points {pair_i[k] + 1} and {pair_j[k] + 1} coincide at different poses or targets; "
                "the distances criterion needs distinct points"
            )

    spread = commanded.max(axis=0) - commanded.min(axis=0)
    size = float(np.sqrt(np.mean(np.sum((measured - measured.mean(axis=0)) ** 2, axis=1))))
    angle_scale = 1.0 / max(size, 1.0)
    kind_scale = np.array([1.0 if kind in LENGTH_KINDS else angle_scale for kind in PARAMETER_KINDS])
    # a joint-model value's unit step turns the joints by C(q) rad: about 1 mm at the cloud's radius once scaled
    extra_scale = np.zeros(0)
    if columns is not None:
        turn = np.sqrt(np.mean(np.sum(columns**2, axis=1), axis=0))  # RMS joint turn per unit value [rad]
        extra_scale = angle_scale / np.where(turn > 0.0, turn, 1.0)
    probe = _Problem(
        start=start.values.copy(),
        free=np.ones((n, 5), dtype=bool),
        base_start=base_start,
        base_free=np.full(6, use_base),
        q=q,
        turning=turning,
        reflector=reflector,
        measured=measured,
        criterion=criterion,
        pair_i=pair_i,
        pair_j=pair_j,
        pair_keep=pair_keep,
        measured_distances=distances,
        targets=targets,
        target_index=target_index,
        unknown=unknown,
        offset_start=offset_start + _GENERIC_OFFSET_MM * _generic_directions(offset_start.shape[0]),
        offset_free=np.ones(offset_start.size, dtype=bool),
        point_weight=point_weight,
        pair_weight=pair_weight,
        joint_columns=columns,
        extra_start=extra_start,
        extra_free=np.ones(extra_start.size, dtype=bool),
    )
    parameters = ~robot.structurally_fixed if explicit_mask is None else explicit_mask
    return _Setup(
        capture=capture,
        start=start,
        probe=probe,
        candidates=np.r_[parameters.ravel(), np.ones(extra_start.size, dtype=bool)],
        all_scale=np.concatenate(
            [np.tile(kind_scale, n), extra_scale, [1.0, 1.0, 1.0, angle_scale, angle_scale, angle_scale]]
        ),
        offset_start=offset_start,
        offset_names=offset_names,
        joint_model=joint_model,
        use_base=use_base,
        explicit=explicit_mask is not None,
        strict=explicit_mask is not None or on_unidentifiable == "raise",
        still=tuple(f"J{k + 1}" for k in np.flatnonzero(spread <= _STILL_RAD)),
        weighted=sigmas is not None,
        n_residuals=capture.n_points * 3 if criterion == "points" else int(pair_i.size),
        method=method,
        max_nfev=max_nfev,
        tolerance=tolerance,
        rank_tolerance=rank_tolerance,
    )


@dataclass(frozen=True, slots=True)
class _Verdict:
    """The gauge, held and confounded quantities of a selection (names), and those the layout holds anyway
    (``accepted``: ``strict`` only reports them)."""

    gauge: tuple[str, ...]
    held: tuple[str, ...]
    confounded: tuple[str, ...]
    flange_frame: str
    accepted: tuple[str, ...]


def _describe(setup: _Setup, chosen: _Selection) -> _Verdict:
    robot = setup.start.robot
    names, n = robot.parameter_names, robot.n_joints
    gauge = tuple(name for name, flag in zip(names, chosen.gauge.ravel(), strict=True) if flag)
    held_mask = chosen.held & ~chosen.gauge
    held = (
        tuple(name for name, flag in zip(names, held_mask.ravel(), strict=True) if flag)
        + tuple(name for name, flag in zip(setup.extra_names, chosen.extra_held, strict=True) if flag)
        + tuple(name for name, flag in zip(setup.offset_names, chosen.offset_held, strict=True) if flag)
        + tuple(BASE_NAMES[k] for k in np.flatnonzero(chosen.base_held))
    )
    every = names + setup.extra_names + setup.offset_names + BASE_NAMES
    confounded = tuple(name for name, flag in zip(every, chosen.confounded, strict=True) if flag)
    flange_frame = _flange_frame_note(setup.probe.targets, setup.probe.unknown, held_mask, n)
    # what any capture of the layout holds: a gauge (a free base frame or distances cannot see a rigid motion),
    # and joint n's parameters, never all determined (behind its own reflector, none of d, theta, a, alpha; behind
    # flange targets, alpha_n, or all four when every offset is unknown): --strict reports them, refusing only
    # what this capture fails to determine (an explicit free set is refused whatever it holds)
    accepted = () if setup.explicit else gauge + tuple(f"J{n}.{kind}" for kind in PARAMETER_KINDS)
    return _Verdict(gauge, held, confounded, flange_frame, accepted)


@dataclass(frozen=True, slots=True, kw_only=True)
class _Fit:
    """The fit a refinement returns: its problem and solution, the Jacobian there (which the statistics use),
    the solver's record over every round, and the free-set decision."""

    problem: _Problem
    x: np.ndarray
    success: bool
    status: int
    message: str
    method: str
    evaluated: tuple[np.ndarray, np.ndarray]
    selection: _Selection
    verdict: _Verdict
    x_scale: np.ndarray
    nfev: int
    njev: int
    start_cost: float
    history: np.ndarray
    refits: int
    unsettled: str


def _solve(setup: _Setup, selection: _Selection) -> _Fit:
    """Fit, then decide the free set again at the solution; refit from the solution while it changes (module
    notes). A refit that fails or ends worse than the fit it started from leaves that fit standing."""
    start, capture = setup.start, setup.capture
    n = start.robot.n_joints
    probe = replace(setup.probe, offset_start=setup.offset_start)
    verdict = _describe(setup, selection)
    start_state = _State(start.values.copy(), probe.extra_start.copy(), setup.offset_start, np.zeros(6))
    fit_state = start_state
    seen = [_selection_key(selection)]
    nfev = njev = 0
    history: list[float] = []
    start_cost = None
    unsettled = ""
    kept = None  # the last fit accepted: what a failed refit falls back to
    for fit_round in range(_MAX_REFITS + 1):
        problem = replace(
            probe,
            start=fit_state.values,
            extra_start=fit_state.extras,
            offset_start=fit_state.offsets,
            base_offset=fit_state.x_base,
            free=selection.free,
            extra_free=selection.extra_free,
            base_free=selection.base_free,
            offset_free=selection.offset_free,
        )
        x0 = problem.x0()
        if x0.size == 0:
            raise IdentifiabilityError(
                f"{capture.source}: no parameter can be refined from this capture",
                parameters=verdict.gauge + verdict.held,
            )
        own = 5 * n + selection.extra_free.size
        x_scale = np.concatenate(
            [
                setup.all_scale[: 5 * n][selection.free.ravel()],
                setup.all_scale[5 * n : own][selection.extra_free],
                np.ones(int(selection.offset_free.sum())),
                setup.all_scale[own:][selection.base_free],
            ]
        )

        def jacobian(x, problem=problem):
            residuals, jac = problem.evaluate(x)
            history.append(0.5 * float(residuals @ residuals))
            return jac

        method = ("lm" if setup.n_residuals >= x0.size else "trf") if setup.method == "auto" else setup.method
        if start_cost is None:
            start_residuals = problem.residuals(x0)
            start_cost = 0.5 * float(start_residuals @ start_residuals)
        evaluations = len(history)
        solution = least_squares(
            problem.residuals,
            x0,
            jac=jacobian,
            method=method,
            x_scale=x_scale,
            ftol=setup.tolerance,
            xtol=setup.tolerance,
            gtol=setup.tolerance,
            max_nfev=setup.max_nfev,
        )
        nfev += int(solution.nfev)
        njev += int(solution.njev) if solution.njev is not None else len(history) - evaluations
        final_cost = float(solution.cost)
        status = int(solution.status)
        if kept is not None and (
            status <= 0 or not np.isfinite(final_cost) or final_cost > kept.cost * (1 + 1e-6) + 1e-12
        ):
            outcome = "did not converge" if status <= 0 else "ended at a higher cost"
            unsettled = (
                f"the refit with the free set decided at the solution of fit {fit_round} {outcome} "
                f"({final_cost:.6g} mm^2 against {kept.cost:.6g} mm^2); fit {fit_round} is returned"
            )
            history.append(kept.cost)
            return _finish(kept.fit, nfev, njev, start_cost, history, len(seen) - 1, unsettled, method)
        x_final = np.asarray(solution.x, dtype=float)
        success = status > 0
        message = str(solution.message)
        if not np.isfinite(final_cost) or final_cost > start_cost:
            # never hand back something worse than what came in (module notes); the start in this round's
            # unknowns: held quantities are at their start values in every round
            message = (
                f"the solver ended at a higher cost ({final_cost:.6g} mm^2) than the start ({start_cost:.6g} mm^2); "
                f"the start is returned. Solver: {message}"
            )
            x_final, success = problem.pack(start_state), False
            start_residuals = problem.residuals(x_final)
            final_cost = 0.5 * float(start_residuals @ start_residuals)
        if not history or abs(history[-1] - final_cost) > 1e-15 * max(final_cost, 1e-300):
            history.append(final_cost)
        solved = problem.unpack_all(x_final)
        # the rank test again, at the solution (the offsets as estimated): its Jacobian serves the statistics too
        at_solution = replace(
            probe,
            start=solved.values,
            extra_start=solved.extras,
            offset_start=solved.offsets,
            base_offset=solved.x_base,
        )
        evaluated = at_solution.evaluate(at_solution.x0())
        fit = _Fit(
            problem=problem, x=x_final, success=success, status=status, message=message, method=method,
            evaluated=evaluated, selection=selection, verdict=verdict, x_scale=x_scale, nfev=0, njev=0,
            start_cost=0.0, history=np.zeros(0), refits=0, unsettled="",
        )  # fmt: skip
        if not success:  # the first fit did not converge (or the start came back): the decision at the start stands
            break
        kept = _Kept(fit=fit, cost=final_cost)
        decided = _select_free(
            at_solution,
            setup.candidates,
            setup.all_scale,
            setup.rank_tolerance,
            evaluated[1],
            preferred=selection,
        )
        key = _selection_key(decided)
        if key == seen[-1]:  # confirmed: report what the solution's test says (gauge, held, confounded)
            fit = replace(fit, verdict=_describe(setup, decided))
            break
        if setup.strict:  # an explicit free set (or "raise") is not re-chosen: held at the solution is an error
            now = _describe(setup, decided)
            if set(now.gauge + now.held) - set(now.accepted):
                _report_held(setup, now, strict=True)
        if key in seen or fit_round == _MAX_REFITS:
            unsettled = (
                f"the free set did not settle: the rank test at the solution of fit {fit_round + 1} "
                f"{'returns to an earlier free set' if key in seen else 'changes it again'}; the last fit is returned"
            )
            break
        seen.append(key)
        selection = decided
        verdict = _describe(setup, selection)
        # refit from the solution: what stays free keeps its value, what is now held goes back to its start value
        fit_state = _State(
            np.where(selection.free, solved.values, start_state.values),
            np.where(selection.extra_free, solved.extras, start_state.extras),
            np.where(selection.offset_free, solved.offsets.ravel(), setup.offset_start.ravel()).reshape(-1, 3),
            np.where(selection.base_free, solved.x_base, 0.0),
        )
    return _finish(fit, nfev, njev, start_cost, history, len(seen) - 1, unsettled, method)


@dataclass(frozen=True, slots=True)
class _Kept:
    fit: _Fit
    cost: float


def _finish(fit: _Fit, nfev, njev, start_cost, history, refits, unsettled, method) -> _Fit:
    """The fit with the record of every round."""
    message = f"{unsettled}. Solver: {fit.message}" if unsettled else fit.message
    return replace(
        fit,
        nfev=nfev,
        njev=njev,
        start_cost=start_cost,
        history=np.asarray(history),
        refits=refits,
        unsettled=unsettled,
        message=message,
        method=method,
    )


def _statistics(setup: _Setup, fit: _Fit, began: float) -> RefinementResult:
    """The result: values at the solution, residual statistics (per point, unweighted, mm), conditioning and the
    linearised covariance from the Jacobian of the rank test at the solution."""
    start, criterion, problem = setup.start, setup.criterion, fit.problem
    robot = start.robot
    names, n = robot.parameter_names, robot.n_joints
    free_mask, offset_free = fit.selection.free, fit.selection.offset_free
    extra_free, base_free = fit.selection.extra_free, fit.selection.base_free
    values, extras, offsets, x_base = problem.unpack_all(fit.x)
    free_names = (
        tuple(name for name, flag in zip(names, free_mask.ravel(), strict=True) if flag)
        + tuple(name for name, flag in zip(setup.extra_names, extra_free, strict=True) if flag)
        + tuple(name for name, flag in zip(setup.offset_names, offset_free, strict=True) if flag)
        + tuple(BASE_NAMES[k] for k in np.flatnonzero(base_free))
    )
    residuals, jac_all = fit.evaluated
    jac = jac_all[:, np.r_[free_mask.ravel(), extra_free, offset_free, base_free[: 6 if setup.use_base else 0]]]
    raw = problem.raw_residuals(fit.x)
    per = np.linalg.norm(raw.reshape(-1, 3), axis=1) if criterion == "points" else np.abs(raw)
    # RMS displacement of a point (points) or change of a distance (distances) per unit of each free quantity
    effect = np.linalg.norm(jac, axis=0) / np.sqrt(jac.shape[0] / 3.0 if criterion == "points" else jac.shape[0])
    cond = conditioning(jac * fit.x_scale)
    covariance, sigma, dof = _covariance(jac, fit.x_scale, residuals, problem.noise_map(fit.x))
    standard = np.full((n, 5), np.nan)
    extra_sd = np.full(extra_free.size, np.nan)
    offset_sd = np.full(setup.offset_start.shape, np.nan)
    message = fit.message
    if covariance is None:
        message = (
            f"no degrees of freedom left to estimate the noise ({setup.n_residuals} residuals, {fit.x.size} free "
            f"unknowns, {dof:.3g} effective degrees of freedom): sigma is NaN and there is no covariance; "
            f"measure more points. Solver: {message}"
        )
    else:
        diagonal = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
        bounds = np.cumsum([problem.n_kinematic, problem.n_extra, problem.n_offsets])
        standard[free_mask] = diagonal[: bounds[0]]
        extra_sd[extra_free] = diagonal[bounds[0] : bounds[1]]
        flat = offset_sd.ravel()
        flat[offset_free] = diagonal[bounds[1] : bounds[2]]
        offset_sd = flat.reshape(setup.offset_start.shape)
    targets, unknown = problem.targets, problem.unknown
    refined_targets = list(targets)
    target_sd = np.full((len(targets), 3), np.nan)
    for slot, t in enumerate(unknown):
        refined_targets[t] = targets[t].with_position(offsets[slot])
        target_sd[t] = offset_sd[slot]
    cost_history = fit.history
    joint_model = None
    if setup.joint_model is not None:
        joint_model = setup.joint_model.with_values(extras, identified=setup.joint_model.identified | extra_free)
    return RefinementResult(
        parameters=ParameterSet(
            robot=robot, values=values, identified=start.identified | free_mask, joint_model=joint_model
        ),
        tracker_from_base=None if problem.base_start is None else _frozen(problem.tracker(x_base)),
        criterion=criterion,
        method=fit.method,
        success=fit.success,
        status=fit.status,
        message=message,
        nfev=fit.nfev,
        njev=fit.njev,
        free=_frozen(free_mask, bool),
        base_free=_frozen(base_free, bool),
        gauge=fit.verdict.gauge,
        held=fit.verdict.held,
        confounded=fit.verdict.confounded,
        still_joints=setup.still,
        free_names=free_names,
        x_scale=_frozen(fit.x_scale),
        start_cost=fit.start_cost,
        cost_history=_frozen(cost_history),
        rms_history=_frozen(np.sqrt(2.0 * cost_history / setup.n_residuals)),
        n_residuals=setup.n_residuals,
        residual_rms=float(np.sqrt(np.mean(per**2))),
        residual_mean=float(per.mean()),
        residual_max=float(per.max()),
        singular_values=cond.singular_values,
        condition_number=cond.condition_number,
        sigma=sigma,
        covariance=None if covariance is None else _frozen(covariance),
        correlation=None if covariance is None else _frozen(correlation_from_covariance(covariance)),
        standard_uncertainty=_frozen(standard),
        wall_time_s=time.perf_counter() - began,
        targets=tuple(refined_targets),
        target_uncertainty=_frozen(target_sd) if targets else None,
        weighted=setup.weighted,
        residual_rms_coordinate=float(np.sqrt(np.mean(raw**2))),
        refits=fit.refits,
        joint_model_uncertainty=None if joint_model is None else _frozen(extra_sd),
        effect=_frozen(effect),
        model="geometric"
        if joint_model is None or joint_model.is_empty
        else "+".join(g for g in JOINT_MODEL_GROUPS if g in joint_model.groups),
    )


def _flange_frame_note(targets, unknown, held_mask, n) -> str:
    """Why joint n's parameters are held when every flange target's offset is unknown (empty otherwise:
    with a known flange target, joint n's alpha is held as with the historical single flange target)."""
    known = [t.name for t in targets if t.frame == "flange" and t.known]
    if not unknown or known or not held_mask[n - 1].any():
        return ""
    names = ", ".join(f"J{n}.{kind}" for kind, flag in zip(PARAMETER_KINDS, held_mask[n - 1], strict=True) if flag)
    unknown_names = ", ".join(targets[t].name for t in unknown)
    return (
        f"every flange target's offset is unknown, so the flange frame {{{n}}} is not determined by the data: an "
        f"unknown offset is confounded with J{n}'s d, theta, a, alpha (a change of those moves the flange frame, "
        f"which the offsets absorb); {names} are held at their start values and the offsets of {unknown_names} "
        "are estimated in that flange frame"
    )


def _report_held(
    setup: _Setup,
    verdict: _Verdict,
    *,
    strict: bool,
    where: str = "the solution",
    refits: int = 0,
    unsettled: str = "",
) -> None:
    """Warn about (or, ``strict``, raise for) the quantities the rank test holds.

    ``verdict.accepted``: what the layout holds whatever the capture (a gauge; joint n's parameters): with
    ``strict`` they alone only warn. ``where``: the point
    of the deciding rank test ("the start", "the solution"); ``refits``: how many times the free set changed
    at a solution and the capture was refitted; ``unsettled``: why the free set did not settle, if so.
    """
    gauge, held, still = verdict.gauge, verdict.held, setup.still
    parts = []
    if gauge:
        why = (
            "a free base frame absorbs them (tracker_from_base is estimated)"
            if setup.use_base
            else "pairwise distances do not see them"
        )
        parts.append(f"{', '.join(gauge)} move the whole point cloud rigidly, a rigid motion of the base: {why}")
    if held:
        detail = f"; joints that never move in the capture: {', '.join(still)}" if still else ""
        parts.append(
            f"the {setup.criterion} criterion cannot determine {', '.join(held)} from this capture "
            f"(rank-deficient column-scaled Jacobian at {where}){detail}"
        )
    if refits:
        parts.append(
            f"the rank test at the solution changed the free set, so the capture was refitted ({refits} refit"
            f"{'s' if refits > 1 else ''}) with the quantities it holds back at their start values"
        )
    if verdict.flange_frame:
        parts.append(verdict.flange_frame)
    if unsettled:
        parts.append(unsettled)
    text = f"{setup.capture.source}: " + "; ".join(parts)
    if strict and set(gauge + held) - set(verdict.accepted):
        raise IdentifiabilityError(text, parameters=gauge + held)
    warnings.warn(text + _held_clause(setup, verdict), IdentifiabilityWarning, stacklevel=3)


def _held_clause(setup: _Setup, verdict: _Verdict) -> str:
    """The warning's last clause: what is held at its start value, in the number its names need, and not again
    what the flange-frame note already says it holds (joint n's parameters)."""
    n = setup.start.robot.n_joints
    said = {name for name in verdict.held if name.startswith(f"J{n}.")} if verdict.flange_frame else set()
    rest = [name for name in verdict.gauge + verdict.held if name not in said]
    if not rest:
        return ""
    if said:  # the note named joint n's: name the others, so that "they" means no more than these
        return f"; {', '.join(rest)} {'is' if len(rest) == 1 else 'are'} held at {'its start value' if len(rest) == 1 else 'their start values'}"
    return "; it is held at its start value" if len(rest) == 1 else "; they are held at their start values"


def _covariance(jac, x_scale, residuals, noise_map) -> tuple[np.ndarray | None, float, float]:
    """Linearised covariance (module notes) in unscaled units, sigma per coordinate [mm], and the
    degrees of freedom of the noise estimate; ``(None, nan, dof)`` when ``dof <= 0``."""
    m, p = jac.shape
    scaled = jac * x_scale
    _, s, vt = np.linalg.svd(triangular_factor(scaled), full_matrices=False)
    good = s > s[0] * 1e-12 if s.size else s.astype(bool)
    inverse = (vt[good].T / s[good] ** 2) @ vt[good]  # (Js^T Js)^+
    ssr = float(residuals @ residuals)
    if noise_map is None:
        dof = float(m - int(good.sum()))
        middle = None
    else:
        projected = np.asarray(noise_map.T @ scaled).T  # Js^T G, (p, 3 n_points)
        middle = projected @ projected.T
        trace_ggt = float(noise_map.multiply(noise_map).sum())
        dof = trace_ggt - float(np.trace(inverse @ middle))
    # relative floor: rounding leaves tr(GG^T) - tr(HGG^T) ~1e-12 tr(GG^T) when it is 0 in exact arithmetic
    if dof <= 1e-9 * max(m, 1):
        return None, float("nan"), dof
    sigma2 = ssr / dof
    covariance = sigma2 * inverse if middle is None else sigma2 * inverse @ middle @ inverse
    covariance = covariance * np.outer(x_scale, x_scale)
    return covariance, float(np.sqrt(sigma2)), dof
