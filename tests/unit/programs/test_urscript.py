"""URScript reader and writer (robotcal.programs.urscript): the sample scripts, frames against closed forms, numbers-only
rewriting, rotation vectors near pi, variables, tools, skipped expressions and malformed scripts."""

from __future__ import annotations

import difflib
import re
from pathlib import Path

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.geometry.transforms import rot_x, rot_y, rot_z, rotation_about_line
from robotcal.programs.base import replace_numbers
from robotcal.programs.urscript import read_program, render

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "programs"
PICK_PLACE = EXAMPLES / "ur_pick_place.script"
DISPENSE = EXAMPLES / "ur_dispense.script"
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def write(tmp_path, text: str, name: str = "prog.script") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return path


def rewrite(tmp_path, program, replacements, name: str):
    """The program's text with ``replacements``, written under ``name`` and read back."""
    (text,) = replace_numbers(program.texts, replacements).values()
    return text, read_program(write(tmp_path, text, name))


def pose_frame(position_mm, axis, angle) -> np.ndarray:
    """Independent Rodrigues frame: a turn of ``angle`` about the unit ``axis`` through the origin, then ``position``."""
    frame = rotation_about_line(np.asarray(axis, float) / np.linalg.norm(axis), np.zeros(3), angle)
    frame[:3, 3] = position_mm
    return frame


def by_label(program):
    return {point.label: point for point in program.points}


# ----------------------------------------------------------------------------------------------- sample scripts ---


def test_pick_place_sample_points_labels_lines_kinds_tools():
    program = read_program(PICK_PLACE)
    assert program.language == "urscript"
    assert list(program.texts) == ["ur_pick_place.script"]
    assert program.texts["ur_pick_place.script"] == PICK_PLACE.read_text(encoding="utf-8")
    assert len(program.points) == 7
    summary = [(p.label, p.line, p.kind, p.motion, p.tool, p.base) for p in program.points]
    assert summary == [
        ("home_q", 10, "joint", "movej", "tcp@7", None),
        ("pick_approach", 13, "cartesian", "movej", "tcp@7", None),  # movej to a pose: Cartesian, motion movej
        ("pick", 14, "cartesian", "movel", "tcp@7", None),
        ("place_approach", 17, "cartesian", "movel", "tcp@7", None),
        ("place", 18, "cartesian", "movel", "tcp@7", None),
        ("ur_pick_place.script:30", 30, "cartesian", "movep", "tcp@7", None),
        ("ur_pick_place.script:38", 38, "joint", "movej", "tcp@7", None),
    ]
    assert all(point.config == {} and point.config_spans == {} for point in program.points)
    points = by_label(program)
    assert points["pick"].values == (0.45, -0.15, 0.18, 0.0, 3.1416, 0.0)
    assert points["home_q"].values == (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)
    text = program.texts["ur_pick_place.script"]
    assert [text[s.start : s.end] for s in points["pick"].spans] == ["0.450", "-0.150", "0.180", "0.0", "3.1416", "0.0"]
    assert text[points["ur_pick_place.script:30"].spans[0].start :].startswith("0.400, 0.050")
    # the set_tcp gripper: 150 mm along the flange z
    assert list(program.frames) == ["tcp@7"]
    np.testing.assert_allclose(program.frames["tcp@7"], pose_frame([0, 0, 150], [0, 0, 1], 0.0), atol=1e-12)
    # the retreat through pose_trans is found and listed, not filtered
    assert len(program.skipped) == 1
    file, line, why = program.skipped[0]
    assert (file, line) == ("ur_pick_place.script", 37)
    assert "pose_trans(place, p[0, 0, -0.05, 0, 0, 0])" in why and "expression" in why


