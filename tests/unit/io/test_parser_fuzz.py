"""Hypothesis fuzz of every file parser: only :class:`InputError` (or a result) may ever escape.

Issue 12: hostile input (random bytes, a 200,000-character cell, a 5,000-digit integer, JSON nested
10,000 deep, a corrupt ``robot_json`` in a draws file, wrong types anywhere) must end in one clean
error naming the file, never a traceback. Each parser gets a bounded number of examples built two
ways: raw random bytes, and a valid file with a few "nasty" tokens spliced in at random places (the
mutations reach deep into the parsers, which random bytes rarely do). A found failure is shrunk by
hypothesis and printed with the exact file content.
"""

from __future__ import annotations

import io
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io import load_scenario
from robotcal.io.formats.capture_csv import capture_to_csv, read_capture
from robotcal.io.formats.draws_npz import read_draws, write_draws
from robotcal.io.formats.parameters_json import read_parameters, write_parameters
from robotcal.io.formats.trajectory_csv import read_trajectory
from robotcal.io.schema.builtins import data_path
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.model import ParameterSet

FUZZ = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,  # the same examples on every run: a CI failure is reproducible locally
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

#: Tokens that broke parsers in issue 12's review, and their relatives.
NASTY = [
    "",
    ",",
    "\n",
    "\r",
    '"',
    "'",
    "#",
    "=",
    "[",
    "]",
    "{",
    "}",
    "[[",
    "\x00",
    "\ufeff",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e400",
    "1_0",
    "0x10",
    "true",
    "null",
    "{}",
    "[]",
    '"text"',
    "9" * 401,
    "9" * 5000,
    "[" * 3000,
    "{" * 3000,
    "a" * 200_000,
    "q99999999999",
    "q" + "9" * 5000,
]


@st.composite
def mutated(draw, text: str):
    """``text`` with 1-3 nasty or random tokens inserted or substituted at random positions."""
    for _ in range(draw(st.integers(1, 3))):
        token = draw(st.one_of(st.sampled_from(NASTY), st.text(max_size=12)))
        start = draw(st.integers(0, len(text)))
        end = min(len(text), start + draw(st.integers(0, 12)))
        text = text[:start] + token + text[end:]
    return text.encode("utf-8", errors="surrogatepass")


def contents(text: str):
    """Strategy over file contents: random bytes or a mutated valid file."""
    return st.one_of(st.binary(max_size=300), mutated(text))


def _only_input_errors(read, data: bytes, suffix: str):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"fuzzed{suffix}"
        path.write_bytes(data)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # warnings (e.g. a repaired matrix) are results, not failures
            try:
                read(path)
            except InputError as exc:
                message = str(exc)
                assert str(path) in message, message  # the error names the file
                assert "\n" not in message, message  # one line


def _capture() -> Capture:
    rng = np.random.default_rng(0)
    circle = np.repeat(np.arange(1, 7), 3)
    readings = np.zeros((18, 6))
    readings[np.arange(18), circle - 1] = np.tile([0.0, 0.3, 0.6], 6)
    return Capture(
        circle=circle,
        direction=np.ones(18, dtype=int),
        readings=readings,
        points=rng.normal(size=(18, 3)) * 500,
        source="",
    )


CAPTURE_TEXT = capture_to_csv(_capture())
TRAJECTORY_TEXT = data_path("trajectories", "kr5-sweep-75.csv").read_text(encoding="utf-8")[:1500]
SCENARIO_TEXT = data_path("scenarios", "kr5-demo.toml").read_text(encoding="utf-8")
ROBOT_TEXT = data_path("robots", "kuka-kr5-sixx-r650.toml").read_text(encoding="utf-8")
ROBOT = load_robot("kuka-kr5-sixx-r650")


def _parameter_text() -> str:
    nominal = ParameterSet(robot=ROBOT, values=ROBOT.nominal, identified=np.ones((6, 5), dtype=bool))
    with tempfile.TemporaryDirectory() as folder:
        return write_parameters(Path(folder) / "p.json", nominal).read_text(encoding="utf-8")


