"""The capture a run keeps in memory is the one read_capture reads from the CSV the run wrote, bit for bit,
including the optional ``target`` and ``u95_mm`` columns."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from robotcal.capture import Capture
from robotcal.io import load_scenario, read_capture
from robotcal.io.capture_csv import capture_to_csv
from robotcal.pipeline.folder import write_csv
from robotcal.pipeline.stages import capture_from_table
from robotcal.workflow import simulate_scenario


def _assert_same(kept: Capture, read: Capture) -> None:
    for field in fields(Capture):
        if field.name in ("source", "seed"):
            continue
        a, b = getattr(kept, field.name), getattr(read, field.name)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_array_equal(a, b, strict=True, err_msg=field.name)
        else:
            assert a == b, field.name


def test_simulated_capture(tmp_path):
    scenario = load_scenario("thesis-laser-tracker")
    simulated = simulate_scenario(scenario, seed=7).capture
    table = write_csv(tmp_path / "capture.csv", capture_to_csv(simulated))
    kept = capture_from_table(table, source="capture.csv", seed=7)
    _assert_same(kept, read_capture(tmp_path / "capture.csv", n_joints=6))
    # the rounding to 12 decimals is real: the simulation's own numbers differ from the file's in the last bits
    assert not np.array_equal(kept.readings, simulated.readings) or not np.array_equal(kept.points, simulated.points)
    np.testing.assert_allclose(kept.points, simulated.points, rtol=0, atol=1e-12)


@pytest.mark.parametrize("with_u95", [False, True])
def test_targets_and_point_uncertainties(tmp_path, with_u95):
    rng = np.random.default_rng(3)
    n = 7
    capture = Capture(
        circle=np.array([1, 1, 1, 2, 2, 2, 0]),
        direction=np.array([1, 1, -1, 1, 1, -1, 1]),
        readings=rng.uniform(-1.0, 1.0, (n, 2)),
        points=rng.uniform(-500.0, 500.0, (n, 3)),
        target=np.array([1, 0, 1, 1, 0, 0, 1]),
        target_names=("flange", "tool"),  # the reader numbers names by first appearance: "tool" first
        u95=rng.uniform(0.01, 0.03, n) if with_u95 else None,
    )
    table = write_csv(tmp_path / "capture.csv", capture_to_csv(capture))
    kept = capture_from_table(table, source="capture.csv", seed=None)
    read = read_capture(tmp_path / "capture.csv", n_joints=2)
    _assert_same(kept, read)
    assert kept.target_names == ("tool", "flange") and kept.point_targets == capture.point_targets
