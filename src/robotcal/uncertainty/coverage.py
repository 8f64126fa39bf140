"""Coverage of the stated 95 % intervals, proven on repeated simulated captures of one known truth.

An uncertainty statement is only as good as its coverage: over many independent captures of the same
robot, the stated 95 % interval must contain the true value 95 % of the time. :func:`coverage_study`
simulates ``captures`` independent captures of one fixed (perturbed) truth and, for each, builds every
interval a user can be given:

``cpa-mc``
    The Monte Carlo of the CPA parameters (thesis ch. 5.2.3), **simulated at the CPA estimate of that
    capture**, as ``robotcal run`` does: the noise-free capture is simulated with the estimate as the
    robot, ``draws`` noisy copies are identified, and the stated interval is the draws' symmetric 95 %
    interval moved by twice the Monte Carlo's bias, ``[q_low - 2 b, q_high - 2 b]`` with
    ``b = mean - estimate`` (:meth:`~robotcal.uncertainty.montecarlo.MonteCarloResult.interval`). The
    truth is unknown to a user, so the estimate is the only place a Monte Carlo can be simulated at;
    its draws scatter around estimate + bias, i.e. around truth + 2 bias, and the move takes the bias
    off again.
``refined-mc``
    The same for the deployed model: capture -> CPA -> refinement per draw, simulated at the refined
    estimate of that capture (the robot simulated with the refined parameters).
``refined-linearised``
    The refinement's own linearised interval, refined +- z u with u from ``refine_parameters``'
    covariance (z = 1.96 at 95 %).

For each Monte Carlo the draws' own percentile interval (``q_low .. q_high``, what robotcal stated
before issue 24) is checked too (:attr:`CoverageStudy.contained_draws`): it is what shows the double
bias, and the record of each capture's estimate, bias, u and draws' interval lets any other interval
be checked on the same captures. Each Monte Carlo also checks the TCP: the 95 % position ellipsoid of
the draws at a pose (``(x - mean)^T V^-1 (x - mean) <= k_p^2``, the Monte Carlo region of JCGM 102
§7.7.2), as ``robotcal tcp`` states it, must contain the true TCP position; the same ellipsoid moved by
twice the TCP's bias (centre ``2 T(y) - mean``) is checked beside it (docs/uncertainty.md says why the
TCP region is not moved).

The empirical coverage of each parameter is the fraction of captures whose interval contains the
truth; with K captures and a true coverage of p it is binomial, so it must fall in the 99 %
binomial band ``binom.interval(0.99, K, p) / K`` (0.917..0.980 at K = 300).

References
----------
JCGM 101:2008 §7.7 (coverage intervals), §8 (validation); JCGM 102:2011 §6.5.3 and §7.7.2 (ellipsoids);
Davison & Hinkley (1997) §5.2 (bootstrap intervals).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from statistics import NormalDist

import numpy as np

from robotcal.errors import InputError, check_count
from robotcal.execution import single_blas_thread
from robotcal.identification.cpa import CPAOptions
from robotcal.instruments import Instrument
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.simulation.generator import JointErrorModel
from robotcal.simulation.plan import CapturePlan

__all__ = [
    "COVERAGE_METHODS",
    "CoverageStudy",
    "ExtendedCoverage",
    "coverage_study",
    "extended_coverage_study",
    "binomial_band",
]

#: The intervals checked, in table order.
COVERAGE_METHODS = ("cpa-mc", "refined-mc", "refined-linearised")


def binomial_band(captures: int, coverage: float = 0.95, confidence: float = 0.99) -> tuple[float, float]:
    """The ``confidence`` band of the empirical coverage of ``captures`` trials of probability ``coverage``."""
    from scipy.stats import binom  # scipy.stats is slow to import: only when a study runs

    low, high = binom.interval(confidence, captures, coverage)
    return float(low) / captures, float(high) / captures


@dataclass(frozen=True, slots=True, kw_only=True)
class CoverageStudy:
    """Outcome of :func:`coverage_study`.

    Attributes
    ----------
    truth : ParameterSet
        The fixed robot every capture was simulated from [mm, rad].
    names : tuple of str
        Parameters checked (those every method estimates in every capture), joint-major.
    captures, draws : int
        K captures; Monte Carlo draws per capture and model.
    coverage : float
        Nominal coverage probability p of the intervals.
    band : tuple of float
        99 % binomial band of the empirical coverage at K captures.
    contained : dict of str to ndarray of bool, shape (captures, n_names)
        Whether each method's stated interval contained the truth, per capture and parameter (the Monte
        Carlos: the bias-corrected interval of ``MonteCarloResult.interval``).
    contained_draws : dict of str to ndarray of bool, shape (captures, n_names)
        The same for the Monte Carlos' draws' own percentile interval (``draws_interval``), which adds
        the estimator's bias twice.
    tcp_contained : dict of str to ndarray of bool, shape (captures,)
        Whether each Monte Carlo's 95 % TCP position ellipsoid (around the draws' mean, as robotcal
        states it) contained the true TCP.
    tcp_contained_corrected : dict of str to ndarray of bool, shape (captures,)
        The same for that ellipsoid moved by twice the TCP's bias (centre ``2 T(estimate) - mean``).
    std_uncertainty : dict of str to ndarray, shape (captures, n_names)
        The stated u of each method [mm, rad].
    bias : dict of str to ndarray, shape (captures, n_names)
        Each Monte Carlo's bias estimate, mean of the draws minus the estimate it was simulated at [mm, rad].
    centre, draws_low, draws_high : dict of str to ndarray, shape (captures, n_names)
        Each Monte Carlo's estimate (where it was simulated) and its draws' interval [mm, rad]: with
        ``bias`` and ``std_uncertainty``, enough to check any other interval built from them.
    error : dict of str to ndarray, shape (captures, n_names)
        Estimate minus truth [mm, rad] (``cpa`` and ``refined``).
    seed : int
    seconds : float
    """

    truth: ParameterSet
    names: tuple[str, ...]
    captures: int
    draws: int
    coverage: float
    band: tuple[float, float]
    contained: dict
    tcp_contained: dict
    std_uncertainty: dict
    error: dict
    contained_draws: dict
    tcp_contained_corrected: dict
    bias: dict
    centre: dict
    draws_low: dict
    draws_high: dict
    seed: int
    seconds: float

    def empirical(self, method: str, *, draws: bool = False) -> np.ndarray:
        """Empirical coverage per parameter, shape (n_names,); ``draws=True``: of the draws' own interval."""
        return (self.contained_draws if draws else self.contained)[method].mean(axis=0)

    def tcp_empirical(self, method: str, *, corrected: bool = False) -> float:
        """Empirical coverage of the TCP ellipsoid; ``corrected=True``: of the one moved by twice the bias."""
        return float((self.tcp_contained_corrected if corrected else self.tcp_contained)[method].mean())

    def in_band(self, method: str, *, draws: bool = False) -> np.ndarray:
        low, high = self.band
        value = self.empirical(method, draws=draws)
        return (value >= low - 1e-12) & (value <= high + 1e-12)


