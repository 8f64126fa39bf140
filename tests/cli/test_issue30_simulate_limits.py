"""Issue 30, item 3: ``simulate --poses`` with a reading outside the joint limits (q2 = 5000 deg) simulated without a
word, where ``predict`` warns for the same pose. Both now give the same :class:`JointLimitWarning`, naming the pose
and the joint; the library's :func:`robotcal.simulate_poses` gives it too."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

import robotcal
from robotcal.cli import app
from robotcal.errors import JointLimitWarning
from robotcal.io import write_parameters
from robotcal.io.formats.trajectory_csv import write_trajectory
from robotcal.kinematics.model import ParameterSet

runner = CliRunner()
POSES_DEG = [[10.0, 60.0, 90.0, 0.0, 30.0, 0.0], [10.0, 5000.0, 90.0, 0.0, 30.0, 0.0]]
SAID = r"pose 2: J2 = 5000 deg outside \[-\d+, -?\d+\] deg"


def _invoke(*args) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("always", JointLimitWarning)  # printed by the CLI as "warning: ..."
        result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return " ".join(result.output.split())


def test_simulate_poses_warns_like_predict(tmp_path):
    poses, nominal = tmp_path / "poses.csv", tmp_path / "nominal.json"
    write_trajectory(poses, np.radians(POSES_DEG))
    scenario = robotcal.load_scenario("kr5-demo")
    write_parameters(nominal, ParameterSet.nominal(scenario.robot))
    predicted = _invoke("predict", nominal, "--scenario", "kr5-demo", "--poses", poses, "--out", tmp_path / "p.csv")
    simulated = _invoke("simulate", "kr5-demo", "--poses", poses, "--seed", 1, "--out", tmp_path / "sim.csv")
    for said in (predicted, simulated):
        assert "warning:" in said and re.search(SAID, said), said
    assert "pose 1" not in simulated  # the pose within the limits is not named
    assert (tmp_path / "sim.csv").exists()  # a warning, as in predict: the capture is still written


def test_the_library_warns_for_given_poses():
    scenario = robotcal.load_scenario("kr5-demo")
    with pytest.warns(JointLimitWarning, match=SAID):
        capture = robotcal.simulate_poses(scenario, POSES_DEG, rng=1)
    assert capture.n_points == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error", JointLimitWarning)
        robotcal.simulate_poses(scenario, POSES_DEG[:1], rng=1)  # within the limits: no warning
        robotcal.simulate_poses(scenario, n_poses=10, rng=1)  # random poses are drawn within the limits
