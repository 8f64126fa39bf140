"""Issue 30, item 1: a TOML boolean is never a number, a number never a boolean.

pydantic's lax mode read ``[montecarlo] seed = true`` as seed 1 and ``[payload] mass_kg = true`` as a 1 kg payload
written into the truth. Every number of a scenario or robot TOML is now strict, and the error names the file, the
key and the value as it was written (``true``, not 1).
"""

from __future__ import annotations

import re
import tomllib

import pytest

from robotcal.errors import InputError
from robotcal.io.schema.builtins import data_path
from robotcal.io.schema.instruments import make_instrument
from robotcal.io.schema.robots import robot_from_dict
from robotcal.io.schema.scenario import load_scenario, scenario_from_dict

ROBOT = "kuka-kr5-sixx-r650"


def _scenario(table: str, key: str, value) -> dict:
    """A valid scenario of the KR 5 with ``[table] key = value`` (other keys of the table that it needs)."""
    needs = {"payload": {"mass_kg": 1.0}}
    entry = dict(needs.get(table, {}))
    entry[key] = value
    return {"robot": ROBOT, table: entry}


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ("montecarlo", "seed"),
        ("montecarlo", "iterations"),
        ("montecarlo", "refined_iterations"),
        ("montecarlo", "coverage"),
        ("capture", "seed"),
        ("joint_model", "harmonic_order"),
        ("joint_model", "folds"),
        ("payload", "mass_kg"),
        ("truth", "length_sd_mm"),
        ("truth", "seed"),
        ("validation", "poses"),
        ("validation", "margin_deg"),
        ("tcp", "workspace_poses"),
        ("instrument", "a_um"),
        ("identification", "near_parallel_deg"),
    ],
)
@pytest.mark.parametrize("written", [True, False])
def test_a_boolean_is_refused_where_a_number_is_expected(table, key, written):
    text = "true" if written else "false"
    with pytest.raises(InputError, match=rf"^s\.toml: key `{table}\.{key}`: .*; got {text}$"):
        scenario_from_dict(_scenario(table, key, written), source="s.toml")


@pytest.mark.parametrize(
    ("table", "key", "value", "written"),
    [
        ("montecarlo", "seed", "5", '"5"'),  # a text is no number either
        ("montecarlo", "iterations", 1000.0, "1000.0"),  # a count is an integer
        ("truth", "compliance_rad_per_nm", [0.0, True, 0.0, 0.0, 0.0, 0.0], "true"),
        ("truth", "include_base", 1, "1"),  # and a number is no boolean
        ("capture", "bidirectional", 0, "0"),
        ("tcp", "pose_deg", [0.0, 90.0, "0", 0.0, 0.0, 0.0], '"0"'),
        ("montecarlo", "coverage", float("nan"), "nan"),
    ],
)
def test_other_lax_values_are_refused_and_quoted_as_written(table, key, value, written):
    with pytest.raises(InputError, match=rf"s\.toml: key `{table}\.{key}(\[\d\])?`: .*; got {re.escape(written)}"):
        scenario_from_dict(_scenario(table, key, value), source="s.toml")


@pytest.mark.parametrize(
    ("table", "key", "value", "bound"),
    [
        ("montecarlo", "iterations", 0, ">= 1"),
        ("montecarlo", "refined_iterations", 0, ">= 1"),
        ("joint_model", "harmonic_order", 9, "<= 4"),
        ("joint_model", "harmonic_order", 0, ">= 1"),
        ("montecarlo", "seed", -3, ">= 0"),
        ("payload", "mass_kg", -2.5, ">= 0"),
    ],
)
def test_an_out_of_range_number_is_quoted_as_written(table, key, value, bound):
    message = rf"^s\.toml: key `{table}\.{key}`: must be {re.escape(bound)}; got {re.escape(str(value))}$"
    with pytest.raises(InputError, match=message):
        scenario_from_dict(_scenario(table, key, value), source="s.toml")


def test_the_whole_file_is_quoted_from_toml(tmp_path):
    """From a file on disk: ``true`` as the user wrote it, the file's path first."""
    path = tmp_path / "s.toml"
    path.write_text(f'robot = "{ROBOT}"\n[payload]\nmass_kg = true\n', encoding="utf-8")
    with pytest.raises(InputError, match=r"s\.toml: key `payload\.mass_kg`: must be a number; got true$") as caught:
        load_scenario(path)
    assert str(caught.value).startswith(str(path))


def _robot(**changes) -> dict:
    data = tomllib.loads(data_path("robots", f"{ROBOT}.toml").read_text(encoding="utf-8"))
    data["joints"][1].update(changes)
    return data


@pytest.mark.parametrize(
    ("key", "value", "written"),
    [
        ("d", True, "true"),
        ("theta", False, "false"),
        ("reading_sign", True, "true"),
        ("reading_offset_deg", "5", '"5"'),
        ("hayati", 1, "1"),
        ("mass_kg", True, "true"),
        ("capsule_radius_mm", float("inf"), "inf"),
    ],
)
def test_robot_toml_numbers_are_strict(key, value, written):
    with pytest.raises(InputError, match=rf"r\.toml: key `joints\[1\]\.{key}`: .*; got {re.escape(written)}"):
        robot_from_dict(_robot(**{key: value}), "r.toml")


def test_robot_limits_and_coupling_are_strict():
    with pytest.raises(InputError, match=r"key `joints\[1\]\.limits_deg\[0\]`: must be a number; got true"):
        robot_from_dict(_robot(limits_deg=[True, 90.0]), "r.toml")
    with pytest.raises(InputError, match=r"key `joints\[1\]\.reading_coupling\.3`: must be a number; got false"):
        robot_from_dict(_robot(reading_coupling={"3": False}), "r.toml")


def test_the_builtin_files_still_read():
    """Every built-in scenario and robot is written with real integers and numbers."""
    from robotcal.io import list_robots, list_scenarios

    assert list_robots() and list_scenarios()


def test_instrument_terms_must_be_numbers():
    """The instrument reader takes its terms from a preset or the caller: a boolean is refused there too."""
    with pytest.raises(InputError, match=r"^instrument: key `a_um`: must be a number; got true$"):
        make_instrument(a_um=True, b_um_per_m=1.0)
    with pytest.raises(InputError, match=r"key `coverage_factor`: must be a number; got \"x\"$"):
        make_instrument(preset="thesis-laser-tracker", coverage_factor="x")


def test_a_key_of_several_types_names_the_element_once():
    """``start_deg`` is numbers or rows of numbers: the error is about the element, not about every type."""
    rows = [[0.0] * 6] * 5 + [[0.0, 0.0, False, 0.0, 0.0, 0.0]]
    for value, message in [
        ([True, 0.0, 0.0, 0.0, 0.0, 0.0], r"key `capture\.start_deg\[0\]`: must be a number; got true"),
        (rows, r"key `capture\.start_deg\[5\]\[2\]`: must be a number; got false"),
        (5, r"key `capture\.start_deg`: must be an array \[\.\.\.\]; got 5"),
    ]:
        with pytest.raises(InputError, match=rf"^s\.toml: {message}$"):
            scenario_from_dict({"robot": ROBOT, "capture": {"start_deg": value}}, source="s.toml")