def _inside(low: np.ndarray, high: np.ndarray, truth: np.ndarray, checked: np.ndarray) -> np.ndarray:
    """Whether ``low <= truth <= high`` for the ``checked`` parameters (``truth`` already reduced to them)."""
    return (low[checked] <= truth) & (truth <= high[checked])


def _inside_ellipsoid(positions: np.ndarray, point: np.ndarray, coverage: float) -> bool:
    """Whether ``point`` lies in the Monte Carlo coverage ellipsoid of position draws ``(M, 3)``.

    The region is ``(x - mean)^T V^-1 (x - mean) <= k_p^2`` with V the draws' covariance and ``k_p^2``
    the ``round(p M)``-th smallest squared Mahalanobis distance of the draws themselves (JCGM 102 §7.7.2):
    it holds a fraction p of the draws whatever their distribution, where the chi-squared scale of
    §6.5.3 assumes a Gaussian position (the CPA draws are heavy-tailed, and the chi-squared ellipsoid
    then over-covers).
    """
    mean = positions.mean(axis=0)
    centred = positions - mean
    covariance = centred.T @ centred / (positions.shape[0] - 1)
    inverse = np.linalg.inv(covariance)
    distances = np.einsum("mi,ij,mj->m", centred, inverse, centred)
    rank = min(max(int(np.floor(coverage * positions.shape[0] + 0.5)), 1), positions.shape[0])
    scale2 = np.sort(distances)[rank - 1]
    offset = point - mean
    return float(offset @ inverse @ offset) <= scale2


