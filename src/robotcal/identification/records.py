"""The records of a refinement: :class:`RefinementResult`, shaped like SciPy's ``OptimizeResult`` (the values and
the solver's record flat), with its statistics in named sub-records, and the cross-validation records of the model
choice (:mod:`robotcal.identification.model_choice`).

They live in a module of their own, which imports neither the refinement nor the model choice, so that the
modules that make them and those that read them import it without a circle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal.identification.health import FitHealth
from robotcal.identification.targets import Target
from robotcal.kinematics.model import ParameterSet

__all__ = [
    "FitStatistics",
    "Identifiability",
    "RefinementUncertainty",
    "CrossValidation",
    "ModelChoice",
    "RefinementResult",
    "SessionFrame",
    "ProbeFrame",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class FitStatistics:
    """The residuals of a refinement and the solver's path to them [mm, mm^2].

    Attributes
    ----------
    n_residuals : int
        3 per point (points criterion) or one per kept pair (distances).
    residual_rms, residual_mean, residual_max : float
        Of the per-point distance ``|T p - m|`` (points) or of ``|D_model - D_measured|`` (distances) at the
        solution [mm].
    residual_rms_coordinate : float
        RMS of the unweighted residuals per coordinate (points) or per pair (distances) [mm].
    start_cost : float
        SciPy cost ``0.5 * sum(r^2)`` [mm^2] at the start; the final cost is never above it.
    cost_history : ndarray, shape (n_iterations + 1,)
        SciPy cost ``0.5 * sum(r^2)`` [mm^2] at the start and after every iteration (each Jacobian evaluation
        happens at an accepted iterate), ending with the final cost; after a refit it goes on with the refit's
        start (the quantities newly held back at their start values) and iterations.
    rms_history : ndarray, shape (n_iterations + 1,)
        ``sqrt(2 cost / m)`` [mm], the RMS residual along the way.
    weighted : bool
        Whether the points were weighted by ``1 / u^2`` from their U(95).
    refits : int
        How many times the rank test at a solution changed the free set and the capture was refitted (0 when
        the start's decision holds at the solution).
    """

    n_residuals: int
    residual_rms: float
    residual_mean: float
    residual_max: float
    residual_rms_coordinate: float
    start_cost: float
    cost_history: np.ndarray
    rms_history: np.ndarray
    weighted: bool = False
    refits: int = 0


@dataclass(frozen=True, slots=True, kw_only=True)
class Identifiability:
    """What the data determine: the free set the rank test chose, what it holds and why, and the conditioning.

    Attributes
    ----------
    free : ndarray of bool, shape (n_joints, 5)
        Parameters estimated.
    base_free : ndarray of bool, shape (6,)
        ``tracker_from_base`` corrections estimated (all False for distances).
    gauge : tuple of str
        Parameters held because their effect on the data is a rigid motion of the whole point cloud, which the
        criterion cannot tell from a base-frame motion (a free base frame, or pairwise distances).
    held : tuple of str
        Other parameters (and ``base.*`` corrections, joint-model values, offsets) held because the data cannot
        determine them. Disjoint from ``gauge``.
    confounded : tuple of str
        Free quantities whose estimate depends on the values at which ``gauge``/``held`` ones are held: only
        the combination is determined.
    still_joints : tuple of str
        Joints whose reading never changes in the capture.
    free_names : tuple of str
        Names of the estimated quantities, in the order of the covariance rows.
    x_scale : ndarray, shape (n_free,)
        Characteristic scale of each unknown [mm | rad].
    singular_values : ndarray, shape (n_free,)
        Of the column-scaled Jacobian at the solution.
    condition_number : float
    effect : ndarray, shape (n_free,)
        RMS displacement of the points (points criterion) or change of the distances (distances) per unit of
        each free quantity at the solution: ``u * effect`` is what one standard uncertainty of the quantity
        alone does to the data (:func:`robotcal.identification.health.refine_health`).
    """

    free: np.ndarray
    base_free: np.ndarray
    gauge: tuple[str, ...]
    held: tuple[str, ...]
    confounded: tuple[str, ...]
    still_joints: tuple[str, ...]
    free_names: tuple[str, ...]
    x_scale: np.ndarray
    singular_values: np.ndarray
    condition_number: float
    effect: np.ndarray | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinementUncertainty:
    """The linearised uncertainty of the refined quantities (module notes of :mod:`robotcal.identification.refine`).

    Attributes
    ----------
    sigma : float
        Estimated point noise per coordinate [mm]; NaN when the capture leaves no degree of freedom for it (then
        ``covariance`` is None and the result's ``message`` says why).
    covariance : ndarray, shape (n_free, n_free), or None
        Of the free quantities (``Identifiability.free_names``) [mm, rad]; None when sigma is NaN.
    correlation : ndarray, shape (n_free, n_free), or None
    standard_uncertainty : ndarray, shape (n_joints, 5)
        ``sqrt(diag(covariance))`` placed per parameter [mm, rad]; NaN where held, and everywhere when sigma is
        NaN.
    joint_model_uncertainty : ndarray, shape (m,), or None
        Of every joint-model value (core units: rad/(N m), rad); NaN where held or without a covariance; None
        for the geometric model.
    target_uncertainty : ndarray, shape (n_targets, 3), or None
        Of every target's offset [mm] (NaN for a known target); None without targets.
    """

    sigma: float
    covariance: np.ndarray | None
    correlation: np.ndarray | None
    standard_uncertainty: np.ndarray
    joint_model_uncertainty: np.ndarray | None = None
    target_uncertainty: np.ndarray | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class CrossValidation:
    """k-fold cross-validation by pose of one model (:mod:`robotcal.identification.model_choice`) [mm, mm^2].

    Attributes
    ----------
    model : str
    unknowns : int
        Free unknowns of the full fit (parameters, joint-model values, offsets, base corrections).
    folds : int
    seed : int
        Seed of the deal of poses into folds.
    calibration_rms_mm : float
        The full fit's residual RMS on its own data.
    cv_rms_mm : float
        RMS of every held-out residual over the folds.
    fold_mse_mm2 : ndarray, shape (folds,)
        Mean squared held-out residual of each fold.
    se_mm2 : float
        Standard error of the CV mean squared error, ``sd(fold_mse) / sqrt(folds)``.
    failed_folds : int
        Folds whose refit did not converge (their held-out residuals still count: a model that cannot be refitted
        on part of the data predicts it badly).
    """

    model: str
    unknowns: int
    folds: int
    seed: int
    calibration_rms_mm: float
    cv_rms_mm: float
    fold_mse_mm2: np.ndarray
    se_mm2: float
    failed_folds: int = 0

    @property
    def cv_mse_mm2(self) -> float:
        return self.cv_rms_mm**2

    def to_dict(self) -> dict:
        return {
            "model": self.model,
            "unknowns": self.unknowns,
            "folds": self.folds,
            "seed": self.seed,
            "calibration_rms_mm": self.calibration_rms_mm,
            "cv_rms_mm": self.cv_rms_mm,
            "fold_rms_mm": [float(v) for v in np.sqrt(self.fold_mse_mm2)],
            "cv_se_mm2": self.se_mm2,
            "failed_folds": self.failed_folds,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class ModelChoice:
    """The candidates of ``auto`` with their cross-validation, the chosen model and why."""

    candidates: tuple[CrossValidation, ...]
    chosen: str
    reason: str

    def to_dict(self) -> dict:
        return {
            "rule": "fewest unknowns within one standard error of the smallest CV mean squared error",
            "chosen": self.chosen,
            "reason": self.reason,
            "candidates": [candidate.to_dict() for candidate in self.candidates],
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class SessionFrame:
    """The base frame of one measurement session (tracker station, day; issue 29), as a refinement estimated it.

    Attributes
    ----------
    name : str
        The session's name (the capture's ``session`` column).
    tracker_from_base : ndarray, shape (4, 4)
        ``p_tracker = T p_base`` in that session [mm].
    standard_uncertainty : ndarray, shape (6,)
        Of its six corrections ``tx, ty, tz`` [mm], ``rx, ry, rz`` [rad] (``T = T_start [Rz Ry Rx | t]``); NaN
        where held (the first session's frame when the base frame is given) or without a covariance.
    """

    name: str
    tracker_from_base: np.ndarray
    standard_uncertainty: np.ndarray


@dataclass(frozen=True, slots=True, kw_only=True)
class ProbeFrame:
    """A 6-DoF probe's frame on the flange as a refinement estimated it (issue 29): its position is its target's
    offset (``targets``), its rotation this.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        From the probe frame to the flange frame {n}.
    standard_uncertainty : ndarray, shape (3,)
        Of the rotation's three corrections ``R = R_start Rz(rz) Ry(ry) Rx(rx)`` [rad] (NaN without a covariance).
    orientation_rms_deg : float
        RMS angle of the orientation residuals at the solution [deg].
    """

    rotation: np.ndarray
    standard_uncertainty: np.ndarray
    orientation_rms_deg: float


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinementResult:
    """Outcome of a refinement, shaped like SciPy's ``OptimizeResult``: the values and the solver's record, then
    named sub-records.

    Attributes
    ----------
    parameters : ParameterSet
        Refined parameters [mm, rad] (with the fitted joint model for an extended model); ``identified`` is the
        start's flags or-ed with ``identifiability.free``.
    tracker_from_base : ndarray, shape (4, 4) or None
        Estimated (or held) base frame for the points criterion; None for distances.
    targets : tuple of Target
        The targets, unknown flange offsets as estimated (empty for a single reflector mount).
    success : bool
        SciPy's success, and False when the solver ended above the start's cost (then the start is returned).
    status : int
        SciPy's termination status.
    message : str
        SciPy's message; prefixed with an explanation when sigma could not be estimated, when the start was
        returned or when the free set did not settle.
    nfev, njev : int
        Residual and Jacobian evaluations, summed over the fits (``fit.refits`` + 1).
    model : str
        The model fitted: ``geometric``, or the joint model's groups (``compliance``, ``harmonic``,
        ``compliance+harmonic``).
    criterion : {"points", "distances"}
    method : {"lm", "trf"}
    wall_time_s : float
        Of this fit (not of its cross-validation nor of the other candidates).
    fit : FitStatistics
        Residual statistics and the cost history.
    identifiability : Identifiability
        The free set, what is held and why, conditioning.
    uncertainty : RefinementUncertainty
        sigma, covariance, correlation, standard uncertainties.
    health : FitHealth
        The fit-health verdict (:func:`robotcal.identification.health.refine_health`), made with the result.
    cross_validation : CrossValidation or None
        Its k-fold cross-validation by pose (:func:`robotcal.identification.model_choice.refine_model`); None
        without folds.
    model_choice : ModelChoice or None
        With ``model="auto"``: every candidate's cross-validation and why the model was chosen.
    sessions : tuple of SessionFrame
        Points criterion on a capture with a ``session`` column: the base frame of every session (the first one's
        is ``tracker_from_base``); empty otherwise.
    probe : ProbeFrame or None
        Points criterion on a capture with orientations (a 6-DoF probe): the probe's rotation on the flange.
    """

    parameters: ParameterSet
    tracker_from_base: np.ndarray | None
    targets: tuple[Target, ...] = ()
    success: bool
    status: int
    message: str
    nfev: int
    njev: int
    model: str = "geometric"
    criterion: str
    method: str
    wall_time_s: float
    fit: FitStatistics
    identifiability: Identifiability
    uncertainty: RefinementUncertainty
    health: FitHealth | None = None
    cross_validation: CrossValidation | None = None
    model_choice: ModelChoice | None = None
    sessions: tuple[SessionFrame, ...] = ()
    probe: ProbeFrame | None = None

    def __repr__(self) -> str:
        health = f", {self.health.verdict}" if self.health is not None else ""
        cv = "" if self.cross_validation is None else f", CV {self.cross_validation.cv_rms_mm * 1e3:.3g} um"
        return (
            f"RefinementResult({self.criterion} criterion, {self.model} model, "
            f"{len(self.identifiability.free_names)} free, residual RMS {self.fit.residual_rms * 1e3:.3g} um{cv}"
            f"{health}, success={self.success})"
        )
