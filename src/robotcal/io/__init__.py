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
>>> capture = robotcal.simulate("thesis-laser-tracker", rng=5)
>>> with tempfile.TemporaryDirectory() as folder:
...     path = write_capture(os.path.join(folder, "capture.csv"), capture)
...     back = read_capture(path, n_joints=6)
>>> back.n_points == capture.n_points, bool(np.array_equal(back.circle, capture.circle))
(True, True)
>>> bool(np.allclose(back.readings, capture.readings, rtol=0, atol=1e-12))  # rad, from 12-decimal degrees
True
"""

from robotcal import _lazy_exports
from robotcal.io.atomic import atomic_directory, atomic_write_bytes, atomic_write_text
from robotcal.io.builtins import builtin_names, data_path, read_toml
from robotcal.io.capture_csv import capture_to_csv, read_capture, write_capture
from robotcal.io.instruments import instrument_presets, make_instrument
from robotcal.io.parameters_json import parameters_to_dict, read_parameters, write_parameters
from robotcal.io.robots import JointEntry, RobotFile, list_robots, load_robot, robot_from_dict, robot_to_dict
from robotcal.io.scenario import Scenario, list_scenarios, load_scenario, scenario_from_dict

_LAZY = {
    **dict.fromkeys(
        ("MissingTable", "MonteCarloTable", "TruthTable", "ValidationTable", "TCPTable"), "robotcal.io.scenario"
    ),
    **dict.fromkeys(("ISO_COLUMNS", "iso_to_csv"), "robotcal.io.iso9283_files"),
    **dict.fromkeys(("targets_to_dict", "read_targets", "read_tracker_from_base"), "robotcal.io.parameters_json"),
    **dict.fromkeys(("ParameterDraws", "write_draws", "read_draws", "parameter_units"), "robotcal.io.draws_npz"),
    **dict.fromkeys(
        (
            "EXPORT_FORMATS",
            "UR_JOINT_NAMES",
            "joint_origins",
            "rpy_from_matrix",
            "parameters_to_urdf",
            "parameters_to_ur_yaml",
            "dh_table",
            "mdh_table",
            "table_to_csv",
            "table_to_markdown",
            "coupled_joints",
            "model_variable_limits",
            "require_uncoupled",
        ),
        "robotcal.io.export",
    ),
    **dict.fromkeys(
        (
            "MARKER",
            "SIGNATURE",
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
        ),
        "robotcal.io.output",
    ),
    **dict.fromkeys(
        ("TCP_CSV_COLUMNS", "tcp_to_csv", "write_tcp_csv", "tcp_to_dict", "tcp_json_text", "write_tcp_json"), "robotcal.io.tcp_results"
    ),
    **dict.fromkeys(
        (
            "MAX_READING_DEG",
            "read_trajectory",
            "write_trajectory",
            "trajectory_to_csv",
            "load_trajectory",
            "builtin_trajectories",
        ),
        "robotcal.io.trajectory_csv",
    ),
    **dict.fromkeys(
        ("CSV_COLUMNS", "uncertainty_rows", "write_uncertainty_csv", "write_uncertainty_json", "read_uncertainty_csv"),
        "robotcal.io.uncertainty_files",
    ),
    **dict.fromkeys(
        (
            "UNITS_MM",
            "TrackerPoints",
            "JointLog",
            "parse_column_map",
            "read_tracker_export",
            "read_joint_log",
            "join_points_to_readings",
            "import_tracker_capture",
        ),
        "robotcal.io.tracker_import",
    ),
}

__all__ = [
    "atomic_directory",
    "atomic_write_bytes",
    "atomic_write_text",
    "builtin_names",
    "data_path",
    "read_toml",
    "capture_to_csv",
    "read_capture",
    "write_capture",
    "instrument_presets",
    "make_instrument",
    "parameters_to_dict",
    "read_parameters",
    "write_parameters",
    "JointEntry",
    "RobotFile",
    "list_robots",
    "load_robot",
    "robot_from_dict",
    "robot_to_dict",
    "Scenario",
    "list_scenarios",
    "load_scenario",
    "scenario_from_dict",
    *_LAZY,
]

__getattr__, __dir__ = _lazy_exports(__name__, _LAZY)
