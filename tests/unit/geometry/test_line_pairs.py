"""Plücker lines and adjacent-line analysis (thesis 4.4.2-4.4.4) on lines with closed-form answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry import PluckerLine, analyse_dh_pair, analyse_hayati_pair, signed_angle_about


def _homogeneous(rotation=np.eye(3), shift=np.zeros(3)):  # noqa: B008 - read-only defaults
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = shift
    return matrix


def _rz(angle):
    return _homogeneous(Rotation.from_euler("z", angle).as_matrix())


def _rx(angle):
    return _homogeneous(Rotation.from_euler("x", angle).as_matrix())


def _ry(angle):
    return _homogeneous(Rotation.from_euler("y", angle).as_matrix())


def _shift(x=0.0, y=0.0, z=0.0):
    return _homogeneous(shift=[x, y, z])


def _motion(seed, max_shift=1000.0):
    """A random rigid motion of the whole scene (the answers are frame-independent)."""
    if seed is None:
        return np.eye(4)
    rng = np.random.default_rng(seed)
    return _homogeneous(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-max_shift, max_shift, 3))


def _axes_of(frame_j, link):
    """Axis j (z of frame_j) and axis k (z of frame_j @ link) as Plücker lines, plus the frames."""
    frame_k = frame_j @ link
    line_j = PluckerLine.from_point_direction(frame_j[:3, 3], frame_j[:3, 2])
    line_k = PluckerLine.from_point_direction(frame_k[:3, 3], frame_k[:3, 2])
    return line_j, line_k, frame_k


def _common_perpendicular_feet(p1, s1, p2, s2):
    """Textbook closed form: minimise |p1 + t1 s1 - p2 - t2 s2|^2, a 2x2 linear system in (t1, t2)."""
    w = p2 - p1
    system = np.array([[s1 @ s1, -(s1 @ s2)], [s1 @ s2, -(s2 @ s2)]])
    t1, t2 = np.linalg.solve(system, [w @ s1, w @ s2])
    return p1 + t1 * s1, p2 + t2 * s2


# ---------------------------------------------------------------------------------------------- Plücker lines


def test_plucker_line_from_point_direction():
    point = np.array([100.0, -20.0, 35.0])
    direction = np.array([3.0, 4.0, 12.0])  # |direction| = 13, normalised by the constructor
    line = PluckerLine.from_point_direction(point, direction)
    np.testing.assert_allclose(line.direction, direction / 13.0, rtol=0, atol=1e-16)  # exact division
    np.testing.assert_allclose(line.moment, np.cross(point, direction / 13.0), rtol=0, atol=1e-13)
    # the moment does not depend on which point of the line is used (eq. 4-7): rounding only
    other = PluckerLine.from_point_direction(point + 250.0 * direction / 13.0, direction)
    np.testing.assert_allclose(other.moment, line.moment, rtol=0, atol=1e-11)
    # ``point`` is the foot of the perpendicular from the origin: on the line and normal to it
    foot = line.point
    np.testing.assert_allclose(foot @ line.direction, 0.0, atol=1e-11)
    np.testing.assert_allclose(np.cross(foot - point, line.direction), 0.0, atol=1e-11)


def test_plucker_line_transformed_flipped_and_indexed():
    rng = np.random.default_rng(1)
    points = rng.uniform(-500.0, 500.0, (4, 3))
    directions = rng.normal(size=(4, 3))
    lines = PluckerLine.from_point_direction(points, directions)
    motion = _motion(2)
    moved = lines.transformed(motion)
    expected = PluckerLine.from_point_direction(
        points @ motion[:3, :3].T + motion[:3, 3], directions @ motion[:3, :3].T
    )
    # a rigid motion maps the line through p along s to the line through Mp along Rs (rounding only)
    np.testing.assert_allclose(moved.direction, expected.direction, rtol=0, atol=1e-14)
    np.testing.assert_allclose(moved.moment, expected.moment, rtol=0, atol=1e-9)
    flipped = lines.flipped(np.array([True, False, True, False]))
    sign = np.array([-1.0, 1.0, -1.0, 1.0])[:, None]
    np.testing.assert_array_equal(flipped.direction, sign * lines.direction)  # exact sign change
    np.testing.assert_array_equal(flipped.moment, sign * lines.moment)
    second = lines[1]
    np.testing.assert_array_equal(second.direction, lines.direction[1])
    assert lines[..., 1:3].direction.shape == (2, 3)


def test_plucker_line_rejects_zero_direction():
    with pytest.raises(InputError, match="finite non-zero vector"):
        PluckerLine.from_point_direction([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "bad",
    [[np.nan, 0.0, 1.0], [np.inf, 0.0, 1.0], [1e200, 1e200, 0.0]],
    ids=["nan", "infinite", "norm-overflows"],
)
def test_plucker_line_rejects_non_finite_directions(bad):
    # one bad item spoils the batch; a finite vector whose norm overflows cannot be normalised either
    directions = np.array([[0.0, 0.0, 1.0], bad])
    with pytest.raises(InputError, match="finite non-zero vector"):
        PluckerLine.from_point_direction(np.zeros((2, 3)), directions)


def test_plucker_line_arrays_are_frozen_and_batch_indexing_does_not_copy():
    rng = np.random.default_rng(6)
    direction, moment = np.array([0.0, 0.6, 0.8]), np.array([10.0, -4.0, 3.0])
    line = PluckerLine(direction=direction, moment=moment)
    direction[0] = 5.0  # the constructor copied the caller's arrays
    np.testing.assert_array_equal(line.direction, [0.0, 0.6, 0.8])
    lines = PluckerLine.from_point_direction(rng.normal(size=(5, 4, 3)), rng.normal(size=(5, 4, 3)))
    column = lines[..., 1]
    # basic indexing: views of the frozen arrays; advanced indexing: frozen copies
    assert np.shares_memory(column.direction, lines.direction) and np.shares_memory(column.moment, lines.moment)
    picked = lines[[0, 3]]
    assert not np.shares_memory(picked.direction, lines.direction)
    np.testing.assert_array_equal(picked.moment, lines.moment[[0, 3]])
    derived = (line, lines, column, picked, lines.flipped(np.ones((5, 4), bool)), lines.transformed(_motion(7)))
    for each in derived:
        for values in (each.direction, each.moment):
            assert not values.flags.writeable
            with pytest.raises(ValueError, match="read-only"):
                values[..., 0] = 0.0


def test_signed_angle_about_closed_forms():
    x, y, z = np.eye(3)
    # quarter turns: right-handed about +z, left-handed about -z (exact up to atan2 rounding)
    np.testing.assert_allclose(signed_angle_about(x, y, z), np.pi / 2, atol=1e-15)
    np.testing.assert_allclose(signed_angle_about(x, y, -z), -np.pi / 2, atol=1e-15)
    np.testing.assert_allclose(signed_angle_about(x, -x, z), np.pi, atol=1e-15)
    # components along the axis are ignored: vectors are projected first
    np.testing.assert_allclose(signed_angle_about(x + 5.0 * z, y - 3.0 * z, z), np.pi / 2, atol=1e-15)


def test_signed_angle_about_in_a_random_frame():
    rng = np.random.default_rng(3)
    rotation = Rotation.random(random_state=rng)
    angles = rng.uniform(-np.pi + 1e-6, np.pi - 1e-6, 10)
    from_vectors = rotation.apply(np.c_[np.ones(10), np.zeros(10), rng.normal(size=10)])
    to_vectors = rotation.apply(np.c_[np.cos(angles), np.sin(angles), rng.normal(size=10)])
    # by construction the projected angle about the rotated z axis is ``angles`` (rounding only)
    np.testing.assert_allclose(
        signed_angle_about(from_vectors, to_vectors, rotation.apply([0, 0, 1])), angles, atol=1e-13
    )


# ---------------------------------------------------------------------------------------------- DH pairs


@pytest.mark.parametrize("motion_seed", [None, 11, 12])
@pytest.mark.parametrize(
    ("d", "theta", "a", "alpha"),
    [(335.0, 0.3, 75.0, np.pi / 2), (-40.0, -2.0, 90.0, 1.1), (12.0, 2.9, -25.0, -0.7), (0.0, 1.0, 120.0, 2.8)],
)
def test_skew_pair_from_known_dh_parameters(motion_seed, d, theta, a, alpha):
    frame_j = _motion(motion_seed)
    link = _rz(theta) @ _shift(z=d) @ _shift(x=a) @ _rx(alpha)  # eq. 3-72 built from scipy rotations
    line_j, line_k, frame_k = _axes_of(frame_j, link)
    x_j = (frame_j @ _rz(theta))[:3, 0]  # the common normal of a DH link is x_j
    pair = analyse_dh_pair(line_j, line_k, normal_hint=x_j, point_j_if_parallel=np.zeros(3))
    assert pair.case == "skew"
    foot_j = (frame_j @ _shift(z=d))[:3, 3]  # O_{j-1} + d z_{j-1}
    foot_k = frame_k[:3, 3]  # O_j
    # exact lines of ~1 m coordinates: feet and lengths to rounding (1e-9 mm), angles to 1e-12 rad
    np.testing.assert_allclose(pair.point_j, foot_j, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.point_k, foot_k, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.normal, x_j, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.length, a, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.twist, alpha, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(pair.beta, 0.0)
    # the feet are the textbook common perpendicular (independent 2x2 solve)
    textbook_j, textbook_k = _common_perpendicular_feet(line_j.point, line_j.direction, line_k.point, line_k.direction)
    np.testing.assert_allclose(pair.point_j, textbook_j, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.point_k, textbook_k, rtol=0, atol=1e-9)
    # mutual moment (eq. 4-22) of two lines is -a sin(alpha) with the DH normal x_j: a closed form
    np.testing.assert_allclose(pair.mutual_moment, -a * np.sin(alpha), rtol=0, atol=1e-9)

    # the hint only chooses the sign of the normal: flipping it flips a_jk, a and alpha
    flipped = analyse_dh_pair(line_j, line_k, normal_hint=-x_j, point_j_if_parallel=np.zeros(3))
    np.testing.assert_allclose(flipped.normal, -x_j, rtol=0, atol=1e-12)
    np.testing.assert_allclose(flipped.length, -a, rtol=0, atol=1e-9)
    np.testing.assert_allclose(flipped.twist, -alpha, rtol=0, atol=1e-12)
    np.testing.assert_allclose(flipped.point_j, foot_j, rtol=0, atol=1e-9)  # the feet do not depend on the sign
    np.testing.assert_allclose(flipped.point_k, foot_k, rtol=0, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_random_skew_lines_match_textbook_common_perpendicular(seed):
    rng = np.random.default_rng(seed)
    p1, p2 = rng.uniform(-800.0, 800.0, (2, 3))
    s1, s2 = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
    line_j = PluckerLine.from_point_direction(p1, s1)
    line_k = PluckerLine.from_point_direction(p2, s2)
    hint = rng.normal(size=3)
    pair = analyse_dh_pair(line_j, line_k, normal_hint=hint, point_j_if_parallel=np.zeros(3))
    foot_j, foot_k = _common_perpendicular_feet(p1, s1, p2, s2)
    # random skew lines at ~1 m: rounding of both closed forms, amplified by 1/sin(angle) (~1e-10 mm)
    np.testing.assert_allclose(pair.point_j, foot_j, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.point_k, foot_k, rtol=0, atol=1e-9)
    expected_normal = np.cross(s1, s2) / np.linalg.norm(np.cross(s1, s2))
    expected_normal *= np.sign(expected_normal @ hint)
    np.testing.assert_allclose(pair.normal, expected_normal, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.length, (foot_k - foot_j) @ expected_normal, rtol=0, atol=1e-9)
    # twist: the angle from s1 to s2 about the oriented normal
    np.testing.assert_allclose(pair.twist, signed_angle_about(s1, s2, expected_normal), rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "common",
    [np.array([120.0, -35.0, 410.0]), np.zeros(3), np.array([300.0, 200.0, 0.0])],
    ids=["generic", "origin", "coplanar-with-origin"],
)
def test_intersecting_pair(common):
    s_j = np.array([0.0, 0.0, 1.0])
    s_k = np.array([1.0, 0.0, 0.0]) if common[2] == 0.0 else np.array([0.6, 0.0, 0.8])
    # "coplanar-with-origin": the common point lies in the plane of the two directions, where eq. 4-44 is 0/0
    line_j = PluckerLine.from_point_direction(common, s_j)
    line_k = PluckerLine.from_point_direction(common, s_k)
    hint = np.array([0.0, 1.0, 0.0])
    pair = analyse_dh_pair(line_j, line_k, normal_hint=hint, point_j_if_parallel=np.full(3, 99.0))
    assert pair.case == "intersecting"
    # both feet are the common point; a = 0 (rounding of ~0.5 m coordinates)
    np.testing.assert_allclose(pair.point_j, common, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.point_k, common, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.length, 0.0, atol=1e-9)
    expected_normal = np.cross(s_j, s_k) / np.linalg.norm(np.cross(s_j, s_k))
    expected_normal *= np.sign(expected_normal @ hint)
    np.testing.assert_allclose(pair.normal, expected_normal, atol=1e-15)
    np.testing.assert_allclose(pair.twist, signed_angle_about(s_j, s_k, expected_normal), atol=1e-15)


@pytest.mark.parametrize("opposite", [False, True])
def test_parallel_pair(opposite):
    rng = np.random.default_rng(4)
    direction = Rotation.random(random_state=rng).apply([0.0, 0.0, 1.0])
    point_j = rng.uniform(-500.0, 500.0, 3)
    offset = np.cross(direction, rng.normal(size=3))
    offset *= 270.0 / np.linalg.norm(offset)  # distance 270 mm, perpendicular to the axes
    line_j = PluckerLine.from_point_direction(point_j, direction)
    line_k = PluckerLine.from_point_direction(
        point_j + offset + 123.0 * direction, -direction if opposite else direction
    )
    given = point_j + 40.0 * direction  # the caller's P_j on line j
    pair = analyse_dh_pair(line_j, line_k, normal_hint=offset, point_j_if_parallel=given)
    assert pair.case == "parallel"
    # eq. 4-52: P_j is the given point, P_k = P_j + offset; rounding of ~1 m coordinates
    np.testing.assert_allclose(pair.point_j, given, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.point_k, given + offset, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.length, 270.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair.normal, offset / 270.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.abs(pair.twist), np.pi if opposite else 0.0, atol=1e-12)
    # the hint sets the sign: a is signed
    flipped = analyse_dh_pair(line_j, line_k, normal_hint=-offset, point_j_if_parallel=given)
    np.testing.assert_allclose(flipped.length, -270.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(flipped.normal, -offset / 270.0, rtol=0, atol=1e-12)


def test_coincident_lines_take_normal_from_hint():
    line = PluckerLine.from_point_direction([10.0, 20.0, 30.0], [0.0, 0.0, 1.0])
    pair = analyse_dh_pair(line, line, normal_hint=[1.0, 1.0, 5.0], point_j_if_parallel=[10.0, 20.0, 0.0])
    assert pair.case == "parallel"
    # no offset: the normal is the hint's component perpendicular to the axis, a = 0
    np.testing.assert_allclose(pair.normal, np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0), atol=1e-15)
    np.testing.assert_allclose(pair.length, 0.0, atol=1e-12)
    np.testing.assert_allclose(pair.point_k, [10.0, 20.0, 0.0], atol=1e-12)


def test_dh_pair_is_batched():
    links = [
        _rz(t) @ _shift(z=d) @ _shift(x=a) @ _rx(al) for t, d, a, al in [(0.1, 5.0, 30.0, 1.0), (-1.0, 0.0, 75.0, 1.5)]
    ]
    pairs = [_axes_of(_motion(20 + k), link) for k, link in enumerate(links)]
    line_j = PluckerLine(
        direction=np.stack([p[0].direction for p in pairs]), moment=np.stack([p[0].moment for p in pairs])
    )
    line_k = PluckerLine(
        direction=np.stack([p[1].direction for p in pairs]), moment=np.stack([p[1].moment for p in pairs])
    )
    hints = np.stack([(_motion(20 + k) @ _rz(t))[:3, 0] for k, t in enumerate([0.1, -1.0])])
    batch = analyse_dh_pair(line_j, line_k, normal_hint=hints, point_j_if_parallel=np.zeros(3))
    assert batch.length.shape == (2,) and batch.point_j.shape == (2, 3)
    # the batch gives the per-item closed-form answers (rounding only)
    np.testing.assert_allclose(batch.length, [30.0, 75.0], atol=1e-9)
    np.testing.assert_allclose(batch.twist, [1.0, 1.5], atol=1e-12)


def _plain_dot(a, b):
    return np.sum(a * b, axis=-1)


def test_skew_pairs_are_the_plain_vector_formulas_to_the_bit():
    # the pair analysis works on component arrays; written with np.cross, np.linalg.norm and sums over the last
    # axis, eqs 4-12, 4-13, 4-22, 4-35 and 4-36 are the same IEEE operations in the same order, so the results
    # are equal to the bit (what keeps the CPA Monte Carlo draws those of the reference implementation)
    rng = np.random.default_rng(8)
    stack = PluckerLine.from_point_direction(rng.uniform(-900.0, 900.0, (400, 6, 3)), rng.normal(size=(400, 6, 3)))
    line_j, line_k = stack[..., 2], stack[..., 3]  # strided views, as the CPA passes them
    hint = rng.normal(size=(400, 3))
    pair = analyse_dh_pair(line_j, line_k, normal_hint=hint, point_j_if_parallel=np.zeros(3))
    assert pair.case.shape == (400,) and np.all(pair.case == "skew")
    s_j, s0_j, s_k, s0_k = line_j.direction, line_j.moment, line_k.direction, line_k.moment
    cross = np.cross(s_j, s_k)
    normal = cross / np.linalg.norm(cross, axis=-1, keepdims=True)
    normal = np.where((_plain_dot(normal, hint) < 0.0)[:, None], -normal, normal)
    n_k, n_j = np.cross(normal, s_k), np.cross(normal, s_j)
    foot_j = (np.cross(n_k, s0_j) - _plain_dot(s0_k, normal)[:, None] * s_j) / _plain_dot(n_k, s_j)[:, None]
    foot_k = (np.cross(n_j, s0_k) - _plain_dot(s0_j, normal)[:, None] * s_k) / _plain_dot(n_j, s_k)[:, None]
    np.testing.assert_array_equal(pair.normal, normal)
    np.testing.assert_array_equal(pair.point_j, foot_j)
    np.testing.assert_array_equal(pair.point_k, foot_k)
    np.testing.assert_array_equal(pair.length, _plain_dot(foot_k - foot_j, normal))
    np.testing.assert_array_equal(pair.twist, np.arctan2(_plain_dot(cross, normal), _plain_dot(s_j, s_k)))
    np.testing.assert_array_equal(pair.mutual_moment, _plain_dot(s_j, s0_k) + _plain_dot(s_k, s0_j))
    np.testing.assert_array_equal(line_j.point, np.cross(s_j, s0_j))
    angles = signed_angle_about(hint, pair.normal, s_j)
    expected = np.arctan2(
        _plain_dot(np.cross(hint, pair.normal), s_j),
        _plain_dot(hint, pair.normal) - _plain_dot(hint, s_j) * _plain_dot(pair.normal, s_j),
    )
    np.testing.assert_array_equal(angles, expected)


def test_dh_pair_of_a_mixed_batch_gives_each_item_its_own_answer():
    # the intersecting and parallel formulas run only when some item needs them: every item of a batch mixing
    # the cases must get exactly what it gets alone, and its own case label
    rng = np.random.default_rng(9)
    s_j = np.array([0.0, 0.0, 1.0])
    items = [  # (point and direction of line j, of line k), expected case
        (([10.0, 20.0, 30.0], s_j, [200.0, -40.0, 75.0], [0.6, 0.0, 0.8]), "skew"),
        (([120.0, -35.0, 410.0], s_j, [120.0, -35.0, 410.0], [0.6, 0.0, 0.8]), "intersecting"),
        (([300.0, 200.0, 0.0], s_j, [300.0, 200.0, 0.0], [1.0, 0.0, 0.0]), "intersecting"),  # eq. 4-44 is 0/0
        (([0.0, 0.0, 0.0], s_j, [270.0, 0.0, 50.0], s_j), "parallel"),
        (([5.0, 5.0, 0.0], s_j, [5.0, -95.0, 0.0], -s_j), "parallel"),
        (([10.0, 20.0, 30.0], s_j, [10.0, 20.0, 99.0], s_j), "parallel"),  # coincident: normal from the hint
        (([-50.0, 80.0, 10.0], [0.0, 1.0, 0.0], [400.0, 0.0, -30.0], [1.0, 0.0, 0.0]), "skew"),
    ]
    hints = rng.normal(size=(len(items), 3))
    starts = rng.uniform(-100.0, 100.0, (len(items), 3))
    lines = [
        (PluckerLine.from_point_direction(p_j, d_j), PluckerLine.from_point_direction(p_k, d_k))
        for (p_j, d_j, p_k, d_k), _ in items
    ]
    batch = analyse_dh_pair(
        PluckerLine(direction=np.stack([j.direction for j, _ in lines]), moment=np.stack([j.moment for j, _ in lines])),
        PluckerLine(direction=np.stack([k.direction for _, k in lines]), moment=np.stack([k.moment for _, k in lines])),
        normal_hint=hints,
        point_j_if_parallel=starts,
    )
    assert list(batch.case) == [case for _, case in items]
    for index, (line_j, line_k) in enumerate(lines):
        alone = analyse_dh_pair(line_j, line_k, normal_hint=hints[index], point_j_if_parallel=starts[index])
        assert alone.case.shape == () and alone.case == items[index][1]
        for field in ("normal", "point_j", "point_k", "length", "twist", "beta", "mutual_moment"):
            np.testing.assert_array_equal(getattr(batch, field)[index], getattr(alone, field), err_msg=field)


# ---------------------------------------------------------------------------------------------- Hayati pairs


@pytest.mark.parametrize("motion_seed", [None, 31])
@pytest.mark.parametrize(
    ("theta", "a", "alpha", "beta"),
    [(0.0, 270.0, 0.0, 0.0), (0.4, 270.0, 0.012, -0.008), (-2.5, 150.0, -0.03, 0.02), (1.2, -60.0, 0.005, 0.05)],
)
def test_nearly_parallel_hayati_pair(motion_seed, theta, a, alpha, beta):
    frame_j = _motion(motion_seed)
    link = _rz(theta) @ _shift(x=a) @ _rx(alpha) @ _ry(beta)  # eq. 3-82 as a factor product
    line_j, line_k, frame_k = _axes_of(frame_j, link)
    x_j = (frame_j @ _rz(theta))[:3, 0]
    pair = analyse_hayati_pair(line_j, line_k, normal_hint=x_j, point_j=frame_j[:3, 3])
    assert pair.case == "nearly-parallel"
    # in the frame of axis j the answer is exact up to rounding (1e-12); after a 1 m rigid motion the
    # rounding of ~1e3 mm coordinates (~1e-13 mm each) enters the lengths (observed <= 3e-13 mm over
    # 29 motions): 1e-11 mm there; the angles stay at 1e-12 rad
    length_tol = 1e-12 if motion_seed is None else 1e-11
    np.testing.assert_allclose(pair.length, a, rtol=0, atol=length_tol)
    np.testing.assert_allclose(pair.twist, alpha, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.beta, beta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.point_k, frame_k[:3, 3], rtol=0, atol=length_tol)  # origin of the Hayati frame
    np.testing.assert_allclose(pair.point_j, frame_j[:3, 3], rtol=0, atol=0)  # the given P_j, unchanged
    np.testing.assert_allclose(pair.normal, x_j, rtol=0, atol=1e-12)


def test_hayati_pair_rejects_perpendicular_axes():
    line_j = PluckerLine.from_point_direction(np.zeros(3), [0.0, 0.0, 1.0])
    line_k = PluckerLine.from_point_direction([100.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    with pytest.raises(DegenerateGeometryError, match="perpendicular"):
        analyse_hayati_pair(line_j, line_k, normal_hint=[1.0, 0.0, 0.0], point_j=np.zeros(3))
