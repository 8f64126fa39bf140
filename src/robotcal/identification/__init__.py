"""Identification: Circle Point Analysis (:mod:`.cpa`), least-squares refinement (:mod:`.refine`, with its
problem and rank test in private modules, records :mod:`.records` and settings :mod:`.settings`), the
model choice (:mod:`.model_choice`), evaluation on validation captures (:mod:`.evaluation`), observability,
capture plausibility, targets, fit health.

The names of :mod:`.cpa` load with the package; the others on first use (the refinement pulls
``scipy.optimize``). Scenario-level wrappers: :func:`robotcal.identify`, :func:`robotcal.refine`,
:func:`robotcal.evaluate`.

Examples
--------
CPA of a noise-free simulated capture returns the parameters it was simulated with:

>>> import numpy as np
>>> import robotcal
>>> from robotcal.identification import identify_cpa
>>> scenario = robotcal.load_scenario("thesis-noise-free")
>>> capture = robotcal.simulate(scenario, rng=0)
>>> result = identify_cpa(capture, scenario.robot, scenario.plan.reflector,
...                       tracker_from_base=scenario.tracker_from_base, options=scenario.identification)
>>> result.pair_cases[:2]
('skew', 'nearly-parallel')
>>> error = result.parameters.difference(robotcal.ParameterSet.nominal(scenario.robot))  # mm, rad
>>> bool(np.abs(error).max() < 1e-9)
True
"""

from robotcal.identification.cpa import CPABatch, CPAOptions, CPAResult, identify_cpa, identify_cpa_batch, prepare_cpa
from robotcal.identification.evaluation import (
    ALL_VIEWS,
    VIEWS,
    EvaluationRow,
    GuessedOffsetWarning,
    absolute_errors,
    distance_errors,
    distinct_pairs,
    evaluate_parameters,
    guessed_targets,
    point_errors,
    predicted_points,
)
from robotcal.identification.health import (
    AXIS_LIMIT_DEG,
    CONDITION_LIMIT,
    PHYSICAL_RESIDUAL_MM,
    RESIDUAL_RATIO_LIMIT,
    VERDICTS,
    FitHealth,
    FitHealthError,
    FitHealthWarning,
    Verdict,
    assess_fit,
    circle_axis_uncertainty,
    cpa_health,
    model_advice,
    refine_health,
    report_health,
    stated_noise,
)
from robotcal.identification.model_choice import (
    COMPLIANCE_TORQUE_FRACTION,
    DEFAULT_FOLDS,
    MODEL_CHOICES,
    MODELS,
    FitTask,
    candidate_joint_model,
    choose_model,
    default_compliance_joints,
    joint_model_for,
    pose_folds,
    refine_model,
    run_fit,
)
from robotcal.identification.observability import (
    Conditioning,
    conditioning,
    correlation_from_covariance,
    select_identifiable,
    triangular_factor,
)
from robotcal.identification.plausibility import (
    OUTLIER_MAD,
    OUTLIER_U,
    RESIDUAL_FLOOR_MM,
    PlausibilityReport,
    PlausibilityWarning,
    check_capture,
    reject_outliers,
)
from robotcal.identification.records import (
    CrossValidation,
    FitStatistics,
    Identifiability,
    ModelChoice,
    RefinementResult,
    RefinementUncertainty,
)
from robotcal.identification.refine import (
    BASE_NAMES,
    CRITERIA,
    base_correction,
    capture_target_index,
    capture_turning_joints,
    measurement_pairs,
    point_sigmas,
    refine_parameters,
    wrap_angles,
)
from robotcal.identification.settings import ModelChoiceSettings, RefinementSettings
from robotcal.identification.targets import Target, point_target_index, resolve_targets

__all__ = [
    "CPAOptions",
    "CPAResult",
    "CPABatch",
    "identify_cpa",
    "identify_cpa_batch",
    "prepare_cpa",
    "VIEWS",
    "ALL_VIEWS",
    "EvaluationRow",
    "point_errors",
    "predicted_points",
    "distinct_pairs",
    "distance_errors",
    "absolute_errors",
    "evaluate_parameters",
    "guessed_targets",
    "GuessedOffsetWarning",
    "AXIS_LIMIT_DEG",
    "CONDITION_LIMIT",
    "PHYSICAL_RESIDUAL_MM",
    "RESIDUAL_RATIO_LIMIT",
    "VERDICTS",
    "FitHealth",
    "FitHealthError",
    "FitHealthWarning",
    "Verdict",
    "assess_fit",
    "model_advice",
    "circle_axis_uncertainty",
    "cpa_health",
    "refine_health",
    "report_health",
    "stated_noise",
    "MODELS",
    "MODEL_CHOICES",
    "DEFAULT_FOLDS",
    "COMPLIANCE_TORQUE_FRACTION",
    "CrossValidation",
    "ModelChoice",
    "ModelChoiceSettings",
    "FitTask",
    "default_compliance_joints",
    "joint_model_for",
    "candidate_joint_model",
    "pose_folds",
    "run_fit",
    "refine_model",
    "choose_model",
    "Conditioning",
    "select_identifiable",
    "conditioning",
    "correlation_from_covariance",
    "triangular_factor",
    "PlausibilityWarning",
    "PlausibilityReport",
    "check_capture",
    "reject_outliers",
    "OUTLIER_U",
    "OUTLIER_MAD",
    "RESIDUAL_FLOOR_MM",
    "CRITERIA",
    "BASE_NAMES",
    "RefinementResult",
    "FitStatistics",
    "Identifiability",
    "RefinementUncertainty",
    "RefinementSettings",
    "refine_parameters",
    "capture_turning_joints",
    "capture_target_index",
    "measurement_pairs",
    "base_correction",
    "wrap_angles",
    "point_sigmas",
    "Target",
    "resolve_targets",
    "point_target_index",
]
