"""Monte Carlo of a measured capture: each point's U(95) as its noise (issue 14, item 3).

The scenario Monte Carlo (:mod:`robotcal.uncertainty.montecarlo`) simulates the scenario's capture
*plan*. A real capture (free poses, several targets, a U(95) per point) has no plan; its refinement
gives the linearised u only. This module repeats, draw after draw, what the user ran on that capture:

1. **Reference.** The capture is refined once more with :func:`refine_parameters`, starting from the
   user's estimate (the refined parameters and estimated target offsets of the parameter JSON): the
   same criterion, base-frame handling (``[identification].base_frame``, ``estimate_base``) and
   weights (``1 / u^2``, u = U(95) / 2). Started at the optimum it converges at once, and it gives
   what the draws need: the free set, the base frame (points criterion) and the linearised
   covariance. Its values are the estimate ``y`` around which the draws scatter.
2. **Simulated capture.** The capture's own poses (its readings, each point on its own target) are
   put through the estimate: ``T F(q; y) r_t`` with the estimated offsets ``r_t`` and the base frame
   ``T`` of the reference (distances criterion: the Horn registration of the predicted points onto
   the measured ones, since it has no base frame; distances do not depend on it).
3. **Noise.** Each point gets independent normal noise per coordinate, ``N(0, (U95 / 2)^2)``:
   the tracker's U(95) is read as an expanded uncertainty with coverage factor k = 2 of a normal
   distribution (the convention of :func:`robotcal.identification.refine.point_sigmas`). A capture
   without a ``u95_mm`` column takes the scenario instrument's noise
   (:meth:`robotcal.instruments.Instrument.sample_noise`: ``U(L) = A + B L``, normal with its coverage
   factor, or uniform); one without either is refused.
4. **Refinement.** :func:`refine_parameters` on the noisy copy, start = the estimate, same options.
   A draw counts as **failed** (counted, never averaged in) when the solver reports no success, when
   it raises, or when its rank test chooses another free set than the reference.

The draws of the free parameters and of the unknown target offsets give mean, u, both coverage
intervals, covariance and correlation (:func:`robotcal.uncertainty.statistics.summarize_draws`, as
the other Monte Carlos). The linearised comparison is the reference refinement's covariance
rescaled to the noise the draws use: ``robotcal refine`` estimates sigma from the residuals
(sigma-hat), the draws use the stated noise (U(95) / 2 per point, or the instrument's standard
uncertainty), so the covariance and the offsets' linearised u are multiplied by
``(u_stated / sigma_hat)^2`` (u by ``u_stated / sigma_hat``), ``u_stated`` the RMS of the points'
stated standard uncertainties (:func:`stated_point_u`); both verdicts then compare one noise model.
The JCGM 101
§8.2 verdict is taken with :data:`COMPARISON_NDIG` = 1 significant digit of u, what a few hundred
draws resolve.

Cost: the draws are not vectorised; each is one ``refine_parameters`` call, rank test included: fine for a
few hundred draws, which give u to about 5 % (relative standard error ``1 / sqrt(2 (M - 1))``).

Reproducibility: draws come in blocks of :data:`DRAWS_PER_BLOCK`; block ``b`` draws its noise from
``SeedSequence(seed, spawn_key=(b,))`` (as :mod:`robotcal.uncertainty.montecarlo`), draw by draw, so
the result does not depend on the number of workers nor on the backend
(:func:`robotcal.execution.open_executor`).

References
----------
JCGM 101:2008 §5.9, §7; thesis ch. 4.5.7 (eqs 4-101, 4-102).
"""

from __future__ import annotations

import functools
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.capture import Capture
from robotcal.errors import IdentifiabilityWarning, InputError, RobotcalError, RobotcalWarning, check_count
from robotcal.execution import check_stop, open_executor, single_blas_thread
from robotcal.geometry.registration import register_points
from robotcal.geometry.transforms import apply_transform
from robotcal.identification.refine import (
    CRITERIA,
    RefinementResult,
    RefinementSettings,
    capture_turning_joints,
    point_sigmas,
    refine_parameters,
    wrap_angles,
)
from robotcal.identification.targets import Target, resolve_targets, split_by_session
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import probe_rotations, target_positions
from robotcal.kinematics.model import ParameterSet, ReflectorMount
from robotcal.uncertainty.linearised import linearised_result
from robotcal.uncertainty.montecarlo import (
    LinearisedResult,
    MonteCarloResult,
    MonteCarloSettings,
    ProgressCallback,
    kept_draws_result,
)
from robotcal.uncertainty.statistics import (
    SampleSummary,
    bias_corrected_interval,
    numerical_tolerance,
    summarize_draws,
)

