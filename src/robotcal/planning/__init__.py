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

from robotcal.planning.cell import REASONS, CellModel, CircleCheck, PlanCheck, check_plan, segment_distance
from robotcal.planning.files import check_document, write_check_files, write_sensitivity_files
from robotcal.planning.optimise import (
    OBJECTIVES,
    OptimisationResult,
    PlanProblem,
    evaluate_plan,
    optimise_plan,
    workspace_readings,
)
from robotcal.planning.program import (
    LANGUAGES,
    NAME_LIMITS,
    check_program_name,
    controller_readings,
    program_name,
    write_program,
)
from robotcal.planning.scenario import (
    DEFAULT_CAPSULE_RADIUS_MM,
    cell_from_scenario,
    robot_capsule_radii,
    scenario_document,
    scenario_from_document,
    set_key,
)
from robotcal.planning.sensitivity import (
    DEFAULT_ANGLE_LIMIT_DEG,
    DEFAULT_LENGTH_LIMIT_MM,
    SensitivityCase,
    SensitivityStudy,
    capability_limits,
    parse_vary,
    process_capability,
    run_sensitivity,
)

__all__ = [
    "CellModel",
    "PlanCheck",
    "CircleCheck",
    "segment_distance",
    "check_plan",
    "REASONS",
    "check_document",
    "write_check_files",
    "write_sensitivity_files",
    "OBJECTIVES",
    "PlanProblem",
    "OptimisationResult",
    "evaluate_plan",
    "optimise_plan",
    "workspace_readings",
    "LANGUAGES",
    "NAME_LIMITS",
    "check_program_name",
    "program_name",
    "write_program",
    "controller_readings",
    "DEFAULT_CAPSULE_RADIUS_MM",
    "scenario_document",
    "scenario_from_document",
    "robot_capsule_radii",
    "cell_from_scenario",
    "set_key",
    "DEFAULT_LENGTH_LIMIT_MM",
    "DEFAULT_ANGLE_LIMIT_DEG",
    "process_capability",
    "capability_limits",
    "SensitivityCase",
    "SensitivityStudy",
    "parse_vary",
    "run_sensitivity",
]
