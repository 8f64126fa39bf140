"""6-DoF measurements (issue 29): a probe whose orientation is measured with its position; the probe's frame on the
flange (position and rotation) identified with the robot, orientation residuals weighted by their uncertainty."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from robotcal.errors import IdentifiabilityWarning, InputError
from robotcal.geometry.transforms import rot_x, rot_y, rot_z
from robotcal.identification.refine import refine_parameters
from robotcal.identification.targets import Target
from robotcal.instruments import Instrument
from robotcal.io.schema.robots import load_robot
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


# -- import: the orientation as exports give it ---------------------------------------------------------------


def test_import_reads_quaternion_abc_and_rpy_alike(tmp_path):
    from scipy.spatial.transform import Rotation

    from robotcal.io.formats.tracker_import import import_tracker_capture

    rotation = Rotation.from_euler("ZYX", [30.0, -15.0, 5.0], degrees=True)
    w = [float(v) for v in rotation.as_quat()[[3, 0, 1, 2]]]
    log = tmp_path / "joints.csv"
    log.write_text("name,q1,q2,q3,q4,q5,q6\nP1,0,10,20,0,30,0\n", encoding="utf-8")
    exports = {
        "quaternion": ("Point;X [mm];Y [mm];Z [mm];qw;qx;qy;qz;u95_deg\n"
                       f"P1;1;2;3;{w[0]!r};{w[1]!r};{w[2]!r};{w[3]!r};0.01\n", None),
        "abc": ("Point;X [mm];Y [mm];Z [mm];A;B;C\nP1;1;2;3;30;-15;5\n", "x=X [mm],y=Y [mm],z=Z [mm],name=Point,a=A,b=B,c=C"),
        "rpy": ("Point;X [mm];Y [mm];Z [mm];R;P;W\nP1;1;2;3;5;-15;30\n",
                "x=X [mm],y=Y [mm],z=Z [mm],name=Point,roll=R,pitch=P,yaw=W"),
    }  # fmt: skip
    for form, (text, columns) in exports.items():
        export = tmp_path / f"{form}.txt"
        export.write_text(text, encoding="utf-8")
        capture = import_tracker_capture(export, log, n_joints=6, columns=columns)
        np.testing.assert_allclose(capture.orientation[0], rotation.as_matrix(), rtol=0, atol=1e-12, err_msg=form)
    assert capture.orientation_u95 is None
    quaternion = import_tracker_capture(tmp_path / "quaternion.txt", log, n_joints=6)
    np.testing.assert_allclose(np.rad2deg(quaternion.orientation_u95), [0.01], rtol=1e-12)
    with pytest.raises(InputError, match="qw, qx, qy, qz"):
        (tmp_path / "bad.txt").write_text("Point;X [mm];Y [mm];Z [mm];qw;qx\nP1;1;2;3;1;0\n", encoding="utf-8")
        import_tracker_capture(tmp_path / "bad.txt", log, n_joints=6)


def test_capture_csv_round_trips_the_orientation(tmp_path):
    from robotcal.io.formats.capture_csv import read_capture, write_capture

    capture = _capture()
    path = write_capture(tmp_path / "six.csv", capture)
    assert path.read_text().splitlines()[0].endswith("x,y,z,target,u95_mm,qw,qx,qy,qz,u95_deg")
    again = read_capture(path, n_joints=6)
    np.testing.assert_allclose(again.orientation, capture.orientation, rtol=0, atol=1e-11)
    np.testing.assert_allclose(again.orientation_u95, capture.orientation_u95, rtol=1e-12)


# -- what the orientation adds to identifiability -------------------------------------------------------------


@pytest.mark.parametrize(("poses", "unknown"), [(8, True), (8, False), (30, True)])
def test_orientation_determines_what_positions_alone_hold(poses, unknown):
    """The same poses with and without the orientations (the table of docs/refinement.md)."""
    from dataclasses import replace

    capture = _capture(poses=poses)
    target = PROBE if unknown else Target(name="probe", frame="flange", positions=PROBE_OFFSET)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        six = refine_parameters(capture, ParameterSet.nominal(ROBOT), target)
        three = refine_parameters(replace(capture, orientation=None, orientation_u95=None), ParameterSet.nominal(ROBOT),
                                  target)  # fmt: skip
    free = six.identifiability.free  # J6 nominal in the truth: the 6-DoF fit recovers every free parameter
    np.testing.assert_allclose(six.parameters.values[free], TRUTH.values[free], rtol=0, atol=1e-8)
    assert three.fit.residual_max < 1e-8  # (its free parameters take up what it holds: confounded, not the truth)
    held_six, held_three = set(six.identifiability.held), set(three.identifiability.held)
    assert held_six <= held_three and held_six == ({"J6.d", "J6.theta", "J6.a", "J6.alpha"} if unknown else {"J6.alpha"})
    if poses == 8:  # J5's theta, a, alpha (and, with a known offset, J6's d, theta, a) held without orientation
        assert held_three - held_six
        assert six.identifiability.condition_number < 0.2 * three.identifiability.condition_number
    assert set(six.identifiability.free_names) >= {"probe.rx", "probe.ry", "probe.rz"}


def test_joining_six_dof_poses_with_positions_only_ones_says_the_orientations_are_dropped():
    from dataclasses import replace

    from robotcal.capture import join_captures
    from robotcal.errors import RobotcalWarning

    six = _capture(poses=5)
    plain = replace(six, orientation=None, orientation_u95=None, source="plain.csv")
    with pytest.warns(RobotcalWarning, match="orientations dropped"):
        joined = join_captures([(six, None), (plain, None)], source="joined")
    assert joined.orientation is None and joined.n_points == 2 * six.n_points
    both = join_captures([(six, None), (six, None)], source="joined")  # every part oriented: kept, no warning
    assert both.orientation is not None and both.orientation.shape[0] == 2 * six.n_points


def test_the_probe_weights_hold_the_stated_repeatability():
    """Issue 29: the orientation rows weigh u_position / u_angle; with a repeatability the position u holds the
    robot's scatter as the position weights do, so orientation rows count relatively more."""
    from robotcal.identification._frames import _orientation_sigmas

    capture = _capture(poses=5)
    _, without = _orientation_sigmas(capture, None)
    _, with_rp = _orientation_sigmas(capture, None, repeatability_mm=0.05)
    assert with_rp > without
    sigma_r = 0.05 / 3.616  # the RP of an isotropic normal scatter is about 3.62 sigma (docs/scenario.md)
    assert with_rp == pytest.approx(np.sqrt(without**2 + sigma_r**2), rel=1e-3)
