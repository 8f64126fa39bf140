"""Tracker exports in (robotcal.io.formats.tracker_import): Leica, plain ``name;x;y;z``, mapped generic text.

Hand-made small exports with their expected values written out, every error path named, and a
round trip: a simulated capture written as a Leica export in metres with decimal commas, imported
back, equal to the capture to 1e-9 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.io.formats.capture_csv import read_capture, write_capture
from robotcal.io.formats.tracker_import import (
    import_tracker_capture,
    join_points_to_readings,
    parse_column_map,
    read_joint_log,
    read_tracker_export,
)
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.forward import forward_kinematics

LEICA_M = """Name;X [m];Y [m];Z [m];U(95) [m];Temperature [C];Time Stamp
P1;1,2345;-0,5;0,75;0,000025;20,1;2024-05-01 10:00:00
P2;1,25;-0,4875;0,8;0,00003;20,1;2024-05-01 10:00:05
P3;1,3;-0,45;0,85;0,00002;20,2;2024-05-01 10:00:10
"""

JOINT_LOG = """name,q1,q2,q3,q4,q5,q6
P1,10,-20,30,0,45,0
P2,11.5,-20,30,0,45,0
P3,13,-20,30,0,45,90.25
"""


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_leica_export_in_metres_with_decimal_comma_and_semicolons(tmp_path):
    points = read_tracker_export(_write(tmp_path, "leica.txt", LEICA_M))
    assert points.layout == "leica" and points.unit == "m"
    assert points.names == ("P1", "P2", "P3")
    # 1 m = 1000 mm exactly; the decimal values are exact in binary to ~1e-13 mm after scaling
    np.testing.assert_allclose(
        points.points, [[1234.5, -500.0, 750.0], [1250.0, -487.5, 800.0], [1300.0, -450.0, 850.0]], rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(points.u95, [0.025, 0.03, 0.02], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(points.lines, [2, 3, 4])


def test_u95_without_a_unit_bracket_is_kept_in_the_coordinates_unit(tmp_path):
    # `U(95)` is a name: its parentheses are no unit bracket ("95" is no unit), so the column is read, in m here
    export = "Name;X [m];Y [m];Z [m];U(95);Time Stamp\nP1;1,5;0,5;0,25;0,00003;2024-05-01 10:00:00\n"
    points = read_tracker_export(_write(tmp_path, "leica.txt", export))
    assert points.layout == "leica" and points.unit == "m"
    np.testing.assert_allclose(points.points, [[1500.0, 500.0, 250.0]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(points.u95, [0.03], rtol=0, atol=1e-12)


def test_leica_comma_export_in_mm_without_names_joins_by_order(tmp_path):
    export = _write(
        tmp_path,
        "leica.csv",
        "X [mm],Y [mm],Z [mm],U(95) [mm],Temperature [C],Time Stamp\n"
        "100.5,200,300,0.02,20,10:00\n"
        "101.5,201,301,0.03,20,10:01\n",
    )
    log = _write(tmp_path, "joints.csv", "q1,q2,q3\n1,2,3\n4,5,6\n")
    capture = import_tracker_capture(export, log, join="order", target="T1")
    np.testing.assert_array_equal(capture.points, [[100.5, 200.0, 300.0], [101.5, 201.0, 301.0]])
    np.testing.assert_allclose(np.rad2deg(capture.readings), [[1, 2, 3], [4, 5, 6]], rtol=0, atol=1e-13)
    np.testing.assert_array_equal(capture.u95, [0.02, 0.03])
    assert capture.point_targets == ("T1", "T1")
    np.testing.assert_array_equal(capture.circle, [0, 0])  # free poses: no circle column
    np.testing.assert_array_equal(capture.direction, [1, 1])
    with pytest.raises(InputError, match="no point-name column to join by name; use --join order"):
        import_tracker_capture(export, log, join="name")


def test_plain_name_xyz_export_needs_its_unit(tmp_path):
    export = _write(tmp_path, "plain.txt", "P1;1,5;2;3\nP2;4;5;6,25\n")
    with pytest.raises(InputError, match=r"does not state its unit; give --units mm\|m\|in"):
        read_tracker_export(export)
    points = read_tracker_export(export, units="in")
    assert points.layout == "plain" and points.names == ("P1", "P2")
    np.testing.assert_array_equal(points.points, np.array([[1.5, 2, 3], [4, 5, 6.25]]) * 25.4)  # exact inch
    assert points.u95 is None


def test_generic_export_with_a_column_map(tmp_path):
    export = _write(
        tmp_path,
        "generic.tsv",
        "Point\tEast [mm]\tNorth [mm]\tUp [mm]\tUnc\tReflector\n"
        "A\t1.5\t2.5\t3.5\t0.04\tT2\n"
        "A\t4\t5\t6\t0.05\tT1\n"
        "B\t7\t8\t9\t0.06\tT1\n",
    )
    columns = 'x="East [mm]",y=North [mm],z=Up [mm],name=Point,u95=Unc,target=Reflector'
    points = read_tracker_export(export, columns=columns)
    assert points.layout == "generic" and points.unit == "mm"
    np.testing.assert_array_equal(points.points, [[1.5, 2.5, 3.5], [4, 5, 6], [7, 8, 9]])
    np.testing.assert_array_equal(points.u95, [0.04, 0.05, 0.06])
    log = _write(tmp_path, "joints.csv", "name,circle,direction,q1,q2\nA,1,-1,10,20\nB,2,1,30,40\n")
    capture = join_points_to_readings(points, read_joint_log(log, n_joints=2))
    # two targets share pose A; names in first-seen order
    assert capture.target_names == ("T2", "T1") and capture.point_targets == ("T2", "T1", "T1")
    np.testing.assert_allclose(np.rad2deg(capture.readings), [[10, 20], [10, 20], [30, 40]], rtol=0, atol=1e-13)
    np.testing.assert_array_equal(capture.circle, [1, 1, 2])
    np.testing.assert_array_equal(capture.direction, [-1, -1, 1])


def test_column_map_by_position_in_a_headerless_file(tmp_path):
    export = _write(tmp_path, "pos.csv", "7,P1,1,2,3\n8,P2,4,5,6\n")
    points = read_tracker_export(export, columns="name=2,x=3,y=4,z=5", units="m")
    assert points.names == ("P1", "P2")
    np.testing.assert_array_equal(points.points, [[1000, 2000, 3000], [4000, 5000, 6000]])


def test_parse_column_map():
    assert parse_column_map('x="X, [mm]",y=Y,z=Z') == {"x": "X, [mm]", "y": "Y", "z": "Z"}
    with pytest.raises(InputError, match="unknown key 'w'"):
        parse_column_map("x=a,y=b,z=c,w=d")
    with pytest.raises(InputError, match="missing z"):
        parse_column_map("x=a,y=b")
    with pytest.raises(InputError, match="key 'x' given twice"):
        parse_column_map("x=a,x=b,y=c,z=d")
    with pytest.raises(InputError, match="KEY=COLUMN"):
        parse_column_map("x,y=b,z=c")


@pytest.mark.parametrize(
    ("text", "kwargs", "message"),
    [
        ("Name;X [mm];Y [mm];U(95) [mm]\nP1;1;2;0,1\n", {}, r"no column z in the header"),
        ("Name;X [mm];Y [mm];Z [mm]\nP1;1;abc;3\n", {}, r"line 2, column `Y \[mm\]`: 'abc' is not a number"),
        ("Name;X [mm];Y [mm];Z [mm]\nP1;1,5;2,5;3\nP2;1.5;2;3\n", {}, r"line 3, column `X \[mm\]`: '1.5' is not a number"),
        ("Name;X [ft];Y [ft];Z [ft]\nP1;1;2;3\n", {}, r"column `X \[ft\]`: unknown unit 'ft'; known: mm, m, in"),
        ("Name;X [mm];Y [m];Z [mm]\nP1;1;2;3\n", {}, r"coordinate columns disagree on the unit"),
        ("Name;X [m];Y [m];Z [m]\nP1;1;2;3\n", {"units": "mm"}, r"--units mm contradicts the header.*in m"),
        ("Name;X;Y;Z\nP1;1;2;3\n", {"units": "yd"}, r"--units: unknown unit 'yd'"),
        ("Name;X [mm];Y [mm];Z [mm]\nP1;1;2;3\nP1;4;5;6\n", {}, r"line 3, column `Name`: name 'P1' already on line 2"),
        ("Name;X [mm];Y [mm];Z [mm];U(95) [mm]\nP1;1;2;3;0\n", {}, r"line 2, column `U\(95\) \[mm\]`: U\(95\) must be > 0"),
        ("Name;X [mm];Y [mm];Z [mm]\nP1;1;2\n", {}, r"line 2 has 3 fields"),
        ("Name;X [mm];Y [mm];Z [mm]\n", {}, r"no data rows"),
        ("Name;X [mm];Y [mm];Z [mm]\nP1;1;2;inf\n", {}, r"'inf' is not a finite number"),
        ("Pt;X;Y;Z\nP1;1;2;3\n", {"columns": "x=X,y=Y,z=Zed", "units": "mm"}, r"--columns z='Zed': no such column"),
        ("Name,X [mm],Y [mm],Z [mm]\nP1,1,2,3\n", {"decimal": ","}, r"decimal ',' needs another delimiter"),
    ],
)
def test_export_errors_name_file_line_and_column(tmp_path, text, kwargs, message):
    path = _write(tmp_path, "bad.txt", text)
    with pytest.raises(InputError, match=message) as info:
        read_tracker_export(path, **kwargs)
    assert "bad.txt" in str(info.value)


@pytest.mark.parametrize(
    ("log", "message"),
    [
        ("name,q1,q2,q3,q4,q5,q6\nP1,1,2,3,4,5,6\nP2,1,2,3,4,5,6\n", r"1 point\(s\) with no joint reading in .*'P3'"),
        (JOINT_LOG + "P4,1,2,3,4,5,6\n", r"line 5: 1 joint reading\(s\) with no measured point in .*'P4'"),
        (JOINT_LOG + "P3,1,2,3,4,5,6\n", r"line 5, column `name`: pose name 'P3' already on line 4"),
        ("name,q1,q2,q3,q4,q5\nP1,1,2,3,4,5\n", r"5 joint columns \(q1..q5\) but the robot has 6 joints"),
        ("name,q1,q2,q4,q5,q6,q7\nP1,1,2,3,4,5,6\n", r"missing joint column\(s\) q3"),
        ("name,q1,q2,q3,q4,q5,q6\nP1,1,2,x,4,5,6\n", r"line 2, column `q3`: 'x' is not a number"),
        ("name,x1,x2\nP1,1,2\n", r"no joint columns q1..qN"),
    ],
)
def test_join_errors_name_both_files(tmp_path, log, message):
    export = _write(tmp_path, "leica.txt", LEICA_M)
    with pytest.raises(InputError, match=message):
        import_tracker_capture(export, _write(tmp_path, "joints.csv", log), n_joints=6)


def test_order_join_counts_and_conflicting_columns(tmp_path):
    export = _write(tmp_path, "leica.txt", LEICA_M)
    log = _write(tmp_path, "j.csv", "q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n")
    with pytest.raises(InputError, match="has 3 points, .*j.csv has 1 rows"):
        import_tracker_capture(export, log, join="order")
    with pytest.raises(InputError, match="--join must be 'name' or 'order'"):
        import_tracker_capture(export, _write(tmp_path, "k.csv", JOINT_LOG), join="nearest")
    both = _write(tmp_path, "t.txt", "Name;X [mm];Y [mm];Z [mm];Target\nP1;1;2;3;T1\n")
    log1 = _write(tmp_path, "l1.csv", "name,target,q1\nP1,T2,5\n")
    with pytest.raises(InputError, match=r"t.txt: line 2: target 'T1' disagrees with the joint-angle log .*l1.csv: line 2"):
        import_tracker_capture(both, log1)
    # issue 29: a target column holding one value (a reflector's serial) is renamed by --target
    renamed = import_tracker_capture(both, _write(tmp_path, "l2.csv", "name,q1\nP1,5\n"), target="T9")
    assert renamed.target_names == ("T9",)


def test_target_values_renamed(tmp_path):
    """Issue 29: an export whose target column holds reflector serials is renamed to the scenario's targets."""
    export = _write(tmp_path, "s.txt", "Name;X [mm];Y [mm];Z [mm];Target\nP1;1;2;3;RRR-1041\nP1;4;5;6;RRR-2207\n")
    log = _write(tmp_path, "l.csv", "name,q1\nP1,5\n")
    capture = import_tracker_capture(export, log, target="RRR-1041=A, RRR-2207=B")
    assert capture.target_names == ("A", "B") and capture.target.tolist() == [0, 1]
    with pytest.raises(InputError, match="holds 2 targets .*rename each: --target VALUE=NAME"):
        import_tracker_capture(export, log, target="A")
    with pytest.raises(InputError, match="RRR-2207 is not renamed"):
        import_tracker_capture(export, log, target="RRR-1041=A")
    with pytest.raises(InputError, match="distinct VALUE=NAME pairs"):
        import_tracker_capture(export, log, target="RRR-1041=A,RRR-1041=B")
    plain = _write(tmp_path, "p.txt", "Name;X [mm];Y [mm];Z [mm]\nP1;1;2;3\n")
    with pytest.raises(InputError, match="neither file has one"):
        import_tracker_capture(plain, log, target="X=A")


