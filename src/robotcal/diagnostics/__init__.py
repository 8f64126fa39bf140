"""Joint error diagnostics (thesis ch. 4.6): backlash, axial/radial eccentricity, harmonic models, and the
ISO 9283 pose characteristics.

Examples
--------
A radial eccentricity of 0.02 mm that turns once per revolution is a first harmonic; the series
fitted to it over a 300 deg circle gives its amplitude back:

>>> import numpy as np
>>> from robotcal.diagnostics import fit_harmonic_series
>>> theta = np.deg2rad(np.linspace(0.0, 300.0, 30))
>>> radial = 0.02 * np.cos(theta - 0.5)
>>> fit = fit_harmonic_series(theta, radial, order=2)
>>> c0, a1, b1 = fit.coefficients[:3]
>>> round(float(np.hypot(a1, b1)), 9), bool(abs(c0) < 1e-12)
(0.02, True)
"""

from robotcal.diagnostics.harmonics import (
    HARMONICS_FORMAT,
    QUANTITIES,
    CircleGeometry,
    HarmonicFit,
    HarmonicModel,
    fit_harmonic_series,
    fit_harmonics,
)
from robotcal.diagnostics.iso9283 import (
    ISO_CYCLES,
    ORIENTATION_AXES,
    Iso9283Result,
    IsoModel,
    IsoStudy,
    default_iso_start,
    iso_cube_corners,
    iso_cube_plan,
    iso_from_capture,
    iso_plan_readings,
    iso_test_positions,
    orientation_deviations,
    pose_characteristics,
    pose_visits,
    register_flange_poses,
    rotation_vectors,
    scenario_flange_point,
    simulate_attained_positions,
    simulate_iso_study,
)
from robotcal.diagnostics.joints import (
    DEFAULT_MATCH_TOLERANCE,
    MAXWELL_MEAN_PER_SIGMA,
    CircleDiagnostics,
    JointDiagnostics,
    JointSummary,
    analyze_joints,
    lash_state,
    local_frame,
)

__all__ = [
    "QUANTITIES",
    "HarmonicFit",
    "CircleGeometry",
    "HarmonicModel",
    "fit_harmonic_series",
    "fit_harmonics",
    "HARMONICS_FORMAT",
    "ISO_CYCLES",
    "ORIENTATION_AXES",
    "Iso9283Result",
    "IsoModel",
    "IsoStudy",
    "default_iso_start",
    "iso_from_capture",
    "orientation_deviations",
    "pose_visits",
    "register_flange_poses",
    "rotation_vectors",
    "scenario_flange_point",
    "simulate_iso_study",
    "iso_cube_corners",
    "iso_cube_plan",
    "iso_test_positions",
    "iso_plan_readings",
    "pose_characteristics",
    "simulate_attained_positions",
    "CircleDiagnostics",
    "JointSummary",
    "JointDiagnostics",
    "analyze_joints",
    "lash_state",
    "local_frame",
    "DEFAULT_MATCH_TOLERANCE",
    "MAXWELL_MEAN_PER_SIGMA",
]
