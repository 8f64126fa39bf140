"""Robot programs: parse every program back and check each angle against the plan and the limits."""

from __future__ import annotations

import re

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.planning.program import controller_readings, write_program
from robotcal.planning.scenario import scenario_document, scenario_from_document, set_key

#: KUKA counts A1-A4 and A6 opposite to the DH z axes (docs/conventions.md, Table 5.8).
KUKA_SIGNS = np.array([-1.0, -1.0, -1.0, -1.0, 1.0, -1.0])


def _feasible_thesis_plan():
    """Table 5.1 with J5 turned 100 deg instead of 200 (within +-120), both directions."""
    document, base, name, source = scenario_document("thesis-noise-free")
    document = set_key(set_key(document, "capture.sweep_deg.5", 100.0), "capture.bidirectional", True)
    return scenario_from_document(document, base, name, source)


def _parse(text: str, language: str):
    if language == "krl":
        moves = [
            [float(v) for v in re.findall(r"A\d+ (-?[\d.]+)", line)] for line in text.splitlines() if "PTP {" in line
        ]
        dwell = [float(v) for v in re.findall(r"WAIT SEC ([\d.]+)", text)]
        return np.deg2rad(moves), dwell
    if language == "rapid":
        moves = [[float(v) for v in m.split(",")] for m in re.findall(r"MoveAbsJ \[\[([^\]]+)\]", text)]
        dwell = [float(v) for v in re.findall(r"WaitTime ([\d.]+);", text)]
        return np.deg2rad(moves), dwell
    moves = [[float(v) for v in m.split(",")] for m in re.findall(r"movej\(\[([^\]]+)\]", text)]
    dwell = [float(v) for v in re.findall(r"sleep\(([\d.]+)\)", text)]
    return np.array(moves), dwell


@pytest.mark.parametrize("language", ["krl", "rapid", "urscript"])
def test_program_round_trip_in_kuka_controller_convention(language):
    scenario = _feasible_thesis_plan()
    controller = load_robot("kuka-kr5-sixx-r650-krc")
    circle, direction, readings = scenario.plan.readings()
    angles = controller_readings(readings, scenario.robot, controller)
    # independent truth: model readings times KUKA's signs (the model robot file has the identity map)
    np.testing.assert_allclose(angles, readings * KUKA_SIGNS, atol=1e-12)
    text = write_program(circle, direction, angles, language=language, dwell_s=1.5)
    moves, dwell = _parse(text, language)
    assert moves.shape == readings.shape == (270, 6)
    # 6 decimals of a degree (KRL, RAPID) or 9 of a radian (URScript) are written
    tolerance = 0.6e-6 if language == "urscript" else np.deg2rad(0.6e-6)
    np.testing.assert_allclose(moves, readings * KUKA_SIGNS, atol=tolerance)
    assert dwell == [1.5] * 270
    low, high = controller.limits[:, 0], controller.limits[:, 1]
    assert np.all((moves >= low - tolerance) & (moves <= high + tolerance))
    comments = re.findall(r"circle (\d) (forward|return) point (\d+)", text)
    assert len(comments) == 270
    assert comments[0] == ("1", "forward", "1") and comments[15] == ("1", "return", "1")
    assert comments[-1] == ("6", "return", "30")


def test_program_refuses_readings_beyond_the_limits():
    document, base, name, source = scenario_document("thesis-noise-free")  # J5 to 200 deg
    scenario = scenario_from_document(document, base, name, source)
    _, _, readings = scenario.plan.readings()
    with pytest.raises(InputError, match=r"A5 = 125.000 deg is outside the limits \[-120, 120\]"):
        controller_readings(readings, scenario.robot, load_robot("kuka-kr5-sixx-r650-krc"))


def test_program_validation():
    readings = np.zeros((3, 7))
    with pytest.raises(InputError, match="6-axis"):
        write_program([1, 1, 1], [1, 1, 1], readings, language="rapid", dwell_s=1.0)
    with pytest.raises(InputError, match="unknown language"):
        write_program([1, 1, 1], [1, 1, 1], readings, language="val3", dwell_s=1.0)
    with pytest.raises(InputError, match="dwell"):
        write_program([1, 1, 1], [1, 1, 1], readings, language="krl", dwell_s=-1.0)
    text = write_program([1, 1, 1], [1, 1, 1], readings, language="krl", dwell_s=0.0)
    assert text.count("PTP {A1 0.000000") == 3 and "A7 0.000000" in text