def test_a_target_column_only_in_the_joint_log_lets_points_share_a_pose_name(tmp_path):
    # the export names its three points P1 (one per reflector, no target column); the log has one row per target
    export = _write(tmp_path, "t.txt", "Name;X [mm];Y [mm];Z [mm]\nP1;1;2;3\nP1;4;5;6\nP1;7;8;9\nP2;1;1;1\n")
    log = _write(
        tmp_path, "j.csv", "name,target,q1,q2\nP1,T1,10,20\nP1,T2,10,20\nP1,T3,10,20\nP2,T1,30,40\n"
    )
    capture = import_tracker_capture(export, log)
    assert capture.target_names == ("T1", "T2", "T3")
    np.testing.assert_array_equal(capture.target, [0, 1, 2, 0])
    np.testing.assert_allclose(capture.points, [[1, 2, 3], [4, 5, 6], [7, 8, 9], [1, 1, 1]], rtol=0, atol=0)
    np.testing.assert_allclose(np.degrees(capture.readings), [[10, 20]] * 3 + [[30, 40]], rtol=0, atol=1e-12)
    # by order the names are not used: repeated names without any target are fine
    plain = _write(tmp_path, "p.txt", "Name;X [mm];Y [mm];Z [mm]\nP1;1;2;3\nP1;4;5;6\n")
    same = _write(tmp_path, "s.csv", "name,q1\nP1,5\nP1,6\n")
    assert import_tracker_capture(plain, same, join="order").n_points == 2
    # by name, (name, target) must still be unique after the join: one log row for two P1 points, one target
    one = _write(tmp_path, "o.csv", "name,target,q1\nP1,T1,5\n")
    with pytest.raises(InputError, match=r"p.txt: line 3, column `name`: name 'P1' with target 'T1' already on line 2"):
        import_tracker_capture(plain, one)
    # and a log repeating (name, target) is refused naming its line
    twice = _write(tmp_path, "w.csv", "name,target,q1\nP1,T1,5\nP1,T1,6\n")
    with pytest.raises(InputError, match=r"w.csv: line 3, column `name`: pose name 'P1' with target 'T1' already"):
        import_tracker_capture(plain, twice)


