"""The orientation rows of a 6-DoF capture (issue 29): their analytic Jacobian (robot, probe-rotation and
per-session rotation columns) against central finite differences, with one session and with two; and a noise-free
two-session 6-DoF capture refined from nominal recovers the truth, the probe's rotation and both session frames."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from robotcal.errors import IdentifiabilityWarning
from robotcal.geometry.transforms import rot_x, rot_y, rot_z
from robotcal.identification.refine import _set_up, refine_parameters
from robotcal.identification.settings import RefinementSettings
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema.robots import load_robot
from robotcal.kinematics.model import ParameterSet
from robotcal.simulation.perturb import perturb_parameters
from robotcal.simulation.poses import random_poses
from robotcal.simulation.probe import simulate_probe_poses

ROBOT = load_robot("kuka-kr5-sixx-r650")
TRUTH = perturb_parameters(ROBOT, length_sd_mm=0.2, angle_sd_deg=0.05, rng=np.random.default_rng(7))
STATION_1 = np.array([[0.0, 1.0, 0.0, 1800.0], [-1.0, 0.0, 0.0, 50.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]])
# the tracker moved by about 500 mm and 10 deg between the sessions
STATION_2 = STATION_1 @ rot_z(np.deg2rad(10.0)) @ rot_x(np.deg2rad(2.0))
STATION_2[:3, 3] += [350.0, -330.0, 120.0]
PROBE_OFFSET = np.array([40.0, -25.0, 80.0])
PROBE_ROTATION = (rot_z(np.deg2rad(30.0)) @ rot_y(np.deg2rad(-15.0)) @ rot_x(np.deg2rad(5.0)))[:3, :3]
PROBE = Target(name="probe", frame="flange", positions=np.zeros(3), known=False)
NOISE_FREE = Instrument(name="noise-free", a_mm=0.0, b_mm_per_m=0.0)


def _session(readings, station, name, seed):
    capture, _, _ = simulate_probe_poses(
        ROBOT, readings, PROBE, PROBE_ROTATION, NOISE_FREE, station, true_parameters=TRUTH, true_offset=PROBE_OFFSET,
        u95_mm=0.02, u95_deg=0.01, rng=seed,
    )  # fmt: skip
    return capture if name is None else capture.with_session(name)


def _capture(sessions: int):
    from robotcal.capture import join_captures

    readings = random_poses(ROBOT, 40, rng=np.random.default_rng(11))
    if sessions == 1:
        return _session(readings[:20], STATION_1, None, 3)
    parts = [(_session(readings[:20], STATION_1, "day1", 3), None), (_session(readings[20:], STATION_2, "day2", 4), None)]
    return join_captures(parts, source="two 6-DoF sessions")


def _problem(capture):
    """The problem refine builds (every quantity free), as ``_set_up`` makes it."""
    setup = _set_up(capture, ParameterSet.nominal(ROBOT), PROBE, RefinementSettings(), None, None, NOISE_FREE)
    return setup.probe


def _central_differences(function, x, steps):
    columns = []
    for k, step in enumerate(steps):
        up, down = x.copy(), x.copy()
        up[k] += step
        down[k] -= step
        columns.append((function(up) - function(down)) / (2.0 * step))
    return np.stack(columns, axis=1)


@pytest.mark.parametrize("sessions", [1, 2])
def test_orientation_rows_jacobian_matches_central_differences(sessions):
    problem = _problem(_capture(sessions))
    assert problem.oriented is not None and problem.n_sessions == sessions
    x0 = problem.x0()
    # away from the start (where the probe correction and the session turns are 0): every column is exercised
    x = x0 + 1e-3 * np.random.default_rng(5).standard_normal(x0.size) * np.maximum(np.abs(x0), 1.0)
    residuals, jacobian = problem.evaluate(x)
    n_orientation = 3 * problem.oriented.size
    rows = slice(residuals.size - n_orientation, None)
    # h = 1e-6 scaled by the unknown's size: the central difference's truncation error (h^2 ~ 1e-12 relative)
    # and its rounding error (eps |r| / h ~ 1e-10 relative) both stay well below the 1e-6 tolerance
    steps = 1e-6 * np.maximum(np.abs(x), 1.0)
    numeric = _central_differences(lambda value: problem.residuals(value)[rows], x, steps)
    analytic = jacobian[rows]
    scale = np.max(np.abs(analytic), axis=0, keepdims=True) + 1e-12
    np.testing.assert_allclose(analytic / scale, numeric / scale, rtol=0, atol=1e-6)
    # the probe-rotation columns (last three offsets) and, with two sessions, the second session's rotation
    # columns carry orientation rows: they are compared, not vacuously zero
    n_base = int(problem.base_free.sum())
    probe_columns = slice(x.size - n_base - 3, x.size - n_base)
    assert np.min(np.max(np.abs(analytic[:, probe_columns]), axis=0)) > 1e-3
    if sessions == 2:
        start = problem.n_kinematic + problem.n_extra + 3 * len(problem.unknown) + 3
        assert np.min(np.max(np.abs(analytic[:, start : start + 3]), axis=0)) > 1e-3


def test_noise_free_two_session_six_dof_capture_recovers_the_truth():
    capture = _capture(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        result = refine_parameters(capture, ParameterSet.nominal(ROBOT), PROBE, instrument=NOISE_FREE)
    assert result.success and result.probe is not None
    free = result.identifiability.free
    np.testing.assert_allclose(result.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    np.testing.assert_allclose(result.targets[0].positions, PROBE_OFFSET, rtol=0, atol=1e-8)
    np.testing.assert_allclose(result.probe.rotation, PROBE_ROTATION, rtol=0, atol=1e-8)
    assert result.fit.residual_max < 1e-8
    frames = {frame.name: frame.tracker_from_base for frame in result.sessions}
    assert list(frames) == ["day1", "day2"]
    # d1, theta1 are a gauge of a free base frame: each station's frame where the robot is the truth's
    correction = _gauge_correction(result.parameters, TRUTH)
    np.testing.assert_allclose(frames["day1"] @ correction, STATION_1, rtol=0, atol=1e-8)
    np.testing.assert_allclose(frames["day2"] @ correction, STATION_2, rtol=0, atol=1e-8)


def _gauge_correction(fitted: ParameterSet, truth: ParameterSet) -> np.ndarray:
    """``Rz(theta1) Tz(d1)`` of the fit undone and the truth's applied (the base frame's gauge)."""

    def base(values):
        transform = rot_z(values[0, 1])
        transform[2, 3] = values[0, 0]
        return transform

    return base(fitted.values) @ np.linalg.inv(base(truth.values))
