"""Joint error diagnostics (thesis ch. 4.6): backlash, axial/radial eccentricity, harmonic models."""

from robotcal.diagnostics.harmonics import (
    QUANTITIES,
    CircleGeometry,
    HarmonicFit,
    HarmonicModel,
    fit_harmonic_series,
    fit_harmonics,
)
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
    "JointDiagnostics",
    "JointSummary",
    "analyze_joints",
    "fit_harmonic_series",
    "fit_harmonics",
    "lash_state",
    "local_frame",
]