def test_joint_log_in_radians_is_converted(tmp_path):
    log = read_joint_log(_write(tmp_path, "j.csv", "name;q1 [rad];q2 [deg]\nA;0,5;90\n"))
    np.testing.assert_allclose(log.readings, [[0.5, np.pi / 2]], rtol=0, atol=1e-15)
    with pytest.raises(InputError, match=r"column `q1 \[grad\]`: unknown angle unit 'grad'"):
        read_joint_log(_write(tmp_path, "g.csv", "name,q1 [grad]\nA,1\n"))


def _simulated_capture(n_points=40, seed=7):
    """Free poses of the KR 5 with three flange targets: readings and tracker-frame points."""
    robot = load_robot("kuka-kr5-sixx-r650")
    rng = np.random.default_rng(seed)
    readings = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (n_points, 6))
    flange = forward_kinematics(robot.nominal, robot.model_joint_variables(readings))
    offsets = np.array([[0.0, 0.0, 50.0], [80.0, 0.0, 20.0], [0.0, 80.0, 20.0]])
    points = np.concatenate([(flange @ np.append(o, 1.0))[:, :3] for o in offsets]) + [1500.0, -200.0, 300.0]
    return Capture(
        circle=np.zeros(3 * n_points, dtype=int),
        direction=np.ones(3 * n_points, dtype=int),
        readings=np.tile(readings, (3, 1)),
        points=points,
        target=np.repeat([0, 1, 2], n_points),
        target_names=("T1", "T2", "T3"),
        u95=rng.uniform(0.01, 0.05, 3 * n_points),
        source="simulated",
    )


