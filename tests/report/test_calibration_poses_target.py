"""The demo's calibration poses are measured on a target named for what it is (issue 30: the report listed the
refinement's targets as ``capture`` and ``validation``, the calibration poses on a target named "validation").

A scenario whose ``[calibration_poses]`` share the offset of its ``[validation]`` target measures them on the
same reflector, named ``flange``; a ``[[targets]]`` flange target declared at that offset is still used under
its own name.
"""

from __future__ import annotations

import numpy as np

from robotcal.api import simulate_poses
from robotcal.io import load_scenario


def test_the_demo_calibration_poses_are_on_the_flange_target():
    scenario = load_scenario("kr5-demo")
    assert scenario.calibration_poses is not None and scenario.validation is not None
    # the kr5-demo puts both on the same reflector offset; the names say which capture is which
    np.testing.assert_array_equal(scenario.calibration_poses.flange_reflector_mm, scenario.validation.flange_reflector_mm)
    assert scenario.poses_target == "flange"
    target = scenario.target("flange")
    assert target.frame == "flange" and target.known
    np.testing.assert_array_equal(target.positions.reshape(-1), scenario.calibration_poses.flange_reflector_mm)
    assert scenario.target("validation").frame == "flange"  # the validation capture keeps its own
    poses = simulate_poses(scenario, kind="calibration", rng=3)
    assert set(poses.target_names) == {"flange"}
