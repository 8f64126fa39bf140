"""A simulated 6-DoF probe capture (issue 29): a probe on the flange measured at free poses, its position and its
orientation, each with the instrument's noise."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from robotcal.capture import Capture
from robotcal.errors import InputError
from robotcal.geometry.rotations import rotation_matrices
from robotcal.instruments import Instrument
from robotcal.kinematics.forward import probe_rotations
from robotcal.kinematics.model import ParameterSet, RobotModel
from robotcal.simulation.generator import simulate_target_poses

__all__ = ["simulate_probe_poses"]


def simulate_probe_poses(
    robot: RobotModel,
    readings: ArrayLike,
    target,
    probe_rotation: ArrayLike,
    instrument: Instrument,
    tracker_from_base: ArrayLike,
    *,
    true_parameters: ParameterSet | None = None,
    true_offset: ArrayLike | None = None,
    u95_mm: float | None = None,
    u95_deg: float | None = None,
    rng: np.random.Generator | int | None = None,
) -> tuple[Capture, np.ndarray, np.ndarray]:
    """A 6-DoF probe measured at every pose: its position ``T F_n r`` (:func:`simulate_target_poses`) and its
    orientation ``R_T F_n R_P``, the latter turned by the instrument's orientation noise
    (:meth:`Instrument.sample_orientation_noise`, drawn after the position noise).

    Parameters
    ----------
    target : robotcal.identification.targets.Target
        The probe's flange target (its name goes to the ``target`` column).
    probe_rotation : array_like, shape (3, 3)
        The probe frame's rotation in the flange frame {n}.
    u95_mm, u95_deg : float, optional
        Written to the ``u95_mm`` and ``u95_deg`` columns of every point (the instrument's stated U(95)).

    Returns
    -------
    capture : Capture
    exact_points : ndarray, shape (n_poses, 3)
    exact_rotations : ndarray, shape (n_poses, 3, 3)
    """
    rng = np.random.default_rng(rng)
    probe_rotation = np.asarray(probe_rotation, dtype=float)
    if probe_rotation.shape != (3, 3):
        raise InputError(f"`probe_rotation` must be a 3x3 rotation; got shape {probe_rotation.shape}")
    offsets = None if true_offset is None else np.reshape(true_offset, (1, 3))
    capture, exact = simulate_target_poses(
        robot, readings, (target,), instrument, tracker_from_base, true_parameters=true_parameters,
        true_offsets=offsets, u95_mm=u95_mm, rng=rng,
    )  # fmt: skip
    parameters = ParameterSet.nominal(robot) if true_parameters is None else true_parameters
    q = parameters.model_joint_variables(capture.readings)
    rotations = probe_rotations(parameters.values, q, probe_rotation, tracker_from_base)
    turns = rotation_matrices(instrument.sample_orientation_noise(capture.n_points, rng=rng))
    measured = rotations @ turns
    u95 = None if u95_deg is None else np.full(capture.n_points, np.deg2rad(u95_deg))
    measured_capture = Capture(
        circle=capture.circle, direction=capture.direction, readings=capture.readings, points=capture.points,
        source="simulated 6-DoF capture", target=capture.target, target_names=capture.target_names, u95=capture.u95,
        orientation=measured, orientation_u95=u95,
    )  # fmt: skip
    return measured_capture, exact, rotations