def _leica_metres(capture: Capture) -> str:
    """The capture's points as a Leica export in metres, decimal comma, ';' (names = pose numbers)."""
    pose = np.unique(capture.readings, axis=0, return_inverse=True)[1].reshape(-1)
    lines = ["Point ID;Target;X [m];Y [m];Z [m];U(95) [m];Time Stamp"]
    for k in range(capture.n_points):
        values = [*(capture.points[k] / 1000.0), capture.u95[k] / 1000.0]
        cells = [f"{v:.15f}".replace(".", ",") for v in values]
        lines.append(f"pose{pose[k]};{capture.point_targets[k]};" + ";".join(cells) + f";2026-11-23 12:{k % 60:02d}")
    return "\n".join(lines) + "\n"


def _joint_log(capture: Capture) -> str:
    """One row per pose, named as :func:`_leica_metres` names it (the index among the unique readings)."""
    unique = np.unique(capture.readings, axis=0)
    lines = ["name,circle,direction," + ",".join(f"q{i + 1}" for i in range(capture.n_joints))]
    for number, row in enumerate(unique):
        lines.append(f"pose{number},0,1," + ",".join(repr(float(v)) for v in np.rad2deg(row)))
    return "\n".join(lines) + "\n"


def test_round_trip_capture_leica_metres_import(tmp_path):
    capture = _simulated_capture()
    export = _write(tmp_path, "export.txt", _leica_metres(capture))
    log = _write(tmp_path, "joints.csv", _joint_log(capture))
    imported = import_tracker_capture(export, log, n_joints=6)
    # same order as the export: the capture's order
    assert imported.point_targets == capture.point_targets
    np.testing.assert_allclose(imported.points, capture.points, rtol=0, atol=1e-9)  # 15 decimals of m = 1e-12 mm
    np.testing.assert_allclose(imported.u95, capture.u95, rtol=0, atol=1e-12)
    np.testing.assert_allclose(imported.readings, capture.readings, rtol=0, atol=1e-15)  # repr of degrees
    written = write_capture(tmp_path / "capture.csv", imported)
    again = read_capture(written, n_joints=6)
    np.testing.assert_allclose(again.points, capture.points, rtol=0, atol=1e-9)  # 12 decimals of mm
    assert again.point_targets == capture.point_targets