def test_dispense_sample_points_tools_and_skipped():
    program = read_program(DISPENSE)
    assert len(program.points) == 17
    kinds = [point.kind for point in program.points]
    assert kinds.count("joint") == 2 and kinds.count("cartesian") == 15
    motions = [point.motion for point in program.points]
    assert motions.count("movec") == 8  # four fillets, via and end points
    assert motions.count("movej") == 1 and motions.count("movel") == 8
    points = by_label(program)
    assert (points["ready_q"].line, points["ready_q"].motion) == (24, "movej")
    assert (points["start"].line, points["start"].motion) == (28, "movel")
    # a movec over two lines: via on line 36, end on 37; pose_via= / pose_to= keywords on line 41
    assert [(p.line, p.motion) for p in program.points if p.line in (36, 37, 41)] == [
        (36, "movec"),
        (37, "movec"),
        (41, "movec"),
        (41, "movec"),
    ]
    assert program.points[-3].values[:3] == (0.38, -0.12, 0.2)
    # joint positions given to movel: a joint point whose motion is movel
    assert (program.points[-1].kind, program.points[-1].motion, program.points[-1].line) == ("joint", "movel", 54)
    # the nozzle is in force until the camera's set_tcp at line 48
    tools = [point.tool for point in program.points]
    assert tools == ["nozzle"] * 15 + ["tcp@48"] * 2
    assert list(program.frames) == ["nozzle", "tcp@48"]
    np.testing.assert_allclose(
        program.frames["nozzle"], pose_frame([20, 0, 120], [0, 1, 0], np.deg2rad(10.0)), atol=1e-9
    )
    np.testing.assert_allclose(program.frames["tcp@48"][:3, 3], [0, -45, 60], atol=1e-12)
    assert [(line, why.split("`")[1]) for _, line, why in program.skipped] == [
        (29, "pose_add(start, p[0, 0, 0.030, 0, 0, 0])"),
        (51, "p[0.300, 0.0, 0.400, 0.0, d2r(180), 0.0]"),
    ]
    assert "d2r(180)" in program.skipped[1][2]


def test_sample_frames_match_closed_forms():
    points = by_label(read_program(PICK_PLACE))
    # rotation vector (0, 3.1416, 0): a turn of 3.1416 rad about y
    np.testing.assert_allclose(points["pick"].frame_mm, pose_frame([450, -150, 180], [0, 1, 0], 3.1416), atol=1e-12)
    axis = np.array([-1.5708, 2.7207, 0.0])
    np.testing.assert_allclose(
        points["place"].frame_mm, pose_frame([350, 250, 210], axis, np.linalg.norm(axis)), atol=1e-12
    )
    # a tool pointing down turned 60 deg about the base z: Rz(60) Ry(180), to the 4 decimals written
    expected = rot_z(np.deg2rad(60.0)) @ rot_y(np.pi)
    np.testing.assert_allclose(points["place"].frame_mm[:3, :3], expected[:3, :3], atol=1e-4)
    np.testing.assert_allclose(
        points["home_q"].joints_deg,
        [0.0, -90.00021045914971, 90.00021045914971, -90.00021045914971, -90.00021, 0.0],
        atol=1e-5,
    )
    np.testing.assert_allclose(points["home_q"].joints_deg, np.array(points["home_q"].values) * 180.0 / np.pi)
    assert points["home_q"].frame_mm is None and points["pick"].joints_deg is None


def test_frame_of_a_quarter_turn_about_z_is_rz90(tmp_path):
    path = write(
        tmp_path,
        "movel(p[0.4, -0.2, 0.3, 0, 0, 1.5707963267948966])\nmovel(p[0.4, 0.0, 0.3, 3.141592653589793, 0, 0])\n",
    )
    first, second = read_program(path).points
    expected = rot_z(np.pi / 2)
    expected[:3, 3] = [400, -200, 300]
    np.testing.assert_allclose(first.frame_mm, expected, atol=1e-12)
    expected = rot_x(np.pi)
    expected[:3, 3] = [400, 0, 300]
    np.testing.assert_allclose(second.frame_mm, expected, atol=1e-12)


# --------------------------------------------------------------------------------------------------- rendering ---


