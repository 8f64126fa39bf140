"""KUKA A, B, C angles: round trips, the peer library (scipy 'ZYX'), the gimbal lock, angle wrapping."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import InputError
from robotcal.geometry.euler import (
    kuka_abc_from_matrix,
    matrix_from_kuka_abc,
    thesis_order,
    wrap_angle_near,
)
from robotcal.geometry.transforms import rot_x, rot_y, rot_z


@pytest.fixture(scope="module")
def rotations():
    return Rotation.random(500, random_state=np.random.default_rng(3))


def test_matches_scipy_intrinsic_zyx(rotations):
    # KUKA A, B, C = scipy's intrinsic "ZYX" angles (independent implementation); float64 rounding
    # of atan2 on unit-norm entries stays below 1e-12 rad away from the gimbal lock
    ours = kuka_abc_from_matrix(rotations.as_matrix())
    np.testing.assert_allclose(ours, rotations.as_euler("ZYX"), rtol=0, atol=1e-12)


def test_matrix_is_rz_ry_rx_product(rotations):
    abc = rotations.as_euler("ZYX")
    expected = (rot_z(abc[:, 0]) @ rot_y(abc[:, 1]) @ rot_x(abc[:, 2]))[:, :3, :3]
    np.testing.assert_allclose(matrix_from_kuka_abc(abc), expected, rtol=0, atol=1e-14)


def test_round_trip_matrix_angles_matrix(rotations):
    matrices = rotations.as_matrix()
    np.testing.assert_allclose(matrix_from_kuka_abc(kuka_abc_from_matrix(matrices)), matrices, rtol=0, atol=1e-13)


def test_round_trip_angles_in_principal_range():
    rng = np.random.default_rng(4)
    abc = np.column_stack(
        [rng.uniform(-np.pi, np.pi, 200), rng.uniform(-1.5, 1.5, 200), rng.uniform(-np.pi, np.pi, 200)]
    )
    np.testing.assert_allclose(kuka_abc_from_matrix(matrix_from_kuka_abc(abc)), abc, rtol=0, atol=1e-12)


def test_accepts_homogeneous_transforms_and_batches():
    transform = np.eye(4)
    transform[:3, :3] = matrix_from_kuka_abc([0.3, -0.2, 1.1])
    stacked = np.broadcast_to(transform, (2, 3, 4, 4))
    np.testing.assert_allclose(kuka_abc_from_matrix(stacked), np.broadcast_to([0.3, -0.2, 1.1], (2, 3, 3)), atol=1e-14)


@pytest.mark.parametrize("b", [np.pi / 2, -np.pi / 2])
def test_gimbal_lock_sets_c_to_zero_and_keeps_the_rotation(b):
    matrix = matrix_from_kuka_abc([0.7, b, -0.4])
    abc = kuka_abc_from_matrix(matrix)
    assert abc[2] == 0.0
    assert abs(abc[1] - b) < 1e-7  # B from atan2(-r20, ~1e-17): exact up to the cos(B) rounding
    np.testing.assert_allclose(matrix_from_kuka_abc(abc), matrix, rtol=0, atol=1e-12)


def test_thesis_order_swaps_a_and_c():
    np.testing.assert_array_equal(thesis_order([1.0, 2.0, 3.0]), [3.0, 2.0, 1.0])


def test_wrap_angle_near_reference():
    reference = np.array([np.pi - 0.01, -np.pi + 0.01, 0.0])
    angle = np.array([-np.pi + 0.01, np.pi - 0.01, 2 * np.pi + 0.2])
    np.testing.assert_allclose(wrap_angle_near(angle, reference), [np.pi + 0.01, -np.pi - 0.01, 0.2], atol=1e-12)


def test_bad_shapes_are_input_errors():
    with pytest.raises(InputError, match=r"`rotation` must have shape"):
        kuka_abc_from_matrix(np.eye(2))
    with pytest.raises(InputError, match=r"`abc` must have shape"):
        matrix_from_kuka_abc([1.0, 2.0])