def test_explicit_delimiter_and_decimal(tmp_path):
    # given explicitly instead of detected
    text = "Name;X [mm];Y [mm];Z [mm]\nP1;1;2;3\nP2;4;5;6\n"
    path = _write(tmp_path, "semi.txt", text + "P3;7,5;8;9\n")
    np.testing.assert_array_equal(read_tracker_export(path, decimal=",").points[2], [7.5, 8.0, 9.0])
    tab = _write(tmp_path, "tab.txt", text.replace(";", "\t"))
    np.testing.assert_array_equal(read_tracker_export(tab, delimiter="tab").points[1], [4.0, 5.0, 6.0])
    with pytest.raises(InputError, match=r"delimiter must be ',', ';', tab or space; got '\|'"):
        read_tracker_export(tab, delimiter="|")
    with pytest.raises(InputError, match=r"decimal separator must be '.' or ','; got ':'"):
        read_tracker_export(tab, decimal=":")


# issue 24: rows are read whole or refused; --columns numbers and space-delimited exports


@pytest.mark.parametrize(
    ("text", "kwargs", "message"),
    [
        # a comma-delimited export with decimal commas: each number splits in two, 11 fields against 7
        (
            "Point ID,X [mm],Y [mm],Z [mm],U(95) [mm],Time Stamp,Target\n"
            "P1,1234,5,470,692512790,750,25,0,025,2024-05-01,T1\n",
            {},
            r"line 2 has 11 fields; expected 7, as in the header \(line 1\); a comma-delimited file with decimal commas",
        ),
        # a row longer than the header is no longer read in part
        ("Name,X [mm],Y [mm],Z [mm]\nP1,1,2,3\nP2,4,5,6,99\n", {}, r"line 3 has 5 fields; expected 4, as in the header"),
        # a plain export has exactly name;x;y;z
        ("P1;1;2;3\nP2;4;5;6;7\n", {"units": "mm"}, r"line 2 has 5 fields; expected 4, as in a plain name;x;y;z export"),
        # a headerless mapped export: every row as wide as the first
        ("7,P1,1,2,3\n8,P2,4,5\n", {"columns": "name=2,x=3,y=4,z=5", "units": "mm"}, r"line 2 has 4 fields; expected 5, as on line 1"),
        # a column number past the last column: was an IndexError
        ("Name,X,Y,Z\nP1,1,2,3\n", {"columns": "x=99,y=3,z=4,name=1", "units": "mm"}, r"--columns x=99: no column 99; line 1 has 4 fields"),
        ("P1 1 2 3\n", {"columns": "x=2,y=3,z=7,name=1", "units": "mm"}, r"--columns z=7: no column 7; line 1 has 4 fields"),
    ],
)
def test_rows_of_another_width_and_missing_column_numbers_are_refused(tmp_path, text, kwargs, message):
    path = _write(tmp_path, "bad.txt", text)
    with pytest.raises(InputError, match=message) as info:
        read_tracker_export(path, **kwargs)
    assert "bad.txt" in str(info.value)


