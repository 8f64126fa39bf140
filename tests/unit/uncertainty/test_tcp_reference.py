"""The vectorised TCP propagation against a plain composition of the reference routines.

``propagate_to_tcp`` restructures the kinematics (column slabs, the first joint applied
analytically, ``arctan`` instead of ``atan2``) and the statistics (one sort per chunk, draws laid
out last). The truth here is the straightforward route it replaced: ``forward_kinematics`` (4x4
frames, eq. 3-84) -> ``kuka_abc_from_matrix`` -> ``wrap_angle_near`` the nominal -> the GUM-S1
summary of :func:`summarize_draws`, ``np.cov`` and :func:`coverage_ellipsoid`.

Tolerances: every quantity is the same arithmetic up to summation order and ulp-level differences
of ``arctan(y/x)`` vs ``atan2``; on coordinates of ~10^3 mm and 10^3 draws that is < 1e-12 mm or
rad, and interval ends are order statistics (the same draw, so the same 1e-12). ``1e-10`` absolute
(mm, rad) is the contract and leaves two decades of margin; covariances are compared with a
relative 1e-9 (sums of products of centred values ~1e-2 mm).
"""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.geometry.euler import kuka_abc_from_matrix, matrix_from_kuka_abc, wrap_angle_near
from robotcal.io import load_robot
from robotcal.kinematics.forward import forward_kinematics
from robotcal.uncertainty.statistics import summarize_draws
from robotcal.uncertainty.tcp import coverage_ellipsoid, position_covariance, propagate_to_tcp
from robotcal.uncertainty.workspace import workspace_uncertainty

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")
ATOL = 1e-10  # mm and rad
FIELDS = ("mean", "std_uncertainty", "symmetric_low", "symmetric_high", "shortest_low", "shortest_high")


def _draws(n_draws, seed=0):
    rng = np.random.default_rng(seed)
    free = ~ROBOT.structurally_fixed
    scale = np.where(np.isin(np.arange(5), [1, 3, 4]), 2e-4, 0.05)
    return ROBOT.nominal + rng.standard_normal((n_draws, 6, 5)) * scale * free


def _readings(n_poses, seed=3):
    rng = np.random.default_rng(seed)
    readings = rng.uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], size=(n_poses, 6)) * 0.9
    readings[0] = np.deg2rad([41.0, -60.0, 100.0, 30.0, 40.0, 20.0])  # nominal A = -179.95 deg
    return readings


def _reference_coordinates(draws, readings, tool):
    """``(n_draws, n_poses, 6)`` by 4x4 frames, the definition the fast path must reproduce."""
    q = ROBOT.model_joint_variables(readings)
    frames = forward_kinematics(draws, q)  # (M, P, 4, 4)
    position = frames[..., :3, :3] @ tool + frames[..., :3, 3]
    nominal_frames = forward_kinematics(ROBOT.nominal, q)
    nominal_abc = kuka_abc_from_matrix(nominal_frames)
    abc = wrap_angle_near(kuka_abc_from_matrix(frames), nominal_abc)
    return np.concatenate([position, abc], axis=-1)


@pytest.mark.parametrize(
    ("coverage", "tool", "max_bytes", "batch_size"),
    [
        (0.95, None, 64 * 2**20, None),  # one chunk, default batches
        (0.9, [10.0, -5.0, 80.0], 48 * 400 * 3, 70),  # 3 poses per chunk, ragged batches of draws
        (0.3, [0.0, 0.0, 5.0], 48 * 400 * 4, 1000),  # q < M - q: intervals from the middle of the draws
    ],
)
def test_propagation_equals_the_plain_composition(coverage, tool, max_bytes, batch_size):
    draws, readings = _draws(400), _readings(8)
    tool_mm = np.zeros(3) if tool is None else np.asarray(tool)
    result = propagate_to_tcp(
        ROBOT, draws, readings, tool=tool, coverage=coverage, max_bytes=max_bytes, batch_size=batch_size
    )
    coords = _reference_coordinates(draws, readings, tool_mm)
    expected = summarize_draws(coords, coverage)
    for name in (*FIELDS, "minimum", "maximum"):
        np.testing.assert_allclose(getattr(result.summary, name), getattr(expected, name), rtol=0, atol=ATOL)
    covariance = np.stack([np.cov(coords[:, p], rowvar=False) for p in range(coords.shape[1])])
    np.testing.assert_allclose(result.covariance, covariance, rtol=1e-9, atol=1e-18)
    ellipsoid = coverage_ellipsoid(coords[..., :3], coverage)
    np.testing.assert_allclose(result.ellipsoid.semi_axes, ellipsoid.semi_axes, rtol=1e-9)
    np.testing.assert_array_equal(result.ellipsoid.fraction_inside, ellipsoid.fraction_inside)
    np.testing.assert_allclose(result.ellipsoid.monte_carlo_scale, ellipsoid.monte_carlo_scale, rtol=1e-9)
    # at A = -179.95 deg some draws pass +180 deg: wrapped near the nominal, they are not split by 2 pi
    assert np.rad2deg(result.summary.maximum[0, 3]) > -179.9 and np.rad2deg(result.summary.minimum[0, 3]) < -180.0
    assert abs(result.summary.mean[0, 3] - result.nominal[0, 3]) < 1e-3


