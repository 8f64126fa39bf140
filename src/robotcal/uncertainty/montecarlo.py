"""GUM Supplement 1 Monte Carlo of the whole capture-and-CPA pipeline (thesis ch. 5.2.3).

The noise-free capture is simulated once. Every draw adds instrument noise (and, where the scenario's
joint error model has a random part, redraws the joint errors), runs CPA, and keeps the parameters.
Draws are vectorised: a batch of ``batch_size`` noisy captures goes through one
``identify_cpa_batch`` call. With ``model="refined"`` every draw is then refined (the deployed model): by
batched Gauss-Newton around the noise-free solution (:mod:`robotcal.uncertainty.gauss_newton`), or, with
``refined_solver="per-draw"``, by Levenberg-Marquardt from its own CPA estimate
(:func:`robotcal.uncertainty.refined.refine_batch`); draws that do not converge are counted and left out of the
statistics.

Reproducibility: draws are organised in fixed blocks of ``block_size`` (by default 10^4, the block
of JCGM 101 §7.9, and 10^3 for a fixed number of refined draws, each of which costs several CPA draws, so
that a few thousand of them still spread over the workers). Block ``b`` draws from its own generators, seeded by
``SeedSequence(seed, spawn_key=(b,))``, instrument noise and joint-error noise from separate
children; a block is consumed in draw order whatever the batch size, and blocks are independent of
which worker computes them. The same seed therefore gives the same draws for any ``batch_size``, any
number of ``workers`` and any backend (:func:`robotcal.execution.open_executor`: serial, local
processes, Dask): a lone draw is computed as a batch of two, since numpy reduces a stack of one with
other loops than a larger stack (last-bit differences, up to 3e-11 mm before this was done).

The parts live in their own modules: the problem (:mod:`robotcal.uncertainty.montecarlo_problem`), the draws
(:mod:`robotcal.uncertainty.draws`), the refined draws' solvers (:mod:`robotcal.uncertainty.gauss_newton`,
:mod:`robotcal.uncertainty.refined`) and the linearised covariances (:mod:`robotcal.uncertainty.linearised`); this
module holds the settings, the driver and the results, and names them all.

References
----------
JCGM 101:2008 §5.9 (propagation), §7 (Monte Carlo), §7.9 (adaptive procedure), §8 (validation of
the GUM uncertainty framework); thesis ch. 5.2.3 (Tables 5.6 and 5.7).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robotcal.errors import InputError, RobotcalError, check_count
from robotcal.execution import open_executor, single_blas_thread
from robotcal.kinematics.model import ANGLE_COLUMNS, ParameterSet, RobotModel
from robotcal.uncertainty.draws import RefinedSolver, _block_sizes, _BlockRunner, draw_block, solve_points
from robotcal.uncertainty.linearised import (
    LinearisedResult,
    _cpa_covariance,
    _refined_full_covariance,
    linearised_result,
)
from robotcal.uncertainty.montecarlo_problem import MonteCarloProblem, prepare_monte_carlo
from robotcal.uncertainty.statistics import (
    INTERVAL_KINDS,
    IntervalKind,
    SampleSummary,
    bias_corrected_interval,
    check_coverage,
    coverage_interval,
    numerical_tolerance,
    summarize_draws,
    widened_interval,
)

if TYPE_CHECKING:
    from robotcal.kinematics.joint_model import JointModel

__all__ = [
    "MonteCarloProblem",
    "MonteCarloSettings",
    "MonteCarloResult",
    "AdaptiveRecord",
    "LinearisedResult",
    "prepare_monte_carlo",
    "run_monte_carlo",
    "linearised_uncertainty",
    "draw_block",
]

#: How the refined model's draws are solved (:attr:`MonteCarloSettings.refined_solver`).
REFINED_SOLVERS = ("gauss-newton", "per-draw")
#: JCGM 101 §7.9.2: M = max(J, 10^4) with J = 100 / (1 - p); 10^4 at p = 0.95.
DEFAULT_BLOCK_SIZE = 10_000
#: Draws per block of the refined model with a fixed number of draws (the adaptive procedure keeps
#: :data:`DEFAULT_BLOCK_SIZE`): a refined draw costs several CPA draws (the most for an extended model), and a
#: block is the unit a worker takes, so a few thousand refined draws still make several blocks for the workers.
REFINED_BLOCK_SIZE = 1_000

ProgressCallback = Callable[[int, int | None], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class MonteCarloSettings:
    """How many draws, and how they are organised.

    Attributes
    ----------
    iterations : int
        Number of draws M (fixed mode). Ignored by the adaptive mode.
    coverage : float
        Coverage probability p of the intervals.
    interval : {"symmetric", "shortest"}
        The interval reported as ``coverage_low/high`` and checked by the adaptive mode.
    adaptive : bool
        JCGM 101 §7.9 adaptive procedure: blocks of ``block_size`` until the mean, the standard
        uncertainty and both interval ends are stable to the numerical tolerance of ``ndig``
        significant digits (or ``max_draws`` is reached).
    ndig : int
        Significant decimal digits regarded as meaningful in the standard uncertainties.
    max_draws : int
        Upper limit of the adaptive mode.
    batch_size : int
        Draws identified per vectorised call; bounds the working memory (~50 kB per draw).
    block_size : int or None
        Draws per seeded block (the reproducibility unit and the work a worker takes; also the adaptive block
        size). None: :data:`REFINED_BLOCK_SIZE` for the refined model's fixed number of draws, else
        :data:`DEFAULT_BLOCK_SIZE`; the result's ``settings`` hold the size used.
    workers : int
        Processes that compute blocks in parallel (1: in this process).
    scheduler : str or None
        Dask scheduler address; None reads ``ROBOTCAL_SCHEDULER``, else local execution
        (:func:`robotcal.execution.open_executor`). Results do not depend on it.
    keep_draws : bool
        Keep every draw in the result (needed for histograms, ``draws.npz`` and the TCP stage).
    refined_solver : {"gauss-newton", "per-draw"}
        How the refined model's draws are solved: ``"gauss-newton"`` (default), batched Gauss-Newton around the
        noise-free solution with the per-draw solve as fallback (:mod:`robotcal.uncertainty.gauss_newton`);
        ``"per-draw"``, Levenberg-Marquardt from every draw's own CPA estimate
        (:func:`robotcal.uncertainty.refined.refine_batch`). Both reach the same least-squares solution of every
        draw (to the stopping rule's tolerance, far below 0.01 u); kept to compare them.
    """

    iterations: int = 100_000
    coverage: float = 0.95
    interval: IntervalKind = "symmetric"
    adaptive: bool = False
    ndig: int = 2
    max_draws: int = 2_000_000
    batch_size: int = 2_000
    block_size: int | None = None
    workers: int = 1
    scheduler: str | None = None
    keep_draws: bool = True
    refined_solver: RefinedSolver = "gauss-newton"

    def __post_init__(self):
        if self.refined_solver not in REFINED_SOLVERS:
            raise InputError(f"`refined_solver` must be one of {REFINED_SOLVERS}; got {self.refined_solver!r}")
        for name in ("iterations", "ndig", "max_draws", "batch_size", "block_size", "workers"):
            value = getattr(self, name)
            if name == "block_size" and value is None:
                continue
            check_count(value, name)
        object.__setattr__(self, "coverage", check_coverage(self.coverage))
        if self.interval not in INTERVAL_KINDS:
            raise InputError(f"`interval` must be one of {INTERVAL_KINDS}; got {self.interval!r}")
        smallest = math.ceil(1.0 / (1.0 - self.coverage)) + 1
        if not self.adaptive and self.iterations < smallest:
            raise InputError(
                f"`iterations` = {self.iterations} is too few for a {self.coverage:g} coverage interval: "
                f"at least {smallest} (JCGM 101 §7.2 recommends 10^4 or more)"
            )
        block = self.block_size or DEFAULT_BLOCK_SIZE
        if self.adaptive and self.max_draws < 2 * block:
            raise InputError(f"adaptive mode needs `max_draws` >= 2 blocks of {block}; got {self.max_draws}")


@dataclass(frozen=True, slots=True, kw_only=True)
class AdaptiveRecord:
    """How the adaptive procedure (JCGM 101 §7.9.4) ended.

    ``stability`` holds, per output quantity (identified parameters, joint-major, core units), twice
    the standard deviation of the block means of y, u(y), y_low and y_high (the quantities compared
    with ``tolerance``).
    """

    blocks: int
    stable: bool
    reason: str
    tolerance: np.ndarray
    stability: dict


@dataclass(frozen=True, slots=True, kw_only=True)
class MonteCarloResult:
    """Monte Carlo uncertainty of every parameter (core units: mm, rad).

    Attributes
    ----------
    robot : RobotModel
    settings : MonteCarloSettings
    seed : int
    n_draws : int
    summary : SampleSummary
        Per parameter (arrays of shape (n_joints, 5)): mean, u, both intervals of the draws, min, max.
        The interval for the measurand is :meth:`interval` (the draws' interval moved by twice the bias
        against :attr:`centre`); :meth:`draws_interval` and :attr:`bias` beside it.
    identified : ndarray of bool, shape (n_joints, 5)
        Parameters CPA determines; the others are nominal in every draw (u = 0).
    covariance, correlation : ndarray, shape (n_params, n_params)
        Over every parameter, joint-major (zeros / NaN-free identity rows for fixed ones).
    draws : ndarray, shape (n_draws, n_joints, 5) or None
    noise_free_values : ndarray, shape (n_joints, 5)
        The model value ``f(x)``: CPA (or its refinement) of the noise-free capture [mm, rad].
    true_values : ndarray, shape (n_joints, 5)
        The robot the capture was simulated from [mm, rad]: the estimate when the Monte Carlo states the
        uncertainty of a calibration (see :attr:`centre`).
    adaptive : AdaptiveRecord or None
    linearised : LinearisedResult or None
    timings_s : dict
    success : bool
        False when the adaptive mode did not stabilise or more than 0.1 % of the draws failed.
    message : str
    model : {"cpa", "refined"}
        The model the draws belong to (capture -> CPA, or capture -> CPA -> refinement).
    criterion : {"points", "distances"} or None
        The refinement objective (``model="refined"``).
    n_failed : int
        Draws whose refinement did not converge: counted here, left out of every statistic.
    joint_model : JointModel or None
        An extended refined model's joint model (values: the noise-free refinement's); None otherwise.
    extra_draws : ndarray, shape (n_draws, m), or None
        Its values in every draw [rad/(N m), rad] (kept with ``keep_draws``).
    extra_summary : SampleSummary or None
        Their statistics (mean, u, intervals of the draws), arrays of shape (m,).
    extra_identified : ndarray of bool, shape (m,)
        Joint-model values the refinement estimates (the others stay 0 in every draw).
    extra_true : ndarray, shape (m,)
        The values of the robot the capture was simulated from (the centre of :meth:`extra_interval`).
    correction_shifts : ndarray, shape (k, 5 n + m), or None
        How the bias moves with each measured joint error of stated uncertainty
        (:func:`correction_shifts`): the bias correction's uncertainty, :attr:`correction_u`.
    """

    robot: RobotModel
    settings: MonteCarloSettings
    seed: int
    n_draws: int
    summary: SampleSummary
    identified: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    draws: np.ndarray | None
    noise_free_values: np.ndarray
    true_values: np.ndarray
    adaptive: AdaptiveRecord | None = None
    linearised: LinearisedResult | None = None
    timings_s: dict = field(default_factory=dict)
    success: bool = True
    message: str = ""
    model: str = "cpa"
    criterion: str | None = None
    n_failed: int = 0
    joint_model: JointModel | None = None
    extra_draws: np.ndarray | None = None
    extra_summary: SampleSummary | None = None
    extra_identified: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    extra_true: np.ndarray = field(default_factory=lambda: np.zeros(0))
    correction_shifts: np.ndarray | None = None

    @property
    def is_extended(self) -> bool:
        """Whether the draws carry an extended model's joint-model values (:attr:`extra_draws`)."""
        return self.joint_model is not None

    def __repr__(self) -> str:
        u = self.summary.std_uncertainty[self.identified]
        extended = "" if self.joint_model is None else f", joint model {', '.join(self.joint_model.names)}"
        return (
            f"MonteCarloResult({self.model} model{extended}, {self.n_draws:,} draws, seed {self.seed}, "
            f"{int(self.identified.sum())} parameters, largest u {u.max() if u.size else 0.0:.3g} (mm or rad))"
        )

    def extra_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """The coverage interval for the measurand of every joint-model value ``(m,)`` [rad/(N m), rad]: the
        draws' interval moved by twice the bias against :attr:`extra_true`, as :meth:`interval`."""
        summary = self.extra_summary
        if summary is None:
            raise InputError("extra_interval: the draws of a geometric model carry no joint-model values")
        low, high = summary.interval(self.settings.interval)
        moved_low, moved_high = bias_corrected_interval(low, high, summary.mean, self.extra_true)
        moved_low, moved_high = widened_interval(
            moved_low, moved_high, self.extra_true - self.extra_bias, self.extra_correction_u, self.settings.coverage
        )
        return np.where(self.extra_identified, moved_low, low), np.where(self.extra_identified, moved_high, high)

    @property
    def correction_u(self) -> np.ndarray:
        """Standard uncertainty of the bias correction ``(n_joints, 5)`` [mm, rad]: the root sum of squares of
        :attr:`correction_shifts` (the measured joint errors' uncertainty, propagated); zeros without them."""
        n = self.robot.n_joints
        if self.correction_shifts is None or self.correction_shifts.size == 0:
            return np.zeros((n, 5))
        u = np.sqrt(np.sum(self.correction_shifts[:, : 5 * n] ** 2, axis=0)).reshape(n, 5)
        return np.where(self.identified, u, 0.0)

    @property
    def extra_correction_u(self) -> np.ndarray:
        """The same for the joint-model values ``(m,)``."""
        n, m = self.robot.n_joints, self.extra_true.size
        if self.correction_shifts is None or self.correction_shifts.size == 0 or m == 0:
            return np.zeros(m)
        return np.sqrt(np.sum(self.correction_shifts[:, 5 * n :] ** 2, axis=0))

    @property
    def combined_u(self) -> np.ndarray:
        """The standard uncertainty of the deployed values ``(n_joints, 5)``: the draws' u and the bias
        correction's :attr:`correction_u` in quadrature [mm, rad]."""
        return np.hypot(self.summary.std_uncertainty, self.correction_u)

    @property
    def centre(self) -> np.ndarray:
        """The parameters the capture was simulated at [mm, rad], shape (n_joints, 5): ``true_values``.

        In a calibration this is the estimate (``robotcal run`` and ``--true-params ESTIMATE`` simulate at
        the CPA or refined estimate); in a planning study the nominal robot or an assumed truth. Angles are
        taken within +-180 deg of the draws' mean, so that the bias of :meth:`interval` never straddles a
        turn.
        """
        mean = self.summary.mean
        offset = self.true_values - mean
        angles = list(ANGLE_COLUMNS)
        offset[:, angles] = np.remainder(offset[:, angles] + math.pi, 2.0 * math.pi) - math.pi
        return mean + offset

    def draws_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """The coverage interval of the draws themselves (the one chosen in the settings, JCGM 101 §7.7),
        ``(low, high)`` of shape (n_joints, 5): where the estimate falls when the robot is :attr:`centre`
        (the thesis's "95 % limits", Tables 5.6/5.7)."""
        return self.summary.interval(self.settings.interval)

    def interval(self) -> tuple[np.ndarray, np.ndarray]:
        """The coverage interval for the measurand, ``(low, high)`` of shape (n_joints, 5) [mm, rad].

        The draws' interval moved by twice the bias, ``[low - 2 b, high - 2 b]`` with ``b`` = :attr:`bias`
        (:func:`robotcal.uncertainty.statistics.bias_corrected_interval`): draws simulated at an estimate
        are centred on estimate + bias, i.e. on truth + 2 bias; moved, the interval is centred on the
        bias-corrected estimate and keeps the draws' shape. Where the bias comes from measured joint errors of
        stated uncertainty, each end is moved away from that centre to cover the bias correction's uncertainty too
        (:attr:`correction_u`, :func:`robotcal.uncertainty.statistics.widened_interval`). Parameters the model does
        not determine (``identified`` False) keep the value they have in every draw.
        """
        low, high = self.draws_interval()
        corrected_low, corrected_high = bias_corrected_interval(low, high, self.summary.mean, self.centre)
        corrected_low, corrected_high = widened_interval(
            corrected_low, corrected_high, self.centre - self.bias, self.correction_u, self.settings.coverage
        )
        return np.where(self.identified, corrected_low, low), np.where(self.identified, corrected_high, high)

    @property
    def bias(self) -> np.ndarray:
        """The estimator's bias at :attr:`centre`, ``mean - centre`` [mm, rad], shape (n_joints, 5); 0 where
        a parameter is not determined by the model."""
        return np.where(self.identified, self.summary.mean - self.centre, 0.0)

    @property
    def extra_bias(self) -> np.ndarray:
        """The same for the joint-model values, ``mean - extra_true`` ``(m,)``; 0 where not estimated."""
        if self.extra_summary is None:
            return np.zeros(0)
        return np.where(self.extra_identified, self.extra_summary.mean - self.extra_true, 0.0)

    def corrected(self, estimate: ParameterSet) -> ParameterSet:
        """``estimate`` corrected for the bias the draws measure: the value to deploy (docs/uncertainty.md,
        "The measurand").

        The Monte Carlo simulated at ``estimate`` (its :attr:`centre`) measures the estimator's bias there,
        which the capture's recognised systematic effects (the joint errors the joints stage measured) and the
        estimator's non-linearity give; GUM (JCGM 100 §3.2.4) corrects a result for recognised systematic
        effects. The corrected values ``centre - bias`` (and ``extra_true - extra_bias`` for the joint model)
        are the centre of :meth:`interval` and :meth:`extra_interval`, which therefore contain them.
        """
        if estimate.robot.n_joints != self.robot.n_joints:
            raise InputError(f"`estimate` has {estimate.robot.n_joints} joints; the draws {self.robot.n_joints}")
        values = np.where(self.identified, self.centre - self.bias, estimate.values)
        joint_model = estimate.joint_model
        if self.joint_model is not None and joint_model is not None and joint_model.names == self.joint_model.names:
            joint_model = joint_model.with_values(joint_model.values - self.extra_bias)
        return dataclasses.replace(estimate, values=values, joint_model=joint_model)


