"""I/O at the edge: TOML robots and scenarios, capture CSV, parameter JSON, result files, atomic writes.

Files hold millimetres and degrees (micrometres where a name says ``_um``); the objects read hold the
core's mm and radians. The modules of scenario, robot, capture and parameter files load with the
package; those of results (draws, uncertainty tables, TCP files, exports, output folders) and of tracker
exports on first use.

Examples
--------
A capture written to CSV (readings in degrees, 12 decimals) reads back the same:

>>> import os, tempfile
>>> import numpy as np
>>> import robotcal
>>> from robotcal.io import read_capture, write_capture
>>> capture = robotcal.simulate(robotcal.load_scenario("thesis-laser-tracker"), rng=5)
>>> with tempfile.TemporaryDirectory() as folder:
...     path = write_capture(os.path.join(folder, "capture.csv"), capture)
...     back = read_capture(path, n_joints=6)
>>> back.n_points == capture.n_points, bool(np.array_equal(back.circle, capture.circle))
(True, True)
>>> bool(np.allclose(back.readings, capture.readings, rtol=0, atol=1e-12))  # rad, from 12-decimal degrees
True
"""

from robotcal.io.atomic import atomic_directory, atomic_write_bytes, atomic_write_text
from robotcal.io.builtins import builtin_names, data_path, read_toml
from robotcal.io.capture_csv import capture_to_csv, read_capture, read_capture_text, write_capture
from robotcal.io.draws_npz import FORMAT, ParameterDraws, parameter_units, read_draws, write_draws
from robotcal.io.evaluation_files import (
    COLUMNS,
    convergence_of,
    evaluation_csv,
    evaluation_document,
    evaluation_headline,
    write_evaluation_folder,
)
from robotcal.io.export import (
    EXPORT_FORMATS,
    UR_JOINT_NAMES,
    coupled_joints,
    dh_table,
    joint_origins,
    mdh_table,
    model_variable_limits,
    parameters_to_ur_yaml,
    parameters_to_urdf,
    require_uncoupled,
    rpy_from_matrix,
    table_to_csv,
    table_to_markdown,
)
from robotcal.io.instruments import instrument_presets, make_instrument
from robotcal.io.iso9283_files import ISO_COLUMNS, iso_to_csv
from robotcal.io.joints_files import (
    SUMMARY_COLUMNS,
    backlash_csv,
    harmonics_document,
    joints_files,
    points_csv,
    summary_csv,
    write_joints_folder,
)
from robotcal.io.output import (
    LOCK_SUFFIX,
    MARKER,
    check_output_file,
    check_output_folder,
    existing_inputs,
    foreign_entries,
    is_robotcal_file,
    is_robotcal_folder,
    output_lock,
    result_file,
    result_folder,
    write_marker,
)
from robotcal.io.parameters_json import (
    parameters_to_dict,
    read_parameters,
    read_targets,
    refined_targets,
    targets_to_dict,
    write_parameters,
)
from robotcal.io.provenance import cpa_provenance, refine_provenance, scenario_echo, versions
from robotcal.io.robots import JointEntry, RobotFile, list_robots, load_robot, robot_from_dict, robot_to_dict
from robotcal.io.run_folder import (
    OUTPUTS,
    REPORT_NAME,
    RUN_ENTRIES,
    RUN_RECORD,
    STAGES,
    Document,
    RunResult,
    Table,
    json_text,
    read_document,
    read_run,
    refusal,
    run_documents,
    table_from_text,
    write_csv,
    write_json,
)
from robotcal.io.run_summary import (
    CONSISTENT_RATIO,
    Consistency,
    ModelUncertainty,
    Spread,
    Summary,
    set_label,
    summarise,
)
from robotcal.io.scenario import (
    MissingTable,
    MonteCarloTable,
    Scenario,
    TCPTable,
    TruthTable,
    ValidationTable,
    list_scenarios,
    load_scenario,
    scenario_from_dict,
)
from robotcal.io.tcp_results import (
    TCP_CSV_COLUMNS,
    tcp_json_text,
    tcp_to_csv,
    tcp_to_dict,
    write_tcp_csv,
    write_tcp_folder,
    write_tcp_json,
)
from robotcal.io.tracker_import import (
    UNITS_MM,
    JointLog,
    TrackerPoints,
    import_tracker_capture,
    join_points_to_readings,
    parse_column_map,
    read_joint_log,
    read_tracker_export,
)
from robotcal.io.trajectory_csv import (
    builtin_trajectories,
    load_trajectory,
    read_trajectory,
    trajectory_to_csv,
    write_trajectory,
)
from robotcal.io.uncertainty_files import (
    CSV_COLUMNS,
    MEASURED_TARGET_COLUMNS,
    measured_target_rows,
    read_uncertainty_csv,
    uncertainty_rows,
    write_measured_folder,
    write_uncertainty_csv,
    write_uncertainty_folder,
    write_uncertainty_json,
)

