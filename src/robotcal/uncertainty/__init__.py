"""Uncertainty: GUM Supplement 1 Monte Carlo of the calibration, its linearised comparison, and the
propagation of parameter draws to the TCP (thesis ch. 5.2.3 and 5.3).

Names load on first use (PEP 562): ``import robotcal.uncertainty.tcp`` does not import the Monte
Carlo engine. Scenario-level wrappers: :func:`robotcal.monte_carlo`, :func:`robotcal.tcp_uncertainty`.

Examples
--------
Draws of a planar two-link arm (links 300 and 200 mm) whose J1 offset theta_1 has a standard
uncertainty of 1e-4 rad: stretched along X, the TCP moves along Y by 500 mm times that angle, so
u(Y) = 0.05 mm, and u(X) is of second order:

>>> import numpy as np
>>> from robotcal.kinematics import RobotModel
>>> from robotcal.uncertainty import propagate_to_tcp
>>> arm = RobotModel(name="planar-2r", nominal=[[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]], hayati=[False, False])
>>> rng = np.random.default_rng(1)
>>> draws = np.repeat(arm.nominal[None], 20_000, axis=0)
>>> draws[:, 0, 1] += rng.normal(0.0, 1e-4, size=20_000)   # J1.theta [rad]
>>> tcp = propagate_to_tcp(arm, draws, [[0.0, 0.0]])
>>> u_x, u_y = tcp.std_uncertainty[0, :2]
>>> bool(abs(u_y / 0.05 - 1) < 0.03), bool(u_x < 1e-5)   # 3 % > 5 Monte Carlo standard errors of u
(True, True)
"""

from robotcal.uncertainty.coverage import (
    COVERAGE_METHODS,
    CoverageStudy,
    ExtendedCoverage,
    binomial_band,
    coverage_study,
    extended_coverage_study,
)
from robotcal.uncertainty.gauss_newton import refine_draws_gauss_newton
from robotcal.uncertainty.joint_errors import MeasuredJointErrors, measured_joint_errors
from robotcal.uncertainty.measured import (
    DRAWS_PER_BLOCK,
    MODEL,
    MeasuredMonteCarloResult,
    MeasuredProblem,
    measured_block,
    measured_monte_carlo,
    prepare_measured,
)
from robotcal.uncertainty.montecarlo import (
    AdaptiveRecord,
    LinearisedResult,
    MonteCarloProblem,
    MonteCarloResult,
    MonteCarloSettings,
    draw_block,
    linearised_uncertainty,
    prepare_monte_carlo,
    run_monte_carlo,
)
from robotcal.uncertainty.refined import (
    RefinedBatch,
    RefinedModel,
    prepare_refined_model,
    refine_batch,
    refined_covariance,
)
from robotcal.uncertainty.statistics import (
    INTERVAL_KINDS,
    SampleSummary,
    bias_corrected_interval,
    check_coverage,
    coverage_interval,
    numerical_tolerance,
    summarize_draws,
    widened_interval,
)
from robotcal.uncertainty.tcp import (
    ORIENTATION_CONVENTION,
    TCP_COORDINATES,
    TCP_UNITS,
    CoverageEllipsoid,
    TCPUncertainty,
    check_readings,
    check_tool,
    coverage_ellipsoid,
    position_covariance,
    propagate_to_tcp,
    tcp_coordinates,
    tcp_jacobian,
)
from robotcal.uncertainty.workspace import PERCENTILES, WorkspaceUncertainty, sample_workspace, workspace_uncertainty

__all__ = [
    "MeasuredJointErrors",
    "measured_joint_errors",
    "COVERAGE_METHODS",
    "CoverageStudy",
    "ExtendedCoverage",
    "coverage_study",
    "extended_coverage_study",
    "binomial_band",
    "DRAWS_PER_BLOCK",
    "MODEL",
    "MeasuredProblem",
    "MeasuredMonteCarloResult",
    "prepare_measured",
    "measured_monte_carlo",
    "measured_block",
    "MonteCarloProblem",
    "MonteCarloSettings",
    "MonteCarloResult",
    "AdaptiveRecord",
    "LinearisedResult",
    "prepare_monte_carlo",
    "run_monte_carlo",
    "linearised_uncertainty",
    "draw_block",
    "RefinedModel",
    "RefinedBatch",
    "prepare_refined_model",
    "refine_batch",
    "refined_covariance",
    "refine_draws_gauss_newton",
    "INTERVAL_KINDS",
    "SampleSummary",
    "summarize_draws",
    "coverage_interval",
    "bias_corrected_interval",
    "widened_interval",
    "numerical_tolerance",
    "check_coverage",
    "TCP_COORDINATES",
    "TCP_UNITS",
    "ORIENTATION_CONVENTION",
    "CoverageEllipsoid",
    "TCPUncertainty",
    "check_readings",
    "check_tool",
    "tcp_coordinates",
    "tcp_jacobian",
    "position_covariance",
    "coverage_ellipsoid",
    "propagate_to_tcp",
    "PERCENTILES",
    "WorkspaceUncertainty",
    "sample_workspace",
    "workspace_uncertainty",
]