def coverage_study(
    robot: RobotModel,
    plan: CapturePlan,
    instrument: Instrument,
    truth: ParameterSet,
    *,
    captures: int,
    draws: int,
    tracker_from_base=None,
    options: CPAOptions | None = None,
    joint_errors: JointErrorModel | None = None,
    joint_limits: str = "warn",
    methods=COVERAGE_METHODS,
    criterion: str = "points",
    coverage: float = 0.95,
    tcp_readings=None,
    rng: np.random.Generator | int | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured_joint_errors: bool = False,
) -> CoverageStudy:
    """Empirical coverage of the CPA and refined-model intervals over repeated simulated captures.

    Parameters
    ----------
    robot, plan, instrument : RobotModel, CapturePlan, Instrument
        The robot, its capture plan (with the reflector) and the instrument of every capture.
    truth : ParameterSet
        The fixed true robot [mm, rad].
    captures : int
        K independent captures (>= 10; 300 gives the 0.917..0.980 band).
    draws : int
        Monte Carlo draws per capture and model (>= 200).
    tracker_from_base : array_like, shape (4, 4), optional
        The base frame (default identity); held by CPA and the refinement when ``options.base_frame`` is
        "given", else registered.
    options : CPAOptions, optional
    joint_errors : JointErrorModel, optional
    joint_limits : {"warn", "error", "ignore"}
    methods : sequence of str
        Subset of :data:`COVERAGE_METHODS`.
    criterion : {"points", "distances"}
        Refinement criterion of the refined methods.
    coverage : float
        Coverage probability p.
    tcp_readings : array_like, shape (n_joints,), optional
        Controller readings [rad] of the pose where the TCP ellipsoid is checked (needed by the Monte Carlo
        methods).
    rng : numpy.random.Generator or int or None
        Seeds every capture (one child seed per capture) and every Monte Carlo.
    progress : callable, optional
        ``progress(done, captures)`` after each capture.
    measured_joint_errors : bool
        Each capture's Monte Carlos simulate the joint errors that capture's joints analysis measures
        (:func:`robotcal.uncertainty.joint_errors.measured_joint_errors`), as ``robotcal run`` does, not
        ``joint_errors`` (which then only make the captures).
    """
    with single_blas_thread():
        from robotcal.uncertainty.montecarlo import MonteCarloSettings
        from robotcal.uncertainty.tcp import tcp_coordinates

        setup = _Setup.of(robot, plan, instrument, tracker_from_base, options, joint_errors, joint_limits, criterion)
        methods = tuple(methods)
        unknown = [m for m in methods if m not in COVERAGE_METHODS]
        if unknown or not methods:
            raise InputError(f"`methods` must be a non-empty subset of {COVERAGE_METHODS}; got {methods!r}")
        _check_size(captures, draws)
        began = time.perf_counter()
        seed = _study_seed(rng)
        children = np.random.SeedSequence(seed).spawn(captures)
        if tcp_readings is None and any(m.endswith("-mc") for m in methods):
            raise InputError("the coverage study checks the TCP ellipsoid at a pose: give `tcp_readings`")
        tcp = None
        if tcp_readings is not None:
            q_tcp = truth.model_joint_variables(np.atleast_2d(np.asarray(tcp_readings, dtype=float)))[:1]
            tcp = (q_tcp, tcp_coordinates(truth.values, q_tcp)[0, :3])
        z = NormalDist().inv_cdf(0.5 + coverage / 2.0)
        settings = MonteCarloSettings(
            iterations=draws, coverage=coverage, block_size=draws, batch_size=min(draws, 2000)
        )
        records = _Records(methods)
        checked = None
        for k, child in enumerate(children):
            capture_seed, mc_seed = (int(s.generate_state(1, np.uint64)[0] % (2**63)) for s in child.spawn(2))
            cpa, refined, capture = _estimates(setup, truth, capture_seed)
            checked = _same_set(cpa.identified & refined.identifiability.free, checked, k, robot.parameter_names)
            records.error["cpa"].append((cpa.values - truth.values)[checked])
            records.error["refined"].append((refined.parameters.values - truth.values)[checked])
            for method in methods:
                if method == "refined-linearised":
                    u = refined.uncertainty.standard_uncertainty
                    interval, result = (refined.parameters.values - z * u, refined.parameters.values + z * u), None
                else:
                    centre = cpa if method == "cpa-mc" else refined.parameters
                    errors = _measured(setup, capture, centre) if measured_joint_errors else setup.joint_errors
                    result = _monte_carlo_at(setup, centre, method, settings, mc_seed, errors)
                    interval, u = result.interval(), result.summary.std_uncertainty
                records.add(method, interval, u, result, truth.values, checked, tcp, coverage)
            if progress is not None:
                progress(k + 1, captures)
        assert checked is not None  # set by the first capture (there are at least 10: _check_size)
        names = tuple(name for name, flag in zip(robot.parameter_names, checked.ravel(), strict=True) if flag)
        return records.study(truth=truth, names=names, captures=captures, draws=draws, coverage=coverage, seed=seed,
                             seconds=time.perf_counter() - began)  # fmt: skip


