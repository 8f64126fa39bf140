"""Forward kinematics against the KUKA KR5 matrices written out in the thesis (eqs 3-85..3-90)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import InputError
from robotcal.kinematics import (
    ReflectorMount,
    check_joint_variables,
    forward_kinematics,
    joint_frames,
    link_transforms,
    target_positions,
)

DEG = np.pi / 180.0

#: KUKA KR5, thesis Table 3.1 (J2 Hayati): d, theta offset, a, alpha, beta [mm, rad]
KR5 = np.array(
    [
        [335.0, 0.0, 75.0, 90 * DEG, 0.0],
        [0.0, 0.0, 270.0, 0.0, 0.0],
        [0.0, 90 * DEG, 90.0, 90 * DEG, 0.0],
        [295.0, 0.0, 0.0, 90 * DEG, 0.0],
        [0.0, 180 * DEG, 0.0, 90 * DEG, 0.0],
        [80.0, 0.0, 0.0, 0.0, 0.0],
    ]
)


def _thesis_links(q):
    """The six link matrices of eqs 3-85..3-90 written out by hand (q in rad, model variables)."""
    c1, s1 = np.cos(q[0]), np.sin(q[0])
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    c3, s3 = np.cos(q[2] + np.pi / 2), np.sin(q[2] + np.pi / 2)  # theta3 + 90
    c4, s4 = np.cos(q[3]), np.sin(q[3])
    c5, s5 = np.cos(q[4] + np.pi), np.sin(q[4] + np.pi)  # theta5 + 180
    c6, s6 = np.cos(q[5]), np.sin(q[5])
    a1 = [[c1, 0, s1, 75 * c1], [s1, 0, -c1, 75 * s1], [0, 1, 0, 335], [0, 0, 0, 1]]  # eq. 3-85
    a2 = [[c2, -s2, 0, 270 * c2], [s2, c2, 0, 270 * s2], [0, 0, 1, 0], [0, 0, 0, 1]]  # eq. 3-86
    a3 = [[c3, 0, s3, 90 * c3], [s3, 0, -c3, 90 * s3], [0, 1, 0, 0], [0, 0, 0, 1]]  # eq. 3-87
    a4 = [[c4, 0, s4, 0], [s4, 0, -c4, 0], [0, 1, 0, 295], [0, 0, 0, 1]]  # eq. 3-88
    a5 = [[c5, 0, s5, 0], [s5, 0, -c5, 0], [0, 1, 0, 0], [0, 0, 0, 1]]  # eq. 3-89
    a6 = [[c6, -s6, 0, 0], [s6, c6, 0, 0], [0, 0, 1, 80], [0, 0, 0, 1]]  # eq. 3-90
    return np.array([a1, a2, a3, a4, a5, a6], dtype=float)


def _homogeneous(rotation=np.eye(3), shift=np.zeros(3)):  # noqa: B008 - read-only defaults
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = shift
    return matrix


def _factor_product(d, theta, a, alpha, beta):
    """Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta) from scipy rotations (eqs 3-72 / 3-82)."""
    rz = _homogeneous(Rotation.from_euler("z", theta).as_matrix())
    rx = _homogeneous(Rotation.from_euler("x", alpha).as_matrix())
    ry = _homogeneous(Rotation.from_euler("y", beta).as_matrix())
    return rz @ _homogeneous(shift=[0.0, 0.0, d]) @ _homogeneous(shift=[a, 0.0, 0.0]) @ rx @ ry


@pytest.fixture
def poses():
    return np.random.default_rng(0).uniform(-np.pi, np.pi, (5, 6))


def test_links_match_thesis_matrices(poses):
    links = link_transforms(KR5, poses)
    assert links.shape == (5, 6, 4, 4)
    for links_of_pose, q in zip(links, poses, strict=True):
        # the same trigonometric products: rounding of entries up to 335 mm (~1e-13)
        np.testing.assert_allclose(links_of_pose, _thesis_links(q), rtol=0, atol=1e-12)


def test_forward_kinematics_matches_thesis_product(poses):
    flange = forward_kinematics(KR5, poses)
    assert flange.shape == (5, 4, 4)
    for pose, q in zip(flange, poses, strict=True):
        expected = np.linalg.multi_dot(list(_thesis_links(q)))
        # a chain of six products of ~1 m reach: rounding ~1e-12 mm
        np.testing.assert_allclose(pose, expected, rtol=0, atol=1e-10)


def test_zero_pose_closed_form():
    # at q = 0 the KR5 is stretched along x0: following eqs 3-85..3-90 by hand, a1 (75), a2 (270),
    # d4 (295) and d6 (80) lie along x0, and d1 (335) and a3 (90, turned by the +90 offset) along z0
    flange = forward_kinematics(KR5, np.zeros(6))[0]
    expected = np.linalg.multi_dot(list(_thesis_links(np.zeros(6))))
    np.testing.assert_allclose(flange, expected, rtol=0, atol=1e-10)
    np.testing.assert_allclose(flange[:3, 3], [75.0 + 270.0 + 295.0 + 80.0, 0.0, 335.0 + 90.0], atol=1e-10)


@pytest.mark.parametrize("seed", range(4))
def test_general_link_equals_factor_product(seed):
    rng = np.random.default_rng(seed)
    d, a = rng.uniform(-400.0, 400.0, 2)
    theta, alpha, beta = rng.uniform(-np.pi, np.pi, 3)
    q = rng.uniform(-np.pi, np.pi)
    parameters = np.array([[d, theta, a, alpha, beta]])
    link = link_transforms(parameters, [[q]])[0, 0]
    # the joint variable adds to theta; same rotations built by scipy: rounding only
    np.testing.assert_allclose(link, _factor_product(d, theta + q, a, alpha, beta), rtol=0, atol=1e-12)


def test_hayati_link_with_beta_equals_rz_tx_rx_ry():
    # Hayati joint (d = 0) with a non-zero beta: Rz(theta + q) Tx(a) Rx(alpha) Ry(beta)
    parameters = np.array([[0.0, 0.1, 270.0, 0.02, -0.03]])
    q = np.array([[0.7]])
    link = link_transforms(parameters, q)[0, 0]
    np.testing.assert_allclose(link, _factor_product(0.0, 0.8, 270.0, 0.02, -0.03), rtol=0, atol=1e-12)


def test_batched_parameters_and_poses_equal_loops(poses):
    rng = np.random.default_rng(1)
    sets = KR5 + rng.normal(0.0, 0.01, (3, 6, 5)) * np.array([1.0, 0.01, 1.0, 0.01, 0.0])
    flange = forward_kinematics(sets, poses)
    links = link_transforms(sets, poses)
    frames = joint_frames(sets, poses)
    assert flange.shape == (3, 5, 4, 4)
    assert links.shape == (3, 5, 6, 4, 4)
    assert frames.shape == (3, 5, 7, 4, 4)
    for s in range(3):
        for p in range(5):
            single = forward_kinematics(sets[s], poses[p])[0]
            # one code path for any leading shape: identical up to the order of rounding
            np.testing.assert_allclose(flange[s, p], single, rtol=0, atol=1e-10)
            np.testing.assert_allclose(links[s, p], link_transforms(sets[s], poses[p : p + 1])[0], atol=1e-12)
    np.testing.assert_array_equal(frames[..., 0, :, :], np.broadcast_to(np.eye(4), (3, 5, 4, 4)))  # base frame
    np.testing.assert_allclose(frames[..., -1, :, :], flange, rtol=0, atol=1e-10)  # last frame is the flange


def test_joint_frames_chain_the_thesis_links(poses):
    frames = joint_frames(KR5, poses)
    for p, q in enumerate(poses):
        expected = np.eye(4)
        for i, link in enumerate(_thesis_links(q)):
            expected = expected @ link
            np.testing.assert_allclose(frames[p, i + 1], expected, rtol=0, atol=1e-10)  # rounding of the chain


def test_single_pose_is_a_batch_of_one():
    q = np.linspace(-1.0, 1.0, 6)
    assert forward_kinematics(KR5, q).shape == (1, 4, 4)
    assert check_joint_variables(q, 6).shape == (1, 6)


def test_check_joint_variables_errors():
    with pytest.raises(InputError, match=r"`q` must have shape \(n_poses, 6\); got \(2, 5\)"):
        check_joint_variables(np.zeros((2, 5)), 6)
    with pytest.raises(InputError, match="NaN or infinite"):
        check_joint_variables([0, 0, np.nan, 0, 0, 0], 6)
    with pytest.raises(InputError, match=r"shape \(n_poses, 6\)"):
        forward_kinematics(KR5, np.zeros((3, 7)))


def test_joint_reflector_positions_follow_eq_5_1(poses):
    rng = np.random.default_rng(2)
    reflector = ReflectorMount(frame="joint", positions=rng.uniform(-200.0, 200.0, (6, 3)))
    turning = np.arange(5) % 6
    points = target_positions(KR5, poses, turning, reflector)
    for p, q in enumerate(poses):
        i = turning[p]
        before = np.linalg.multi_dot([np.eye(4), np.eye(4), *_thesis_links(q)[:i]])
        turn = _factor_product(0.0, q[i], 0.0, 0.0, 0.0)  # Rz(q_i) without the theta offset
        expected = (before @ turn @ np.r_[reflector.positions[i], 1.0])[:3]
        # base_p = F_{i-1} Rz(q_i) r_i: rounding of ~1 m chains
        np.testing.assert_allclose(points[p], expected, rtol=0, atol=1e-10)


def test_flange_reflector_and_identity_joint_errors(poses):
    flange_target = np.array([10.0, -20.0, 50.0])
    reflector = ReflectorMount(frame="flange", positions=flange_target)
    points = target_positions(KR5, poses, np.zeros(5, dtype=int), reflector)
    expected = np.array([(np.linalg.multi_dot(list(_thesis_links(q))) @ np.r_[flange_target, 1.0])[:3] for q in poses])
    np.testing.assert_allclose(points, expected, rtol=0, atol=1e-10)  # F_n r, rounding only
    identity = np.broadcast_to(np.eye(4), (5, 6, 4, 4))
    with_errors = target_positions(KR5, poses, np.zeros(5, dtype=int), reflector, joint_errors=identity)
    np.testing.assert_allclose(with_errors, points, rtol=0, atol=1e-12)  # identity error transforms change nothing


def test_joint_reflector_needs_one_position_per_joint():
    reflector = ReflectorMount(frame="joint", positions=np.zeros((5, 3)))
    with pytest.raises(InputError, match="needs 6 positions; got 5"):
        target_positions(KR5, np.zeros((1, 6)), [0], reflector)