PARAMETER_TEXT = _parameter_text()


@FUZZ
@given(data=contents(CAPTURE_TEXT), n_joints=st.sampled_from([None, 6]))
def test_capture_csv_fuzz(data, n_joints):
    _only_input_errors(lambda p: read_capture(p, n_joints=n_joints), data, ".csv")


@FUZZ
@given(data=contents(TRAJECTORY_TEXT))
def test_trajectory_csv_fuzz(data):
    _only_input_errors(lambda p: read_trajectory(p, n_joints=6), data, ".csv")


@FUZZ
@given(data=contents(SCENARIO_TEXT))
def test_scenario_toml_fuzz(data):
    _only_input_errors(load_scenario, data, ".toml")


@FUZZ
@given(data=contents(ROBOT_TEXT))
def test_robot_toml_fuzz(data):
    _only_input_errors(load_robot, data, ".toml")


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**450), max_value=10**450)
    | st.floats()
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=6), children, max_size=3),
    max_leaves=8,
)


@st.composite
def parameter_documents(draw):
    """A valid parameter JSON with one key (top level or inside a joint) replaced by any JSON value."""
    document = json.loads(PARAMETER_TEXT)
    value = draw(json_values)
    where = draw(st.sampled_from(["robot", "units", "joints", "identified", "joint", "joint-entry"]))
    if where == "joint":
        document["joints"][draw(st.integers(0, 5))] = value
    elif where == "joint-entry":
        key = draw(st.sampled_from(["d", "theta", "a", "alpha", "beta", "hayati"]))
        document["joints"][draw(st.integers(0, 5))][key] = value
    else:
        document[where] = value
    return json.dumps(document).encode()


@FUZZ
@given(data=st.one_of(contents(PARAMETER_TEXT), parameter_documents()))
def test_parameter_json_fuzz(data):
    _only_input_errors(lambda p: read_parameters(p, ROBOT), data, ".json")


arrays = st.one_of(
    st.just(np.array("{not json")),
    st.just(np.array("[" * 5000)),
    st.just(np.array(json.dumps({"name": "x", "joints": [{"d": 10**401}]}))),
    st.just(np.array(json.dumps([1, 2]))),
    st.just(np.array(["a", "b"])),
    st.just(np.zeros((0,))),
    st.just(np.zeros((2, 3))),
    st.just(np.array(2**70, dtype=object).astype(float)),
    st.just(np.array([True])),
    st.just(np.array(1.5)),
    st.just(np.array("text")),
    st.just(np.full((3, 30), np.nan)),
)


@st.composite
def draws_files(draw):
    """A valid draws.npz with one key replaced (or dropped), or random bytes."""
    with tempfile.TemporaryDirectory() as folder:
        path = write_draws(Path(folder) / "d.npz", ROBOT, np.repeat(ROBOT.nominal[None], 3, 0), np.ones((6, 5)), seed=1)
        with np.load(path) as archive:
            keys = {key: archive[key] for key in archive.files}
    key = draw(st.sampled_from(sorted(keys)))
    if draw(st.booleans()):
        keys[key] = draw(arrays)
    else:
        del keys[key]
    buffer = io.BytesIO()
    np.savez(buffer, **keys)
    return buffer.getvalue()


@FUZZ
@given(data=st.one_of(st.binary(max_size=300), draws_files()))
def test_draws_npz_fuzz(data):
    _only_input_errors(read_draws, data, ".npz")


@pytest.mark.parametrize(
    "document",
    [
        "[" * 100_000,
        '{"a":' * 50_000,
        json.dumps({"joints": [{"d": 10**401}]}),
        '{"joints": [{"d": 1' + "0" * 5000 + "}]}",
    ],
)
def test_parameter_json_nesting_and_huge_numbers(tmp_path, document):
    path = tmp_path / "p.json"
    path.write_text(document)
    with pytest.raises(InputError, match="p.json"):
        read_parameters(path, ROBOT)
