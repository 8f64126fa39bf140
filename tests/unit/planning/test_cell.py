"""Cell check: segment distances and a hand-computed two-joint cell (line of sight, range, acceptance, limits)."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io.schema.robots import robot_from_dict
from robotcal.kinematics.model import ReflectorMount
from robotcal.planning.cell import CellModel, check_plan, segment_distance
from robotcal.simulation.plan import CapturePlan


@pytest.mark.parametrize(
    ("p0", "p1", "q0", "q1", "expected"),
    [
        # skew perpendicular lines crossing at a height of 3: distance 3
        ([-1, 0, 0], [1, 0, 0], [0, -1, 3], [0, 1, 3], 3.0),
        # parallel, overlapping, offset by 2
        ([0, 0, 0], [5, 0, 0], [1, 2, 0], [4, 2, 0], 2.0),
        # collinear, disjoint: gap between the ends is 1
        ([0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], 1.0),
        # the closest points are two end points: (1,0,0) and (2,1,0) -> sqrt(2)
        ([0, 0, 0], [1, 0, 0], [2, 1, 0], [2, 5, 0], np.sqrt(2.0)),
        # a point (zero-length segment) above the middle of a segment
        ([0, 0, 4], [0, 0, 4], [-1, 0, 0], [1, 0, 0], 4.0),
        # two points
        ([0, 0, 0], [0, 0, 0], [3, 4, 0], [3, 4, 0], 5.0),
        # intersecting segments
        ([0, 0, 0], [2, 2, 0], [0, 2, 0], [2, 0, 0], 0.0),
    ],
)
def test_segment_distance_hand_cases(p0, p1, q0, q1, expected):
    # closed forms; 1e-12 is rounding only
    assert segment_distance(p0, p1, q0, q1) == pytest.approx(expected, abs=1e-12)
    assert segment_distance(q0, q1, p0, p1) == pytest.approx(expected, abs=1e-12)  # symmetric


def test_segment_distance_matches_dense_sampling():
    rng = np.random.default_rng(3)
    ends = rng.normal(size=(100, 4, 3))
    exact = segment_distance(ends[:, 0], ends[:, 1], ends[:, 2], ends[:, 3])
    s = np.linspace(0.0, 1.0, 101)
    u, v = ends[:, 1] - ends[:, 0], ends[:, 3] - ends[:, 2]
    a = ends[:, 0, None] + s[None, :, None] * u[:, None]
    b = ends[:, 2, None] + s[None, :, None] * v[:, None]
    sampled = np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))
    # sampling only overestimates, by at most half a step on each segment: 0.005 (|u| + |v|)
    assert np.all(exact <= sampled + 1e-12)
    bound = 0.005 * (np.linalg.norm(u, axis=1) + np.linalg.norm(v, axis=1))
    assert np.all(sampled - exact <= bound + 1e-12)


def _two_joint_cell(**cell_options):
    """Column J1 (d = 1000 mm, radius 100) and arm J2 (a = 400 mm); tracker at (2000, 0, 1000) mm."""
    robot = robot_from_dict(
        {"name": "two", "joints": [{"d": 1000.0, "limits_deg": [-180, 180]}, {"a": 400.0, "limits_deg": [-90, 90]}]}
    )
    plan = CapturePlan(
        start=np.deg2rad([-90.0, 0.0]),
        sweep=np.deg2rad([90.0, 180.0]),
        points=[3, 3],
        reflector=ReflectorMount(frame="joint", positions=[[300.0, 0.0, 500.0], [400.0, 0.0, 0.0]]),
    )
    tracker_from_base = np.eye(4)
    tracker_from_base[:3, 3] = [-2000.0, 0.0, -1000.0]
    options = {"capsule_radius": [100.0, 50.0], "max_distance": 2100.0, "acceptance": np.deg2rad(60.0), "aim": "start"}
    cell = CellModel(tracker_from_base=tracker_from_base, **(options | cell_options))
    return robot, plan, cell


def test_two_joint_cell_hand_computed():
    robot, plan, cell = _two_joint_cell()
    np.testing.assert_allclose(cell.tracker_position, [2000.0, 0.0, 1000.0])
    check = check_plan(robot, plan, cell)
    circle2 = np.flatnonzero(check.circle == 2)  # J2 at 0, 90, 180 deg; target (400 cos, 400 sin, 1000)
    # distances tracker-target: 1600, sqrt(2000^2 + 400^2), 2400
    np.testing.assert_allclose(check.distance[circle2], [1600.0, np.hypot(2000.0, 400.0), 2400.0], rtol=1e-12)
    # clearance to the column (link 1, radius 100; link 2 carries the target): its top (0,0,1000) is
    # 400 from the sight line at 0 deg, 800000/sqrt(2000^2+400^2) at 90 deg, on it at 180 deg
    np.testing.assert_allclose(
        check.clearance[circle2], [300.0, 800000.0 / np.hypot(2000.0, 400.0) - 100.0, -100.0], rtol=1e-12
    )
    np.testing.assert_array_equal(check.blocking_link[circle2], [0, 0, 1])
    # the normal faces the tracker (+x) at 0 deg and turns with J2: at 90 deg it is +y, the tracker
    # direction (2000, -400, 0)/|.|: incidence arccos(-400/2039.6) = 101.31 deg
    np.testing.assert_allclose(
        np.rad2deg(check.incidence[circle2]), [0.0, np.rad2deg(np.arccos(-400.0 / np.hypot(2000.0, 400.0))), 180.0],
        atol=1e-6,
    )  # fmt: skip
    expected = np.array([[0, 0, 0, 0], [0, 0, 1, 0], [1, 1, 1, 1]], dtype=bool)  # limit J2 = 180 > 90
    np.testing.assert_array_equal(check.failures[circle2], expected)
    assert check.limit_joint[circle2[-1]] == 1
    assert not check.feasible
    summary = check.circles[1]
    assert summary.first_failure == 2 and summary.usable_deg == (0.0, 0.0)
    assert summary.first_reasons == ("acceptance (101 deg)",)


def test_unchecked_acceptance_and_range_and_middle_aim():
    robot, plan, cell = _two_joint_cell(acceptance=None, max_distance=np.inf, aim="middle")
    check = check_plan(robot, plan, cell)
    circle2 = np.flatnonzero(check.circle == 2)
    assert not check.failures[:, 1:3].any()
    # middle aim: the normal faces the tracker at 90 deg
    assert check.incidence[circle2[1]] == pytest.approx(0.0, abs=1e-6)


def test_cell_validation():
    with pytest.raises(InputError, match="capsule_radius"):
        CellModel(tracker_from_base=np.eye(4), capsule_radius=[-1.0])
    with pytest.raises(InputError, match="measuring range"):
        CellModel(tracker_from_base=np.eye(4), capsule_radius=[1.0], min_distance=5.0, max_distance=1.0)
    with pytest.raises(InputError, match="aim"):
        CellModel(tracker_from_base=np.eye(4), capsule_radius=[1.0], aim="end")
    robot, plan, _ = _two_joint_cell()
    with pytest.raises(InputError, match="capsule radii"):
        check_plan(robot, plan, CellModel(tracker_from_base=np.eye(4), capsule_radius=[1.0]))


def test_thesis_plan_exceeds_the_kr5_limits():
    """Table 5.1 turns J5 to 200 deg; Fig. 4.17 allows +-120 deg: 10 points of circle 5 and all of circle 6."""
    from robotcal.io import load_scenario
    from robotcal.planning.scenario import cell_from_scenario

    scenario = load_scenario("thesis-laser-tracker")
    cell, _ = cell_from_scenario(scenario, no_acceptance=True)
    check = check_plan(scenario.robot, scenario.plan, cell)
    limit = check.failures[:, 0]
    # circle 5: 25 points 0..200 deg in steps of 200/24: those above 120 deg are k >= 15 (10 points)
    assert int(limit[check.circle == 5].sum()) == 10
    assert bool(limit[check.circle == 6].all())
    assert set(check.limit_joint[limit]) == {4}
    assert not check.feasible