__all__ = [
    "DRAWS_PER_BLOCK",
    "MODEL",
    "MeasuredProblem",
    "MeasuredMonteCarloResult",
    "prepare_measured",
    "measured_monte_carlo",
    "measured_block",
]

#: The ``model`` recorded in the result and its files.
MODEL = "measured capture"
#: Largest move of a parameter (in its standard uncertainty) when the capture is refined again from the
#: estimate, beyond which the estimate is taken not to be this capture's refinement (a warning).
SHIFT_TOLERANCE = 0.1
#: Significant digits of u for the JCGM 101 §8.2 comparison with the linearised u: a few hundred draws
#: resolve u to about one digit (relative standard error 1/sqrt(2 (M - 1)): 4 % at 300 draws, and the
#: interval ends to ~10 %), so ndig = 2 would call almost every parameter "differs".
COMPARISON_NDIG = 1
#: Draws per seeded block: the reproducibility unit and the unit of work handed to a worker.
DRAWS_PER_BLOCK = 20


@dataclass(frozen=True, slots=True, kw_only=True)
class MeasuredProblem:
    """What every draw shares.

    Attributes
    ----------
    capture : Capture
        The measured capture (readings, targets, u95); its points are replaced in every draw.
    reflector : ReflectorMount or tuple of Target
        The target(s), unknown flange offsets at their estimated values.
    reference : RefinementResult
        The refinement of the measured capture from the estimate (free set, base frame, covariance).
    exact_points : ndarray, shape (n_points, 3)
        The capture's poses put through the estimate, tracker frame [mm].
    noise_sd : ndarray, shape (n_points,) or None
        Standard deviation per coordinate [mm], ``U95 / 2``; None: ``instrument`` gives the noise.
    instrument : Instrument or None
    noise_source : str
        Where the noise comes from, in words (recorded in the files).
    options : dict
        Keyword arguments of every draw's :func:`refine_parameters` call.
    exact_rotations : ndarray, shape (n_points, 3, 3), or None
        A 6-DoF capture (issue 29): the probe's orientation at every pose through the estimate, tracker frame.
    orientation_sd : ndarray, shape (n_points,), or None
        Standard deviation of each rotation-vector component of the orientation noise [rad] (``u95_deg / 2``);
        None with ``exact_rotations``: the instrument's orientation term gives it.
    """

    capture: Capture
    reflector: ReflectorMount | Sequence[Target]
    reference: RefinementResult
    exact_points: np.ndarray
    noise_sd: np.ndarray | None
    instrument: Instrument | None
    noise_source: str
    options: dict = field(default_factory=dict)
    exact_rotations: np.ndarray | None = None
    orientation_sd: np.ndarray | None = None

    @property
    def robot(self):
        return self.reference.parameters.robot

    @property
    def unknown_targets(self) -> tuple[Target, ...]:
        """The targets whose offsets are estimated (their draws are kept)."""
        return tuple(target for target in self.reference.targets if not target.known)


@dataclass(frozen=True, slots=True, kw_only=True)
class MeasuredMonteCarloResult:
    """The Monte Carlo of a measured capture.

    Attributes
    ----------
    parameters : MonteCarloResult
        Statistics of the kinematic parameters (core units), ``model = "measured capture"``;
        ``identified`` is the refinement's free set (held parameters keep the estimate, u = 0);
        ``noise_free_values`` and ``true_values`` are the estimate; ``linearised`` the reference
        refinement's covariance.
    target_names : tuple of str
        The targets whose offsets were estimated (rows of the next arrays).
    target_estimate, target_linearised_u : ndarray, shape (n_targets, 3)
        Estimated offsets [mm] and their linearised standard uncertainty (NaN where not estimated).
    target_summary : SampleSummary or None
        Statistics of the offsets' draws, arrays of shape (n_targets, 3) [mm]; None without unknown targets.
    target_draws : ndarray, shape (n_draws, n_targets, 3) or None
    noise_source : str
    reference : RefinementResult
    stated_u_mm, residual_sigma_mm : float
        RMS of the points' stated standard uncertainties and the reference's sigma-hat [mm]; the linearised
        covariance (and ``target_linearised_u``) are rescaled by ``(stated_u_mm / residual_sigma_mm)^2``
        (module notes); NaN sigma: not rescaled (there is no covariance).
    """

    parameters: MonteCarloResult
    target_names: tuple[str, ...]
    target_estimate: np.ndarray
    target_linearised_u: np.ndarray
    target_summary: SampleSummary | None
    target_draws: np.ndarray | None
    noise_source: str
    reference: RefinementResult
    stated_u_mm: float = float("nan")
    residual_sigma_mm: float = float("nan")

    def target_draws_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """The offsets' draws' own coverage interval (the kind of the settings), ``(n_targets, 3)`` each [mm]."""
        if self.target_summary is None:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return self.target_summary.interval(self.parameters.settings.interval)

    def target_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """The offsets' interval for the measurand: the draws' interval moved by twice their bias against the
        estimated offsets, as the parameters' (:meth:`MonteCarloResult.interval`; the draws are simulated at the
        estimate) [mm]."""
        low, high = self.target_draws_interval()
        if self.target_summary is None or not low.size:
            return low, high
        return bias_corrected_interval(low, high, self.target_summary.mean, self.target_estimate)