@pytest.mark.parametrize("sample", [PICK_PLACE, DISPENSE], ids=["pick_place", "dispense"])
def test_render_same_targets_changes_no_value_and_no_other_text(tmp_path, sample):
    program = read_program(sample)
    replacements = {}
    for point in program.points:
        if point.kind == "cartesian":
            replacements.update(render(point, frame_mm=point.frame_mm))
        else:
            replacements.update(render(point, joints_deg=point.joints_deg, config={}))
    text, again = rewrite(tmp_path, program, replacements, sample.name)
    original = program.texts[sample.name]
    assert NUMBER.sub("#", text) == NUMBER.sub("#", original)
    assert len(again.points) == len(program.points)
    for before, after in zip(program.points, again.points, strict=True):
        assert (after.label, after.line, after.kind, after.motion, after.tool) == (
            before.label,
            before.line,
            before.kind,
            before.motion,
            before.tool,
        )
        np.testing.assert_allclose(after.values, before.values, rtol=0, atol=1e-9)
    assert again.skipped == program.skipped
    # rendering the re-read program again gives the same text
    replacements = {}
    for point in again.points:
        key = "frame_mm" if point.kind == "cartesian" else "joints_deg"
        replacements.update(render(point, **{key: getattr(point, key)}))
    assert replace_numbers(again.texts, replacements)[sample.name] == text


def changed_lines(before: str, after: str) -> set[int]:
    lines = set()
    matcher = difflib.SequenceMatcher(None, before.splitlines(keepends=True), after.splitlines(keepends=True))
    for tag, i1, i2, _, _ in matcher.get_opcodes():
        if tag != "equal":
            lines.update(range(i1 + 1, i2 + 1))
    return lines


def test_changed_cartesian_target_touches_only_its_numbers(tmp_path):
    program = read_program(PICK_PLACE)
    pick = by_label(program)["pick"]
    target = pick.frame_mm @ pose_frame([1.25, -0.5, 0.75], [1, 2, 3], np.deg2rad(0.3))
    text, again = rewrite(tmp_path, program, render(pick, frame_mm=target), "moved.script")
    original = program.texts["ur_pick_place.script"]
    assert changed_lines(original, text) == {pick.line}
    assert NUMBER.sub("#", text) == NUMBER.sub("#", original)
    moved = by_label(again)["pick"]
    np.testing.assert_allclose(moved.frame_mm[:3, 3], target[:3, 3], atol=1e-7)
    np.testing.assert_allclose(moved.frame_mm[:3, :3], target[:3, :3], atol=1e-9)
    # the rotation vector stays on the side of the original (0, 3.1416, 0), not the equivalent (0, -3.14, 0)
    assert moved.values[4] > 3.0
    assert [p.values for p in again.points if p.label != "pick"] == [
        p.values for p in program.points if p.label != "pick"
    ]


def test_changed_joint_and_movec_targets_touch_only_their_lines(tmp_path):
    program = read_program(DISPENSE)
    points = by_label(program)
    ready = points["ready_q"]
    via = next(p for p in program.points if p.line == 36)
    new_joints = ready.joints_deg + [0.5, -0.25, 0.125, 0.0, 1.0, -2.0]
    new_via = via.frame_mm.copy()
    new_via[:3, 3] += [0.4, -0.3, 0.0]
    replacements = render(ready, joints_deg=new_joints) | render(via, frame_mm=new_via)
    text, again = rewrite(tmp_path, program, replacements, "moved.script")
    original = program.texts["ur_dispense.script"]
    assert changed_lines(original, text) == {ready.line, via.line}
    assert NUMBER.sub("#", text) == NUMBER.sub("#", original)
    np.testing.assert_allclose(by_label(again)["ready_q"].joints_deg, new_joints, atol=1e-7)
    moved = next(p for p in again.points if p.line == 36)
    np.testing.assert_allclose(moved.frame_mm, new_via, atol=1e-7)
    assert moved.values[3] == 3.1415926536  # the same rotation keeps the numbers written