@dataclass(frozen=True, slots=True, kw_only=True)
class _Setup:
    """What every capture of a study shares: the robot, plan, instrument, base frame and identification."""

    robot: RobotModel
    plan: CapturePlan
    instrument: Instrument
    tracker_from_base: np.ndarray
    held_base: np.ndarray | None
    options: CPAOptions
    joint_errors: JointErrorModel | None
    joint_limits: str
    criterion: str

    @classmethod
    def of(cls, robot, plan, instrument, tracker_from_base, options, joint_errors, joint_limits, criterion):
        options = CPAOptions() if options is None else options
        tracker_from_base = np.eye(4) if tracker_from_base is None else np.asarray(tracker_from_base, dtype=float)
        held_base = tracker_from_base if options.base_frame == "given" else None
        return cls(
            robot=robot, plan=plan, instrument=instrument, tracker_from_base=tracker_from_base, held_base=held_base,
            options=options, joint_errors=joint_errors, joint_limits=joint_limits, criterion=criterion,
        )  # fmt: skip


def _check_size(captures, draws) -> None:
    check_count(captures, "captures", minimum=10)
    check_count(draws, "draws", minimum=200)


def _study_seed(rng) -> int:
    """The study's recorded seed: drawn from a Generator, fresh entropy for None, else the integer given."""
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(2**63 - 1))
    if rng is None:
        entropy = np.random.SeedSequence().entropy
        assert isinstance(entropy, int)  # fresh entropy is one integer
        return int(entropy % (2**63))
    return int(rng)


