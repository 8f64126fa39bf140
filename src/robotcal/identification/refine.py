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
still runs and returns its parameters, but sigma cannot be estimated: the result's ``uncertainty``
then has ``sigma = NaN``, ``covariance = correlation = None``, ``standard_uncertainty`` all NaN, and
``message`` says so (the solver's message follows). Writers must map those NaNs to null.

Where it lives
--------------
:mod:`~robotcal.identification._problem` (the least-squares problem: unknowns, residuals, Jacobian),
:mod:`~robotcal.identification._free_set` (the rank test and the names of what it holds),
:mod:`~robotcal.identification.records` (:class:`RefinementResult` and its sub-records ``fit``,
``identifiability``, ``uncertainty``), :mod:`~robotcal.identification.settings`
(:class:`RefinementSettings`), and this module, the driver: set up, fit, decide again, statistics.

References
----------
Thesis ch. 4.5.7, eqs 4-101 and 4-102, Tables 4.8-4.11, Figs 4.24-4.25.
"""


from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityError, InputError
from robotcal.execution import single_blas_thread
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import check_rigid_transform
from robotcal.identification._frames import (
    PROBE_NAMES,
    capture_sessions,
    probe_frame,
    session_frames,
    session_starts,
    with_probe,
)
from robotcal.identification._free_set import (
    HeldNames,
    Selection,
    check_free,
    describe_held,
    report_held,
    select_free,
    selection_key,
)
from robotcal.identification._problem import (
    BASE_AXES,
    BASE_NAMES,
    Problem,
    Setup,
    State,
    base_correction,
    capture_target_index,
    capture_turning_joints,
    least_squares,
    measurement_pairs,
    pdist,
    point_sigmas,
    wrap_angles,
)
from robotcal.identification.health import refine_health
from robotcal.identification.observability import conditioning, correlation_from_covariance, triangular_factor
from robotcal.identification.records import (
    FitStatistics,
    Identifiability,
    RefinementResult,
    RefinementUncertainty,
)
from robotcal.identification.settings import CRITERIA, RefinementSettings
from robotcal.identification.targets import Target, resolve_targets, split_by_session
from robotcal.kinematics.forward import target_positions
from robotcal.kinematics.joint_model import JOINT_MODEL_GROUPS, JointModel, lash_turns
from robotcal.kinematics.model import LENGTH_KINDS, PARAMETER_KINDS, ParameterSet, ReflectorMount

__all__ = [
    "CRITERIA",
    "BASE_NAMES",
    "PROBE_NAMES",
    "RefinementSettings",
    "RefinementResult",
    "refine_parameters",
    "capture_turning_joints",
    "capture_target_index",
    "measurement_pairs",
    "base_correction",
    "wrap_angles",
    "point_sigmas",
]

_STILL_RAD = 1e-9
#: The rank test sees unknown flange offsets at their guess moved by this much in a fixed generic direction
#: [mm]: a guess on axis n (the default, the flange origin) would hide joint n's rotation from the test,
#: while the data, taken off the axis, do show it.
_GENERIC_OFFSET_MM = 50.0
#: Refits when the rank test at a solution changes the free set (module notes); a free set seen before also stops.
_MAX_REFITS = 3
_DEFAULT_SETTINGS = RefinementSettings()


def _generic_directions(count: int, rows: int) -> np.ndarray:
    """``(rows, 3)``: fixed unit vectors in generic directions (seeded), one per unknown offset (the first
    ``count`` rows), then zeros (the session frames' rows)."""
    directions = np.random.default_rng(12345).normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.concatenate([directions, np.zeros((rows - count, 3))])


def refine_parameters(
    capture: Capture,
    start: ParameterSet,
    reflector: ReflectorMount | Target | Sequence[Target],
    *,
    settings: RefinementSettings = _DEFAULT_SETTINGS,
    tracker_from_base=None,
    joint_model: JointModel | None = None,
    instrument=None,
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
        has its offset estimated, reported in ``targets`` and ``uncertainty.target_uncertainty``).
    settings : RefinementSettings
        The criterion (eq. 4-101 or 4-102, module notes), the base-frame mode, the free set, the solver's
        options and the weights.
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the base frame, held unless ``settings.estimate_base`` (then the start of its
        estimate); registered by Horn's method from the start parameters when omitted (and then
        always estimated). Ignored by distances.
    joint_model : JointModel, optional
        The non-geometric joint-angle errors to fit with the geometry (gravity compliance, harmonic errors:
        :mod:`robotcal.kinematics.joint_model`), starting from its values; every one of its parameters is a
        candidate of the rank test, after the geometric ones. None: the start's joint model (none for a
        geometric start: the geometric model).
    instrument : Instrument, optional
        The stated noise of the fit health (the points' U(95) when the capture has them;
        :func:`robotcal.identification.health.refine_health`).

    Returns
    -------
    RefinementResult
        With its ``health``. When the capture leaves no degree of freedom for the noise (fewer residuals, or for
        distances fewer independent ones, than free unknowns + 1) the fit is still returned, with
        ``uncertainty.sigma = NaN``, no covariance, ``standard_uncertainty`` all NaN and a ``message`` that says
        so with the counts (see the module notes). When the solver ends at a higher cost than the start, the
        start is returned with ``success=False``.

    Raises
    ------
    InputError
        Capture inconsistent with the robot, bad inputs.
    IdentifiabilityError
        An explicitly freed parameter cannot be determined (``parameters`` names them), or any
        with ``settings.on_unidentifiable="raise"``.
    """
    if not isinstance(settings, RefinementSettings):
        raise InputError(f"`settings` must be RefinementSettings; got {type(settings).__name__}")
    with single_blas_thread():
        began = time.perf_counter()
        setup = _set_up(capture, start, reflector, settings, tracker_from_base, joint_model, instrument)
        selection = select_free(setup.probe, setup.candidates, setup.all_scale, settings.rank_tolerance)
        verdict = describe_held(setup, selection)
        if setup.strict and set(verdict.gauge + verdict.held) - set(verdict.accepted):  # refused before any fit
            report_held(setup, verdict, strict=True, where="the start")
        # (what the layout holds anyway only warns, after the fit)
        fit = _solve(setup, selection)
        if fit.verdict.gauge or fit.verdict.held or fit.unsettled:
            report_held(
                setup,
                fit.verdict,
                strict=setup.strict,
                where="the solution" if fit.success else "the start",
                refits=fit.refits,
                unsettled=fit.unsettled,
            )
        return _statistics(setup, fit, began, instrument)


def _check_capture(capture: Capture, robot, settings: RefinementSettings, tracker_from_base) -> None:
    """The inputs the settings cannot check alone."""
    n = robot.n_joints
    if settings.criterion == "points" and settings.estimate_base is False and tracker_from_base is None:
        raise InputError("`estimate_base=False` holds the base frame: give `tracker_from_base`")
    if capture.n_joints != n:
        raise InputError(
            f"{capture.source}: {capture.n_joints} joint readings per point; robot {robot.name!r} has {n} joints"
        )
    minimum = 3 if settings.criterion == "points" else 4
    if capture.n_points < minimum:
        raise InputError(f"{capture.source}: {capture.n_points} points; refinement needs at least {minimum}")


@dataclass(frozen=True, slots=True)
class _Layout:
    """Where the points were measured: the targets (empty for one mount), the target of each point, the unknown
    offsets, the turning joint of each point, the key that tells measurements apart, and the single mount."""

    targets: tuple[Target, ...]
    target_index: np.ndarray | None
    unknown: tuple[int, ...]
    turning: np.ndarray
    pair_key: np.ndarray | None
    reflector: ReflectorMount


def _layout(capture: Capture, reflector, n: int) -> _Layout:
    """The targets of the capture's points, checked against the capture."""
    if isinstance(reflector, ReflectorMount):
        turning = capture_turning_joints(capture, reflector)
        return _Layout((), None, (), turning, capture_target_index(capture, reflector), reflector)
    given = (reflector,) if isinstance(reflector, Target) else tuple(reflector)
    targets, target_index = resolve_targets(*split_by_session(capture, given))
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
    # the first mount: unused with targets, kept for the single-target code paths
    return _Layout(targets, target_index, unknown, turning, pair_key, targets[0].mount)