def _with_offsets(reflector, offsets: Mapping[str, object] | None):
    """``reflector`` with the unknown flange targets moved to ``offsets[name]`` (estimated values)."""
    if isinstance(reflector, ReflectorMount) or not offsets:
        return reflector
    single = isinstance(reflector, Target)
    targets = (reflector,) if single else tuple(reflector)
    moved = tuple(
        target.with_position(offsets[target.name]) if not target.known and target.name in offsets else target
        for target in targets
    )
    return moved[0] if single else moved


def _base_points(capture: Capture, parameters: ParameterSet, reflector) -> np.ndarray:
    """Every point of ``capture`` put through ``parameters``: its pose, its target, base frame [mm]."""
    q = parameters.model_joint_variables(capture.readings)
    if isinstance(reflector, ReflectorMount):
        return target_positions(parameters.values, q, capture_turning_joints(capture, reflector), reflector)
    targets, index = resolve_targets(capture, (reflector,) if isinstance(reflector, Target) else tuple(reflector))
    turning = np.maximum(capture.circle - 1, 0)
    points = np.empty((capture.n_points, 3))
    for t, target in enumerate(targets):
        rows = np.flatnonzero(index == t)
        points[rows] = target_positions(parameters.values, q[rows], turning[rows], target.mount)
    return points


def _in_tracker(capture: Capture, predicted: np.ndarray, tracker, sessions) -> np.ndarray:
    """The predicted points in the tracker frame: each session's in its own frame (``sessions``, the reference's
    :class:`~robotcal.identification.records.SessionFrame`), else all in ``tracker``."""
    if not sessions:
        return apply_transform(tracker, predicted)
    exact = np.empty_like(predicted)
    for frame in sessions:
        rows = np.flatnonzero(capture.session == capture.session_names.index(frame.name))
        exact[rows] = apply_transform(frame.tracker_from_base, predicted[rows])
    return exact


def _noise_model(capture: Capture, instrument: Instrument | None) -> tuple[np.ndarray | None, Instrument | None, str]:
    sigmas = point_sigmas(capture)
    if sigmas is not None:
        return _frozen(sigmas), None, "each point's U(95) from the capture's u95_mm column (k = 2, normal: u = U / 2)"
    if instrument is not None:
        return None, instrument, f"the instrument {instrument.name!r} ({instrument.noise}; no u95_mm column)"
    raise InputError(
        f"{capture.source}: no noise to simulate: the capture has no `u95_mm` column and no instrument is given "
        "(a scenario's [instrument] table); add one of them (the Monte Carlo draws each point's noise from its "
        "U(95), k = 2, normal, else from the instrument)"
    )