# ------------------------------------------------------------------------------------ statistics


def _flat_identified(values: np.ndarray, identified: np.ndarray) -> np.ndarray:
    return values.reshape(values.shape[0], -1)[:, identified.reshape(-1)]


def _block_estimates(
    values: np.ndarray, identified: np.ndarray, coverage: float, interval: IntervalKind
) -> np.ndarray:
    """``(4, n_identified)``: y, u(y), y_low, y_high of one block (JCGM 101 §7.9.4 c)."""
    flat = _flat_identified(values, identified)
    low, high = coverage_interval(flat, coverage, interval)
    return np.stack([flat.mean(axis=0), flat.std(axis=0, ddof=1), low, high])


def _adaptive_check(estimates: list[np.ndarray], u_all: np.ndarray, ndig: int) -> tuple[bool, dict, np.ndarray]:
    """JCGM 101 §7.9.4 d-g: twice the standard deviation of the mean of the block estimates vs delta,
    delta from u(y) of all draws so far (``u_all``)."""
    stack = np.stack(estimates)  # (h, 4, n_identified)
    h = stack.shape[0]
    spread = 2.0 * stack.std(axis=0, ddof=1) / math.sqrt(h)
    tolerance = numerical_tolerance(u_all, ndig)
    stable = bool(np.all(spread <= tolerance))
    stability = {name: spread[row] for row, name in enumerate(("mean", "std_uncertainty", "low", "high"))}
    return stable, stability, tolerance


