"""The in-memory capture that identification consumes: validation and immutability."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.errors import InputError


def _arrays(n=4, n_joints=6):
    rng = np.random.default_rng(0)
    return {
        "circle": np.array([1, 1, 2, 2])[:n],
        "direction": np.array([1, -1, 1, 1])[:n],
        "readings": rng.uniform(-1.0, 1.0, (n, n_joints)),
        "points": rng.uniform(-1000.0, 1000.0, (n, 3)),
    }


def test_capture_coerces_and_freezes():
    arrays = _arrays()
    capture = Capture(**arrays, source="a.csv", seed=0)
    assert capture.n_points == 4 and capture.n_joints == 6
    assert capture.circle.dtype.kind == "i" and capture.points.dtype == float
    np.testing.assert_array_equal(capture.points, arrays["points"])  # values kept exactly
    with pytest.raises(ValueError, match="read-only"):
        capture.points[0, 0] = 1.0
    arrays["points"][0, 0] = 123.0
    assert capture.points[0, 0] != 123.0  # the capture holds its own copy


def test_with_points_keeps_everything_else():
    capture = Capture(**_arrays(), source="a.csv", seed=7)
    moved = capture.with_points(capture.points + 1.0)
    np.testing.assert_array_equal(moved.points, capture.points + 1.0)
    np.testing.assert_array_equal(moved.readings, capture.readings)
    np.testing.assert_array_equal(moved.circle, capture.circle)
    np.testing.assert_array_equal(moved.direction, capture.direction)
    assert moved.source == "a.csv" and moved.seed == 7


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"points": np.zeros((4, 2))}, r"a.csv: inconsistent capture shapes: .*points \(4, 2\)"),
        ({"readings": np.zeros((3, 6))}, r"inconsistent capture shapes: .*readings \(3, 6\)"),
        ({"direction": np.ones(3)}, r"inconsistent capture shapes: circle \(4,\), direction \(3,\)"),
        ({"circle": np.array([1, 1, 2, 7])}, r"`circle` values must be joint numbers 1..6"),
        ({"circle": np.array([-1, 1, 2, 2])}, r"`circle` values must be joint numbers 1..6"),
        ({"circle": np.array([1.0, 1.5, 2.0, 2.0])}, r"`circle` values must be joint numbers"),
        ({"direction": np.array([1, 0, 1, 1])}, r"`direction` values must be \+1 or -1"),
    ],
)
def test_capture_validation(changes, message):
    with pytest.raises(InputError, match=message):
        Capture(**(_arrays() | changes), source="a.csv")


def test_nan_point_and_reading_are_located():
    arrays = _arrays()
    arrays["points"][2, 1] = np.nan
    with pytest.raises(InputError, match="a.csv: point 3 has NaN or infinite points"):
        Capture(**arrays, source="a.csv")
    arrays = _arrays()
    arrays["readings"][1, 4] = np.inf
    with pytest.raises(InputError, match="a.csv: point 2 has NaN or infinite readings"):
        Capture(**arrays, source="a.csv")
