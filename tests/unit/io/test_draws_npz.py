"""``draws.npz`` and the robot-dict round trip it relies on."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io.formats.draws_npz import read_draws, write_draws
from robotcal.io.schema.robots import load_robot, robot_from_dict, robot_to_dict


@pytest.mark.parametrize("name", ["kuka-kr5-sixx-r650", "kuka-kr5-sixx-r650-krc"])
def test_robot_dict_round_trip(name):
    robot = load_robot(name)
    again = robot_from_dict(robot_to_dict(robot))
    np.testing.assert_allclose(again.nominal, robot.nominal, rtol=0, atol=1e-12)  # mm stay mm, rad via deg
    np.testing.assert_array_equal(again.hayati, robot.hayati)
    np.testing.assert_array_equal(again.reading_sign, robot.reading_sign)
    np.testing.assert_allclose(again.limits, robot.limits, atol=1e-15)


def test_draws_round_trip_in_file_units(tmp_path):
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    rng = np.random.default_rng(0)
    values = np.broadcast_to(robot.nominal, (7, 6, 5)) + rng.normal(0, 1e-3, (7, 6, 5)) * ~robot.structurally_fixed
    identified = np.zeros((6, 5), dtype=bool)
    identified[:5, :4] = True
    path = write_draws(tmp_path / "draws.npz", robot, values, identified, seed=3)
    with np.load(path, allow_pickle=False) as archive:
        assert archive["values"].shape == (7, 30)
        assert archive["values"][0, 1] == pytest.approx(np.rad2deg(values[0, 0, 1]))  # J1.theta in deg
        assert archive["values"][0, 2] == pytest.approx(values[0, 0, 2])  # J1.a in mm
        assert list(archive["units"][:3]) == ["mm", "deg", "mm"]
    back = read_draws(path)
    np.testing.assert_allclose(back.values, values, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.identified, identified)
    np.testing.assert_allclose(back.robot.nominal, robot.nominal, atol=1e-12)
    assert back.seed == 3 and back.n_draws == 7


def test_bad_draws_files(tmp_path):
    with pytest.raises(InputError, match="no such draws file"):
        read_draws(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="not a readable .npz file"):
        read_draws(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", values=np.zeros((2, 30)))
    with pytest.raises(InputError, match="missing key"):
        read_draws(tmp_path / "other.npz")
