"""Horn's quaternion registration against exact rigid motions and SciPy's Kabsch solution."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotcal.errors import DegenerateGeometryError, InputError
from robotcal.geometry import register_points
from thesis_data import random_rigid

_rigid = random_rigid


def _apply(matrix, points):
    return points @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize("seed", range(6))
def test_recovers_exact_rigid_transform(seed):
    rng = np.random.default_rng(seed)
    truth = _rigid(rng)
    source = rng.uniform(-1000.0, 1000.0, (10, 3))
    result = register_points(source, _apply(truth, source))
    # exact correspondences: rounding of ~3 m coordinates only (~1e-12 mm); rotation entries are O(1)
    np.testing.assert_allclose(result.transform[:3, :3], truth[:3, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.transform[:3, 3], truth[:3, 3], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(result.transform[3], [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(result.residuals, 0.0, atol=1e-9)
    assert result.residuals.shape == (10,)


@pytest.mark.parametrize("seed", range(4))
def test_agrees_with_scipy_align_vectors_on_noisy_data(seed):
    rng = np.random.default_rng(100 + seed)
    truth = _rigid(rng)
    source = rng.uniform(-800.0, 800.0, (25, 3))
    target = _apply(truth, source) + rng.normal(0.0, 0.5, (25, 3))
    result = register_points(source, target)
    # independent truth: Kabsch/SVD solution of min sum |q_c - R p_c|^2 on the centred sets
    p = source - source.mean(axis=0)
    q = target - target.mean(axis=0)
    rotation, _ = Rotation.align_vectors(q, p)
    expected_rotation = rotation.as_matrix()
    expected_translation = target.mean(axis=0) - expected_rotation @ source.mean(axis=0)
    # both are closed forms of the same well-conditioned problem (distinct eigenvalues): rounding only
    np.testing.assert_allclose(result.transform[:3, :3], expected_rotation, rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.transform[:3, 3], expected_translation, rtol=0, atol=1e-7)
    residuals = np.linalg.norm(_apply(result.transform, source) - target, axis=1)
    np.testing.assert_allclose(result.residuals, residuals, rtol=1e-10, atol=1e-10)  # definition of residuals
    np.testing.assert_allclose(result.rms, np.sqrt(np.mean(residuals**2)), rtol=1e-10)


def test_batched_registration_equals_loop():
    rng = np.random.default_rng(7)
    source = rng.uniform(-500.0, 500.0, (5, 12, 3))
    target = np.stack([_apply(_rigid(rng), s) for s in source]) + rng.normal(0.0, 0.1, (5, 12, 3))
    batch = register_points(source, target)
    assert batch.transform.shape == (5, 4, 4) and batch.residuals.shape == (5, 12) and batch.rms.shape == (5,)
    for k in range(5):
        single = register_points(source[k], target[k])
        # one code path over a leading axis: identical up to batched eigen-solver rounding
        np.testing.assert_allclose(batch.transform[k], single.transform, rtol=0, atol=1e-9)
        np.testing.assert_allclose(batch.rms[k], single.rms, rtol=0, atol=1e-10)


def test_one_source_broadcasts_against_batch_of_targets():
    rng = np.random.default_rng(8)
    source = rng.uniform(-500.0, 500.0, (9, 3))
    targets = np.stack([_apply(_rigid(rng), source) for _ in range(3)]) + rng.normal(0.0, 0.1, (3, 9, 3))
    batch = register_points(source, targets)
    for k in range(3):
        # a Monte Carlo batch of measured sets against one predicted set: same as item by item
        np.testing.assert_allclose(batch.transform[k], register_points(source, targets[k]).transform, atol=1e-9)


def test_collinear_points_are_degenerate():
    source = np.linspace(0.0, 1.0, 6)[:, None] * np.array([100.0, 50.0, -20.0])
    with pytest.raises(DegenerateGeometryError, match="at least 3 non-collinear points"):
        register_points(source, source + 1.0)


def test_mismatched_point_counts():
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="same number of points"):
        register_points(rng.normal(size=(5, 3)), rng.normal(size=(6, 3)))


def test_invalid_points_name_the_argument():
    rng = np.random.default_rng(0)
    bad = rng.normal(size=(5, 3))
    bad[0, 0] = np.nan
    with pytest.raises(InputError, match="`target_points` contains NaN"):
        register_points(rng.normal(size=(5, 3)), bad)
    with pytest.raises(InputError, match=r"`source_points` must have shape \(n_points, 3\)"):
        register_points(np.zeros((2, 3)), np.zeros((2, 3)))