def test_kept_draws_equal_the_plain_composition():
    draws, readings = _draws(300, seed=4), _readings(2, seed=5)
    result = propagate_to_tcp(ROBOT, draws, readings, keep_draws=True, batch_size=64)
    np.testing.assert_allclose(result.draws, _reference_coordinates(draws, readings, np.zeros(3)), rtol=0, atol=ATOL)


def test_gimbal_lock_draws_take_the_exact_branch():
    """At B = -90 deg the fast arctan formulas are undefined; those draws use kuka_abc_from_matrix."""
    nominal = ROBOT.nominal.copy()
    draws = np.repeat(nominal[None], 50, axis=0)  # identical draws: every one exactly at the lock
    q = np.zeros((1, 6))
    frame = forward_kinematics(nominal, q)[0]
    if abs(abs(frame[2, 0]) - 1.0) > 1e-12:
        # find a wrist angle that puts the flange's x axis along the base Z axis (B = -+90 deg)
        candidates = np.deg2rad(np.arange(-180.0, 180.0, 0.5))
        grid = np.zeros((candidates.size, 6))
        grid[:, 4] = candidates
        r20 = forward_kinematics(nominal, grid)[:, 2, 0]
        best = int(np.argmax(np.abs(r20)))
        if abs(abs(r20[best]) - 1.0) > 1e-9:
            pytest.skip("no exact gimbal-lock pose on the 0.5 deg grid for this robot")
        q = grid[best : best + 1]
    readings = (q - ROBOT.reading_offset) / ROBOT.reading_sign
    result = propagate_to_tcp(ROBOT, draws, readings)
    np.testing.assert_allclose(result.summary.mean[0, 3:], result.nominal[0, 3:], rtol=0, atol=ATOL)


def test_workspace_equals_the_plain_composition():
    draws = _draws(200, seed=6)
    ws = workspace_uncertainty(ROBOT, draws, 40, rng=9, max_bytes=48 * 200 * 7)
    coords = _reference_coordinates(draws, ws.tcp.readings, np.zeros(3))
    expected = summarize_draws(coords, 0.95)
    np.testing.assert_allclose(ws.tcp.summary.shortest_low, expected.shortest_low, rtol=0, atol=ATOL)
    np.testing.assert_allclose(ws.tcp.std_uncertainty, expected.std_uncertainty, rtol=0, atol=ATOL)
    u = np.sqrt(np.einsum("mpi,mpi->p", *(2 * [coords[..., :3] - coords[..., :3].mean(axis=0)])) / 199)
    np.testing.assert_allclose(ws.position_uncertainty, u, rtol=1e-9)


def test_abc_fast_path_keeps_the_quadrant_of_a_negative_zero():
    # atan2(1, -0.0) = +90 deg: arctan(y / x) + pi * (x < 0) gave -90 deg for x = -0.0 (review finding)
    from robotcal.geometry.euler import kuka_abc_from_matrix
    from robotcal.uncertainty.tcp_kinematics import _abc_near

    rotation = np.array([[-0.0, -1.0, 0.0], [1.0, -0.0, 0.0], [0.0, 0.0, 1.0]])  # Rz(90 deg), r00 = -0.0
    block = np.zeros((1, 4, 3, 1))
    block[0, :3, :, 0] = rotation.T  # column k of R in block[:, k]
    fast = _abc_near(block, np.zeros(1), np.zeros((1, 3)))[:, 0, 0]
    np.testing.assert_allclose(fast, kuka_abc_from_matrix(rotation), atol=1e-15)