def _pairs(capture: Capture, commanded, pair_key, measured, sigmas, reference, sessions):
    """The distances criterion's kept pairs, measured distances and pair weights; with ``sessions`` (the session
    of each point) only pairs within a session: a distance between two tracker stations is no measurement."""
    pair_i, pair_j, pair_keep = measurement_pairs(commanded, pair_key)
    if sessions is not None:
        within = sessions[pair_i] == sessions[pair_j]
        pair_keep[np.flatnonzero(pair_keep)[~within]] = False
        pair_i, pair_j = pair_i[within], pair_j[within]
    distances = pdist(measured)[pair_keep]
    pair_weight = None
    if sigmas is not None:
        pair_weight = np.sqrt(2.0) * reference / np.hypot(sigmas[pair_i], sigmas[pair_j])
    if np.any(distances <= 0.0):
        k = int(np.flatnonzero(distances <= 0.0)[0])
        raise InputError(
            f"{capture.source}: points {pair_i[k] + 1} and {pair_j[k] + 1} coincide at different poses or targets; "
            "the distances criterion needs distinct points"
        )
    return pair_i, pair_j, pair_keep, distances, pair_weight


def _radius(measured) -> float:
    """L: the RMS radius of the measured point cloud about its centroid [mm]."""
    return float(np.sqrt(np.mean(np.sum((measured - measured.mean(axis=0)) ** 2, axis=1))))