def prepare_measured(
    capture: Capture,
    estimate: ParameterSet,
    reflector,
    *,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    criterion: str = "points",
    offsets: Mapping[str, object] | None = None,
    estimate_base: bool = False,
    weights: str = "auto",
) -> MeasuredProblem:
    """Refine ``capture`` from ``estimate`` once (the reference) and set up the draws.

    Parameters
    ----------
    capture : Capture
        The measured capture [mm]; its ``u95_mm`` column (if any) is each point's noise.
    estimate : ParameterSet
        The refined parameters the user obtained [mm, rad].
    reflector : ReflectorMount, Target or sequence of Target
        Where the points were measured (as for :func:`refine_parameters`).
    instrument : Instrument, optional
        The noise of a capture without ``u95_mm``.
    tracker_from_base : array_like, shape (4, 4), optional
        Points criterion: the base frame the refinement held (None: it was estimated from a registration).
    criterion : {"points", "distances"}
    offsets : mapping of str to (x, y, z), optional
        Estimated flange offsets [mm] by target name (``read_targets`` of the parameter JSON); unknown
        targets not named here start from their guess.
    estimate_base : bool
        Points criterion: the base frame was estimated from ``tracker_from_base`` (``refine --estimate-base``).
    weights : {"auto", "none"}
        As for :func:`refine_parameters`.
    """
    if criterion not in CRITERIA:
        raise InputError(f"`criterion` must be one of {CRITERIA}; got {criterion!r}")
    if estimate.robot.n_joints != capture.n_joints:
        raise InputError(
            f"the estimate is for robot {estimate.robot.name!r} ({estimate.robot.n_joints} joints); the capture has "
            f"{capture.n_joints} joint readings per point"
        )
    stated = instrument  # a 6-DoF capture's refinement may need its orientation term
    noise_sd, instrument, source = _noise_model(capture, instrument)
    if not isinstance(reflector, ReflectorMount):  # a re-seated target: one target per session (NAME@SESSION)
        capture, reflector = split_by_session(capture, (reflector,) if isinstance(reflector, Target) else reflector)
    reflector = _with_offsets(reflector, offsets)
    base = True if criterion == "points" and estimate_base else None
    settings = RefinementSettings(criterion=criterion, weights=weights, estimate_base=base)
    options: dict = {"settings": settings, "tracker_from_base": tracker_from_base if criterion == "points" else None}
    if capture.orientation is not None:
        options["instrument"] = stated
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)  # the user saw them when refining
        reference = refine_parameters(capture, estimate, reflector, **options)
    if not reference.success:
        raise RobotcalError(f"{capture.source}: the refinement from the estimate did not converge: {reference.message}")
    shift = np.abs(wrap_angles(reference.parameters.values - estimate.values))[reference.identifiability.free]
    scale = np.asarray(reference.uncertainty.standard_uncertainty)[reference.identifiability.free]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = shift / scale
    moved = float(ratio[np.isfinite(ratio)].max()) if np.isfinite(ratio).any() else 0.0
    if moved > SHIFT_TOLERANCE:
        warnings.warn(
            f"{capture.source}: refined again from the estimate, the parameters move by up to {moved:.3g} of their "
            "standard uncertainty: the estimate is not the refinement of this capture with these options (another "
            "capture, criterion or weights?); the Monte Carlo is made around the refined-again values",
            RobotcalWarning,
            stacklevel=2,
        )
    reflector = reference.targets if reference.targets else reflector
    predicted = _base_points(capture, reference.parameters, reflector)
    if reference.tracker_from_base is not None:
        tracker = reference.tracker_from_base
        # every draw starts from the reference's base frame; estimated again where the reference estimated it
        options["tracker_from_base"] = tracker
        options["settings"] = replace(settings, estimate_base=bool(np.any(reference.identifiability.base_free)))
    else:  # distances: no base frame; any rigid placement gives the same distances
        tracker = register_points(predicted, capture.points).transform
    exact = _in_tracker(capture, predicted, tracker, reference.sessions)
    rotations, orientation_sd = _exact_rotations(capture, reference, tracker, stated)
    if rotations is not None and orientation_sd is not None:
        source += "; orientations: each point's u95_deg (k = 2, normal: u = U / 2 per rotation-vector component)"
    elif rotations is not None:
        assert stated is not None  # without u95_deg, _exact_rotations asked for the instrument's orientation term
        source += f"; orientations: the instrument {stated.name!r}'s orientation_deg"
    return MeasuredProblem(
        capture=capture,
        reflector=reflector,
        reference=reference,
        exact_points=_frozen(exact),
        noise_sd=noise_sd,
        instrument=instrument,
        noise_source=source,
        options=options,
        exact_rotations=rotations,
        orientation_sd=orientation_sd,
    )