@pytest.mark.parametrize(
    ("spread", "offset_deg"),
    [(1e-3, 0.0), (0.05, 0.0), (1e-3, 120.0), (1e-3, 179.0)],
    ids=["near", "wider", "120deg", "179deg"],
)
def test_abc_near_equals_the_matrix_formula(spread, offset_deg):
    """``_abc_near`` against ``kuka_abc_from_matrix`` + ``wrap_angle_near`` for rotations near the reference,
    farther from it, and more than 90 deg away, where the turned vector points backwards; the first joint added
    to A."""
    from robotcal.uncertainty.tcp_kinematics import _abc_near

    rng = np.random.default_rng(12)
    m, n_poses = 50, 7
    reference = rng.uniform([-np.pi, -1.2, -np.pi], [np.pi, 1.2, np.pi], size=(n_poses, 3))
    first_joint = rng.uniform(-np.pi, np.pi, n_poses)
    angles = reference[None] + rng.normal(0.0, spread, size=(m, n_poses, 3))
    angles[..., 0] += np.deg2rad(offset_deg)
    angles[..., 2] -= np.deg2rad(offset_deg)
    angles[..., 1] = np.clip(angles[..., 1], -1.5, 1.5)
    a_local = angles[..., 0] - first_joint  # the block holds the rotation before Rz(q_1)
    rotation = matrix_from_kuka_abc(np.stack([a_local, angles[..., 1], angles[..., 2]], axis=-1))  # (m, P, 3, 3)
    block = np.zeros((m, 4, 3, n_poses))
    block[:, :3] = np.moveaxis(rotation, (2, 3), (2, 1))  # block[s, k, r, p] = R[s, p, r, k]
    fast = np.moveaxis(_abc_near(block, first_joint, reference), 0, -1)
    exact = kuka_abc_from_matrix(rotation)
    exact[..., 0] += first_joint
    expected = exact.copy()
    expected[..., ::2] = wrap_angle_near(exact[..., ::2], reference[None, :, ::2])
    np.testing.assert_allclose(fast, expected, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast, angles, rtol=0, atol=1e-12)  # and the angles the rotations were made of


@pytest.mark.parametrize(
    ("tool", "max_bytes", "batch_size"), [(None, 64 * 2**20, None), ([10.0, -5.0, 80.0], 24 * 300 * 3, 70)]
)
def test_position_covariance_equals_the_plain_composition(tool, max_bytes, batch_size):
    """The position-only chain (evaluated from the tool end) against 4x4 frames and ``np.cov``."""
    draws, readings = _draws(300, seed=7), _readings(8, seed=8)
    tool_mm = np.zeros(3) if tool is None else np.asarray(tool)
    covariance = position_covariance(ROBOT, draws, readings, tool=tool, max_bytes=max_bytes, batch_size=batch_size)
    coords = _reference_coordinates(draws, readings, tool_mm)
    expected = np.stack([np.cov(coords[:, p, :3], rowvar=False) for p in range(coords.shape[1])])
    np.testing.assert_allclose(covariance, expected, rtol=1e-9, atol=1e-18)
    full = propagate_to_tcp(ROBOT, draws, readings, tool=tool).covariance[:, :3, :3]
    np.testing.assert_allclose(covariance, full, rtol=1e-9, atol=1e-18)


def test_position_covariance_refuses_a_single_draw():
    from robotcal.errors import InputError

    with pytest.raises(InputError, match="at least 2 draws"):
        position_covariance(ROBOT, _draws(1), _readings(2))


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("function", ["propagate_to_tcp", "position_covariance"])
def test_overflowing_draw_is_refused(function):
    """A finite but absurd draw (link offsets of 1e308 mm) overflows the kinematics: InputError, from
    whichever thread and chunk met it, not NaN statistics."""
    from robotcal.errors import InputError
    from robotcal.uncertainty import tcp

    draws = _draws(300, seed=9)
    draws[123, :, 0] = 1e308  # every d: their sum along the base z axis overflows
    with pytest.raises(InputError, match="not finite numbers"):
        getattr(tcp, function)(ROBOT, draws, _readings(8), max_bytes=48 * 300 * 4)


@pytest.mark.parametrize("batch_size", [None, 37])
def test_pose_chunks_shared_by_the_threads_equal_the_plain_composition(batch_size):
    """40 poses, 150 draws, room for 13 poses: four chunks of 10 poses through the same reused buffers, each
    chunk's statistics split between the threads (5 poses each), and with ``batch_size=37`` its ragged
    batches of draws filled in the threads."""
    draws, readings = _draws(150, seed=10), _readings(40, seed=11)
    result = propagate_to_tcp(
        ROBOT, draws, readings, tool=[1.0, 2.0, 30.0], batch_size=batch_size, max_bytes=48 * 150 * 13
    )
    coords = _reference_coordinates(draws, readings, np.array([1.0, 2.0, 30.0]))
    expected = summarize_draws(coords, 0.95)
    for name in (*FIELDS, "minimum", "maximum"):
        np.testing.assert_allclose(getattr(result.summary, name), getattr(expected, name), rtol=0, atol=ATOL)
    covariance = np.stack([np.cov(coords[:, p], rowvar=False) for p in range(coords.shape[1])])
    np.testing.assert_allclose(result.covariance, covariance, rtol=1e-9, atol=1e-18)
    ellipsoid = coverage_ellipsoid(coords[..., :3], 0.95)
    np.testing.assert_array_equal(result.ellipsoid.fraction_inside, ellipsoid.fraction_inside)
    np.testing.assert_allclose(result.ellipsoid.monte_carlo_scale, ellipsoid.monte_carlo_scale, rtol=1e-9)
