"""What result files record about how they were made: versions, the scenario, the fits (mm, deg).

The writers of :mod:`robotcal.io` put these under a file's ``provenance`` (or ``versions``) key, so that a
result can be traced to the code, the inputs and the options that produced it.
"""

from __future__ import annotations

import platform

import numpy as np

from robotcal.kinematics.model import ANGLE_KINDS

__all__ = ["cpa_provenance", "refine_provenance", "scenario_echo", "versions"]


def versions() -> dict[str, str]:
    """Versions of robotcal and of the numeric stack."""
    import scipy

    from robotcal._version import installed_version

    return {
        "robotcal": installed_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


def scenario_echo(scenario) -> dict | None:
    """``{"name", "source"}`` of the scenario a result was computed with (None without one)."""
    return None if scenario is None else {"name": scenario.name, "source": scenario.source}


def _finite_or_none(value):
    """JSON has no NaN/inf: an undefined figure (e.g. sigma with no degrees of freedom) is null."""
    value = float(value)
    return value if np.isfinite(value) else None


def _health(result) -> dict | None:
    return None if result.health is None else result.health.as_dict()


def cpa_provenance(result, capture, *, scenario=None) -> dict:
    """What a parameter JSON records about a CPA identification (``result`` from :func:`robotcal.identify`)."""
    return {
        "method": "circle point analysis (thesis ch. 4.4-4.5)",
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "scenario": scenario_echo(scenario),
        "options": {
            "circle_fit": result.options.circle_fit,
            "base_frame": result.options.base_frame,
            "base_axis": result.options.base_axis,
            "near_parallel_deg": result.options.near_parallel_deg,
            "still_tolerance_deg": result.options.still_tolerance_deg,
        },
        "fit_health": _health(result),
        "reference_readings_deg": np.rad2deg(result.reference_readings).tolist(),
        "circles": [
            {
                "circle": joint + 1,
                "points": int(fit.plane_residuals.shape[-1]),
                "radius_mm": float(fit.radius),
                "plane_rms_mm": float(fit.plane_rms),
                "circle_rms_mm": float(fit.circle_rms),
            }
            for joint, fit in enumerate(result.circle_fits)
        ],
        "line_pairs": [f"J{j + 1}-J{j + 2}: {case}" for j, case in enumerate(result.pair_cases)],
        "tracker_from_base": result.tracker_from_base.tolist(),
        "registration_rms_mm": result.registration_rms,
        "success": result.success,
        "message": result.message,
        "versions": versions(),
    }


def refine_provenance(result, capture, start_source: str, *, scenario=None) -> dict:
    """What a parameter JSON records about a refinement (``result`` from :func:`robotcal.refine`), convergence
    history included."""
    names = result.parameters.robot.parameter_names
    sd = {}
    for name, value in zip(names, result.uncertainty.standard_uncertainty.ravel(), strict=True):
        if np.isfinite(value):
            sd[name] = float(np.rad2deg(value)) if name.split(".")[1] in ANGLE_KINDS else float(value)
    joint_model = result.parameters.joint_model
    extra_u = result.uncertainty.joint_model_uncertainty
    if joint_model is not None and extra_u is not None:  # k in rad/(N m), the others in deg
        for name, value in zip(joint_model.names, joint_model.to_display(extra_u), strict=True):
            if np.isfinite(value):
                sd[name] = float(value)
    return {
        "method": f"least-squares refinement, {result.criterion} criterion (thesis ch. 4.5.7, "
        + ("eq. 4-101)" if result.criterion == "points" else "eq. 4-102)"),
        "criterion": result.criterion,
        "solver": f"scipy.optimize.least_squares method={result.method!r}",
        "start": start_source,
        "capture": capture.source,
        "capture_seed": capture.seed,
        "points": int(capture.n_points),
        "residuals": result.fit.n_residuals,
        "scenario": scenario_echo(scenario),
        "free": list(result.identifiability.free_names),
        "base_frame": None
        if result.tracker_from_base is None
        else ("estimated" if bool(np.any(result.identifiability.base_free)) else "held"),
        "gauge": list(result.identifiability.gauge),
        "held": list(result.identifiability.held),
        "confounded": list(result.identifiability.confounded),
        "still_joints": list(result.identifiability.still_joints),
        "success": result.success,
        "message": result.message,
        "nfev": result.nfev,
        "njev": result.njev,
        "wall_time_s": result.wall_time_s,
        "convergence": {
            "criterion": result.criterion,
            "cost_mm2": result.fit.cost_history.tolist(),
            "rms_mm": result.fit.rms_history.tolist(),
        },
        "residual_rms_mm": result.fit.residual_rms,
        "residual_mean_mm": result.fit.residual_mean,
        "residual_max_mm": result.fit.residual_max,
        "sigma_mm": _finite_or_none(result.uncertainty.sigma),
        "condition_number": _finite_or_none(result.identifiability.condition_number),
        "singular_values": [_finite_or_none(v) for v in result.identifiability.singular_values],
        "standard_uncertainty": sd,
        "correlation": None
        if result.uncertainty.correlation is None
        else {
            "names": list(result.identifiability.free_names),
            "matrix": [[round(float(v), 12) for v in row] for row in result.uncertainty.correlation],
        },
        "tracker_from_base": None if result.tracker_from_base is None else result.tracker_from_base.tolist(),
        "base_frame_note": None
        if result.tracker_from_base is not None
        else "the distances criterion has no base frame (pairwise distances do not depend on it)",
        "weights": "1/u^2 per point, u = U(95) / 2 (k = 2, normal)" if result.fit.weighted else "equal",
        "targets": {
            target.name: {
                "frame": target.frame,
                "known": bool(target.known),
                "points": int(np.sum(np.asarray(capture.point_targets or ()) == target.name))
                if capture.target is not None
                else int(capture.n_points),
            }
            for target in result.targets
        },
        "fit_health": _health(result),
        "model": result.model,
        "cross_validation": None if result.cross_validation is None else result.cross_validation.to_dict(),
        "model_choice": None if result.model_choice is None else result.model_choice.to_dict(),
        "versions": versions(),
    }
