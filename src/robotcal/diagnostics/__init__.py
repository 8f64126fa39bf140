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

from robotcal import _lazy_exports
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
    Iso9283Result,
    iso_cube_corners,
    iso_plan_readings,
    iso_test_positions,
    pose_characteristics,
    simulate_attained_positions,
)
from robotcal.diagnostics.joints import (
    DEFAULT_MATCH_TOLERANCE,
    CircleDiagnostics,
    JointDiagnostics,
    JointSummary,
    analyze_joints,
    lash_state,
    local_frame,
)

#: Names loaded on first use.
_LAZY = {
    "MAXWELL_MEAN_PER_SIGMA": "robotcal.diagnostics.joints",
    **dict.fromkeys(
        (
            "ORIENTATION_AXES",
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
            "iso_cube_plan",
        ),
        "robotcal.diagnostics.iso9283",
    ),
}

__all__ = [
    "HARMONICS_FORMAT",
    "QUANTITIES",
    "CircleDiagnostics",
    "CircleGeometry",
    "DEFAULT_MATCH_TOLERANCE",
    "HarmonicFit",
    "HarmonicModel",
    "ISO_CYCLES",
    "Iso9283Result",
    "JointDiagnostics",
    "JointSummary",
    "analyze_joints",
    "fit_harmonic_series",
    "fit_harmonics",
    "iso_cube_corners",
    "iso_plan_readings",
    "iso_test_positions",
    "lash_state",
    "local_frame",
    "pose_characteristics",
    "simulate_attained_positions",
    *_LAZY,
]

__getattr__, __dir__ = _lazy_exports(__name__, _LAZY)
