"""The captures a run keeps in memory are those of its CSV files, bit for bit (the later stages use them, and a
stand-alone command reading ``capture.csv`` must reproduce the run's numbers)."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from robotcal.api import simulate
from robotcal.capture import Capture
from robotcal.io import load_scenario, read_capture
from robotcal.pipeline.stages import simulate_stage


def _assert_same(kept: Capture, read: Capture) -> None:
    for field in fields(Capture):
        if field.name in ("source", "seed"):
            continue
        a, b = getattr(kept, field.name), getattr(read, field.name)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_array_equal(a, b, strict=True, err_msg=field.name)
        else:
            assert a == b, field.name


def test_the_simulate_stage_keeps_the_captures_as_written(tmp_path):
    scenario = load_scenario("kr5-demo")
    seeds = {"truth": 1, "capture": 7, "validation": 8}
    output = simulate_stage(scenario, seeds, tmp_path)
    for name, kept in (("capture", output.value.capture), ("validation", output.value.validation)):
        _assert_same(kept, read_capture(tmp_path / f"{name}.csv", n_joints=6))
        assert kept.seed == seeds[name] and kept.source == f"{name}.csv"
    # the rounding to 12 decimals is real: the simulation's own numbers differ from the file's in the last bits
    simulated = simulate(scenario, rng=7, true_parameters=output.value.truth)
    kept = output.value.capture
    assert not np.array_equal(kept.readings, simulated.readings) or not np.array_equal(kept.points, simulated.points)
    np.testing.assert_allclose(kept.points, simulated.points, rtol=0, atol=1e-12)