def _exact_rotations(capture: Capture, reference: RefinementResult, tracker, instrument):
    """A 6-DoF capture's orientations through the reference ``R_T F R_P`` and their noise's standard deviation
    per rotation-vector component [rad] (``u95_deg / 2``; None: the instrument's); ``(None, None)`` otherwise."""
    if reference.probe is None:
        return None, None
    parameters = reference.parameters
    trackers = np.broadcast_to(np.asarray(tracker, dtype=float), (capture.n_points, 4, 4)).copy()
    frames = {frame.name: frame.tracker_from_base for frame in reference.sessions}
    for k, name in enumerate(capture.session_names if frames else ()):
        rows = np.asarray(capture.session == k)
        if rows.any():  # a session the capture names but no point is in has no frame (capture_sessions)
            trackers[rows] = frames[name]
    q = parameters.model_joint_variables(capture.readings)
    rotations = probe_rotations(parameters.values, q, reference.probe.rotation, trackers)
    if capture.orientation_u95 is not None:
        return _frozen(rotations), _frozen(capture.orientation_u95 / 2.0)
    if instrument is None or not instrument.orientation_standard_uncertainty:
        raise InputError(f"{capture.source}: no orientation noise to simulate: give `u95_deg` or the instrument's")
    return _frozen(rotations), None


def _block_generator(seed: int, block: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(entropy=seed, spawn_key=(block,)))


def draw_noise(problem: MeasuredProblem, rng: np.random.Generator) -> np.ndarray:
    """One draw's coordinate errors ``(n_points, 3)`` [mm]: ``N(0, (U95/2)^2)`` per coordinate, or the instrument's."""
    if problem.noise_sd is not None:
        return rng.standard_normal((problem.exact_points.shape[0], 3)) * problem.noise_sd[:, None]
    assert problem.instrument is not None  # without per-point U(95) the instrument gives the noise (_noise_model)
    return problem.instrument.sample_noise(problem.exact_points, rng=rng)


def draw_rotations(problem: MeasuredProblem, rng: np.random.Generator) -> np.ndarray | None:
    """One draw's measured orientations of a 6-DoF capture (drawn after the positions' noise): the exact ones
    turned by a rotation vector ``N(0, (U95/2)^2)`` per component (or the instrument's); None without them."""
    from robotcal.geometry.rotations import rotation_matrices

    if problem.exact_rotations is None:
        return None
    count = problem.exact_rotations.shape[0]
    if problem.orientation_sd is not None:
        turns = rng.standard_normal((count, 3)) * problem.orientation_sd[:, None]
    else:
        turns = problem.options["instrument"].sample_orientation_noise(count, rng=rng)
    return problem.exact_rotations @ rotation_matrices(turns)


def _refine_draw(problem: MeasuredProblem, points: np.ndarray, rotations=None) -> tuple[np.ndarray, np.ndarray] | None:
    """Parameters ``(n, 5)`` and unknown offsets ``(k, 3)`` of one noisy copy; None when the draw failed."""
    reference = problem.reference
    capture = problem.capture.with_points(points)
    if rotations is not None:
        capture = capture.with_orientation(rotations)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            result = refine_parameters(capture, reference.parameters, problem.reflector, **problem.options)
    except (RobotcalError, np.linalg.LinAlgError, ValueError):
        return None
    if not result.success or result.identifiability.free_names != reference.identifiability.free_names:
        return None
    offsets = np.array([t.positions for t in result.targets if not t.known], dtype=float).reshape(-1, 3)
    return result.parameters.values, offsets


