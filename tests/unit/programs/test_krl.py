"""KUKA KRL programs: the sample programs parse to the points they hold, tool and base follow the program, and a
written program differs from the read one in number characters only."""

from __future__ import annotations

import difflib
import re
from pathlib import Path

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.programs.base import replace_numbers
from robotcal.programs.krl import IntegerSpan, read_program, render

PROGRAMS = Path(__file__).resolve().parents[3] / "examples" / "programs"
CONFIG = PROGRAMS / "kuka_config.dat"
NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
HEADER = "DEFDAT prog PUBLIC\n"


def _write(folder: Path, src: str, dat: str | None = None, *, name: str = "prog", dat_suffix: str = ".dat") -> Path:
    (folder / f"{name}.src").write_text(src, newline="")
    if dat is not None:
        (folder / f"{name}{dat_suffix}").write_text(dat, newline="")
    return folder / f"{name}.src"


def _read(folder: Path, src: str, dat: str | None = None, **options):
    return read_program(_write(folder, src, dat), **options)


def _rotation(a, b, c) -> np.ndarray:
    """``Rz(A) Ry(B) Rx(C)`` [deg] by scipy's intrinsic Z-Y'-X'' angles, independently of robotcal's euler module."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("ZYX", [a, b, c], degrees=True).as_matrix()


def _by_label(program):
    return {point.label: point for point in program.points}


def _same_target(program):
    replacements = {}
    for point in program.points:
        if point.kind == "cartesian":
            replacements.update(render(point, frame_mm=point.frame_mm, config=point.config))
        else:
            replacements.update(render(point, joints_deg=point.joints_deg))
    return replacements


def _masked(text: str) -> str:
    return NUMBER.sub("#", text)


def _write_texts(folder: Path, texts: dict[str, str]) -> None:
    for name, text in texts.items():
        (folder / name).write_text(text, newline="")


# ------------------------------------------------------------------------------------------------ sample programs


def test_pick_place_sample_points_tool_base_and_skipped():
    program = read_program(PROGRAMS / "kuka_pick_place.src", config_dat=CONFIG)
    assert program.language == "krl"
    assert list(program.texts) == ["kuka_pick_place.src", "kuka_pick_place.dat", "kuka_config.dat"]
    assert program.texts["kuka_pick_place.src"] == (PROGRAMS / "kuka_pick_place.src").read_bytes().decode()
    assert "\r\n" in program.texts["kuka_pick_place.src"]  # line ends as read
    labels = [point.label for point in program.points]
    assert labels == ["XHOME", "XP1", "XP2", "XP3", "XP4", "XP5", "XP6", "XP7"]  # 8 points, in order of first use
    points = _by_label(program)
    home = points["XHOME"]
    assert (home.kind, home.file, home.line, home.motion) == ("joint", "kuka_config.dat", 6, "PTP")
    np.testing.assert_array_equal(home.joints_deg, [0.0, -90.0, 90.0, 0.0, 0.0, 0.0])
    assert home.frame_mm is None and dict(home.config) == {}
    assert (home.tool, home.base) == (None, None)  # FDAT FHOME: TOOL_NO 0, BASE_NO 0
    expected = {"XP1": 16, "XP2": 19, "XP3": 22, "XP4": 25, "XP5": 28, "XP6": 29, "XP7": 32}
    for label, line in expected.items():
        point = points[label]
        assert (point.kind, point.file, point.line) == ("cartesian", "kuka_pick_place.dat", line)
        # the inline forms' FDATs: TOOL_NO 1, BASE_NO 2
        assert (point.tool, point.base) == ("TOOL_DATA[1]", "BASE_DATA[2]")
        assert all(span.file == "kuka_pick_place.dat" for span in point.spans)  # never the ;FOLD comment
    assert [points[label].motion for label in expected] == ["PTP", "LIN", "LIN", "PTP", "CIRC", "CIRC", "LIN"]
    assert points["XP2"].values == (-19.874, -140.216, 18.502, 0.317, 89.846, 0.095)
    assert dict(points["XP1"].config) == {"S": 2, "T": 2} and dict(points["XP4"].config) == {"S": 2, "T": 3}
    text = program.texts["kuka_pick_place.dat"]
    assert [text[s.start : s.end] for s in points["XP2"].spans] == [
        "-19.874",
        "-140.216",
        "18.502",
        "0.317",
        "89.846",
        "0.095",
    ]
    assert program.skipped == [("kuka_pick_place.dat", 36, "XP9 declared, used by no motion")]
    assert sorted(program.frames) == ["BASE_DATA[1]", "BASE_DATA[2]", "TOOL_DATA[1]", "TOOL_DATA[2]"]


def test_pick_place_without_config_lists_home_as_declared_nowhere():
    program = read_program(PROGRAMS / "kuka_pick_place.src")
    assert list(program.texts) == ["kuka_pick_place.src", "kuka_pick_place.dat"]
    assert [point.label for point in program.points] == ["XP1", "XP2", "XP3", "XP4", "XP5", "XP6", "XP7"]
    nowhere = [entry for entry in program.skipped if "XHOME is declared in none" in entry[2]]
    assert [(file, line) for file, line, _ in nowhere] == [("kuka_pick_place.src", 25), ("kuka_pick_place.src", 112)]
    assert program.frames == {}  # referenced, declared in none of the files read: the caller asks for them


def test_weld_seam_sample_points_and_skipped():
    program = read_program(PROGRAMS / "kuka_weld_seam.src", config_dat=CONFIG)
    labels = [point.label for point in program.points]
    assert labels == [
        "XHOME",
        "kuka_weld_seam.src:22",
        "XAPPROACH",
        "XSEAM_START",
        "XSEAM_MID",
        "XARC_AUX",
        "XARC_END",
        "kuka_weld_seam.src:37",
    ]
    points = _by_label(program)
    clean = points["kuka_weld_seam.src:22"]
    assert (clean.kind, clean.file, clean.line) == ("joint", "kuka_weld_seam.src", 22)
    np.testing.assert_array_equal(clean.joints_deg, [-62.5, -78.0, 104.0, 0.0, 64.0, -10.5])
    seam_end = points["kuka_weld_seam.src:37"]
    assert (seam_end.kind, seam_end.motion, dict(seam_end.config)) == ("cartesian", "LIN", {})
    assert seam_end.values == (50.0, -50.0, 4.0, 90.0, 45.0, 180.0)
    for label in ("XAPPROACH", "XSEAM_START", "XSEAM_MID", "XARC_AUX", "XARC_END", "kuka_weld_seam.src:37"):
        assert (points[label].tool, points[label].base) == ("TOOL_DATA[2]", "BASE_DATA[1]")  # BAS(#TOOL, 2) ...
        assert points[label].kind == "cartesian"
    assert [points[label].line for label in ("XAPPROACH", "XSEAM_START", "XSEAM_MID", "XARC_AUX", "XARC_END")] == [
        6,
        7,
        8,
        11,
        12,
    ]
    assert (points["XARC_AUX"].motion, points["XARC_END"].motion) == ("CIRC", "CIRC")
    # S and T as decimal, as 'B010' and as 'B 010': the same integers
    for label in ("XAPPROACH", "XSEAM_START", "XSEAM_MID", "XARC_AUX", "XARC_END"):
        assert dict(points[label].config) == {"S": 2, "T": 42}
    text = program.texts["kuka_weld_seam.dat"]
    start = points["XSEAM_START"].config_spans
    assert (text[start["S"].start : start["S"].end], text[start["T"].start : start["T"].end]) == ("010", "101010")
    assert isinstance(start["S"], IntegerSpan) and (start["S"].radix, start["S"].digits) == (2, 3)
    assert points["XAPPROACH"].config_spans["T"].radix == 10
    assert program.skipped == [
        ("kuka_weld_seam.src", 41, "LIN_REL {Z 40.0}: a relative motion; not filtered"),
        ("kuka_weld_seam.dat", 15, "XARC_OLD declared, used by no motion"),
    ]


def test_frames_and_point_frames_against_an_independent_computation():
    program = read_program(PROGRAMS / "kuka_weld_seam.src", config_dat=CONFIG)
    base = program.frames["BASE_DATA[1]"]
    np.testing.assert_allclose(base[:3, 3], [431.26, 118.745, 162.38], atol=1e-12)
    np.testing.assert_allclose(base[:3, :3], _rotation(-30.412, 0.215, 0.108), atol=1e-12)
    np.testing.assert_array_equal(base[3], [0, 0, 0, 1])
    tool = program.frames["TOOL_DATA[2]"]
    np.testing.assert_allclose(tool[:3, :3], _rotation(0.0, -22.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(tool[:3, 3], [312.4, 0.2, 62.5], atol=1e-12)
    points = _by_label(program)
    arc = points["XARC_AUX"].frame_mm
    np.testing.assert_allclose(arc[:3, :3], _rotation(135.0, 45.0, 180.0), atol=1e-12)
    np.testing.assert_allclose(arc[:3, 3], [41.213, 31.213, 4.0], atol=1e-12)
    # by hand: XP4 A 90, B 90, C 0 is Rz(90) Ry(90); the tool's x axis points down
    xp4 = _by_label(read_program(PROGRAMS / "kuka_pick_place.src"))["XP4"].frame_mm
    np.testing.assert_allclose(xp4[:3, :3], [[0, -1, 0], [0, 0, 1], [-1, 0, 0]], atol=1e-15)
    np.testing.assert_allclose(xp4[:3, 3], [40.0, 120.0, 180.0])


def test_a_rotation_about_z_alone_is_rz(tmp_path):
    src = "DEF prog()\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nLIN {X 400, Y 0, Z 300, A 90, B 0, C 0}\nEND\n"
    (point,) = _read(tmp_path, src).points
    np.testing.assert_allclose(point.frame_mm[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    assert (point.tool, point.base, point.label) == (None, None, "prog.src:4")


# ----------------------------------------------------------------------------------------------------- writing


@pytest.mark.parametrize("name", ["kuka_pick_place", "kuka_weld_seam"])
def test_same_target_changes_number_texts_only(tmp_path, name):
    program = read_program(PROGRAMS / f"{name}.src", config_dat=CONFIG)
    replacements = _same_target(program)
    config_spans = {span for point in program.points for span in point.config_spans.values()}
    assert config_spans and not config_spans & set(replacements)  # S and T unchanged: not even rewritten
    written = replace_numbers(program.texts, replacements)
    for file, text in written.items():
        assert _masked(text) == _masked(program.texts[file]), file
    _write_texts(tmp_path, written)
    again = read_program(tmp_path / f"{name}.src", config_dat=tmp_path / "kuka_config.dat")
    assert [p.label for p in again.points] == [p.label for p in program.points]
    for before, after in zip(program.points, again.points, strict=True):
        np.testing.assert_allclose(after.values, before.values, atol=1e-9, rtol=0)
        assert dict(after.config) == dict(before.config)
    assert again.skipped == program.skipped


def test_changed_target_touches_only_its_numbers(tmp_path):
    program = read_program(PROGRAMS / "kuka_pick_place.src", config_dat=CONFIG)
    point = _by_label(program)["XP2"]
    frame = point.frame_mm.copy()
    frame[:3, 3] += [0.512, -0.25, 0.125]
    frame[:3, :3] = _rotation(0.2, 0.0, 0.0) @ frame[:3, :3]
    written = replace_numbers(program.texts, render(point, frame_mm=frame, config={"S": 2, "T": 2}))
    for file in program.texts:
        if file != "kuka_pick_place.dat":
            assert written[file] == program.texts[file]
    old = program.texts["kuka_pick_place.dat"].splitlines(keepends=True)
    new = written["kuka_pick_place.dat"].splitlines(keepends=True)
    matcher = difflib.SequenceMatcher(a=old, b=new, autojunk=False)
    changed = [(tag, i1, i2) for tag, i1, i2, _, _ in matcher.get_opcodes() if tag != "equal"]
    assert changed == [("replace", point.line - 1, point.line)]
    assert _masked(new[point.line - 1]) == _masked(old[point.line - 1])
    assert new[point.line - 1].endswith("\r\n")
    _write_texts(tmp_path, written)
    again = _by_label(read_program(tmp_path / "kuka_pick_place.src", config_dat=tmp_path / "kuka_config.dat"))
    np.testing.assert_allclose(again["XP2"].frame_mm, frame, atol=1e-6)
    np.testing.assert_allclose(again["XP2"].values[:3], np.array(point.values[:3]) + [0.512, -0.25, 0.125], atol=1e-9)


def test_round_trip_of_a_frame(tmp_path):
    dat = HEADER + "DECL E6POS XP1={X 1.0,Y 2.0,Z 3.0,A -120.0,B 10.0,C 170.0,S 6,T 27,E1 0.0}\nENDDAT\n"
    src = "DEF prog()\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\nLIN XP1\nEND\n"
    program = _read(tmp_path, src, dat)
    (point,) = program.points
    frame = np.eye(4)
    frame[:3, :3] = _rotation(-123.456789, 12.345678, 167.891234)
    frame[:3, 3] = [412.123456, -87.654321, 333.000001]
    _write_texts(tmp_path, replace_numbers(program.texts, render(point, frame_mm=frame)))
    (again,) = read_program(tmp_path / "prog.src").points
    np.testing.assert_allclose(again.frame_mm, frame, atol=1e-9, rtol=0)
    np.testing.assert_allclose(again.values, [412.123456, -87.654321, 333.000001, -123.456789, 12.345678, 167.891234])
    rng = np.random.default_rng(28)
    from scipy.spatial.transform import Rotation

    for rotation in Rotation.from_quat(rng.normal(size=(20, 4))).as_matrix():
        frame = np.eye(4)
        frame[:3, :3] = rotation
        frame[:3, 3] = rng.uniform(-500, 500, 3)
        _write_texts(tmp_path, replace_numbers(program.texts, render(point, frame_mm=frame)))
        (again,) = read_program(tmp_path / "prog.src").points
        np.testing.assert_allclose(again.frame_mm[:3, 3], frame[:3, 3], atol=5e-7)
        np.testing.assert_allclose(again.frame_mm[:3, :3], rotation, atol=3e-8)
        assert all(-180.0 <= value <= 180.0 for value in again.values[3:])


@pytest.mark.parametrize(
    "written",
    [
        (180.0, 45.0, 180.0),
        (-180.0, 45.0, -180.0),
        (30.0, 90.0, 10.0),
        (-40.0, -90.0, 25.0),
        (0.0, 90.0, 0.0),
        (-10.0, 135.0, 170.0),
    ],
)
def test_render_keeps_the_written_angle_triple(tmp_path, written):
    """Of equivalent A, B, C (A+180, 180-B, C+180; at B = +-90 every split of A -+ C) the one written is kept."""
    a, b, c = written
    src = f"DEF prog()\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nLIN {{X 400, Y 0, Z 300, A {a}, B {b}, C {c}}}\nEND\n"
    (point,) = _read(tmp_path, src).points
    texts = render(point, frame_mm=point.frame_mm)
    assert [float(texts[span]) for span in point.spans[3:]] == [a, b, c]


def test_render_joints_config_notation_and_errors(tmp_path):
    program = read_program(PROGRAMS / "kuka_weld_seam.src", config_dat=CONFIG)
    points = _by_label(program)
    clean = points["kuka_weld_seam.src:22"]
    out = render(clean, joints_deg=[-62.5, -78.25, 104.0, 0.0, 64.0, -10.5])
    assert list(out.values()) == ["-62.50000000", "-78.25000000", "104.00000000", "0.00000000", "64.00000000", "-10.50000000"]
    assert set(out) == set(clean.spans)
    start, mid, approach = points["XSEAM_START"], points["XSEAM_MID"], points["XAPPROACH"]
    out = render(start, frame_mm=start.frame_mm, config={"S": 3, "T": 42})
    assert out[start.config_spans["S"]] == "011" and start.config_spans["T"] not in out
    assert render(mid, frame_mm=mid.frame_mm, config={"s": 6})[mid.config_spans["S"]] == "110"
    assert render(approach, frame_mm=approach.frame_mm, config={"T": 43})[approach.config_spans["T"]] == "43"
    written = replace_numbers(program.texts, render(mid, frame_mm=mid.frame_mm, config={"S": 3, "T": 3}))
    line = written["kuka_weld_seam.dat"].splitlines()[mid.line - 1]
    assert "S 'B 011',T 'B 000011'" in line
    seam_end = points["kuka_weld_seam.src:37"]
    assert set(render(seam_end, frame_mm=seam_end.frame_mm, config={"S": 2})) == set(seam_end.spans)  # no S written
    with pytest.raises(InputError, match="Cartesian"):
        render(start, joints_deg=np.zeros(6))
    with pytest.raises(InputError, match="joint point"):
        render(clean, frame_mm=np.eye(4))
    with pytest.raises(InputError, match="6 finite"):
        render(clean, joints_deg=np.zeros(5))
    with pytest.raises(InputError, match="4x4"):
        render(start, frame_mm=np.eye(3))
    with pytest.raises(InputError, match="S and T"):
        render(start, frame_mm=start.frame_mm, config={"cf1": 1})
    with pytest.raises(InputError, match="whole number"):
        render(start, frame_mm=start.frame_mm, config={"S": 2.5})


# -------------------------------------------------------------------------------------------- tool, base, FDAT


def test_inline_form_fdat_tool_and_base(tmp_path):
    dat = HEADER + (
        "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0,S 6,T 27}\n"
        'DECL FDAT FP1={TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE,POINT2[] " "}\n'
        "DECL E6POS XP2={X 11.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        'DECL FDAT FP2={TOOL_NO 0,BASE_NO 0,IPO_FRAME #BASE,POINT2[] " "}\n'
        "DECL E6POS XP3={X 12.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        'DECL FDAT FP3={TOOL_NO 3,BASE_NO 1,IPO_FRAME #TCP,POINT2[] " "}\n'
        "DECL E6POS XP4={X 13.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        "ENDDAT\n"
    )
    fold = ";FOLD {m} P{n} Vel=100 % PDAT{n} Tool[1]:gripper Base[2]:table;%{{PE}}%R 8.3.31,%MKUKATPBASIS,%CMOVE,%V{m},%P 1:{m}, 2:P{n}, 3:, 5:100, 7:PDAT{n}\n"
    src = "DEF prog()\n"
    for n, fdat in ((1, "FP1"), (2, "FP2"), (3, "FP3"), (4, "FP9")):
        src += (
            fold.format(m="PTP", n=n)
            + f"$BWDSTART=FALSE\nPDAT_ACT=PPDAT{n}\nFDAT_ACT={fdat}\nBAS(#PTP_PARAMS,100)\nPTP XP{n}\n;ENDFOLD\n"
        )
    src += "END\n"
    program = _read(tmp_path, src, dat)
    points = _by_label(program)
    assert list(points) == ["XP1", "XP2"]
    assert (points["XP1"].tool, points["XP1"].base) == ("TOOL_DATA[1]", "BASE_DATA[2]")
    assert (points["XP2"].tool, points["XP2"].base) == (None, None)
    lines = src.splitlines()
    why = {line: text for _, line, text in program.skipped}
    assert set(why) == {lines.index("PTP XP3") + 1, lines.index("PTP XP4") + 1}
    assert "external TCP" in why[lines.index("PTP XP3") + 1] and "FDAT FP3" in why[lines.index("PTP XP3") + 1]
    assert "FDAT FP9" in why[lines.index("PTP XP4") + 1] and "declared in none" in why[lines.index("PTP XP4") + 1]
    # the FOLD comment's numbers ("Vel=100", "P1", "5:100") are no spans: every span is in the .dat
    assert {span.file for point in program.points for span in point.spans} == {"prog.dat"}


def test_tool_and_base_statements_in_program_order(tmp_path):
    dat = HEADER + (
        "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        "DECL FRAME MY_TABLE={X 500.0,Y 10.0,Z 100.0,A 90.0,B 0.0,C 0.0}\n"
        "DECL FRAME TOOL_DATA[16]\n"
        "TOOL_DATA[1]={X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}\n"
        "DECL FDAT FP1={TOOL_NO 4,BASE_NO 5,IPO_FRAME #BASE}\n"
        "ENDDAT\n"
    )
    src = (
        "DEF prog()\n"
        "LIN {X 1, Y 2, Z 3, A 0, B 90, C 0}\n"  # 2: nothing selected yet
        "$tool = tool_data[1]\n"
        "$Base=BASE_DATA[2]\n"
        "lin {x 2, y 2, z 3, a 0, b 90, c 0}\n"  # 5
        "BAS (#TOOL, 0)\n"
        "BAS(#BASE,3)\n"
        "LIN {X 3, Y 2, Z 3, A 0, B 90, C 0}\n"  # 8
        "$TOOL = $NULLFRAME\n"
        "$BASE = MY_TABLE\n"
        "LIN {X 4, Y 2, Z 3, A 0, B 90, C 0}\n"  # 11
        "$BASE = BASE_DATA[1]:{X 10, Y 0, Z 0, A 0, B 0, C 0}\n"
        "LIN {X 5, Y 2, Z 3, A 0, B 90, C 0}\n"  # 13: base is an expression
        "PTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}\n"  # 14: a joint target needs no base
        "$BASE = $WORLD\n"
        "SLIN XP1 WITH $TOOL = STOOL2( FP1 ), $BASE = SBASE( FP1.BASE_NO ), $VEL = {CP 0.2, ORI1 100, ORI2 100}\n"
        "LIN {X 6, Y 2, Z 3, A 0, B 90, C 0}\n"  # 17: the WITH held for its motion only
        "END\n"
    )
    program = _read(tmp_path, src, dat)
    tools = {point.line: (point.tool, point.base) for point in program.points}
    assert tools == {
        5: ("TOOL_DATA[1]", "BASE_DATA[2]"),
        8: (None, "BASE_DATA[3]"),
        11: (None, "MY_TABLE"),
        14: (None, None),  # the base in force there is unknown, but a joint target does not use it
        2: ("TOOL_DATA[4]", "BASE_DATA[5]"),  # XP1 (prog.dat line 2) with the spline motion's WITH
        17: (None, None),
    }
    why = {line: text for _, line, text in program.skipped}
    assert set(why) == {2, 13}
    assert "no tool is selected" in why[2] and "no base is selected" in why[2]
    assert "$BASE is set by an expression" in why[13]
    assert sorted(program.frames) == ["MY_TABLE", "TOOL_DATA[1]"]
    np.testing.assert_allclose(program.frames["MY_TABLE"][:3, :3], _rotation(90, 0, 0), atol=1e-15)


def test_a_point_used_with_two_bases_is_read_once_with_a_warning(tmp_path):
    dat = HEADER + "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n"
    src = "DEF prog()\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\nLIN XP1\n$BASE=BASE_DATA[2]\nLIN xp1\nLIN XP1\nEND\n"
    program = _read(tmp_path, src, dat)
    (point,) = program.points
    assert (point.base, point.line, point.file) == ("BASE_DATA[1]", 2, "prog.dat")
    assert [(file, line) for file, line, _ in program.skipped] == [("prog.src", 6), ("prog.src", 7)]
    assert "BASE_DATA[2]" in program.skipped[0][2] and "line 4" in program.skipped[0][2]


# ------------------------------------------------------------------------------------------ what is not filtered


def test_expressions_relative_and_partial_targets_are_skipped_with_a_reason(tmp_path):
    dat = HEADER + (
        "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        "DECL POS XPART={X 10.0,Y 20.0}\n"
        "DECL E6POS XPOS[3]\n"
        "XPOS[2]={X 1.5,Y -2,Z 1.0E+02,A .5,B +3,C 0}\n"
        "ENDDAT\n"
    )
    src = (
        "DEF prog()\n"
        "$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\n"
        "LIN XP1 : $NULLFRAME\n"  # 4
        "PTP SHIFTED(XP1, 10)\n"  # 5
        "LIN {X 100} C_DIS\n"  # 6
        "PTP_REL {A1 10}\n"  # 7
        "LIN $POS_ACT\n"  # 8
        "LIN {X xval, Y 0, Z 300, A 0, B 90, C 0}\n"  # 9
        "LIN XPART\n"  # 10
        "CIRC XP1, XP1 : {X 1, Y 0, Z 0, A 0, B 0, C 0}\n"  # 11
        "LIN XPOS[I]\n"  # 12
        "LIN XPOS[2]\n"  # 13
        "END\n"
    )
    program = _read(tmp_path, src, dat)
    assert [point.label for point in program.points] == ["XPOS[2]"]
    assert program.points[0].values == (1.5, -2.0, 100.0, 0.5, 3.0, 0.0)
    why = {line: text for _, line, text in program.skipped}
    assert set(why) == {4, 5, 6, 7, 8, 9, 10, 11, 12}
    assert "expression" in why[4] and "$NULLFRAME" in why[4]
    assert "expression" in why[5]
    assert "only some components" in why[6]
    assert "relative" in why[7]
    assert "system variable" in why[8]
    assert "not a literal number" in why[9]
    assert "only some components" in why[10]
    assert "expression" in why[11]
    assert "index" in why[12]


def test_a_point_missing_from_the_dat_is_listed_in_skipped(tmp_path):
    dat = HEADER + "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n"
    src = "DEF prog()\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\nLIN XP1\nLIN XP5\nEND\n"
    program = _read(tmp_path, src, dat)
    assert [point.label for point in program.points] == ["XP1"]
    assert program.skipped == [("prog.src", 5, "XP5 is declared in none of the files read (prog.dat)")]


def test_no_dat_is_fine_for_inline_points(tmp_path):
    src = "DEF prog()\nPTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}\nPTP XHOME\nEND\n"
    program = _read(tmp_path, src)
    assert list(program.texts) == ["prog.src"]
    assert [point.label for point in program.points] == ["prog.src:2"]
    assert program.skipped == [("prog.src", 3, "XHOME is declared in none of the files read (no .dat)")]


def test_run_time_changes_of_a_declared_point_are_warned(tmp_path):
    dat = HEADER + "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n"
    src = "DEF prog()\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\nXP1.Z = XP1.Z + 5\nLIN XP1\nEND\n"
    program = _read(tmp_path, src, dat)
    assert len(program.points) == 1
    assert program.skipped[0][:2] == ("prog.src", 4) and "changed at run time" in program.skipped[0][2]


def test_dat_found_beside_in_any_case_and_declarations_without_decl(tmp_path):
    dat = (
        "&ACCESS RVP\nDEFDAT prog PUBLIC\n"
        "E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0,S 'B 110',T 'H1B',E1 5.0}  ; no DECL\n"
        "DECL GLOBAL E6AXIS XAX={A1 1,A2 2,A3 3,A4 4,A5 5,A6 6,E1 7}\n"
        "ENDDAT\n"
    )
    src = "DEF prog()\nBAS(#TOOL,1)\nBAS(#BASE,1)\nLIN Xp1 C_DIS\nPTP xax C_PTP\nEND\n"
    program = read_program(_write(tmp_path, src, dat, dat_suffix=".DAT"))
    assert list(program.texts) == ["prog.src", "prog.DAT"]
    xp1, xax = program.points
    assert (xp1.label, dict(xp1.config), xax.label, xax.values) == ("XP1", {"S": 6, "T": 27}, "XAX", (1, 2, 3, 4, 5, 6))
    assert xp1.config_spans["T"].radix == 16
    assert render(xp1, frame_mm=xp1.frame_mm, config={"S": 7, "T": 28})[xp1.config_spans["T"]] == "1C"


def test_encoding(tmp_path):
    dat = HEADER + "; Bügel, linke Seite\nDECL E6AXIS XAX={A1 1,A2 2,A3 3,A4 4,A5 5,A6 6}\nENDDAT\n"
    (tmp_path / "prog.src").write_text("DEF prog()\nPTP XAX\nEND\n")
    (tmp_path / "prog.dat").write_bytes(dat.encode("cp1252"))
    program = read_program(tmp_path / "prog.src", encoding="cp1252")
    assert "Bügel" in program.texts["prog.dat"] and len(program.points) == 1
    with pytest.raises(InputError, match=r"prog\.dat, line 2: not valid utf-8"):
        read_program(tmp_path / "prog.src")


# ------------------------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("dat", "src", "message"),
    [
        ("DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0\n", "LIN XP1\n", r"prog\.dat, line 2: unterminated aggregate"),
        (
            "DECL E6POS XP1={X 1.2.3,Y 0,Z 0,A 0,B 0,C 0}\n",
            "LIN XP1\n",
            r"prog\.dat, line 2: bad number '1\.2\.3' for X",
        ),
        ("DECL E6POS XP1={X 1,Y 0,Z 0,A 0,B 0,C 0,S 'B012'}\n", "LIN XP1\n", r"prog\.dat, line 2: bad number"),
        (
            "DECL E6POS XP1={X 1,Y 0,Z 0,A 0,B 0,C 0}\nDECL E6POS xp1={X 1}\n",
            "",
            r"prog\.dat, line 3: xp1 is declared twice",
        ),
        ("", "LIN {X 1, Y 2, Z 3, A 0, B 90, C 0\n", r"prog\.src, line 3: unterminated aggregate"),
        ("", "LIN {X 1, Y -, Z 3, A 0, B 90, C 0}\n", r"prog\.src, line 3: bad number '-' for Y"),
        ("", "CIRC {X 1, Y 2, Z 3, A 0, B 90, C 0}\n", r"prog\.src, line 3: CIRC needs an auxiliary point"),
        ("", "PTP\n", r"prog\.src, line 3: PTP without a target"),
    ],
)
def test_malformed_input_names_file_and_line(tmp_path, dat, src, message):
    with pytest.raises(InputError, match=message):
        _read(tmp_path, "DEF prog()\n$TOOL=TOOL_DATA[1]\n" + src + "END\n", HEADER + dat + "ENDDAT\n")


def test_missing_files(tmp_path):
    src = _write(tmp_path, "DEF prog()\nEND\n")
    with pytest.raises(InputError, match=r"other\.dat: no such file"):
        read_program(src, dat_path=tmp_path / "other.dat")
    with pytest.raises(InputError, match=r"config\.dat: no such file"):
        read_program(src, config_dat=tmp_path / "config.dat")
    with pytest.raises(InputError, match=r"absent\.src: no such file"):
        read_program(tmp_path / "absent.src")


def test_spline_inline_forms_ipo_mode_and_circular_angle(tmp_path):
    dat = HEADER + (
        "DECL E6POS XP1={X 10.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        'DECL FDAT FP1={TOOL_NO 2,BASE_NO 1,IPO_FRAME #BASE,POINT2[] " ",TQ_STATE FALSE}\n'
        "DECL E6POS XP2={X 11.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        'DECL FDAT FP2={TOOL_NO 2,BASE_NO 1,IPO_FRAME #TCP,POINT2[] " ",TQ_STATE FALSE}\n'
        "DECL E6POS XP3={X 12.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        "DECL E6POS XP4={X 13.0,Y 20.0,Z 30.0,A 0.0,B 90.0,C 0.0}\n"
        "ENDDAT\n"
    )
    with_clause = (
        "WITH $TOOL = STOOL2( {f} ), $BASE = SBASE( {f}.BASE_NO ), $IPO_MODE = SIPO_MODE( {f}.IPO_FRAME ), "
        "$LOAD = SLOAD( {f}.TOOL_NO ), $ACC = SACC_JOINT( PPDAT1 ), $APO = SAPO_PTP( PPDAT1 ), "
        "$GEAR_JERK = SGEAR_JERK( PPDAT1 ), $COLLMON_TOL_PRO[1] = USE_CM_PRO_VALUES(0)"
    )
    src = (
        "DEF prog()\n"
        ";FOLD SPTP P1 Vel=100 % PDAT1 Tool[2]:torch Base[1]:fixture ;%{PE}\n"
        f"SPTP XP1 {with_clause.format(f='FP1')}\n"  # 3
        ";ENDFOLD\n"
        f"SLIN XP2 {with_clause.format(f='FP2')}\n"  # 5: external TCP
        "$TOOL = TOOL_DATA[1]\n$BASE = BASE_DATA[1]\n$IPO_MODE = #TCP\n"
        "LIN XP3\n"  # 9: external TCP
        "$IPO_MODE = #BASE\n"
        "CIRC XP3, XP4, CA 90.0 C_DIS\n"  # 11
        "SPLINE\n  SPL XP2\nENDSPLINE\n"  # 13
        "END\n"
    )
    program = _read(tmp_path, src, dat)
    points = {point.label: (point.motion, point.tool, point.base) for point in program.points}
    assert points == {
        "XP1": ("SPTP", "TOOL_DATA[2]", "BASE_DATA[1]"),
        "XP3": ("CIRC", "TOOL_DATA[1]", "BASE_DATA[1]"),
        "XP4": ("CIRC", "TOOL_DATA[1]", "BASE_DATA[1]"),
        "XP2": ("SPL", "TOOL_DATA[1]", "BASE_DATA[1]"),
    }
    why = {line: text for _, line, text in program.skipped}
    assert set(why) == {5, 9}
    assert "external TCP (IPO_FRAME #TCP in FDAT FP2" in why[5] and "$IPO_MODE = #TCP" in why[9]