def _same_set(mask: np.ndarray, checked: np.ndarray | None, k: int, names) -> np.ndarray:
    """The set of parameters checked: the first capture's; every capture of one plan must determine the same (a
    different free set means a rank decision sat on a threshold, and the study would compare different things)."""
    if checked is None or np.array_equal(mask, checked):
        return mask
    changed = [n for n, a, b in zip(names, np.ravel(mask), np.ravel(checked), strict=True) if a != b]
    raise InputError(
        f"capture {k + 1} of the coverage study determines a different set of parameters ({', '.join(changed)}) "
        "than the first capture; the study needs one fixed set"
    )


def _estimates(setup: _Setup, truth: ParameterSet, capture_seed: int):
    """One simulated capture of ``truth``: its CPA parameters and its refinement."""
    from robotcal.identification.cpa import identify_cpa
    from robotcal.identification.refine import RefinementSettings, refine_parameters
    from robotcal.simulation.generator import simulate_capture

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture, _ = simulate_capture(
            setup.robot, setup.plan, setup.instrument, setup.tracker_from_base, true_parameters=truth,
            joint_errors=setup.joint_errors, joint_limits=setup.joint_limits, rng=np.random.default_rng(capture_seed),
        )  # fmt: skip
        cpa = identify_cpa(
            capture, setup.robot, setup.plan.reflector, tracker_from_base=setup.held_base, options=setup.options
        ).parameters
        refined = refine_parameters(
            capture, cpa, setup.plan.reflector, settings=RefinementSettings(criterion=setup.criterion),
            tracker_from_base=setup.held_base,
        )  # fmt: skip
    return cpa, refined, capture


def _measured(setup: _Setup, capture, centre: ParameterSet, calibration=None, diagnostics=None) -> JointErrorModel:
    """The joint errors the joints analysis of ``capture`` (``diagnostics`` where already made) measures, in the
    simulation's form at ``centre``, with their uncertainty (:class:`robotcal.uncertainty.joint_errors.
    MeasuredJointErrors`); ``calibration``: the refinement of circles and calibration poses whose residuals show
    what the circles cannot (:class:`robotcal.uncertainty.joint_errors.CalibrationFit`)."""
    from robotcal.uncertainty.joint_errors import measured_joint_errors

    method = setup.options.circle_fit
    diagnostics = _joints_analysis(setup, capture) if diagnostics is None else diagnostics
    return measured_joint_errors(
        diagnostics, centre, setup.plan, setup.tracker_from_base, circle_fit=method, calibration=calibration
    )


def _joints_analysis(setup: _Setup, capture):
    """The joints analysis of a capture (thesis ch. 4.6), as ``robotcal run``'s joints stage makes it."""
    from robotcal.diagnostics.joints import analyze_joints

    return analyze_joints(capture, backlash=setup.plan.bidirectional, method=setup.options.circle_fit)


def _stage_lash(diagnostics, structure):
    """``structure`` correcting the circles for the lash ``robotcal run`` corrects them for
    (:meth:`robotcal.diagnostics.joints.JointDiagnostics.lash_correction`)."""
    lash = diagnostics.lash_correction()
    return structure.with_backlash(lash, "the joints stage") if np.any(lash) else structure


def _monte_carlo_at(
    setup: _Setup, centre: ParameterSet, method: str, settings, seed: int, joint_errors=None
):
    """The Monte Carlo a user is given for one capture: simulated at its estimate ``centre`` (module notes), with
    ``joint_errors`` (measured ones with their uncertainty)."""
    from robotcal.uncertainty.montecarlo import prepare_monte_carlo, run_monte_carlo

    problem = prepare_monte_carlo(
        setup.robot, setup.plan, setup.instrument, setup.tracker_from_base, options=setup.options,
        true_parameters=centre, joint_errors=joint_errors, joint_limits=setup.joint_limits,
        model="cpa" if method == "cpa-mc" else "refined", criterion=setup.criterion,
    )  # fmt: skip
    return run_monte_carlo(problem, settings, seed=seed, linearised=False)