def test_round_trip_of_frames(tmp_path):
    from scipy.spatial.transform import Rotation

    path = write(tmp_path, "def go():\n  movel(p[0.4, 0.1, 0.3, 0, 3.1416, 0], a=1.2, v=0.25)\nend\n")
    program = read_program(path)
    (point,) = program.points
    # a frame whose numbers 10 decimals hold exactly: back to 1e-9
    exact = pose_frame([412.3456789, -123.4567891, 250.0000001], [0.3, -0.2, 0.9], 2.5)
    _, again = rewrite(tmp_path, program, render(point, frame_mm=exact), "exact.script")
    np.testing.assert_allclose(again.points[0].frame_mm, exact, rtol=0, atol=1e-9)
    # any frame: positions to the 5e-8 mm of 10 decimals in metres, rotations to 1e-9
    rng = np.random.default_rng(28)
    for rotation in Rotation.random(20, random_state=rng):
        frame = np.eye(4)
        frame[:3, :3] = rotation.as_matrix()
        frame[:3, 3] = rng.uniform(-600, 600, 3)
        _, again = rewrite(tmp_path, program, render(point, frame_mm=frame), "random.script")
        np.testing.assert_allclose(again.points[0].frame_mm[:3, 3], frame[:3, 3], rtol=0, atol=6e-8)
        np.testing.assert_allclose(again.points[0].frame_mm[:3, :3], frame[:3, :3], rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("written", "expected"),
    [
        ("0, 3.1416, 0", ["0.0000000000", "3.1416000000", "0.0000000000"]),  # angle just over pi
        ("0, -3.1416, 0", ["0.0000000000", "-3.1416000000", "0.0000000000"]),
        ("-3.1415926536, 0.0, 0.0", ["-3.1415926536", "0.0000000000", "0.0000000000"]),
        ("3.1415926536, 0.0, 0.0", ["3.1415926536", "0.0000000000", "0.0000000000"]),
        ("-1.5708, 2.7207, 0.0", ["-1.5708000000", "2.7207000000", "0.0000000000"]),
        ("0, 0, 0", ["0.0000000000", "0.0000000000", "0.0000000000"]),
    ],
)
def test_rotation_vector_near_pi_rendered_near_the_original(tmp_path, written, expected):
    program = read_program(write(tmp_path, f"movel(p[0.4, 0.1, 0.3, {written}])\n"))
    (point,) = program.points
    rendered = render(point, frame_mm=point.frame_mm)
    assert [rendered[span] for span in point.spans[3:]] == expected


def test_rotation_crossing_pi_stays_on_the_original_side(tmp_path):
    program = read_program(write(tmp_path, "movel(p[0.4, 0.1, 0.3, 0, 3.14159, 0])\n"))
    (point,) = program.points
    # turn 1e-4 rad further about y: angle just over pi, whose shortest vector is about -y
    target = point.frame_mm @ rot_y(1e-4)
    rendered = [render(point, frame_mm=target)[span] for span in point.spans[3:]]
    assert rendered == ["0.0000000000", "3.1416900000", "0.0000000000"]
    # and back below pi from an original written with the opposite sign
    program = read_program(write(tmp_path, "movel(p[0.4, 0.1, 0.3, 0, -3.14169, 0])\n"))
    (point,) = program.points
    rendered = [render(point, frame_mm=point.frame_mm @ rot_y(1e-4))[span] for span in point.spans[3:]]
    assert rendered == ["0.0000000000", "-3.1415900000", "0.0000000000"]