def measured_block(problem: MeasuredProblem, seed: int, item: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Draws of block ``item = (block, size)``: parameters ``(size, n, 5)`` and offsets ``(size, k, 3)``;
    NaN rows where a draw failed. Noise drawn draw by draw from the block's own generator."""
    block, size = item
    rng = _block_generator(seed, block)
    n = problem.robot.n_joints
    k = len(problem.unknown_targets)
    values = np.full((size, n, 5), np.nan)
    offsets = np.full((size, k, 3), np.nan)
    for draw in range(size):
        check_stop()  # in a pool worker: end the block when the pool shuts down
        points = problem.exact_points + draw_noise(problem, rng)
        rotations = draw_rotations(problem, rng)
        outcome = _refine_draw(problem, points) if rotations is None else _refine_draw(problem, points, rotations)
        if outcome is not None:
            values[draw], offsets[draw] = outcome
    return values, offsets


def _block_items(total: int) -> list[tuple[int, int]]:
    full, rest = divmod(total, DRAWS_PER_BLOCK)
    return [(b, DRAWS_PER_BLOCK) for b in range(full)] + ([(full, rest)] if rest else [])


def stated_point_u(problem: MeasuredProblem) -> float:
    """RMS [mm] of the points' stated standard uncertainties per coordinate: ``U(95) / 2``, else the
    instrument's (:meth:`robotcal.instruments.Instrument.standard_uncertainty`), the noise the draws use."""
    if problem.noise_sd is not None:
        u = np.asarray(problem.noise_sd, dtype=float)
    else:
        assert problem.instrument is not None  # without per-point U(95) the instrument gives the noise (_noise_model)
        u = np.asarray(problem.instrument.standard_uncertainty(problem.exact_points), dtype=float)
    return float(np.sqrt(np.mean(u**2)))


def _noise_rescale(problem: MeasuredProblem) -> float:
    """``u_stated / sigma_hat``: the factor on the reference's linearised u (module notes); 1 without sigma-hat."""
    sigma = float(problem.reference.uncertainty.sigma)
    if not np.isfinite(sigma) or sigma <= 0.0:
        return 1.0
    return stated_point_u(problem) / sigma


def _linearised(problem: MeasuredProblem, summary: SampleSummary, settings: MonteCarloSettings) -> LinearisedResult:
    """The reference refinement's covariance rescaled to the stated noise (``(u_stated / sigma_hat)^2``),
    embedded joint-major, with the JCGM 101 §8.2 comparison."""
    reference = problem.reference
    n = problem.robot.n_joints
    free = np.asarray(reference.identifiability.free).reshape(-1)
    index = np.flatnonzero(free)
    covariance = np.zeros((5 * n, 5 * n))
    if reference.uncertainty.covariance is not None:
        covariance[np.ix_(index, index)] = (
            reference.uncertainty.covariance[: index.size, : index.size] * _noise_rescale(problem) ** 2
        )
    else:
        covariance[np.ix_(index, index)] = np.nan
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None)).reshape(n, 5)
    return linearised_result(
        estimate=reference.parameters.values,
        covariance=covariance,
        std=std,
        tolerance=numerical_tolerance(np.nan_to_num(std), COMPARISON_NDIG),
        coverage=settings.coverage,
        drawn=summary.interval(settings.interval),
        determined=np.asarray(reference.identifiability.free),
        step_mm=0.0,
    )


def measured_monte_carlo(
    capture: Capture,
    estimate: ParameterSet | RefinementResult,
    reflector,
    settings: MonteCarloSettings | None = None,
    *,
    seed: int,
    instrument: Instrument | None = None,
    tracker_from_base=None,
    criterion: str | None = None,
    offsets: Mapping[str, object] | None = None,
    estimate_base: bool = False,
    weights: str = "auto",
    progress: ProgressCallback | None = None,
) -> MeasuredMonteCarloResult:
    """Monte Carlo (JCGM 101) of the refinement of a measured capture (module notes).

    Parameters
    ----------
    capture : Capture
        The measured capture; a ``u95_mm`` column gives each point's noise (k = 2, normal).
    estimate : ParameterSet or RefinementResult
        The user's refined parameters (a :class:`RefinementResult` also gives its criterion and
        estimated target offsets).
    settings : MonteCarloSettings, optional
        ``iterations`` draws (a few hundred: each is one refinement), ``coverage``, ``interval``,
        ``workers``, ``scheduler``, ``keep_draws``; the adaptive mode is refused (too slow per draw).
    seed : int
        Seed of the run; block ``b`` uses ``SeedSequence(seed, spawn_key=(b,))``.
    criterion : {"points", "distances"}, optional
        Default: the estimate's (a RefinementResult), else ``"points"``.
    reflector, instrument, tracker_from_base, offsets, estimate_base, weights
        See :func:`prepare_measured`.
    progress : callable, optional
        ``progress(draws_done, draws_total)`` after every block.
    """
    with single_blas_thread():
        settings = MonteCarloSettings(iterations=200) if settings is None else settings
        if settings.adaptive:
            raise InputError(
                "the adaptive mode is not available for the Monte Carlo of a measured capture (each draw is a full "
                "refinement); give a fixed number of draws"
            )
        settings = replace(settings, block_size=DRAWS_PER_BLOCK)  # the blocks used, as the result records them
        seed = check_count(seed, "seed", minimum=0)
        estimate, criterion, offsets, estimate_base = _from_estimate(
            estimate, criterion, offsets, estimate_base, tracker_from_base
        )
        started = time.perf_counter()
        problem = prepare_measured(
            capture,
            estimate,
            reflector,
            instrument=instrument,
            tracker_from_base=tracker_from_base,
            criterion=criterion,
            offsets=offsets,
            estimate_base=estimate_base,
            weights=weights,
        )
        all_values, all_offsets = _measured_draws(problem, seed, settings, progress)
        good = np.isfinite(all_values).all(axis=(1, 2)) & np.isfinite(all_offsets).all(axis=(1, 2))
        n_failed = int((~good).sum())
        draws, offset_draws = all_values[good], all_offsets[good]
        if draws.shape[0] < 2:
            raise RobotcalError(f"only {draws.shape[0]} of {good.size} draws converged: no statistics can be made")
        draw_time = time.perf_counter() - started
        reference = problem.reference
        summary = summarize_draws(draws, settings.coverage)
        result = kept_draws_result(
            draws, summary, np.asarray(reference.identifiability.free, dtype=bool), settings, failed=n_failed,
            computed=good.size, failure="failed (no convergence, or another free set)", started=started,
            timings_s={"draws": draw_time, "per_draw": draw_time / good.size}, robot=problem.robot, seed=seed,
            noise_free_values=reference.parameters.values, true_values=reference.parameters.values,
            linearised=_linearised(problem, summary, settings), model=MODEL, criterion=criterion,
        )  # fmt: skip
        return _with_targets(problem, result, offset_draws, settings)


