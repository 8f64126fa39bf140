"""The run-option tables of a scenario stay typed and frozen, and their defaults live in one place (issue 13).

``[montecarlo]``, ``[truth]``, ``[validation]`` and ``[tcp]`` are the pydantic models of
``robotcal.io.schema.scenario``; every consumer reads their attributes. The proof that no consumer restates a
default: change the default in the table definition and see the change arrive at every consumer.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from robotcal.api import perturb, simulate_poses, tcp_targets
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.io.schema.builtins import data_path, read_toml
from robotcal.io.schema.scenario import (
    MonteCarloTable,
    ScenarioFile,
    TCPTable,
    TruthTable,
    ValidationTable,
    scenario_from_dict,
)
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline import plan_run

DOCS = Path(__file__).parents[3] / "docs" / "scenario.md"
TABLES = {"montecarlo": MonteCarloTable, "truth": TruthTable, "validation": ValidationTable, "tcp": TCPTable}


def test_tables_are_typed_frozen_and_hold_the_file_values():
    demo = load_scenario("kr5-demo")
    assert isinstance(demo.montecarlo, MonteCarloTable) and demo.montecarlo.iterations == 100_000
    assert demo.montecarlo.seed == 1 and demo.montecarlo.coverage == 0.95
    assert isinstance(demo.truth, TruthTable) and (demo.truth.length_sd_mm, demo.truth.seed) == (0.2, 11)
    assert demo.truth.include_base is False  # not in the file: the default
    assert isinstance(demo.validation, ValidationTable) and (demo.validation.poses, demo.validation.seed) == (100, 2)
    assert demo.validation.flange_reflector_mm == (60.0, 40.0, 30.0)  # a tuple: the table cannot be mutated
    assert demo.tcp == TCPTable()  # no [tcp] table: the defaults, typed all the same
    with pytest.raises(ValidationError, match="frozen"):
        demo.montecarlo.iterations = 5
    # the settings echo (run.json) is a plain document of the same values
    assert demo.settings["montecarlo"] == demo.montecarlo.model_dump()
    assert demo.settings["validation"]["poses"] == 100 and demo.settings["tcp"] == TCPTable().model_dump()


def test_absent_tables():
    noise_free = load_scenario("thesis-noise-free")  # no [montecarlo], [truth], [validation], [tcp]
    assert noise_free.truth is None and noise_free.validation is None
    assert noise_free.montecarlo == MonteCarloTable() and noise_free.tcp == TCPTable()


def test_table_errors_name_the_key():
    data = read_toml(data_path("scenarios", "kr5-demo.toml"))
    bad = {**data, "validation": {**data["validation"], "flange_reflector_mm": [1.0, 2.0]}}
    with pytest.raises(InputError, match=r"key `validation\.flange_reflector_mm`: .*\[x, y, z\]; got 2 values"):
        scenario_from_dict(bad)
    bad = {**data, "tcp": {"tool_mm": [0.0, 0.0, 1.0, 2.0]}}
    with pytest.raises(InputError, match=r"key `tcp\.tool_mm`: .*\[x, y, z\]; got 4 values"):
        scenario_from_dict(bad)


def _documented_defaults(section: str) -> dict[str, str]:
    """``key -> default`` of the docs/scenario.md table under ``### `[section]```."""
    text = DOCS.read_text(encoding="utf-8")
    start = text.index(f"### `[{section}]`")
    end = text.find("\n### ", start + 1)
    rows = re.findall(r"^\| `(\w+)` \| [^|]+ \| ([^|]+) \|", text[start:end], flags=re.MULTILINE)
    return {key: default.strip() for key, default in rows}


@pytest.mark.parametrize("section", sorted(TABLES))
def test_documented_defaults_are_the_table_defaults(section):
    documented = _documented_defaults(section)
    defaults = TABLES[section]()
    assert set(documented) == set(TABLES[section].model_fields), f"docs/scenario.md [{section}] lists other keys"
    for key, shown in documented.items():
        value = getattr(defaults, key)
        literal = re.fullmatch(r"`(.+)`", shown)
        if literal is None:  # prose ("none", "the Table 5.8 pose", "flange origin"): no value
            assert value is None, f"[{section}] {key}: documented as {shown!r}, default {value!r}"
            continue
        text = literal.group(1).strip('"')
        if isinstance(value, bool):
            assert text == str(value).lower(), key
        elif isinstance(value, tuple):
            assert [float(v) for v in text.strip("[]").split(",")] == list(value), key
        elif isinstance(value, int | float):
            assert float(text) == value, key
        else:  # the built-in trajectory: a name the code resolves, not a field default
            assert section == "tcp" and key == "trajectory" and value is None, key


@pytest.fixture
def changed_defaults():
    """Change one default of each table, in the table definition only, for one test (the file model,
    which embeds the tables' validators, is rebuilt with them)."""
    changes = {
        MonteCarloTable: {"iterations": 777},
        TruthTable: {"length_sd_mm": 0.0, "angle_sd_deg": 0.0},
        ValidationTable: {"poses": 9},
        TCPTable: {"workspace_poses": 13, "workspace_seed": 5},
    }
    saved = []
    try:
        for table, fields in changes.items():
            for name, value in fields.items():
                saved.append((table, name, table.model_fields[name].default))
                table.model_fields[name].default = value
            table.model_rebuild(force=True)
        ScenarioFile.model_rebuild(force=True)
        yield changes
    finally:
        for table, name, value in saved:
            table.model_fields[name].default = value
        for table in changes:
            table.model_rebuild(force=True)
        ScenarioFile.model_rebuild(force=True)


def test_a_default_changed_in_the_table_reaches_every_consumer(tmp_path, changed_defaults):
    text = data_path("scenarios", "kr5-demo.toml").read_text(encoding="utf-8")
    text = text[: text.index("[montecarlo]")]  # drop [montecarlo], [truth], [validation]; no [tcp] either
    path = tmp_path / "bare.toml"
    path.write_text(text + "[validation]\nflange_reflector_mm = [60.0, 40.0, 30.0]\n", encoding="utf-8")
    plan = plan_run(path)
    scenario = plan.scenario
    assert plan.montecarlo.iterations == 777  # pipeline.plan_run
    assert tcp_targets(scenario).workspace_poses == 13 and plan.tcp.workspace_poses == 13  # workflow, run
    assert plan.seeds["workspace"] == 5
    assert simulate_poses(scenario, rng=3).n_points == 9  # [validation] given without `poses`
    truth = perturb(scenario, rng=3)  # no [truth] table: the table defaults, zero deviations
    np.testing.assert_array_equal(truth.values, ParameterSet.nominal(scenario.robot).values)


def test_the_fixture_restores_the_defaults():
    assert MonteCarloTable().iterations == 100_000 and ValidationTable().poses == 100
    assert ScenarioFile.model_validate({"robot": "r", "validation": {}}).validation.poses == 100
    assert TCPTable().workspace_poses == 1000 and TruthTable().length_sd_mm == 0.2
