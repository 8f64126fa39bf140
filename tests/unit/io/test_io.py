"""io: file contracts round-trip exactly and bad files fail with errors naming file, line and key."""

from __future__ import annotations

import os

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.errors import InputError, RigidTransformWarning, RobotcalWarning
from robotcal.io import (
    atomic_write_text,
    load_robot,
    load_scenario,
    read_capture,
    read_parameters,
    scenario_from_dict,
    write_capture,
    write_parameters,
)
from robotcal.io.schema.builtins import read_toml
from robotcal.kinematics import ParameterSet, RobotModel


def test_capture_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    capture = Capture(
        circle=np.repeat([1, 2], 4),
        direction=np.array([1, 1, -1, -1] * 2),
        readings=rng.uniform(-3, 3, (8, 2)),
        points=rng.uniform(-2000, 2000, (8, 3)),
    )
    back = read_capture(write_capture(tmp_path / "c.csv", capture))
    np.testing.assert_array_equal(back.circle, capture.circle)
    np.testing.assert_array_equal(back.direction, capture.direction)
    # 12 decimals in mm and deg: errors below 1e-12 mm and 1e-12 deg
    np.testing.assert_allclose(back.points, capture.points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.readings, capture.readings, rtol=0, atol=np.deg2rad(1e-12))


def test_capture_csv_errors(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("circle,direction,q1,x,y,z\n1,1,0,1,2,3\n1,1,0,1,2\n")
    with pytest.raises(InputError, match="line 3 has 5 fields"):
        read_capture(path)
    path.write_text("circle,direction,q1,x,y,z\n2,1,0,1,2,3\n")
    with pytest.raises(InputError, match="line 2, column `circle`"):
        read_capture(path)
    path.write_text("")
    with pytest.raises(InputError, match="empty file"):
        read_capture(path)
    with pytest.raises(InputError, match="file not found"):
        read_capture(tmp_path / "absent.csv")


def test_parameters_json_round_trip_and_checks(tmp_path):
    robot = load_robot("kuka-kr5-sixx-r650")
    values = robot.nominal.copy()
    values[0, 0] += 0.25
    values[1, 4] = np.deg2rad(0.01)
    identified = np.zeros((6, 5), dtype=bool)
    identified[0, 0] = identified[1, 4] = True
    path = write_parameters(tmp_path / "p.json", ParameterSet(robot=robot, values=values, identified=identified))
    back = read_parameters(path, robot)
    np.testing.assert_allclose(back.values, values, rtol=0, atol=1e-15)  # deg <-> rad conversion only
    np.testing.assert_array_equal(back.identified, identified)
    with pytest.raises(InputError, match="6 joints but robot"):
        read_parameters(path, RobotModel(name=robot.name, nominal=np.zeros((2, 5)), hayati=[0, 0]))
    with pytest.warns(RobotcalWarning, match="written for robot 'kuka-kr5-sixx-r650'"):
        read_parameters(path, load_robot("kuka-kr5-sixx-r650-krc"))
    text = path.read_text().replace('"d": 335.25', '"d": "x"')
    path.write_text(text)
    with pytest.raises(InputError, match=r"joints\[0\].d"):
        read_parameters(path, robot)


def test_builtin_scenarios_load_with_thesis_values():
    laser = load_scenario("thesis-laser-tracker")
    assert laser.instrument.a_mm == pytest.approx(0.010) and laser.instrument.b_mm_per_m == pytest.approx(0.0025)
    igps = load_scenario("thesis-igps")
    assert igps.instrument.a_mm == pytest.approx(0.2) and igps.instrument.b_mm_per_m == 0.0
    np.testing.assert_allclose(laser.tracker_from_base[:3, 3], [1866.9489, 5.0186, 625.5015])
    # the stored rotation is the nearest rotation to Table 5.4's printed matrix: within its 5 printed digits
    printed = np.array([[0.0066, 0.99995, 0.00651], [-0.99992, 0.00666, -0.01008], [-0.01013, -0.00645, 0.99992]])
    np.testing.assert_allclose(laser.tracker_from_base[:3, :3], printed, atol=1e-5)
    noise_free = load_scenario("thesis-noise-free")
    assert noise_free.instrument.is_noise_free


def test_printed_matrix_is_repaired_with_a_warning(tmp_path):
    data = read_toml(load_scenario("thesis-laser-tracker").source)
    data["tracker_from_base"] = [
        [0.0066, 0.99995, 0.00651, 1866.9489],
        [-0.99992, 0.00666, -0.01008, 5.0186],
        [-0.01013, -0.00645, 0.99992, 625.5015],
        [0, 0, 0, 1],
    ]
    with pytest.warns(RigidTransformWarning, match="nearest rotation"):
        scenario = scenario_from_dict(data)
    rotation = scenario.tracker_from_base[:3, :3]
    np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)


def test_scenario_validation_names_keys():
    data = read_toml(load_scenario("thesis-noise-free").source)
    bad = {**data, "capture": {**data["capture"], "points": [15, 20, 30]}}
    with pytest.raises(InputError, match=r"capture.points.*3 values"):
        scenario_from_dict(bad)
    bad = {**data, "instrument": {"preset": "laser-9000"}}
    with pytest.raises(InputError, match="unknown instrument preset 'laser-9000'"):
        scenario_from_dict(bad)
    bad = {**data, "capture": {**data["capture"], "flange_reflector_mm": [0, 0, 50]}}
    with pytest.raises(InputError, match="exactly one of"):
        scenario_from_dict(bad)
    bad = {k: v for k, v in data.items() if k != "robot"}
    with pytest.raises(InputError, match="key `robot`: missing required key"):
        scenario_from_dict(bad)


def test_joint_errors_table_converts_units():
    data = read_toml(load_scenario("thesis-noise-free").source)
    data["capture"]["joint_errors"] = [
        {"joint": 3, "dz": {"amplitude": 0.02, "period_deg": 180}, "ey": {"amplitude": 0.001, "noise_sd": 0.0005}}
    ]
    model = scenario_from_dict(data).joint_errors
    assert model.amplitude[2, 2] == 0.02 and model.period[2, 2] == pytest.approx(np.pi)
    assert model.amplitude[2, 4] == pytest.approx(np.deg2rad(0.001))
    assert model.noise_sd[2, 4] == pytest.approx(np.deg2rad(0.0005))


def test_atomic_write_leaves_nothing_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "out.txt"
    atomic_write_text(target, "old")

    def failing_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(InputError, match="cannot write .*disk full"):
        atomic_write_text(target, "new")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_atomic_write_refuses_a_folder_and_keeps_the_umask_mode(tmp_path):
    with pytest.raises(InputError, match="it is a folder"):
        atomic_write_text(tmp_path, "x")
    written = atomic_write_text(tmp_path / "f.txt", "x")
    mask = os.umask(0)
    os.umask(mask)
    assert written.stat().st_mode & 0o777 == 0o666 & ~mask