__all__ = [
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_directory",
    "data_path",
    "builtin_names",
    "read_toml",
    "capture_to_csv",
    "read_capture",
    "read_capture_text",
    "write_capture",
    "FORMAT",
    "ParameterDraws",
    "write_draws",
    "read_draws",
    "parameter_units",
    "COLUMNS",
    "evaluation_csv",
    "evaluation_document",
    "convergence_of",
    "evaluation_headline",
    "write_evaluation_folder",
    "EXPORT_FORMATS",
    "UR_JOINT_NAMES",
    "coupled_joints",
    "joint_origins",
    "model_variable_limits",
    "require_uncoupled",
    "rpy_from_matrix",
    "parameters_to_urdf",
    "parameters_to_ur_yaml",
    "dh_table",
    "mdh_table",
    "table_to_csv",
    "table_to_markdown",
    "instrument_presets",
    "make_instrument",
    "ISO_COLUMNS",
    "iso_to_csv",
    "SUMMARY_COLUMNS",
    "backlash_csv",
    "harmonics_document",
    "joints_files",
    "points_csv",
    "summary_csv",
    "write_joints_folder",
    "MARKER",
    "LOCK_SUFFIX",
    "check_output_folder",
    "check_output_file",
    "existing_inputs",
    "foreign_entries",
    "is_robotcal_folder",
    "is_robotcal_file",
    "output_lock",
    "result_file",
    "result_folder",
    "write_marker",
    "parameters_to_dict",
    "read_parameters",
    "read_targets",
    "refined_targets",
    "targets_to_dict",
    "write_parameters",
    "cpa_provenance",
    "refine_provenance",
    "scenario_echo",
    "versions",
    "robot_to_dict",
    "RobotFile",
    "JointEntry",
    "load_robot",
    "robot_from_dict",
    "list_robots",
    "OUTPUTS",
    "REPORT_NAME",
    "RUN_ENTRIES",
    "RUN_RECORD",
    "STAGES",
    "Document",
    "RunResult",
    "Table",
    "json_text",
    "read_document",
    "read_run",
    "refusal",
    "run_documents",
    "table_from_text",
    "write_csv",
    "write_json",
    "CONSISTENT_RATIO",
    "Consistency",
    "ModelUncertainty",
    "Spread",
    "Summary",
    "set_label",
    "summarise",
    "Scenario",
    "MissingTable",
    "MonteCarloTable",
    "TruthTable",
    "ValidationTable",
    "TCPTable",
    "load_scenario",
    "list_scenarios",
    "scenario_from_dict",
    "TCP_CSV_COLUMNS",
    "tcp_json_text",
    "tcp_to_csv",
    "tcp_to_dict",
    "write_tcp_csv",
    "write_tcp_folder",
    "write_tcp_json",
    "UNITS_MM",
    "TrackerPoints",
    "JointLog",
    "parse_column_map",
    "read_tracker_export",
    "read_joint_log",
    "join_points_to_readings",
    "import_tracker_capture",
    "read_trajectory",
    "write_trajectory",
    "trajectory_to_csv",
    "load_trajectory",
    "builtin_trajectories",
    "CSV_COLUMNS",
    "uncertainty_rows",
    "write_uncertainty_csv",
    "write_uncertainty_json",
    "read_uncertainty_csv",
    "write_uncertainty_folder",
    "MEASURED_TARGET_COLUMNS",
    "measured_target_rows",
    "write_measured_folder",
]
