"""6-DoF measurements (issue 29): a probe whose orientation is measured with its position; the probe's frame on the
flange (position and rotation) identified with the robot, orientation residuals weighted by their uncertainty."""

from __future__ import annotations

import warnings

import numpy as np

from robotcal.errors import IdentifiabilityWarning
from robotcal.geometry.transforms import rot_x, rot_y, rot_z
from robotcal.identification.refine import refine_parameters
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.robots import load_robot
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.probe import simulate_probe_poses

ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(7))
TRACKER = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 50.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
PROBE_OFFSET = np.array([40.0, -25.0, 80.0])
PROBE_ROTATION = (rot_z(np.deg2rad(30.0)) @ rot_y(np.deg2rad(-15.0)) @ rot_x(np.deg2rad(5.0)))[:3, :3]
PROBE = Target(name="probe", frame="flange", positions=np.zeros(3), known=False)
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


def _capture(instrument=NOISE_FREE, poses=30, seed=3, u95_mm=0.02, u95_deg=0.01):
    readings = random_poses(ROBOT, poses, rng=np.random.default_rng(11))
    capture, _, _ = simulate_probe_poses(
        ROBOT, readings, PROBE, PROBE_ROTATION, instrument, TRACKER, true_parameters=TRUTH, true_offset=PROBE_OFFSET,
        u95_mm=u95_mm, u95_deg=u95_deg, rng=seed,
    )  # fmt: skip
    return capture


def _refine(capture, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        return refine_parameters(capture, ParameterSet.nominal(ROBOT), PROBE, **kwargs)


def test_noise_free_six_dof_capture_recovers_the_robot_and_the_probe_frame():
    result = _refine(_capture())
    assert result.success and result.probe is not None
    free = result.identifiability.free
    np.testing.assert_allclose(result.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    np.testing.assert_allclose(result.targets[0].positions, PROBE_OFFSET, rtol=0, atol=1e-8)
    np.testing.assert_allclose(result.probe.rotation, PROBE_ROTATION, rtol=0, atol=1e-10)
    assert result.probe.orientation_rms_deg < 1e-8
    assert result.fit.residual_max < 1e-8
