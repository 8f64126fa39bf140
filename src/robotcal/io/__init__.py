"""I/O at the edge: TOML robots and scenarios, capture CSV, parameter JSON, atomic writes."""

from robotcal.io.atomic import atomic_write_bytes, atomic_write_text
from robotcal.io.builtins import builtin_names, data_path
from robotcal.io.capture_csv import capture_to_csv, read_capture, write_capture
from robotcal.io.instruments import instrument_presets, make_instrument
from robotcal.io.parameters_json import parameters_to_dict, read_parameters, write_parameters
from robotcal.io.robots import list_robots, load_robot, robot_from_dict
from robotcal.io.scenario import Scenario, list_scenarios, load_scenario, scenario_from_dict

__all__ = [
    "atomic_write_bytes",
    "atomic_write_text",
    "builtin_names",
    "data_path",
    "capture_to_csv",
    "read_capture",
    "write_capture",
    "instrument_presets",
    "make_instrument",
    "parameters_to_dict",
    "read_parameters",
    "write_parameters",
    "list_robots",
    "load_robot",
    "robot_from_dict",
    "Scenario",
    "list_scenarios",
    "load_scenario",
    "scenario_from_dict",
]
