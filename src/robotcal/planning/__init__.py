"""Capture planning (thesis 4.5.2, 5.2.4, 6.2): cell check, robot programs, sensitivity, optimisation.

Names load on first use (PEP 562); :mod:`.scenario` is the glue that reads scenario and robot files
for the cell. Scenario-level wrappers: :func:`robotcal.check_plan`, :func:`robotcal.change_plan`.

Examples
--------
The process capability index of eq. 5-5, ``Cpk = min(USL - mean, mean - LSL) / (3 u)``:

>>> from robotcal.planning import process_capability
>>> round(float(process_capability(0.01, 0.02, -0.1, 0.1)), 12)
1.5
"""

from robotcal import _lazy_exports

_LAZY = {
    **dict.fromkeys(
        ("CellModel", "PlanCheck", "CircleCheck", "segment_distance", "check_plan", "REASONS"), "robotcal.planning.cell"
    ),
    **dict.fromkeys(
        ("OBJECTIVES", "PlanProblem", "OptimisationResult", "evaluate_plan", "optimise_plan", "workspace_readings"),
        "robotcal.planning.optimise",
    ),
    **dict.fromkeys(
        ("LANGUAGES", "NAME_LIMITS", "check_program_name", "program_name", "write_program", "controller_readings"),
        "robotcal.planning.program",
    ),
    **dict.fromkeys(
        (
            "DEFAULT_CAPSULE_RADIUS_MM",
            "scenario_document",
            "scenario_from_document",
            "robot_capsule_radii",
            "cell_from_scenario",
            "set_key",
        ),
        "robotcal.planning.scenario",
    ),
    **dict.fromkeys(
        (
            "DEFAULT_LENGTH_LIMIT_MM",
            "DEFAULT_ANGLE_LIMIT_DEG",
            "process_capability",
            "capability_limits",
            "SensitivityCase",
            "SensitivityStudy",
            "parse_vary",
            "run_sensitivity",
        ),
        "robotcal.planning.sensitivity",
    ),
}

__all__ = list(_LAZY)

__getattr__, __dir__ = _lazy_exports(__name__, _LAZY)
