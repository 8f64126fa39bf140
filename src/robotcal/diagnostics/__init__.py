"""Joint error diagnostics (thesis ch. 4.6): backlash, axial/radial eccentricity, harmonic models."""

from robotcal.diagnostics.harmonics import (
    QUANTITIES,
    CircleGeometry,
    HarmonicFit,
    HarmonicModel,
    fit_harmonic_series,
    fit_harmonics,
)
from robotcal.diagnostics.iso9283 import Iso9283Result, iso_plan_readings, iso_test_positions, pose_characteristics
from robotcal.diagnostics.joints import (
    CircleDiagnostics,
    JointDiagnostics,
    JointSummary,
    analyze_joints,
    lash_state,
    local_frame,
)

__all__ = [
    "QUANTITIES",
    "CircleDiagnostics",
    "CircleGeometry",
    "HarmonicFit",
    "HarmonicModel",
    "Iso9283Result",
    "JointDiagnostics",
    "JointSummary",
    "analyze_joints",
    "fit_harmonic_series",
    "fit_harmonics",
    "iso_plan_readings",
    "iso_test_positions",
    "lash_state",
    "local_frame",
    "pose_characteristics",
]