class _Records:
    """Each capture's record of a :func:`coverage_study`, method by method."""

    def __init__(self, methods: tuple[str, ...]):
        monte_carlos = [m for m in methods if m.endswith("-mc")]
        self.contained: dict[str, list[np.ndarray]] = {m: [] for m in methods}
        self.std: dict[str, list[np.ndarray]] = {m: [] for m in methods}
        self.error: dict[str, list[np.ndarray]] = {"cpa": [], "refined": []}
        names = ("contained_draws", "tcp_contained", "tcp_contained_corrected", "bias", "centre", "low", "high")
        self.mc: dict[str, dict[str, list]] = {name: {m: [] for m in monte_carlos} for name in names}

    def add(
        self, method: str, interval: tuple[np.ndarray, np.ndarray], u, result, truth_values, checked, tcp, coverage
    ) -> None:
        """One capture's interval (and, for a Monte Carlo, its draws' interval, bias and TCP ellipsoids)."""
        from robotcal.uncertainty.tcp import tcp_coordinates

        true_values = truth_values[checked]
        self.contained[method].append(_inside(*interval, true_values, checked))
        self.std[method].append(u[checked])
        if result is None:
            return
        low_draws, high_draws = result.draws_interval()
        record = self.mc
        record["contained_draws"][method].append(_inside(low_draws, high_draws, true_values, checked))
        record["bias"][method].append(result.bias[checked])
        record["centre"][method].append(result.centre[checked])
        record["low"][method].append(low_draws[checked])
        record["high"][method].append(high_draws[checked])
        q_tcp, true_tcp = tcp
        positions = tcp_coordinates(result.draws, q_tcp)[:, 0, :3]
        at_estimate = tcp_coordinates(result.centre, q_tcp)[0, :3]
        moved = positions + 2.0 * (at_estimate - positions.mean(axis=0))  # centre 2 T(y) - mean
        record["tcp_contained"][method].append(_inside_ellipsoid(positions, true_tcp, coverage))
        record["tcp_contained_corrected"][method].append(_inside_ellipsoid(moved, true_tcp, coverage))

    def study(self, **fields) -> CoverageStudy:
        def stacked(records: dict, dtype=None) -> dict:
            return {m: np.array(v, dtype=dtype) for m, v in records.items()}

        mc = self.mc
        return CoverageStudy(
            band=binomial_band(fields["captures"], fields["coverage"]),
            contained=stacked(self.contained, bool),
            contained_draws=stacked(mc["contained_draws"], bool),
            tcp_contained=stacked(mc["tcp_contained"], bool),
            tcp_contained_corrected=stacked(mc["tcp_contained_corrected"], bool),
            std_uncertainty=stacked(self.std),
            bias=stacked(mc["bias"]),
            centre=stacked(mc["centre"]),
            draws_low=stacked(mc["low"]),
            draws_high=stacked(mc["high"]),
            error=stacked(self.error),
            **fields,
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ExtendedCoverage:
    """Outcome of :func:`extended_coverage_study`: the deployed extended model's Monte Carlo intervals.

    Attributes
    ----------
    names : tuple of str
        The parameters and joint-model values checked (those every capture's refinement estimates).
    contained : ndarray of bool, shape (captures, n_names)
        Whether the interval for the measurand (:meth:`MonteCarloResult.interval`, :meth:`~MonteCarloResult.
        extra_interval`) contained the truth.
    contained_draws : ndarray of bool, shape (captures, n_names)
        The same for the draws' own interval.
    std_uncertainty, error : ndarray, shape (captures, n_names)
        The Monte Carlo's u and the refined estimate minus the truth [mm, rad, rad/(N m)].
    band : tuple of float
        The 99 % binomial band at K captures.
    """

    names: tuple[str, ...]
    captures: int
    draws: int
    coverage: float
    band: tuple[float, float]
    contained: np.ndarray
    contained_draws: np.ndarray
    std_uncertainty: np.ndarray
    error: np.ndarray
    seed: int
    seconds: float

    def empirical(self, *, draws: bool = False) -> np.ndarray:
        return (self.contained_draws if draws else self.contained).mean(axis=0)

    def in_band(self, *, draws: bool = False) -> np.ndarray:
        value = self.empirical(draws=draws)
        return (value >= self.band[0] - 1e-12) & (value <= self.band[1] + 1e-12)


def extended_coverage_study(
    robot: RobotModel,
    plan: CapturePlan,
    instrument: Instrument,
    truth: ParameterSet,
    *,
    poses,
    poses_target,
    captures: int,
    draws: int,
    tracker_from_base=None,
    options: CPAOptions | None = None,
    joint_limits: str = "warn",
    joint_errors: JointErrorModel | None = None,
    coverage: float = 0.95,
    rng: np.random.Generator | int | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured_joint_errors: bool = False,
) -> ExtendedCoverage:
    """Coverage of the deployed extended model's Monte Carlo (issue 22).

    ``captures`` independent captures of the plan's circles and of the calibration ``poses`` (readings [rad] on
    the flange ``poses_target``; the same poses, fresh noise) on an extended ``truth``; each is identified by
    CPA, refined over circles and poses with the truth's joint model (its values fitted from zero), and the
    refined Monte Carlo (``draws`` draws, the same model, circles and poses) simulated at that refined estimate
    states the intervals checked: those of the parameters and of the joint-model values. ``joint_errors`` (default
    none) act on every capture (its circles, and its poses without lash) and, unless ``measured_joint_errors``, on
    the Monte Carlo (simulated at the estimate with the same errors, whose effect the interval's bias correction
    then takes off). ``measured_joint_errors``: each capture's Monte Carlo simulates the joint errors that capture
    measures, its joints analysis and the refinement's residuals at the poses
    (:func:`robotcal.uncertainty.joint_errors.measured_joint_errors` with a ``CalibrationFit``), as ``robotcal run``
    does. Other arguments as :func:`coverage_study`.
    """
    with single_blas_thread():
        from robotcal.identification.targets import Target
        from robotcal.uncertainty.montecarlo import MonteCarloSettings

        if truth.joint_model is None or truth.joint_model.is_empty:
            raise InputError("the extended coverage study needs a truth with a joint model")
        _check_size(captures, draws)
        began = time.perf_counter()
        setup = _Setup.of(robot, plan, instrument, tracker_from_base, options, joint_errors, joint_limits, "points")
        seed = _study_seed(rng)
        children = np.random.SeedSequence(seed).spawn(captures)
        structure = truth.joint_model.with_values(np.zeros(truth.joint_model.size))
        circles = Target.from_mount(plan.reflector, "capture")
        settings = MonteCarloSettings(
            iterations=draws, coverage=coverage, block_size=draws, batch_size=min(draws, 2000)
        )
        everything = truth.robot.parameter_names + truth.joint_model.names
        true_all = np.r_[truth.values.ravel(), truth.joint_model.values]
        rows: dict[str, list] = {"contained": [], "draws": [], "u": [], "error": []}
        checked = None
        for k, child in enumerate(children):
            seeds = [int(s.generate_state(1, np.uint64)[0] % (2**63)) for s in child.spawn(3)]
            refined, result = _extended_capture(
                setup, truth, structure, circles, poses, poses_target, settings, seeds, measured_joint_errors
            )
            mask = np.r_[(result.identified & refined.identifiability.free).ravel(), result.extra_identified]
            if checked is None:
                checked = mask
            elif not np.array_equal(mask, checked):
                raise InputError(f"capture {k + 1} of the study determines another set of parameters than the first")
            true_values = true_all[checked]
            intervals = {
                "contained": (result.interval(), result.extra_interval()),
                "draws": (result.draws_interval(), result.extra_summary.interval(settings.interval)),
            }
            for key, ((low, high), (extra_low, extra_high)) in intervals.items():
                low, high = np.r_[low.ravel(), extra_low][checked], np.r_[high.ravel(), extra_high][checked]
                rows[key].append((low <= true_values) & (true_values <= high))
            rows["u"].append(
                np.r_[result.summary.std_uncertainty.ravel(), result.extra_summary.std_uncertainty][checked]
            )
            estimate = np.r_[refined.parameters.values.ravel(), refined.parameters.joint_model.values][checked]
            rows["error"].append(estimate - true_values)
            if progress is not None:
                progress(k + 1, captures)
        assert checked is not None  # set by the first capture (there are at least 10: _check_size)
        return ExtendedCoverage(
            names=tuple(name for name, flag in zip(everything, checked, strict=True) if flag),
            captures=captures,
            draws=draws,
            coverage=coverage,
            band=binomial_band(captures, coverage),
            contained=np.array(rows["contained"], dtype=bool),
            contained_draws=np.array(rows["draws"], dtype=bool),
            std_uncertainty=np.array(rows["u"]),
            error=np.array(rows["error"]),
            seed=seed,
            seconds=time.perf_counter() - began,
        )


def _extended_capture(
    setup: _Setup, truth, structure, circles, poses, poses_target, settings, seeds, measured_errors=False
):  # fmt: skip
    """One capture of circles and calibration poses of ``truth``: its extended refinement (from CPA, the joint
    model from zero) and the refined Monte Carlo simulated at that refinement. ``measured_errors``: as ``robotcal
    run``, the refinement corrects the circles for the lash the joints analysis measures, and the Monte Carlo
    simulates the joint errors the capture measures."""
    from robotcal.capture import join_captures
    from robotcal.identification.cpa import identify_cpa
    from robotcal.identification.refine import refine_parameters
    from robotcal.simulation.generator import simulate_capture, simulate_target_poses
    from robotcal.uncertainty.joint_errors import CalibrationFit
    from robotcal.uncertainty.montecarlo import prepare_monte_carlo, run_monte_carlo

    capture_seed, pose_seed, mc_seed = seeds
    robot, plan, instrument, base = setup.robot, setup.plan, setup.instrument, setup.tracker_from_base
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        capture, _ = simulate_capture(
            robot, plan, instrument, base, true_parameters=truth, joint_errors=setup.joint_errors,
            joint_limits=setup.joint_limits, rng=np.random.default_rng(capture_seed),
        )  # fmt: skip
        pose_capture, _ = simulate_target_poses(
            robot, poses, (poses_target,), instrument, base, true_parameters=truth, joint_errors=setup.joint_errors,
            rng=np.random.default_rng(pose_seed),
        )  # fmt: skip
        cpa = identify_cpa(
            capture, robot, plan.reflector, tracker_from_base=setup.held_base, options=setup.options
        ).parameters
        fitted = join_captures([(capture, circles.name), (pose_capture, None)], source="coverage capture")
        targets = (circles, poses_target)
        diagnostics = _joints_analysis(setup, capture) if measured_errors else None
        if diagnostics is not None:
            structure = _stage_lash(diagnostics, structure)
        refine = partial(refine_parameters, start=cpa, reflector=targets, tracker_from_base=setup.held_base,
                         joint_model=structure)  # fmt: skip
        refined = refine(fitted)
        errors = setup.joint_errors
        if diagnostics is not None:
            calibration = CalibrationFit(capture=fitted, targets=targets, result=refined, refit=refine)
            errors = _measured(setup, capture, refined.parameters, calibration, diagnostics)
        problem = prepare_monte_carlo(
            robot, plan, instrument, base, options=setup.options, true_parameters=refined.parameters,
            joint_errors=errors, joint_limits=setup.joint_limits, model="refined", poses=poses,
            poses_target=poses_target, joint_model=structure,
        )  # fmt: skip
        return refined, run_monte_carlo(problem, settings, seed=mc_seed, linearised=False)