@pytest.mark.parametrize("language", ["krl", "rapid", "urscript"])
def test_program_with_labels_instead_of_circles(language):
    readings = np.radians([[0.0, 90.0, -90.0, 0.0, 45.0, 0.0], [10.0, 80.0, -70.0, 5.0, 40.0, -5.0]])
    text = write_program(None, None, readings, language=language, dwell_s=0.5, labels=["cycle 1 P1", "cycle 1 P2"])
    comment = {"krl": ";", "rapid": "!", "urscript": "#"}[language]
    assert re.findall(rf"{comment} (cycle 1 P\d)", text) == ["cycle 1 P1", "cycle 1 P2"]
    assert "circle" not in text
    moves, dwell = _parse(text, language)
    tolerance = 0.6e-6 if language == "urscript" else np.deg2rad(0.6e-6)
    np.testing.assert_allclose(moves, readings, rtol=0, atol=tolerance)
    assert dwell == [0.5, 0.5]
    with pytest.raises(InputError, match="2 one-line comments"):
        write_program(None, None, readings, language=language, dwell_s=0.5, labels=["only one"])
    with pytest.raises(InputError, match="one-line"):
        write_program(None, None, readings, language=language, dwell_s=0.5, labels=["a", "b\nDEF x()"])


# --- issue 24: KRL names (24 characters, DEF name = file name) and no negative zero -------------------


@pytest.mark.parametrize("language", ["krl", "rapid", "urscript"])
def test_no_negative_zero_in_any_language(language):
    # KUKA's signs turn the plan's 0 deg readings into -0.0; a tiny negative reading rounds to zero too
    readings = np.array([[0.0, -0.0, -1e-12, 0.25, -0.0, 0.0]]) * KUKA_SIGNS
    text = write_program([1], [1], readings, language=language, dwell_s=-0.0)
    assert not re.search(r"-0\.0+\b", text), text
    assert not re.search(r"(SEC|WaitTime|sleep\() ?-0", text), text
    moves, _ = _parse(text, language)
    tolerance = 0.6e-9 if language == "urscript" else np.deg2rad(0.6e-6)  # the decimals written
    np.testing.assert_allclose(moves, readings, rtol=0, atol=tolerance)
    assert not np.any(np.signbit(moves[moves == 0.0]))  # parsed back as +0.0


def test_program_names_per_language():
    from robotcal.planning.program import check_program_name, program_name

    assert program_name("krl", "out/capture_1.src") == "capture_1"  # DEF name = file name
    assert program_name("krl", "out/Capture_1.src", "CAPTURE_1") == "Capture_1"  # KRL ignores case: the file's spelling
    assert program_name("rapid", "out/x.mod") == "robotcal_capture"
    assert program_name("urscript", "out/x.script", "calib") == "calib"
    assert check_program_name("a" * 24, "krl") == "a" * 24
    assert check_program_name("a" * 32, "rapid") == "a" * 32
    assert check_program_name("a" * 200, "urscript") == "a" * 200
    for name, language, message in [
        ("a" * 25, "krl", r"has 25 characters; KRL allows at most 24"),
        ("a" * 33, "rapid", r"has 33 characters; RAPID allows at most 32"),
        ("9lives", "krl", r"is not a valid KRL name: it must start with a letter"),
        ("my-prog", "urscript", r"not a valid URSCRIPT name"),
        ("capture\nDEF x", "krl", r"not a valid KRL name"),
        ("loop", "krl", r"'loop' is a KRL keyword"),
    ]:
        with pytest.raises(InputError, match=message):
            check_program_name(name, language)
    with pytest.raises(InputError, match=r"--name 'other' differs from the file name 'capture.src': a KRL program's DEF"):
        program_name("krl", "capture.src", "other")
    with pytest.raises(InputError, match=r"--name 'a{36}\.\.\. has 200 characters; KRL allows at most 24"):
        program_name("krl", "capture.src", "a" * 200)
    with pytest.raises(InputError, match=r"KRL program name \(the file name of 'calibration_of_the_kr5_robot.src'\)"):
        program_name("krl", "calibration_of_the_kr5_robot.src")
    with pytest.raises(InputError, match=r"has 200 characters; KRL allows at most 24"):
        write_program([1], [1], np.zeros((1, 6)), language="krl", dwell_s=1.0, name="a" * 200)
