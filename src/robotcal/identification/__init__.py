"""Identification: Circle Point Analysis (:mod:`.cpa`), least-squares refinement (:mod:`.refine`),
evaluation on validation captures (:mod:`.evaluation`), observability, capture plausibility, targets,
fit health.

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

from robotcal import _lazy_exports
from robotcal.identification.cpa import CPABatch, CPAOptions, CPAResult, identify_cpa, identify_cpa_batch, prepare_cpa

_LAZY = {
    **dict.fromkeys(
        (
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
        ),
        "robotcal.identification.refine",
    ),
    **dict.fromkeys(
        (
            "VIEWS",
            "ALL_VIEWS",
            "EvaluationRow",
            "point_errors",
            "distance_errors",
            "absolute_errors",
            "evaluate_parameters",
        ),
        "robotcal.identification.evaluation",
    ),
    **dict.fromkeys(
        ("Conditioning", "select_identifiable", "conditioning", "correlation_from_covariance", "triangular_factor"),
        "robotcal.identification.observability",
    ),
    **dict.fromkeys(
        (
            "PlausibilityWarning",
            "PlausibilityReport",
            "check_capture",
            "reject_outliers",
            "OUTLIER_U",
            "OUTLIER_MAD",
            "RESIDUAL_FLOOR_MM",
        ),
        "robotcal.identification.plausibility",
    ),
    **dict.fromkeys(("Target", "resolve_targets", "point_target_index"), "robotcal.identification.targets"),
    **dict.fromkeys(
        (
            "RESIDUAL_RATIO_LIMIT",
            "CONDITION_LIMIT",
            "AXIS_LIMIT_DEG",
            "FitHealth",
            "FitHealthWarning",
            "FitHealthError",
            "fit_health",
            "circle_axis_uncertainty",
        ),
        "robotcal.identification.health",
    ),
}

__all__ = ["CPABatch", "CPAOptions", "CPAResult", "identify_cpa", "identify_cpa_batch", "prepare_cpa", *_LAZY]

__getattr__, __dir__ = _lazy_exports(__name__, _LAZY)