class _PooledMoments:
    """Running mean and sum of squared deviations over blocks (Chan et al.'s pairwise update)."""

    def __init__(self):
        self.count, self.mean, self.m2 = 0, None, None

    def add(self, values: np.ndarray) -> None:
        n = values.shape[0]
        mean = values.mean(axis=0)
        m2 = ((values - mean) ** 2).sum(axis=0)
        if self.count == 0:
            self.count, self.mean, self.m2 = n, mean, m2
            return
        total = self.count + n
        delta = mean - self.mean
        self.mean = self.mean + delta * n / total
        self.m2 = self.m2 + m2 + delta**2 * self.count * n / total
        self.count = total

    def std(self) -> np.ndarray:
        return np.sqrt(self.m2 / (self.count - 1))


def draw_covariance(values: np.ndarray, identified: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Covariance and correlation ``(n_params, n_params)`` of draws ``(n_draws, n_joints, 5)`` over the
    ``identified`` parameters (zero rows and identity correlation for the others)."""
    flat = values.reshape(values.shape[0], -1)
    n_params = flat.shape[1]
    mask = identified.reshape(-1)
    covariance = np.zeros((n_params, n_params))
    correlation = np.eye(n_params)
    if mask.sum() >= 1:
        # np.cov(free, rowvar=False) without BLAS: a multi-threaded BLAS on a busy machine spends its threads
        # waiting on this thin (p x M) product, which einsum does in one pass
        centred = np.ascontiguousarray(flat[:, mask].T)
        centred -= centred.mean(axis=1, keepdims=True)
        sub = np.atleast_2d(np.einsum("ik,jk->ij", centred, centred) / (flat.shape[0] - 1))
        covariance[np.ix_(mask, mask)] = sub
        scale = np.sqrt(np.diag(sub))
        with np.errstate(divide="ignore", invalid="ignore"):
            corr = sub / np.outer(scale, scale)
        corr[~np.isfinite(corr)] = 0.0
        np.fill_diagonal(corr, 1.0)
        correlation[np.ix_(mask, mask)] = corr
    return covariance, correlation


# ---------------------------------------------------------------------------------------- driver


def run_monte_carlo(
    problem: MonteCarloProblem,
    settings: MonteCarloSettings | None = None,
    *,
    seed: int,
    linearised: bool = True,
    progress: ProgressCallback | None = None,
) -> MonteCarloResult:
    """Monte Carlo propagation of the capture noise to the CPA parameters (JCGM 101 §7).

    Parameters
    ----------
    problem : MonteCarloProblem
        From :func:`prepare_monte_carlo`.
    settings : MonteCarloSettings, optional
    seed : int
        Seed of the whole run (blocks are seeded from it, see the module notes). Recorded.
    linearised : bool
        Also compute the GUM law-of-propagation result and the JCGM 101 §8 comparison.
    progress : callable, optional
        Called as ``progress(draws_done, draws_total_or_None)`` after every block.

    Returns
    -------
    MonteCarloResult
    """
    with single_blas_thread():
        settings = MonteCarloSettings() if settings is None else settings
        block_size = settings.block_size
        if block_size is None:
            fixed_refined = problem.model == "refined" and not settings.adaptive
            block_size = REFINED_BLOCK_SIZE if fixed_refined else DEFAULT_BLOCK_SIZE
            settings = dataclasses.replace(settings, block_size=block_size)
        seed = check_count(seed, "seed", minimum=0)
        started = time.perf_counter()
        n = problem.robot.n_joints
        capacity = settings.max_draws if settings.adaptive else settings.iterations
        # Filled block by block; untouched pages of np.empty cost no memory, and no concatenation copy is made.
        store = _Store(np.empty((capacity, 5 * n + problem.n_extra)))
        adaptive_record = None
        with open_executor(workers=settings.workers, scheduler=settings.scheduler) as executor:
            runner = _BlockRunner(problem, seed, settings, executor)
            if not settings.adaptive:
                blocks = list(enumerate(_block_sizes(settings.iterations, block_size)))
                for _, values in runner.map(blocks):
                    store.add(values)
                    if progress is not None:
                        progress(store.computed, settings.iterations)
            else:
                adaptive_record = _run_adaptive(runner, settings, problem.identified_all, store, progress)
        if store.done < 2:
            raise RobotcalError(f"only {store.done} of {store.computed} draws converged: no statistics can be made")
        return _result(problem, settings, seed, store, adaptive_record, linearised=linearised, started=started)


def _result(problem, settings, seed, store, adaptive_record, *, linearised: bool, started: float) -> MonteCarloResult:
    """The statistics of the draws kept in ``store`` (JCGM 101 §7.6-7.7) and, if asked, the linearised comparison."""
    n, done = problem.robot.n_joints, store.done
    draws = store.values[:done, : 5 * n].reshape(done, n, 5)
    extras = store.values[:done, 5 * n :]
    draw_time = time.perf_counter() - started
    summary_start = time.perf_counter()
    summary = summarize_draws(draws, settings.coverage)
    extra_summary = summarize_draws(extras, settings.coverage) if problem.n_extra else None
    timings = {"draws": draw_time, "statistics": time.perf_counter() - summary_start}
    linear = None
    if linearised:
        linear_start = time.perf_counter()
        linear = linearised_uncertainty(problem, summary, settings)
        timings["linearised"] = time.perf_counter() - linear_start
    return kept_draws_result(
        draws, summary, problem.identified, settings, failed=store.failed, computed=store.computed,
        failure="did not converge", started=started, timings_s=timings, robot=problem.robot, seed=seed,
        noise_free_values=problem.noise_free_values, true_values=problem.true_parameters.values,
        adaptive=adaptive_record, linearised=linear, model=problem.model,
        criterion=None if problem.refined is None else problem.refined.criterion,
        joint_model=None if not problem.n_extra else problem.refined.joint_model,
        extra_draws=extras if problem.n_extra and settings.keep_draws else None, extra_summary=extra_summary,
        extra_identified=problem.identified_all[5 * n :], extra_true=problem.extra_true,
        correction_shifts=correction_shifts(problem),
    )  # fmt: skip


def kept_draws_result(
    draws: np.ndarray,
    summary: SampleSummary,
    identified: np.ndarray,
    settings: MonteCarloSettings,
    *,
    failed: int,
    computed: int,
    failure: str,
    started: float,
    timings_s: dict,
    adaptive: AdaptiveRecord | None = None,
    **fields: Any,
) -> MonteCarloResult:
    """The :class:`MonteCarloResult` of the kept ``draws`` (n_draws, n_joints, 5) and their ``summary``: of the
    simulated Monte Carlo and of the measured one (:mod:`robotcal.uncertainty.measured`).

    Adds their covariance and correlation over the ``identified`` parameters, the draws themselves with
    ``settings.keep_draws``, the total time since ``started`` to ``timings_s``, and the verdict: the message counts
    the draws and the ``failed`` of ``computed`` that ``failure`` (left out of every statistic); success is at
    most 0.1 % of them failed and, with an ``adaptive`` record, the procedure stabilised. ``fields``: the result's
    other fields.
    """
    covariance, correlation = draw_covariance(draws, identified)
    message = f"{draws.shape[0]} draws"
    if failed:
        message += (
            f"; {failed} of {computed} draws {failure} and are left out of the statistics ({failed / computed:.2%})"
        )
    success = failed <= 0.001 * computed
    if adaptive is not None:
        message += f"; adaptive: {adaptive.reason}"
        success = success and adaptive.stable
    return MonteCarloResult(
        settings=settings,
        n_draws=int(draws.shape[0]),
        summary=summary,
        identified=identified,
        covariance=covariance,
        correlation=correlation,
        draws=draws if settings.keep_draws else None,
        adaptive=adaptive,
        timings_s={**timings_s, "total": time.perf_counter() - started},
        success=success,
        message=message,
        n_failed=failed,
        **fields,
    )


def correction_shifts(problem: MonteCarloProblem) -> np.ndarray | None:
    """:attr:`MonteCarloResult.correction_shifts`: the noise-free capture with each source of the measured joint
    errors' uncertainty (:attr:`MonteCarloProblem.source_points`), solved as a draw is, minus the noise-free
    solution: the measured inputs' uncertainty propagated linearly to the bias (JCGM 100 §5.1.2). None without
    sources."""
    if problem.source_points.size == 0:
        return None
    values = solve_points(problem, np.concatenate([problem.exact_points[None], problem.source_points]))
    return values[1:] - values[0]


class _Store:
    """Draws kept so far; a draw that failed (NaN row: a refinement that did not converge) is counted, not kept."""

    def __init__(self, values: np.ndarray):
        self.values, self.done, self.computed, self.failed = values, 0, 0, 0

    def add(self, values: np.ndarray) -> np.ndarray:
        good = np.isfinite(values).all(axis=1)
        kept = values if good.all() else values[good]
        self.values[self.done : self.done + kept.shape[0]] = kept
        self.done += kept.shape[0]
        self.computed += values.shape[0]
        self.failed += int((~good).sum())
        return kept


def _run_adaptive(runner: _BlockRunner, settings, identified, store: _Store, progress) -> AdaptiveRecord:
    """Blocks of ``block_size`` until stable (JCGM 101 §7.9.4), computed ``workers`` at a time.

    Stability is checked after each block in block order, so the stopping block, and hence the
    result, do not depend on the number of workers (blocks computed past it are discarded). Draws
    that failed are left out of their block's estimates. The kept draws are in ``store``.
    """
    size = settings.block_size
    max_blocks = settings.max_draws // size
    estimates: list[np.ndarray] = []
    moments = _PooledMoments()
    next_block = 0
    workers = max(settings.workers, getattr(runner.executor, "workers", 1))
    while next_block < max_blocks:
        wave = [(b, size) for b in range(next_block, min(next_block + workers, max_blocks))]
        next_block += len(wave)
        for block, values in runner.map(wave):
            kept = store.add(values)
            estimates.append(_block_estimates(kept, identified, settings.coverage, settings.interval))
            moments.add(_flat_identified(kept, identified))
            if progress is not None:
                progress(store.computed, None)
            if len(estimates) < 2:
                continue
            stable, stability, tolerance = _adaptive_check(estimates, moments.std(), settings.ndig)
            if stable:
                reason = (
                    f"stable after {block + 1} blocks of {size}: mean, u and both {settings.interval} "
                    f"interval ends within the numerical tolerance of ndig = {settings.ndig}"
                )
                return AdaptiveRecord(
                    blocks=block + 1, stable=True, reason=reason, tolerance=tolerance, stability=stability
                )
    reason = f"max_draws = {settings.max_draws} reached before the results were stable to ndig = {settings.ndig}"
    return AdaptiveRecord(blocks=max_blocks, stable=False, reason=reason, tolerance=tolerance, stability=stability)


# ------------------------------------------------------------------------------------ linearised


def linearised_uncertainty(
    problem: MonteCarloProblem, summary: SampleSummary | None = None, settings: MonteCarloSettings | None = None
) -> LinearisedResult:
    """GUM law of propagation: ``U_y = J U_x J^T`` with J the Jacobian of CPA w.r.t. the measured points.

    J is computed by central differences, all ``2 x 3 n_points`` perturbed captures in one batched
    CPA call, with a step of 1e-3 mm (CPA is exact to ~1e-12 mm, so the truncation and rounding
    errors are ~1e-6 and ~1e-9 relative). Only instrument noise enters U_x (independent coordinates);
    a random joint-error part, if the scenario has one, is not linearised (the Monte Carlo covers it).
    For the refined model (``problem.refined``) the estimated parameters take the refinement's
    first-order covariance at the noise-free solution, ``(J^T J)^-1 J^T G U_x G^T J (J^T J)^-1``
    (:func:`robotcal.uncertainty.refined.refined_covariance`): the least-squares estimator
    linearised in the measured coordinates, whatever start CPA gives it.

    When ``summary`` is given, the JCGM 101 §8.2 comparison is made: the linearised interval
    ``f(x) -+ k_p u`` against the Monte Carlo interval chosen in ``settings``, endpoint by endpoint,
    within the numerical tolerance of ``settings.ndig`` significant digits of the linearised u.
    """
    settings = MonteCarloSettings() if settings is None else settings
    step = 1e-3
    covariance = _cpa_covariance(problem, step)
    if problem.refined is not None:
        covariance = _refined_full_covariance(problem, covariance)
    n_joints = problem.robot.n_joints
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None)).reshape(n_joints, 5)
    return linearised_result(
        estimate=problem.noise_free_values,
        covariance=covariance,
        std=std,
        tolerance=numerical_tolerance(std, settings.ndig),
        coverage=settings.coverage,
        drawn=None if summary is None else summary.interval(settings.interval),
        determined=problem.identified,
        step_mm=step,
    )
