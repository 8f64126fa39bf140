"""Elementary rotations, rotation about a line, inversion and rigid-transform checks against SciPy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from robotcal.errors import InputError
from robotcal.geometry import (
    apply_transform,
    check_rigid_transform,
    invert_transform,
    nearest_rotation,
    rot_x,
    rot_y,
    rot_z,
    rotation_about_line,
    translation,
)


def _homogeneous(rotation=np.eye(3), shift=np.zeros(3)):  # noqa: B008 - read-only defaults
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = shift
    return matrix


@pytest.mark.parametrize(("function", "axis"), [(rot_x, "x"), (rot_y, "y"), (rot_z, "z")])
def test_elementary_rotations_match_scipy(function, axis):
    angles = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, (4, 3))
    matrices = function(angles)
    assert matrices.shape == (4, 3, 4, 4)
    expected = Rotation.from_euler(axis, angles.ravel()[:, None]).as_matrix().reshape(4, 3, 3, 3)
    # right-handed rotation matrices: same formula up to rounding of sin/cos
    np.testing.assert_allclose(matrices[..., :3, :3], expected, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(matrices[..., :3, 3], 0.0)
    np.testing.assert_array_equal(matrices[..., 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (4, 3, 4)))


def test_rot_z_quarter_turn_is_right_handed():
    # closed form: Rz(90 deg) takes x to y (exact up to cos(pi/2) ~ 6e-17)
    np.testing.assert_allclose(rot_z(np.pi / 2)[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_translation():
    vectors = np.array([[1.0, -2.0, 3.5], [0.0, 10.0, -7.0]])
    matrices = translation(vectors)
    assert matrices.shape == (2, 4, 4)
    for matrix, vector in zip(matrices, vectors, strict=True):
        np.testing.assert_array_equal(matrix, _homogeneous(shift=vector))  # exact construction


@pytest.mark.parametrize("seed", range(4))
def test_rotation_about_line_equals_conjugated_rotation(seed):
    rng = np.random.default_rng(seed)
    direction = Rotation.random(random_state=rng).apply([0.0, 0.0, 1.0])
    point = rng.uniform(-1000.0, 1000.0, 3)
    angle = rng.uniform(-np.pi, np.pi)
    result = rotation_about_line(direction, point, angle)
    rotation = Rotation.from_rotvec(angle * direction).as_matrix()  # right-handed about the direction
    expected = _homogeneous(shift=point) @ _homogeneous(rotation) @ _homogeneous(shift=-point)
    # Trans(p) Rot Trans(-p): rounding of ~1 m translations only
    np.testing.assert_allclose(result, expected, rtol=0, atol=1e-10)
    on_line = point + np.linspace(-500.0, 500.0, 5)[:, None] * direction
    # points of the line are fixed (rounding of ~1.5 m coordinates)
    np.testing.assert_allclose(apply_transform(result, on_line), on_line, rtol=0, atol=1e-10)


def test_rotation_about_line_broadcasts():
    rng = np.random.default_rng(9)
    directions = Rotation.random(3, random_state=rng).apply([0.0, 0.0, 1.0])
    points = rng.uniform(-100.0, 100.0, (3, 3))
    angles = rng.uniform(-np.pi, np.pi, (2, 1))
    result = rotation_about_line(directions, points, angles)
    assert result.shape == (2, 3, 4, 4)
    for i in range(2):
        for j in range(3):
            single = rotation_about_line(directions[j], points[j], angles[i, 0])
            np.testing.assert_allclose(result[i, j], single, rtol=0, atol=1e-13)  # same arithmetic


def test_invert_and_apply_transform():
    rng = np.random.default_rng(3)
    transforms = np.stack(
        [_homogeneous(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-2000, 2000, 3)) for _ in range(4)]
    )
    inverse = invert_transform(transforms)
    # T^-1 T = I, rounding of ~2 m translations
    np.testing.assert_allclose(inverse @ transforms, np.broadcast_to(np.eye(4), (4, 4, 4)), rtol=0, atol=1e-10)
    np.testing.assert_allclose(inverse, np.linalg.inv(transforms), rtol=0, atol=1e-10)
    points = rng.uniform(-500.0, 500.0, (4, 3))
    homogeneous = np.einsum("kij,kj->ki", transforms, np.c_[points, np.ones(4)])[:, :3]
    np.testing.assert_allclose(apply_transform(transforms, points), homogeneous, rtol=0, atol=1e-10)


def test_check_rigid_transform_accepts_and_returns_float_matrix():
    matrix = _homogeneous(Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix(), [1.0, 2.0, 3.0])
    checked = check_rigid_transform(matrix.tolist())
    assert checked.shape == (4, 4) and checked.dtype == float
    np.testing.assert_array_equal(checked, matrix)  # returned unchanged


def _bad_matrices():
    good = _homogeneous(Rotation.from_euler("z", 30, degrees=True).as_matrix(), [1.0, 2.0, 3.0])
    nan = good.copy()
    nan[0, 3] = np.nan
    stretched = good.copy()
    stretched[:3, :3] *= 1.01
    last_row = good.copy()
    last_row[3] = [0.0, 0.0, 1.0, 1.0]
    mirrored = good.copy()
    mirrored[:3, 2] *= -1.0
    return [
        (good[:3], r"must have shape \(4, 4\); got \(3, 4\)"),
        (nan, "NaN or infinite"),
        (stretched, "not a rigid transform: its rotation block deviates from orthonormal"),
        (last_row, r"last row must be \[0, 0, 0, 1\]"),
        (mirrored, "det <= 0"),
        ("not a matrix", "must be a 4x4 numeric matrix"),
    ]


@pytest.mark.parametrize(("matrix", "message"), _bad_matrices())
def test_check_rigid_transform_errors(matrix, message):
    with pytest.raises(InputError, match=message):
        check_rigid_transform(matrix, "tracker_from_base")


def test_check_rigid_transform_names_argument():
    with pytest.raises(InputError, match="`tracker_from_base`"):
        check_rigid_transform(np.eye(3), "tracker_from_base")


def test_nearest_rotation_of_perturbed_rotation():
    rng = np.random.default_rng(5)
    truth = Rotation.random(6, random_state=rng).as_matrix()
    perturbation = rng.normal(0.0, 1e-3, truth.shape)
    result = nearest_rotation(truth + perturbation)
    assert result.shape == (6, 3, 3)
    # orthonormal with det +1 (rounding only)
    np.testing.assert_allclose(result @ np.swapaxes(result, -1, -2), np.broadcast_to(np.eye(3), (6, 3, 3)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(result), 1.0, atol=1e-14)
    for k in range(6):
        # independent truth: the orthogonal polar factor (scipy) is the Frobenius-nearest rotation
        np.testing.assert_allclose(result[k], polar(truth[k] + perturbation[k])[0], rtol=0, atol=1e-13)
    # close to the unperturbed rotation: within the perturbation size (1e-3 per entry, a few sigma)
    np.testing.assert_allclose(result, truth, rtol=0, atol=5e-3)


def test_nearest_rotation_never_returns_a_reflection():
    rng = np.random.default_rng(6)
    reflection = Rotation.random(random_state=rng).as_matrix() @ np.diag([1.0, 1.0, -1.0])
    result = nearest_rotation(reflection + rng.normal(0.0, 1e-3, (3, 3)))
    # a proper rotation even when the input has det < 0 (rounding only)
    np.testing.assert_allclose(np.linalg.det(result), 1.0, atol=1e-14)
    np.testing.assert_allclose(result @ result.T, np.eye(3), atol=1e-14)