def test_a_trailing_delimiter_is_no_extra_field(tmp_path):
    points = read_tracker_export(_write(tmp_path, "t.txt", "Name;X [mm];Y [mm];Z [mm];\nP1;1;2;3;\nP2;4;5;6\n"))
    np.testing.assert_array_equal(points.points, [[1, 2, 3], [4, 5, 6]])


def test_space_delimited_exports_are_read(tmp_path):
    # a headerless name x y z export (runs of spaces), a headed one, and a mapped one: was an IndexError
    plain = read_tracker_export(_write(tmp_path, "p.txt", "P1  1234.5 470.6   750.2\nP2 1250 -487.5 800\n"), units="mm")
    assert plain.layout == "plain" and plain.names == ("P1", "P2")
    np.testing.assert_array_equal(plain.points, [[1234.5, 470.6, 750.2], [1250, -487.5, 800]])
    headed = read_tracker_export(_write(tmp_path, "h.txt", "Name X Y Z\nP1 1 2 3\n"), units="m")
    np.testing.assert_array_equal(headed.points, [[1000, 2000, 3000]])
    mapped = read_tracker_export(_write(tmp_path, "m.txt", "P1 1 2 3\n"), columns="x=2,y=3,z=4,name=1", units="mm")
    np.testing.assert_array_equal(mapped.points, [[1, 2, 3]])
    decimal_comma = read_tracker_export(_write(tmp_path, "d.txt", "P1 1,5 2 3\n"), units="mm", delimiter="space")
    np.testing.assert_array_equal(decimal_comma.points, [[1.5, 2, 3]])
    log = read_joint_log(_write(tmp_path, "j.txt", "name q1 q2\nP1 10 20\n"))
    np.testing.assert_allclose(np.rad2deg(log.readings), [[10, 20]], rtol=0, atol=1e-13)


def test_joint_log_rows_of_another_width_are_refused(tmp_path):
    with pytest.raises(InputError, match=r"j.csv: line 3 has 5 fields; expected 3, as in the header \(line 1\)"):
        read_joint_log(_write(tmp_path, "j.csv", "name,q1,q2\nP1,1,2\nP2,1,5,2,5\n"))