def _from_estimate(
    estimate: ParameterSet | RefinementResult,
    criterion: str | None,
    offsets: Mapping[str, object] | None,
    estimate_base: bool,
    tracker_from_base: ArrayLike | None,
) -> tuple[ParameterSet, str, Mapping[str, object] | None, bool]:
    """The parameters, criterion, offsets and base handling of ``estimate``: a :class:`RefinementResult` gives
    its own where they are not given."""
    if isinstance(estimate, RefinementResult):
        criterion = estimate.criterion if criterion is None else criterion
        if offsets is None and estimate.targets:
            offsets = {t.name: t.positions for t in estimate.targets if not t.known}
        if estimate.tracker_from_base is not None and tracker_from_base is not None:
            estimate_base = estimate_base or bool(np.any(estimate.identifiability.base_free))
        estimate = estimate.parameters
    return estimate, "points" if criterion is None else criterion, offsets, estimate_base


def _measured_draws(problem, seed: int, settings: MonteCarloSettings, progress) -> tuple[np.ndarray, np.ndarray]:
    """Every block's parameter and target-offset draws, in block order (NaN where a draw failed)."""
    items = _block_items(settings.iterations)
    task = functools.partial(measured_block, problem, seed)
    values, offsets = [], []
    done = 0
    with open_executor(workers=settings.workers, scheduler=settings.scheduler) as executor:
        for block_values, block_offsets in executor.map(task, items):
            values.append(block_values)
            offsets.append(block_offsets)
            done += block_values.shape[0]
            if progress is not None:
                progress(done, settings.iterations)
    return np.concatenate(values), np.concatenate(offsets)


def _with_targets(problem, result: MonteCarloResult, offset_draws: np.ndarray, settings) -> MeasuredMonteCarloResult:
    """The parameters' result with the estimated target offsets' draws and linearised u."""
    reference = problem.reference
    unknown = problem.unknown_targets
    rows = [k for k, t in enumerate(reference.targets) if not t.known]
    target_u = (
        np.asarray(reference.uncertainty.target_uncertainty)[rows] * _noise_rescale(problem)
        if reference.uncertainty.target_uncertainty is not None
        else np.zeros((0, 3))
    )
    return MeasuredMonteCarloResult(
        parameters=result,
        target_names=tuple(t.name for t in unknown),
        target_estimate=np.array([t.positions for t in unknown], dtype=float).reshape(-1, 3),
        target_linearised_u=target_u.reshape(-1, 3),
        target_summary=summarize_draws(offset_draws, settings.coverage) if unknown else None,
        target_draws=offset_draws if (unknown and settings.keep_draws) else None,
        noise_source=problem.noise_source,
        reference=reference,
        stated_u_mm=stated_point_u(problem),
        residual_sigma_mm=float(reference.uncertainty.sigma),
    )


def with_model(result: MonteCarloResult, model: str) -> MonteCarloResult:
    """``result`` under another ``model`` name (for writers that know only the scenario models)."""
    return replace(result, model=model)
