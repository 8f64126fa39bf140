"""ABB RAPID modules: the sample programs parse to the expected points and frames, rewriting changes numbers only,
quaternions keep their hemisphere, expressions and unsupported targets are listed, malformed files name their line."""

from __future__ import annotations

import difflib
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import InputError
from robotcal.programs.base import replace_numbers
from robotcal.programs.rapid import quaternion_from_frame, read_program, render

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "programs"
#: A number as RAPID writes it, with its sign: replaced by '#' to compare everything else.
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
EXTAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"


def _write(folder: Path, text: str, name: str = "cell.mod") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8", newline="")
    return path


def _module(body: str, data: str = "") -> str:
    return f"MODULE Cell\n{data}\n    PROC main()\n{body}\n    ENDPROC\nENDMODULE\n"


def _rewrite(program, replacements, folder: Path):
    """The program's texts with ``replacements``, written to ``folder`` and read back."""
    texts = replace_numbers(program.texts, replacements)
    (name,) = texts
    return texts, read_program(_write(folder, texts[name], name))


def _rz(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _frame(rotation: np.ndarray, translation) -> np.ndarray:
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = rotation, translation
    return frame


# ---- the sample programs ------------------------------------------------------------------------------------------
def test_pick_place_sample_points():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    assert program.language == "rapid"
    assert list(program.texts) == ["abb_pick_place.mod"]
    assert program.texts["abb_pick_place.mod"] == (EXAMPLES / "abb_pick_place.mod").read_text(encoding="utf-8")
    points = program.points
    assert len(points) == 7
    assert [p.label for p in points] == [
        "jHome",
        "pAbovePick",
        "pPick",
        "pAbovePlace",
        "pPlace",
        "abb_pick_place.mod:40",
        "abb_pick_place.mod:61",
    ]
    assert [p.line for p in points] == [15, 18, 19, 23, 24, 40, 61]
    assert [p.kind for p in points] == [
        "joint",
        "cartesian",
        "cartesian",
        "cartesian",
        "cartesian",
        "joint",
        "cartesian",
    ]
    assert [p.motion for p in points] == ["MoveAbsJ", "MoveJ", "MoveL", "MoveJ", "MoveL", "MoveAbsJ", "MoveC"]
    assert [p.tool for p in points] == ["tGripper"] * 5 + [None, "tGripper"]
    assert [p.base for p in points] == [None, None, None, "wobjTray", "wobjTray", None, None]
    by_label = {p.label: p for p in points}
    assert by_label["pPick"].values == (450.5, 150.25, 252.75, 0.0, 0.0, 1.0, 0.0)
    assert by_label["pPick"].config == {"cf1": 0, "cf4": 0, "cf6": 0, "cfx": 0}
    assert by_label["pPlace"].config == {"cf1": -1, "cf4": 0, "cf6": 0, "cfx": 0}
    np.testing.assert_array_equal(by_label["jHome"].joints_deg, [0, -20, 30, 0, 80, 0])
    np.testing.assert_array_equal(by_label["abb_pick_place.mod:40"].joints_deg, [-30, -25, 35, 0, 75, 0])
    assert by_label["jHome"].frame_mm is None and by_label["jHome"].config == {}
    # every span holds exactly the number it stands for, external axes (9E+09) are never spans
    text = program.texts["abb_pick_place.mod"]
    for point in points:
        assert len(point.spans) == len(point.values) == (7 if point.kind == "cartesian" else 6)
        for span, value in zip(point.spans, point.values, strict=True):
            assert float(text[span.start : span.end]) == value
        for key, span in point.config_spans.items():
            assert int(text[span.start : span.end]) == point.config[key]
        assert all("9E" not in text[span.start : span.end] for span in point.spans)
    assert set(program.frames) == {"tGripper", "wobjTray"}
    np.testing.assert_allclose(program.frames["tGripper"], _frame(np.eye(3), [0, 0, 125]), atol=1e-15)


def test_pick_place_sample_skipped():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    lines = {line: why for _, line, why in program.skipped}
    assert sorted(lines) == [26, 51, 59]
    assert "pPlaceOld" in lines[26] and "declared, used by no motion" in lines[26]
    assert "Offs(pPick,0,0,150)" in lines[51] and "run time" in lines[51]
    assert "RelTool(pPlace,0,0,-90)" in lines[59]
    assert all(file == "abb_pick_place.mod" for file, _, _ in program.skipped)


def test_glue_path_sample_points():
    program = read_program(EXAMPLES / "abb_glue_path.mod")
    points = program.points
    assert len(points) == 10
    assert [p.label for p in points] == [
        "jSafe",
        "pStart",
        "pEdge1",
        "pArc1",
        "pEdge2",
        "pEdge3",
        "pArc2",
        "pEdge4",
        "pEnd",
        "abb_glue_path.mod:47",
    ]
    # pEdge3 spans four lines: its line is that of its first number
    assert [p.line for p in points] == [16, 19, 20, 21, 22, 23, 27, 28, 29, 47]
    assert [p.motion for p in points] == [
        "MoveAbsJ",
        "MoveL",
        "MoveL",
        "MoveC",
        "MoveC",
        "MoveL",
        "MoveC",
        "MoveC",
        "MoveLDO",
        "MoveL",
    ]
    assert [p.kind for p in points] == ["joint"] + ["cartesian"] * 9
    assert all(p.tool == "tGlueGun" for p in points)
    assert [p.base for p in points] == [None] + ["wobjFixture"] * 9
    pedge3 = points[5]
    text = program.texts["abb_glue_path.mod"]
    assert {text.count("\n", 0, span.start) + 1 for span in pedge3.spans} == {23, 24}
    assert text.count("\n", 0, pedge3.config_spans["cfx"].start) + 1 == 25
    assert points[-1].values == (20.0, 140.0, 60.0, 0.0, -0.707106781, -0.707106781, 0.0)
    assert points[-1].config == {"cf1": 0, "cf4": -1, "cf6": 1, "cfx": 0}
    assert [(line, "Offs(pStart,0,0,50)" in why) for _, line, why in program.skipped] == [(34, True)]
    # speeddata and num declarations are no frames
    assert set(program.frames) == {"tGlueGun", "wobjFixture"}


# ---- frames against closed forms ----------------------------------------------------------------------------------
def test_work_object_is_uframe_times_oframe_by_hand():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    # wobjTray: uframe = Rz(30) at (420, -180, 180) (q = [cos 15, 0, 0, sin 15]); oframe = (20, 10, 0), no turn
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    expected = np.array(
        [
            [c, -s, 0.0, 420 + 20 * c - 10 * s],
            [s, c, 0.0, -180 + 20 * s + 10 * c],
            [0.0, 0.0, 1.0, 180.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    # the quaternion is written with 9 decimals: the rotation is exact to ~1e-9
    np.testing.assert_allclose(program.frames["wobjTray"], expected, rtol=0, atol=1e-7)
    # pPlace in the robot base: work object @ target; target turned 180 deg about (1, 1, 0)/sqrt 2
    pplace = next(p for p in program.points if p.label == "pPlace")
    half_turn = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    np.testing.assert_allclose(pplace.frame_mm, _frame(half_turn, [60, 40, 30]), rtol=0, atol=1e-8)
    in_base = program.frames["wobjTray"] @ pplace.frame_mm
    x, y = 20 + 60, 10 + 40  # the target in the user frame
    np.testing.assert_allclose(in_base[:3, 3], [420 + x * c - y * s, -180 + x * s + y * c, 210.0], atol=1e-7)

    glue = read_program(EXAMPLES / "abb_glue_path.mod")
    # wobjFixture: uframe a translation (380, -90, 150); oframe Rz(10) at (12.5, 8, 0)
    np.testing.assert_allclose(glue.frames["wobjFixture"], _frame(_rz(10), [392.5, -82, 150]), rtol=0, atol=1e-8)
    # tGlueGun: Ry(20) (q = [cos 10, 0, sin 10, 0]) at (-45.5, 0, 162.25) in the flange frame
    c20, s20 = np.cos(np.radians(20)), np.sin(np.radians(20))
    tilt = np.array([[c20, 0.0, s20], [0.0, 1.0, 0.0], [-s20, 0.0, c20]])
    np.testing.assert_allclose(glue.frames["tGlueGun"], _frame(tilt, [-45.5, 0, 162.25]), rtol=0, atol=1e-8)


def test_point_frames_by_hand():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    ppick = next(p for p in program.points if p.label == "pPick")
    # q = [0, 0, 1, 0]: half turn about y
    np.testing.assert_allclose(ppick.frame_mm, _frame(np.diag([-1.0, 1.0, -1.0]), [450.5, 150.25, 252.75]), atol=1e-15)
    glue = read_program(EXAMPLES / "abb_glue_path.mod")
    pstart = next(p for p in glue.points if p.label == "pStart")
    # q = [0, 0, -1, 0] is the same rotation as [0, 0, 1, 0]
    np.testing.assert_allclose(pstart.frame_mm, _frame(np.diag([-1.0, 1.0, -1.0]), [20, 0, 10]), atol=1e-15)


def test_quaternion_is_normalised(tmp_path):
    # [0.5, 0, 0, 0.5] has length 1/sqrt 2: the rotation is Rz(90) all the same
    text = _module(
        "        MoveL p1, v100, fine, tool0;",
        f"    CONST robtarget p1 := [[400,0,300],[0.5,0,0,0.5],[0,0,0,0],{EXTAX}];",
    )
    (point,) = read_program(_write(tmp_path, text)).points
    np.testing.assert_allclose(point.frame_mm, _frame(_rz(90), [400, 0, 300]), atol=1e-15)
    assert point.values[3:] == (0.5, 0.0, 0.0, 0.5)


# ---- writing numbers only -------------------------------------------------------------------------------------------
def _same_target(point):
    if point.kind == "cartesian":
        return render(point, frame_mm=point.frame_mm, config=dict(point.config))
    return render(point, joints_deg=point.joints_deg)


@pytest.mark.parametrize("sample", ["abb_pick_place.mod", "abb_glue_path.mod"])
def test_same_targets_rewrite_numbers_only(sample, tmp_path):
    program = read_program(EXAMPLES / sample)
    replacements = {}
    for point in program.points:
        replacements.update(_same_target(point))
    texts, again = _rewrite(program, replacements, tmp_path)
    assert NUMBER.sub("#", texts[sample]) == NUMBER.sub("#", program.texts[sample])
    assert len(again.points) == len(program.points)
    for before, after in zip(program.points, again.points, strict=True):
        assert (after.label, after.kind, after.line, after.tool, after.base) == (
            before.label,
            before.kind,
            before.line,
            before.tool,
            before.base,
        )
        # quaternions already written with at most 9 decimals come back digit for digit
        np.testing.assert_allclose(after.values, before.values, rtol=0, atol=1e-9)
        assert after.config == before.config
    assert again.skipped == program.skipped
    # a rewritten file rewrites to itself
    replacements = {}
    for point in again.points:
        replacements.update(_same_target(point))
    assert replace_numbers(again.texts, replacements) == again.texts


def test_changed_target_touches_only_its_number_characters(tmp_path):
    program = read_program(EXAMPLES / "abb_glue_path.mod")
    pedge3 = next(p for p in program.points if p.label == "pEdge3")
    moved = pedge3.frame_mm.copy()
    moved[:3, :3] = Rotation.from_rotvec([0.002, -0.001, 0.003]).as_matrix() @ moved[:3, :3]
    moved[:3, 3] += [0.125, -0.25, 0.375]
    texts, again = _rewrite(program, render(pedge3, frame_mm=moved), tmp_path)
    old, new = program.texts["abb_glue_path.mod"], texts["abb_glue_path.mod"]
    changed = [
        line
        for line in difflib.unified_diff(old.splitlines(), new.splitlines(), lineterm="", n=0)
        if line[:1] in "+-" and not line.startswith(("+++", "---"))
    ]
    assert changed == [
        "-    CONST robtarget pEdge3:=[[160,100,10],",
        "-                             [0,-0.382683432,-0.923879533,0],",
        f"+    CONST robtarget pEdge3:=[[{moved[0, 3]:.6f},{moved[1, 3]:.6f},{moved[2, 3]:.6f}],",
        changed[3],
    ]
    assert changed[3].startswith("+                             [") and changed[3].endswith("],")
    assert NUMBER.sub("#", new) == NUMBER.sub("#", old)
    after = next(p for p in again.points if p.label == "pEdge3")
    np.testing.assert_allclose(after.frame_mm[:3, 3], moved[:3, 3], rtol=0, atol=5e-7)
    np.testing.assert_allclose(after.frame_mm[:3, :3], moved[:3, :3], rtol=0, atol=2e-9)
    # the quaternion keeps the hemisphere it was written in (q2, q3 negative)
    assert after.values[4] < 0 and after.values[5] < 0
    for before, now in zip(program.points, again.points, strict=True):
        if before.label != "pEdge3":
            assert now.values == before.values


def test_round_trip_of_frames(tmp_path):
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    point = next(p for p in program.points if p.label == "pAbovePlace")
    rng = np.random.default_rng(28)
    for rotation in Rotation.random(40, random_state=rng).as_matrix():
        target = _frame(rotation, np.round(rng.uniform(-600, 600, 3), 6))
        _, again = _rewrite(program, render(point, frame_mm=target), tmp_path)
        back = next(p for p in again.points if p.label == "pAbovePlace")
        # 6 decimals of a mm are exact for a target written to 6 decimals; 9 decimals of a quaternion hold the
        # rotation to ~1e-9 (<= 1e-7 deg)
        np.testing.assert_allclose(back.frame_mm[:3, 3], target[:3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(back.frame_mm[:3, :3], target[:3, :3], rtol=0, atol=2e-9)
        angle = Rotation.from_matrix(back.frame_mm[:3, :3] @ target[:3, :3].T).magnitude()
        assert np.degrees(angle) < 1e-7
        assert abs(np.linalg.norm(back.values[3:]) - 1.0) < 2e-9


def test_quaternion_sign_kept(tmp_path):
    glue = read_program(EXAMPLES / "abb_glue_path.mod")
    pstart = next(p for p in glue.points if p.label == "pStart")  # written [0, 0, -1, 0]
    texts = render(pstart, frame_mm=pstart.frame_mm)
    assert [texts[span] for span in pstart.spans] == [
        "20.000000",
        "0.000000",
        "10.000000",
        "0.000000000",
        "0.000000000",
        "-1.000000000",
        "0.000000000",
    ]
    pick = read_program(EXAMPLES / "abb_pick_place.mod")
    ppick = next(p for p in pick.points if p.label == "pPick")  # written [0, 0, 1, 0], the same rotation
    assert [render(ppick, frame_mm=pstart.frame_mm)[span] for span in ppick.spans[3:]] == [
        "0.000000000",
        "0.000000000",
        "1.000000000",
        "0.000000000",
    ]
    # a turned target stays in the written hemisphere, whichever sign scipy picks
    turned = pstart.frame_mm.copy()
    turned[:3, :3] = Rotation.from_rotvec([0.0, 0.0, 0.3]).as_matrix() @ turned[:3, :3]
    q = [float(render(pstart, frame_mm=turned)[span]) for span in pstart.spans[3:]]
    assert q[2] < -0.9 and np.dot(q, pstart.values[3:]) > 0
    q = [float(render(ppick, frame_mm=turned)[span]) for span in ppick.spans[3:]]
    assert q[2] > 0.9 and np.dot(q, ppick.values[3:]) > 0
    # the helper, directly: w-first order, hemisphere of the reference, else w >= 0
    np.testing.assert_allclose(quaternion_from_frame(_frame(_rz(90), [0, 0, 0])), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    np.testing.assert_allclose(
        quaternion_from_frame(_frame(_rz(90), [0, 0, 0]), near_wxyz=[-1, 0, 0, -1]),
        [-np.sqrt(0.5), 0, 0, -np.sqrt(0.5)],
    )


def test_config_written_only_when_given_and_different():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    ppick = next(p for p in program.points if p.label == "pPick")
    plain = render(ppick, frame_mm=ppick.frame_mm)
    assert set(plain) == set(ppick.spans)
    same = render(ppick, frame_mm=ppick.frame_mm, config={"cf1": 0, "cf4": 0, "cf6": 0, "cfx": 0})
    assert set(same) == set(ppick.spans)
    changed = render(ppick, frame_mm=ppick.frame_mm, config={"cf1": 0, "cf6": -1, "cfx": np.int64(1)})
    assert set(changed) - set(ppick.spans) == {ppick.config_spans["cf6"], ppick.config_spans["cfx"]}
    assert changed[ppick.config_spans["cf6"]] == "-1" and changed[ppick.config_spans["cfx"]] == "1"
    texts = replace_numbers(program.texts, changed)
    assert "[0,0,-1,1],\n" in texts["abb_pick_place.mod"]
    with pytest.raises(InputError, match="unknown configuration entry 'cf5'"):
        render(ppick, frame_mm=ppick.frame_mm, config={"cf5": 1})
    with pytest.raises(InputError, match="whole number"):
        render(ppick, frame_mm=ppick.frame_mm, config={"cf1": 0.5})


def test_joint_target_rendered_external_axes_untouched(tmp_path):
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    jhome = program.points[0]
    joints = [1.5, -21.25, 30.125, 0.0, 79.5, -0.000000001]
    texts, again = _rewrite(program, render(jhome, joints_deg=joints), tmp_path)
    line = texts["abb_pick_place.mod"].splitlines()[14]
    assert line == (
        "    CONST jointtarget jHome:=[[1.50000000,-21.25000000,30.12500000,0.00000000,79.50000000,0.00000000],"
        "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];"
    )
    np.testing.assert_allclose(again.points[0].joints_deg, np.round(joints, 6), atol=1e-12)


def test_render_refuses_the_wrong_target():
    program = read_program(EXAMPLES / "abb_pick_place.mod")
    jhome, pick = program.points[0], program.points[2]
    with pytest.raises(InputError, match="cannot write it from joint values"):
        render(pick, joints_deg=[0, 0, 0, 0, 0, 0])
    with pytest.raises(InputError, match="give its new frame_mm"):
        render(pick)
    with pytest.raises(InputError, match="not a rigid transform"):
        render(pick, frame_mm=np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(InputError, match="give joints_deg, not frame_mm"):
        render(jhome, frame_mm=np.eye(4))
    with pytest.raises(InputError, match="6 finite values"):
        render(jhome, joints_deg=[0, 0, 0])
    with pytest.raises(InputError, match="no configuration"):
        render(jhome, joints_deg=[0] * 6, config={"cf1": 0})


# ---- constructs -----------------------------------------------------------------------------------------------------
def test_optional_arguments_variants_and_case(tmp_path):
    data = f"""    PERS tooldata Tool1 := [TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    PERS wobjdata Wobj1 := [FALSE,TRUE,"",[[300,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    TASK PERS robtarget P10 := [[10,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    LOCAL CONST robtarget p20 := [[20,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p30 := [[30,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p40 := [[40,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p50 := [[50,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p60 := [[60,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    const JOINTTARGET j1 := [[1,2,3,4,5,6],{EXTAX}];
    VAR triggdata gunOn;"""
    body = """        movel p10, V100, Z10, TOOL1\\wobj:=WOBJ1;
        MoveL \\Conc, p20\\ID:=10, v100\\V:=120, z10\\Z:=12, tool1, \\WObj:=wobj1\\TLoad:=load0;
        MoveJSync p30, v100\\T:=2, fine, tool1\\WObj:=wobj1, "OpenGun";
        TriggL p40, v200, gunOn\\T2:=gunOff, z10, tool1\\WObj:=wobj1;
        TriggC p50, p60, v200, gunOn, fine, tool1\\WObj:=wobj1;
        MOVEABSJ j1\\NoEOffs, v100, fine, tool1;
        IF reg1 > 5 MoveC """
    # two inline targets on one line (extax written 9E9: the same number as 9E+09)
    body += ", ".join(f"[[{x},0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]" for x in (1, 2))
    body += ", v100, z10, tool0;"
    program = read_program(_write(tmp_path, _module(body, data)))
    labels = [p.label for p in program.points]
    assert labels == ["P10", "p20", "p30", "p40", "p50", "p60", "j1", "cell.mod:19", "cell.mod:19#2"]
    motions = [p.motion for p in program.points]
    assert motions == ["MoveL", "MoveL", "MoveJSync", "TriggL", "TriggC", "TriggC", "MoveAbsJ", "MoveC", "MoveC"]
    # declared spelling of tools and work objects, whatever the case of the motion
    assert [(p.tool, p.base) for p in program.points[:6]] == [("Tool1", "Wobj1")] * 6
    assert program.points[7].tool is None and program.points[7].base is None
    assert [p.values[0] for p in program.points[:6]] == [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]
    assert program.points[8].values[0] == 2.0
    assert program.skipped == []


def test_stationary_tool_and_moving_work_objects(tmp_path):
    data = f"""    PERS tooldata tStand := [FALSE,[[800,0,300],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    PERS wobjdata wHeld := [TRUE,TRUE,"",[[0,0,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    PERS wobjdata wTable := [FALSE,FALSE,"STN1",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    CONST robtarget p1 := [[10,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p2 := [[20,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    CONST robtarget p3 := [[30,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];"""
    body = """        MoveL p1, v100, fine, tStand\\WObj:=wHeld;
        MoveL p2, v100, fine, tool0\\WObj:=wHeld;
        MoveL p3, v100, fine, tool0\\WObj:=wTable;"""
    program = read_program(_write(tmp_path, _module(body, data)))
    assert program.points == []
    whys = [why for _, _, why in program.skipped]
    assert len(whys) == 3
    assert "tool tStand is stationary" in whys[0] and "not supported" in whys[0]
    assert "wHeld is held by the robot" in whys[1]
    assert "wTable is moved by a mechanical unit" in whys[2]
    # the stationary tool is recorded all the same (its TCP in the world frame)
    np.testing.assert_allclose(program.frames["tStand"], _frame(np.eye(3), [800, 0, 300]))


def test_point_moved_with_two_work_objects(tmp_path):
    data = f"""    PERS wobjdata wA := [FALSE,TRUE,"",[[0,0,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    PERS tooldata tA := [TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    CONST robtarget p1 := [[10,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];"""
    body = """        MoveL p1, v100, fine, tA\\WObj:=wA;
        MoveJ p1, v100, fine, TA\\WObj:=WA;
        MoveL p1, v100, fine, tA;"""
    program = read_program(_write(tmp_path, _module(body, data)))
    (point,) = program.points
    assert (point.tool, point.base, point.motion) == ("tA", "wA", "MoveL")
    (entry,) = program.skipped
    # line 7 names the same tool and work object in other case: no conflict; line 8 has no work object
    assert entry[1] == 8 and "wobj0" in entry[2] and "first use only" in entry[2] and "line 6" in entry[2]


def test_targets_not_filtered_are_listed(tmp_path):
    data = f"""    CONST robtarget pBase := [[400,0,300],[0,0,1,0],[0,0,0,0],{EXTAX}];
    CONST robtarget pCopy := pBase;
    VAR robtarget pNow;
    VAR robtarget pTaught := [[400,50,300],[0,0,1,0],[0,0,0,0],{EXTAX}];
    CONST robtarget pPath{{2}} := [[[1,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}],[[2,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}]];
    CONST robtarget pSearch := [[400,0,200],[0,0,1,0],[0,0,0,0],{EXTAX}];
    CONST robtarget pFar := [[500,0,200],[0,0,1,0],[0,0,0,0],{EXTAX}];"""
    body = """        MoveL Offs(pBase,0,0,50), v100, z10, tool0;
        MoveL RelTool(pBase,0,0,-20\\Rz:=45), v100, z10, tool0;
        pNow := CRobT(\\Tool:=tool0);
        MoveL pNow, v100, fine, tool0;
        MoveL CRobT(), v100, fine, tool0;
        MoveL pCopy, v100, fine, tool0;
        pTaught.trans.z := pTaught.trans.z + 10;
        MoveL pTaught, v100, fine, tool0;
        MoveL pPath{2}, v100, fine, tool0;
        MoveL pElsewhere, v100, fine, tool0;
        SearchL \\Stop, diStop, pSearch, pFar, v100, tool0;
        MoveL pBase, v100, fine, tool0;
    ENDPROC
    PROC Visit(robtarget pTarget, PERS tooldata tVisit)
        MoveL pTarget, v100, fine, tVisit;"""
    program = read_program(_write(tmp_path, _module(body, data)))
    assert [p.label for p in program.points] == ["pBase"]
    skipped = {}
    for _, line, why in program.skipped:
        skipped.setdefault(line, []).append(why)
    expected = {
        3: "pCopy has a value that is an expression",
        4: "pNow has no initial value",
        5: "pTaught is assigned at run time (line 16)",
        6: "arrays of robtargets",
        7: "pSearch: declared, used by no motion (named at line 20",
        8: "pFar: declared, used by no motion",
        10: "Offs(pBase,0,0,50) is an expression computed at run time by Offs()",
        11: "RelTool(pBase,0,0,-20\\Rz:=45) is an expression computed at run time by RelTool()",
        14: "CRobT() is an expression",
        18: "pPath{2} is an array element",
        19: "pElsewhere is declared nowhere in this file",
        20: "SearchL: its targets are not filtered",
        24: "pTarget is a parameter of routine Visit",
    }
    assert sorted(skipped) == sorted(expected)
    for line, text in expected.items():
        assert len(skipped[line]) == 1 and text in skipped[line][0], (line, skipped[line])


def test_comments_strings_headers_and_line_endings(tmp_path):
    text = (
        "%%%\r\n  VERSION:1\r\n  LANGUAGE:ENGLISH\r\n%%%\r\n\r\n"
        "MODULE Old\r\n"
        f"  CONST robtarget p1:=[[400,-20,300],[0,0,1,0],[0,0,0,0],{EXTAX}]; ! MoveL p9, v1, z1, tool0;\r\n"
        "  PROC main()\r\n"
        '    TPWrite "MoveL p1, v100 ! no comment ""quoted"";";\r\n'
        "    ! MoveL p1, v100, fine, tool0;\r\n"
        "    MoveL p1, v100, fine, tool0;\r\n"
        "  ENDPROC\r\n"
        "ENDMODULE\r\n"
    )
    program = read_program(_write(tmp_path, text, "old.prg"))
    (point,) = program.points
    assert (point.label, point.line, point.motion) == ("p1", 7, "MoveL")
    assert program.texts["old.prg"] == text
    moved = point.frame_mm.copy()
    moved[0, 3] = 401.5
    new = replace_numbers(program.texts, render(point, frame_mm=moved))["old.prg"]
    assert new.count("\r\n") == text.count("\r\n") and "\n" not in new.replace("\r\n", "")
    assert "[[401.500000,-20.000000,300.000000],[0.000000000,0.000000000,1.000000000,0.000000000]" in new


def test_data_of_another_module_of_the_file(tmp_path):
    # a .prg may hold several modules; task data declared in a later module is found
    text = f"""MODULE Main
    PROC main()
        MoveL pShared, v100, fine, tShared\\WObj:=wShared;
    ENDPROC
ENDMODULE
MODULE Data
    PERS tooldata tShared := [TRUE,[[0,0,50],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    PERS wobjdata wShared := [FALSE,TRUE,"",[[300,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    PERS robtarget pShared := [[1,2,3],[1,0,0,0],[0,0,0,0],{EXTAX}];
ENDMODULE
"""
    program = read_program(_write(tmp_path, text, "cell.prg"))
    (point,) = program.points
    assert (point.label, point.line, point.tool, point.base) == ("pShared", 9, "tShared", "wShared")
    assert program.skipped == []


def test_routine_data_shadows_module_data(tmp_path):
    text = f"""MODULE Cell
    CONST robtarget pA := [[1,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
    PROC main()
        CONST robtarget pA := [[2,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];
        MoveL pA, v100, fine, tool0;
    ENDPROC
    PROC other()
        MoveL pA, v100, fine, tool0;
    ENDPROC
ENDMODULE
"""
    program = read_program(_write(tmp_path, text))
    assert [(p.label, p.line, p.values[0]) for p in program.points] == [("pA", 2, 1.0), ("pA", 4, 2.0)]


# ---- malformed input ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (f"MODULE M\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],[0,0,0,0],{EXTAX};\nENDMODULE\n", 2, "not closed"),
        (f"MODULE M\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],\n  [0,0,0,0],{EXTAX}\nENDMODULE\n", 2, "never closed"),
        (f"MODULE M\n\n  CONST robtarget p1 := [[1,2.5.1,3],[1,0,0,0],[0,0,0,0],{EXTAX}];\n", 3, "bad number '2.5.1'"),
        (
            "MODULE M\n  PROC main()\n    MoveL [[1,2,3],[1,0,0,0],[0,0,0,0],[9E+,0,0,0,0,0]], v1, z1, tool0;\n",
            3,
            "9E+",
        ),
        ('MODULE M\n  PROC main()\n    TPWrite "Hello;\n  ENDPROC\nENDMODULE\n', 3, "not closed on its line"),
        ("MODULE M\n  PROC main()\n    MoveL p1, v100, fine, tool0\n", 3, "not ended by ';'"),
        (
            "MODULE M\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],[0,0,0,0]];\n  PROC m()\n  MoveL p1,v1,z1,tool0;",
            2,
            "must be [[x,y,z]",
        ),
        (
            f"MODULE M\n  CONST robtarget p1 := [[1,2,3],[0,0,0,0],[0,0,0,0],{EXTAX}];\n"
            "  PROC m()\n  MoveL p1,v1,z1,t;",
            2,
            "zero length",
        ),
        (
            f"MODULE M\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],[0,0.5,0,0],{EXTAX}];\n"
            "  PROC m()\n  MoveL p1,v1,z1,t;",
            2,
            "not a whole number",
        ),
        ("MODULE M\n  PROC main()\n\n    MoveL p1, v100;\n  ENDPROC\n", 4, "needs at least 4"),
        # malformed even where no motion uses it
        (f"MODULE M\n  CONST jointtarget j := [[1,2,3,4,5],{EXTAX}];\nENDMODULE\n", 2, "must be [[rax_1"),
        ("MODULE M\n  PERS wobjdata w := [FALSE,TRUE,[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n", 2, "ufmec"),
        ("MODULE M\n  PERS tooldata t := [TRUE,[[0,0,0],[0,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n", 2, "zero length"),
        (f"MODULE M\n  VAR robtarget p := [[1,0,0],[1,0,0,0],[0,0,0,0],{EXTAX}];\n  VAR robtarget P;\n", 3, "twice"),
    ],
)
def test_malformed_input_names_file_and_line(tmp_path, text, line, message):
    with pytest.raises(InputError, match=re.escape(message)) as caught:
        read_program(_write(tmp_path, text, "bad.mod"))
    assert "bad.mod: line " + str(line) + ":" in str(caught.value)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="not a RAPID module"):
        read_program(_write(tmp_path, "MODULE M\nENDMODULE\n", "m.txt"))
    with pytest.raises(InputError, match="no such RAPID module"):
        read_program(tmp_path / "missing.mod")
    (tmp_path / "latin.mod").write_bytes("MODULE M\n! Grüße\nENDMODULE\n".encode("latin-1"))
    with pytest.raises(InputError, match="latin.mod, line 2: not valid utf-8"):
        read_program(tmp_path / "latin.mod")
    program = read_program(tmp_path / "latin.mod", encoding="latin-1")
    assert "Grüße" in program.texts["latin.mod"] and program.points == []