def test_render_refuses_what_urscript_cannot_write():
    program = read_program(PICK_PLACE)
    points = by_label(program)
    with pytest.raises(InputError, match=r"ur_pick_place.script: line 14: pick: .*joint values"):
        render(points["pick"], joints_deg=np.zeros(6))
    with pytest.raises(InputError, match="needs frame_mm"):
        render(points["pick"])
    with pytest.raises(InputError, match="not a rigid transform"):
        render(points["pick"], frame_mm=np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(InputError, match="cannot be written as a frame"):
        render(points["home_q"], frame_mm=np.eye(4))
    with pytest.raises(InputError, match="6 finite values"):
        render(points["home_q"], joints_deg=np.zeros(5))
    with pytest.raises(InputError, match="no configuration data"):
        render(points["pick"], frame_mm=np.eye(4), config={"cf1": 0})


# ------------------------------------------------------------------------------------------ constructs and edges ---


def test_number_forms_signs_and_crlf_line_endings(tmp_path):
    text = (
        "def numbers():\r\n  # p[9, 9, 9, 9, 9, 9] in a comment is no target\r\n"
        "  movel(p[.4, -.25, 3e-1, +0, 1E-3, -2], a=1.2)\r\n  movej([1, -2, 0.5e0, 3., -0.0, 0], v=1)\r\nend\r\n"
    )
    program = read_program(write(tmp_path, text))
    cartesian, joint = program.points
    assert cartesian.values == (0.4, -0.25, 0.3, 0.0, 0.001, -2.0)
    assert joint.values == (1.0, -2.0, 0.5, 3.0, -0.0, 0.0)
    assert (cartesian.line, joint.line) == (3, 4)
    assert [text[s.start : s.end] for s in cartesian.spans] == [".4", "-.25", "3e-1", "+0", "1E-3", "-2"]
    assert program.texts["prog.script"] == text  # \r\n kept
    new = replace_numbers(program.texts, render(joint, joints_deg=np.zeros(6)))["prog.script"]
    assert new.count("\r\n") == 5 and "movej([0.0000000000, 0.0000000000," in new


def test_variables_resolve_to_the_assignment_above_their_use(tmp_path):
    text = """\
global target = p[0.3, 0.2, 0.4, 0, 3.14, 0]
def approach_target():
  movel(later_pose, a=1.2, v=0.25)
end
later_pose = p[0.5, 0.0, 0.3, 0, 3.14, 0]
movel(target)
movej(target)
target = p[0.35, 0.2, 0.4, 0, 3.14, 0]
movep(target)
movel(pose=target)
approach_target()
"""
    program = read_program(write(tmp_path, text))
    assert [(p.label, p.line, p.motion) for p in program.points] == [
        ("target", 1, "movel"),
        ("later_pose", 5, "movel"),  # used in a function written above its only assignment
        ("target", 8, "movep"),
    ]
    assert program.skipped == []


@pytest.mark.parametrize(
    ("script", "line", "why"),
    [
        ("movel(pose_trans(get_actual_tcp_pose(), p[0, 0, 0.05, 0, 0, 0]))\n", 1, "pose_trans(get_actual_tcp_pose()"),
        ("movej(get_inverse_kin(p[0.4, 0, 0.3, 0, 3.14, 0]), a=1.4)\n", 1, "get_inverse_kin("),
        ("movel(p[0.4, 0, 0.3, 0, pi, 0])\n", 1, "has the expression `pi`"),
        ("movej([0, -pi/2, 1.57, 0, 0, 0])\n", 1, "has the expression `-pi/2`"),
        ("x = 0.4\nmovel(p[x, 0, 0.3, 0, 3.14, 0])\n", 2, "has the expression `x`"),
        ("a1 = p[0.4, 0, 0.3, 0, 3.14, 0]\nb1 = pose_add(a1, p[0, 0, 0.1, 0, 0, 0])\nmovel(b1)\n", 3, "b1"),
        ("q = [0, -1.57, 1.57, 0, 0, 0]\nq[0] = 0.5\nmovej(q)\n", 3, "changed element by element at line 2"),
        ("movel(Waypoint_1_p, a=1.2, v=0.25)\n", 1, "assigned nowhere"),
        ("def go(target):\n  movel(target)\nend\ngo(p[0.4, 0, 0.3, 0, 3.14, 0])\n", 2, "parameter"),
        ("servoj([0, -1.57, 1.57, 0, 0, 0], t=0.008)\n", 1, "servoj"),
        ("offset = p[0, 0, 0.05, 0, 0, 0]\nmovel(pose_trans(get_actual_tcp_pose(), offset))\n", 1, "pose `offset`"),
    ],
)
def test_expressions_are_skipped_with_a_reason(tmp_path, script, line, why):
    program = read_program(write(tmp_path, script))
    assert program.points == [] or all(point.label != "b1" for point in program.points)
    assert any(entry[1] == line and why in entry[2] for entry in program.skipped), program.skipped
    assert all(entry[0] == "prog.script" for entry in program.skipped)


def test_pose_trans_target_is_skipped_but_its_literal_neighbours_are_points(tmp_path):
    text = "base_pose = p[0.4, 0.0, 0.3, 0, 3.14, 0]\nmovel(base_pose)\nmovel(pose_trans(base_pose, p[0, 0, -0.05, 0, 0, 0]))\n"
    program = read_program(write(tmp_path, text))
    assert [(p.label, p.motion) for p in program.points] == [("base_pose", "movel")]
    assert [(line, "pose_trans(base_pose" in why) for _, line, why in program.skipped] == [(3, True)]


def test_set_tcp_tools_in_force_per_point(tmp_path):
    text = """\
movel(p[0.4, 0, 0.3, 0, 3.14, 0])
set_tcp(p[0, 0, 0.1, 0, 0, 0])
movel(p[0.4, 0, 0.31, 0, 3.14, 0])
gripper = p[0.0, 0.02, 0.15, 0, 0, 1.5707963267948966]
set_tcp(gripper)
movel(p[0.4, 0, 0.32, 0, 3.14, 0])
set_tcp(pose_add(gripper, p[0, 0, 0.01, 0, 0, 0]))
movel(p[0.4, 0, 0.33, 0, 3.14, 0])
movej([0, -1.57, 1.57, 0, 0, 0])
"""
    program = read_program(write(tmp_path, text))
    assert [(p.line, p.kind, p.tool) for p in program.points] == [
        (1, "cartesian", None),  # the flange (the installation's TCP is not in the script)
        (3, "cartesian", "tcp@2"),
        (6, "cartesian", "gripper"),
        (9, "joint", "tcp@7"),  # a joint target needs no tool frame; this name is not in frames
    ]
    assert list(program.frames) == ["tcp@2", "gripper"]
    expected = rot_z(np.pi / 2)
    expected[:3, 3] = [0, 20, 150]
    np.testing.assert_allclose(program.frames["gripper"], expected, atol=1e-12)
    # the Cartesian target under a set_tcp of an expression cannot be filtered
    assert len(program.skipped) == 1 and program.skipped[0][1] == 8
    assert "set_tcp at line 7" in program.skipped[0][2] and "pose_add(gripper" in program.skipped[0][2]


def test_a_pose_variable_used_under_two_tools_is_filtered_for_the_first(tmp_path):
    text = "spot = p[0.4, 0, 0.3, 0, 3.14, 0]\nmovel(spot)\nset_tcp(p[0, 0, 0.1, 0, 0, 0])\nmovel(spot)\n"
    program = read_program(write(tmp_path, text))
    assert [(p.label, p.tool) for p in program.points] == [("spot", None)]
    assert [line for _, line, _ in program.skipped] == [4]
    assert "tool tcp@3" in program.skipped[0][2]


@pytest.mark.parametrize(
    ("script", "line", "message"),
    [
        ("def main():\n  movel(p[0.4, 0.1, 0.3, 0, 3.14, 0)\nend\n", 2, r"unterminated `p\[`"),
        ("def main():\n  movel(p[0.4, 0.1, 0.3, 0, 3.14, 0]\nend\n", 2, r"unterminated `movel\(`"),
        ("movel(p[0.4, 0.1.2, 0.3, 0, 3.14, 0])\n", 1, "bad number `0.1.2`"),
        ("x = 1\nmovel(p[0.4, 0.1, 0.3, 0, 3.14, 1e])\n", 2, "bad number `1e`"),
        ("movel(p[0.4, 0.1, 0.3, 0, 3.14])\n", 1, "needs 6 numbers; got 5"),
        ("q = [0, 1, 2]\n\nmovej(q)\n", 1, "needs 6 numbers; got 3"),
        ("movel(p[0.4, , 0.3, 0, 3.14, 0])\n", 1, "empty element"),
        ('textmsg("no end)\n', 1, "unterminated string"),
        ("movel(a=1.2, v=0.25)\n", 1, r"without its target \(pose\)"),
        ("movec(p[0.4, 0.1, 0.3, 0, 3.14, 0])\n", 1, r"without its target \(pose_to\)"),
        ("set_tcp(p[0, 0, 0.1, 0, 0])\n", 1, "needs 6 numbers"),
        ("x = 1)\n", 1, r"`\)` closes nothing"),
    ],
)
def test_malformed_scripts_name_file_and_line(tmp_path, script, line, message):
    with pytest.raises(InputError, match=rf"bad\.script: line {line}: .*{message}"):
        read_program(write(tmp_path, script, "bad.script"))


def test_unreadable_files_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="no such URScript file"):
        read_program(tmp_path / "missing.script")
    path = tmp_path / "latin.script"
    path.write_bytes("# pi\xe8ce\nmovel(p[0.4, 0, 0.3, 0, 3.14, 0])\n".encode("latin-1"))
    with pytest.raises(InputError, match="latin.script, line 1: not valid utf-8 text.*--encoding"):
        read_program(path)
    assert len(read_program(path, encoding="latin-1").points) == 1
    with pytest.raises(InputError, match="unknown text encoding 'klingon'"):
        read_program(path, encoding="klingon")