def _scales(measured, columns, n: int) -> np.ndarray:
    """The column scale ``(5 n + m + 6,)`` of the parameters, the joint-model values and the base corrections: 1 mm
    for lengths and translations, ``1/L`` rad for angles (module notes)."""
    angle_scale = 1.0 / max(_radius(measured), 1.0)
    kind_scale = np.array([1.0 if kind in LENGTH_KINDS else angle_scale for kind in PARAMETER_KINDS])
    # a joint-model value's unit step turns the joints by C(q) rad: about 1 mm at the cloud's radius once scaled
    extra_scale = np.zeros(0)
    if columns is not None:
        turn = np.sqrt(np.mean(np.sum(columns**2, axis=1), axis=0))  # RMS joint turn per unit value [rad]
        extra_scale = angle_scale / np.where(turn > 0.0, turn, 1.0)
    return np.concatenate([np.tile(kind_scale, n), extra_scale, [1.0, 1.0, 1.0] + [angle_scale] * 3])


def _set_up(
    capture, start, reflector, settings: RefinementSettings, tracker_from_base, joint_model, instrument=None
) -> Setup:
    """Check the inputs, resolve the targets, weights, base frame and pairs, and build the problem on which the
    free set is chosen."""
    robot = start.robot
    n = robot.n_joints
    criterion = settings.criterion
    _check_capture(capture, robot, settings, tracker_from_base)
    q = robot.model_joint_variables(capture.readings)
    measured = np.asarray(capture.points, dtype=float)
    layout = _layout(capture, reflector, n)
    targets, unknown = layout.targets, layout.unknown
    session_names, session_index = capture_sessions(capture)
    n_moved = max(len(session_names) - 1, 0) if criterion == "points" else 0  # sessions 2..S: their frames in the offsets
    oriented = criterion == "points" and capture.orientation is not None  # a 6-DoF probe: its rotation, last
    offset_start = np.concatenate(
        [np.array([targets[t].positions for t in unknown], dtype=float).reshape(-1, 3), np.zeros((2 * n_moved, 3))]
        + ([np.zeros((1, 3))] if oriented else [])
    )
    sigmas = point_sigmas(capture, settings.repeatability_mm) if settings.weights == "auto" else None
    point_weight = reference = None
    if sigmas is not None:
        reference = float(np.sqrt(np.mean(sigmas**2)))
        point_weight = reference / sigmas  # relative weights: sigma keeps its meaning [mm] (module notes)
    estimate_base = settings.estimate_base
    use_base = criterion == "points" and (tracker_from_base is None if estimate_base is None else estimate_base)
    explicit_mask = check_free(settings.free, robot)
    joint_model = start.joint_model if joint_model is None else joint_model
    if joint_model is not None and joint_model.nominal.shape != (n, 5):
        raise InputError(f"the joint model was built for another robot than {robot.name!r}")
    commanded = q
    if joint_model is not None and joint_model.has_backlash:  # the circles' lash, a fixed correction
        q = q + lash_turns(joint_model.backlash, q, capture.circle)
    columns = None if joint_model is None or joint_model.is_empty else joint_model.columns(commanded)
    extra_start = np.zeros(0) if columns is None else np.asarray(joint_model.values, dtype=float)
    base_start = None
    if criterion == "points" and tracker_from_base is None and session_index is None:
        start_q = q if columns is None else q + columns @ extra_start
        nominal_points = target_positions(start.values, start_q, layout.turning, layout.reflector)
        base_start = register_points(nominal_points, measured).transform
    elif criterion == "points" and tracker_from_base is not None:
        base_start = check_rigid_transform(tracker_from_base, "tracker_from_base")
    pair_i = pair_j = distances = pair_keep = pair_weight = None
    if criterion == "distances":
        pair_i, pair_j, pair_keep, distances, pair_weight = _pairs(
            capture, commanded, layout.pair_key, measured, sigmas, reference, session_index
        )
    probe = Problem(
        start=start.values.copy(), free=np.ones((n, 5), dtype=bool), base_start=base_start,
        base_free=np.full(6, use_base), q=q, turning=layout.turning, reflector=layout.reflector, measured=measured,
        criterion=criterion, pair_i=pair_i, pair_j=pair_j, pair_keep=pair_keep, measured_distances=distances,
        targets=targets, target_index=layout.target_index, unknown=unknown,
        offset_start=offset_start + _GENERIC_OFFSET_MM * _generic_directions(len(unknown), offset_start.shape[0]),
        offset_free=np.ones(offset_start.size, dtype=bool), point_weight=point_weight, pair_weight=pair_weight,
        joint_columns=columns, extra_start=extra_start, extra_free=np.ones(extra_start.size, dtype=bool),
        session_index=session_index if criterion == "points" else None, rotation_length=max(_radius(measured), 1.0),
    )  # fmt: skip
    if criterion == "points" and session_index is not None:
        probe = session_starts(probe, start.values, offset_start, capture.source, session_names)
    if oriented:
        state = State(start.values, extra_start, offset_start, np.zeros(6))
        probe = with_probe(probe, capture, instrument, state, settings.repeatability_mm)
    parameters = ~robot.structurally_fixed if explicit_mask is None else explicit_mask
    spread = commanded.max(axis=0) - commanded.min(axis=0)
    return Setup(
        capture=capture,
        start=start,
        settings=settings,
        probe=probe,
        candidates=np.r_[parameters.ravel(), np.ones(extra_start.size, dtype=bool)],
        all_scale=_scales(measured, columns, n),
        offset_start=offset_start,
        offset_names=tuple(f"target.{targets[t].name}.{axis}" for t in unknown for axis in "xyz")
        + tuple(f"session.{name}.{axis}" for name in session_names[1 : 1 + n_moved] for axis in BASE_AXES)
        + (PROBE_NAMES if oriented else ()),
        session_names=session_names if criterion == "points" else (),
        joint_model=joint_model,
        use_base=use_base,
        still=tuple(f"J{k + 1}" for k in np.flatnonzero(spread <= _STILL_RAD)),
        weighted=sigmas is not None,
        n_residuals=capture.n_points * (6 if oriented else 3) if pair_i is None else int(pair_i.size),  # None: points
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class _Fit:
    """The fit a refinement returns: its problem and solution, the Jacobian there (which the statistics use),
    the solver's record over every round, and the free-set decision."""

    problem: Problem
    x: np.ndarray
    success: bool
    status: int
    message: str
    method: str
    evaluated: tuple[np.ndarray, np.ndarray]
    selection: Selection
    verdict: HeldNames
    x_scale: np.ndarray
    nfev: int = 0
    njev: int = 0
    start_cost: float = 0.0
    history: np.ndarray = field(default_factory=lambda: np.zeros(0))
    refits: int = 0
    unsettled: str = ""


@dataclass(frozen=True, slots=True)
class _Kept:
    fit: _Fit
    cost: float


class _Record:
    """The solver's record over the rounds: evaluations, the cost history, the start cost."""

    def __init__(self) -> None:
        self.nfev = self.njev = 0
        self.history: list[float] = []
        self.start_cost: float | None = None

    def finish(self, fit: _Fit, refits: int, unsettled: str, method: str) -> _Fit:
        """The fit with the record of every round."""
        message = f"{unsettled}. Solver: {fit.message}" if unsettled else fit.message
        assert self.start_cost is not None  # set by the first round, before its solve
        return replace(
            fit, nfev=self.nfev, njev=self.njev, start_cost=self.start_cost, history=np.asarray(self.history),
            refits=refits, unsettled=unsettled, message=message, method=method,
        )  # fmt: skip


def _x_scale(setup: Setup, selection: Selection) -> np.ndarray:
    """The scale of each unknown of a round (module notes)."""
    n = setup.start.robot.n_joints
    own = 5 * n + selection.extra_free.size
    return np.concatenate(
        [
            setup.all_scale[: 5 * n][selection.free.ravel()],
            setup.all_scale[5 * n : own][selection.extra_free],
            np.ones(int(selection.offset_free.sum())),
            setup.all_scale[own:][selection.base_free],
        ]
    )


def _fit_round(setup: Setup, problem: Problem, x_scale: np.ndarray, record: _Record):
    """One ``least_squares`` run from ``problem.x0()``; the record counts its evaluations and costs."""
    x0 = problem.x0()
    history = record.history

    def jacobian(x):
        residuals, jac = problem.evaluate(x)
        history.append(0.5 * float(residuals @ residuals))
        return jac

    settings = setup.settings
    method = ("lm" if setup.n_residuals >= x0.size else "trf") if settings.method == "auto" else settings.method
    if record.start_cost is None:
        start_residuals = problem.residuals(x0)
        record.start_cost = 0.5 * float(start_residuals @ start_residuals)
    evaluations = len(history)
    solution = least_squares(
        problem.residuals, x0, jac=jacobian, method=method, x_scale=x_scale, ftol=settings.tolerance,
        xtol=settings.tolerance, gtol=settings.tolerance, max_nfev=settings.max_nfev,
    )  # fmt: skip
    record.nfev += int(solution.nfev)
    record.njev += int(solution.njev) if solution.njev is not None else len(history) - evaluations
    return solution, method


def _accepted(problem: Problem, solution, start_state: State, record: _Record):
    """The solution's unknowns, success, message and cost; the start when the solver ended above it (module
    notes: never hand back something worse than what came in)."""
    final_cost = float(solution.cost)
    x_final = np.asarray(solution.x, dtype=float)
    success = int(solution.status) > 0
    message = str(solution.message)
    start_cost = record.start_cost
    assert start_cost is not None  # set above
    if not np.isfinite(final_cost) or final_cost > start_cost:
        # the start in this round's unknowns: held quantities are at their start values in every round
        message = (
            f"the solver ended at a higher cost ({final_cost:.6g} mm^2) than the start ({start_cost:.6g} mm^2); "
            f"the start is returned. Solver: {message}"
        )
        x_final, success = problem.pack(start_state), False
        start_residuals = problem.residuals(x_final)
        final_cost = 0.5 * float(start_residuals @ start_residuals)
    history = record.history
    if not history or abs(history[-1] - final_cost) > 1e-15 * max(final_cost, 1e-300):
        history.append(final_cost)
    return x_final, success, message, final_cost


def _round_problem(probe: Problem, state: State, selection: Selection) -> Problem:
    """The problem of a round: ``state`` as the start, ``selection``'s quantities free."""
    return replace(
        probe, start=state.values, extra_start=state.extras, offset_start=state.offsets, base_offset=state.x_base,
        free=selection.free, extra_free=selection.extra_free, base_free=selection.base_free,
        offset_free=selection.offset_free,
    )  # fmt: skip


def _solve(setup: Setup, selection: Selection) -> _Fit:
    """Fit, then decide the free set again at the solution; refit from the solution while it changes (module
    notes). A refit that fails or ends worse than the fit it started from leaves that fit standing."""
    probe = replace(setup.probe, offset_start=setup.offset_start)
    verdict = describe_held(setup, selection)
    start_state = State(setup.start.values.copy(), probe.extra_start.copy(), setup.offset_start, np.zeros(6))
    fit_state = start_state
    seen = [selection_key(selection)]
    record = _Record()
    unsettled = ""
    kept = None  # the last fit accepted: what a failed refit falls back to
    for fit_round in range(_MAX_REFITS + 1):
        problem = _round_problem(probe, fit_state, selection)
        if problem.x0().size == 0:
            raise IdentifiabilityError(
                f"{setup.capture.source}: no parameter can be refined from this capture",
                parameters=verdict.gauge + verdict.held,
            )
        x_scale = _x_scale(setup, selection)
        solution, method = _fit_round(setup, problem, x_scale, record)
        final_cost, status = float(solution.cost), int(solution.status)
        if kept is not None and (
            status <= 0 or not np.isfinite(final_cost) or final_cost > kept.cost * (1 + 1e-6) + 1e-12
        ):
            outcome = "did not converge" if status <= 0 else "ended at a higher cost"
            unsettled = (
                f"the refit with the free set decided at the solution of fit {fit_round} {outcome} "
                f"({final_cost:.6g} mm^2 against {kept.cost:.6g} mm^2); fit {fit_round} is returned"
            )
            record.history.append(kept.cost)
            return record.finish(kept.fit, len(seen) - 1, unsettled, method)
        x_final, success, message, final_cost = _accepted(problem, solution, start_state, record)
        solved = problem.unpack_all(x_final)
        # the rank test again, at the solution (the offsets as estimated): its Jacobian serves the statistics too
        at_solution = replace(
            probe, start=solved.values, extra_start=solved.extras, offset_start=solved.offsets,
            base_offset=solved.x_base,
        )  # fmt: skip
        evaluated = at_solution.evaluate(at_solution.x0())
        fit = _Fit(
            problem=problem, x=x_final, success=success, status=status, message=message, method=method,
            evaluated=evaluated, selection=selection, verdict=verdict, x_scale=x_scale,
        )  # fmt: skip
        if not success:  # the first fit did not converge (or the start came back): the decision at the start stands
            break
        kept = _Kept(fit=fit, cost=final_cost)
        decided = select_free(
            at_solution, setup.candidates, setup.all_scale, setup.settings.rank_tolerance, evaluated[1],
            preferred=selection,
        )  # fmt: skip
        key = selection_key(decided)
        if key == seen[-1]:  # confirmed: report what the solution's test says (gauge, held, confounded)
            fit = replace(fit, verdict=describe_held(setup, decided))
            break
        if setup.strict:  # an explicit free set (or "raise") is not re-chosen: held at the solution is an error
            now = describe_held(setup, decided)
            if set(now.gauge + now.held) - set(now.accepted):
                report_held(setup, now, strict=True)
        if key in seen or fit_round == _MAX_REFITS:
            unsettled = (
                f"the free set did not settle: the rank test at the solution of fit {fit_round + 1} "
                f"{'returns to an earlier free set' if key in seen else 'changes it again'}; the last fit is returned"
            )
            break
        seen.append(key)
        selection = decided
        verdict = describe_held(setup, selection)
        fit_state = _refit_start(setup, selection, solved, start_state)
    return record.finish(fit, len(seen) - 1, unsettled, method)


def _refit_start(setup: Setup, selection: Selection, solved: State, start_state: State) -> State:
    """The refit's start: what stays free keeps its solved value, what is now held goes back to its start value."""
    return State(
        np.where(selection.free, solved.values, start_state.values),
        np.where(selection.extra_free, solved.extras, start_state.extras),
        np.where(selection.offset_free, solved.offsets.ravel(), setup.offset_start.ravel()).reshape(-1, 3),
        np.where(selection.base_free, solved.x_base, 0.0),
    )


def _statistics(setup: Setup, fit: _Fit, began: float, instrument) -> RefinementResult:
    """The result: values at the solution, residual statistics (per point, unweighted, mm), conditioning, the
    linearised covariance from the Jacobian of the rank test at the solution, and the fit health."""
    start, criterion, problem = setup.start, setup.criterion, fit.problem
    solved = problem.unpack_all(fit.x)
    values, extras, offsets, x_base = solved
    selection = fit.selection
    residuals, jac_all = fit.evaluated
    use = np.r_[selection.free.ravel(), selection.extra_free, selection.offset_free]
    jac = jac_all[:, np.r_[use, selection.base_free[: 6 if setup.use_base else 0]]]
    raw = problem.raw_residuals(fit.x)
    per = np.linalg.norm(raw.reshape(-1, 3), axis=1) if criterion == "points" else np.abs(raw)
    history = fit.history
    statistics = FitStatistics(
        n_residuals=setup.n_residuals, residual_rms=float(np.sqrt(np.mean(per**2))), residual_mean=float(per.mean()),
        residual_max=float(per.max()), residual_rms_coordinate=float(np.sqrt(np.mean(raw**2))),
        start_cost=fit.start_cost, cost_history=_frozen(history),
        rms_history=_frozen(np.sqrt(2.0 * history / setup.n_residuals)), weighted=setup.weighted, refits=fit.refits,
    )  # fmt: skip
    identifiability = _identifiability(setup, fit, jac)
    uncertainty, message = _uncertainty(setup, fit, jac, residuals)
    joint_model = None
    if setup.joint_model is not None:
        identified = setup.joint_model.identified | selection.extra_free
        joint_model = setup.joint_model.with_values(extras, identified=identified)
    targets = list(problem.targets)
    for slot, t in enumerate(problem.unknown):
        targets[t] = targets[t].with_position(offsets[slot])
    model = "geometric"
    if joint_model is not None and not joint_model.is_empty:
        model = "+".join(g for g in JOINT_MODEL_GROUPS if g in joint_model.groups)
    health = refine_health(
        statistics, identifiability, uncertainty, criterion=criterion, converged=fit.success, model=model,
        capture=setup.capture, instrument=instrument, repeatability_mm=setup.settings.repeatability_mm,
    )  # fmt: skip
    return RefinementResult(
        parameters=ParameterSet(
            robot=start.robot, values=values, identified=start.identified | selection.free, joint_model=joint_model
        ),
        tracker_from_base=None if problem.base_start is None else _frozen(problem.tracker(x_base)),
        targets=tuple(targets), success=fit.success, status=fit.status, message=message, nfev=fit.nfev,
        njev=fit.njev, model=model, criterion=criterion, method=fit.method,
        wall_time_s=time.perf_counter() - began, fit=statistics, identifiability=identifiability,
        uncertainty=uncertainty, health=health, sessions=session_frames(setup, problem, selection, solved, uncertainty.covariance),
        probe=probe_frame(problem, selection, solved, uncertainty.covariance),
    )  # fmt: skip


def _identifiability(setup: Setup, fit: _Fit, jac: np.ndarray) -> Identifiability:
    """The free set, what is held, and the conditioning of the free columns ``jac`` at the solution."""
    names = setup.start.robot.parameter_names
    selection = fit.selection
    free_names = (
        tuple(name for name, flag in zip(names, selection.free.ravel(), strict=True) if flag)
        + tuple(name for name, flag in zip(setup.extra_names, selection.extra_free, strict=True) if flag)
        + tuple(name for name, flag in zip(setup.offset_names, selection.offset_free, strict=True) if flag)
        + tuple(BASE_NAMES[k] for k in np.flatnonzero(selection.base_free))
    )
    # RMS displacement of a point (points) or change of a distance (distances) per unit of each free quantity
    rows = jac.shape[0] / 3.0 if setup.criterion == "points" else jac.shape[0]
    effect = np.linalg.norm(jac, axis=0) / np.sqrt(rows)
    cond = conditioning(jac * fit.x_scale)
    return Identifiability(
        free=_frozen(selection.free, bool), base_free=_frozen(selection.base_free, bool), gauge=fit.verdict.gauge,
        held=fit.verdict.held, confounded=fit.verdict.confounded, still_joints=setup.still, free_names=free_names,
        x_scale=_frozen(fit.x_scale), singular_values=cond.singular_values, condition_number=cond.condition_number,
        effect=_frozen(effect),
    )  # fmt: skip


def _uncertainty(setup: Setup, fit: _Fit, jac, residuals) -> tuple[RefinementUncertainty, str]:
    """The linearised uncertainty (module notes) placed per parameter, joint-model value and target offset, and the
    result's message (which says so when no degree of freedom is left for the noise)."""
    problem, selection = fit.problem, fit.selection
    n = setup.start.robot.n_joints
    covariance, sigma, dof = _covariance(jac, fit.x_scale, residuals, problem.noise_map(fit.x))
    standard = np.full((n, 5), np.nan)
    extra_sd = np.full(selection.extra_free.size, np.nan)
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
        standard[selection.free] = diagonal[: bounds[0]]
        extra_sd[selection.extra_free] = diagonal[bounds[0] : bounds[1]]
        flat = offset_sd.ravel()
        flat[selection.offset_free] = diagonal[bounds[1] : bounds[2]]
        offset_sd = flat.reshape(setup.offset_start.shape)
    target_sd = np.full((len(problem.targets), 3), np.nan)
    for slot, t in enumerate(problem.unknown):
        target_sd[t] = offset_sd[slot]
    uncertainty = RefinementUncertainty(
        sigma=sigma,
        covariance=None if covariance is None else _frozen(covariance),
        correlation=None if covariance is None else _frozen(correlation_from_covariance(covariance)),
        standard_uncertainty=_frozen(standard),
        joint_model_uncertainty=None if setup.joint_model is None else _frozen(extra_sd),
        target_uncertainty=_frozen(target_sd) if problem.targets else None,
    )
    return uncertainty, message


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
