"""Thesis Table 5.8 through the TCP propagation path: built-in robot file, reading map, KUKA A, B, C.

tests/reference/test_kr5_tables.py checks the nominal flange of the typed-in Table 3.1 with scipy;
this module checks what users get from ``robotcal.uncertainty.tcp`` with the shipped robot file
``kuka-kr5-sixx-r650-krc``: the nominal row of Table 5.8, with the published angles (rotations about
X, Y, Z) equal to KUKA (C, B, A). Source: ``tests/data/thesis_tables.json`` (as printed).
"""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import JointLimitWarning
from robotcal.geometry.euler import thesis_order
from robotcal.io import load_robot
from robotcal.uncertainty.tcp import propagate_to_tcp, tcp_coordinates
from thesis_data import thesis_tables


@pytest.fixture(scope="module")
def table():
    return thesis_tables()


def test_nominal_row_of_table_5_8_from_the_builtin_robot(table):
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    readings = np.deg2rad(table["table_5_8_pose"])
    draws = np.repeat(robot.nominal[None], 25, axis=0)
    # the thesis pose leaves the controller limits (A2 = 80, A4 = 200, A5 = 125 deg): warned, not refused
    with pytest.warns(JointLimitWarning, match=r"pose 1: J4 = 200 deg outside"):
        result = propagate_to_tcp(robot, draws, readings)
    published = np.array(table["table_5_8"]["nominal"])
    # printed to 4 decimals; the thesis's own rounding leaves up to 3e-4 mm (Y), so 1e-3 mm and 1e-3 deg
    np.testing.assert_allclose(result.nominal[0, :3], published[:3], rtol=0, atol=1e-3)
    np.testing.assert_allclose(np.rad2deg(thesis_order(result.nominal[0, 3:])), published[3:], rtol=0, atol=1e-3)
    # and in KUKA order: A (about Z) = the published "C", C (about X) = the published "A"
    np.testing.assert_allclose(np.rad2deg(result.nominal[0, 3:]), published[3:][::-1], rtol=0, atol=1e-3)


def test_published_mean_lies_within_the_published_spread(table):
    # consistency of the transcription used by validation pages: |mean - nominal| << u per coordinate
    stats = table["table_5_8"]
    nominal, mean, u = (np.array(stats[key]) for key in ("nominal", "mean", "std"))
    assert np.all(np.abs(mean - nominal) < 0.1 * u)
    assert np.all(np.array(stats["lo"]) < mean) and np.all(mean < np.array(stats["hi"]))


def test_the_flange_is_the_tcp_of_table_5_8(table):
    # a tool offset moves the TCP: the table is reproduced only with the flange origin (tool = 0)
    robot = load_robot("kuka-kr5-sixx-r650-krc")
    q = robot.model_joint_variables(np.deg2rad(table["table_5_8_pose"]))
    shifted = tcp_coordinates(robot.nominal, q, tool=[0.0, 0.0, 10.0])[0]
    assert np.linalg.norm(shifted[:3] - np.array(table["table_5_8"]["nominal"][:3])) > 9.0
