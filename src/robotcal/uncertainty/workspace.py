"""TCP position uncertainty across the workspace (thesis 5.4: "generalizarse en todo el espacio de trabajo").

A seeded random sample of poses, uniform within the robot's reading limits, goes through
:func:`~robotcal.uncertainty.tcp.propagate_to_tcp`; per pose the position's standard uncertainty
``sqrt(trace V)`` and the largest semi-axis of its coverage ellipsoid say how far the calibrated
robot can be trusted there, and percentiles over the sample summarise the whole workspace.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal.errors import InputError
from robotcal.execution import single_blas_thread
from robotcal.kinematics.model import RobotModel
from robotcal.uncertainty.tcp import TCPUncertainty, propagate_to_tcp

__all__ = ["PERCENTILES", "WorkspaceUncertainty", "sample_workspace", "workspace_uncertainty"]

#: Percentiles reported over the sampled poses.
PERCENTILES = (0.0, 5.0, 25.0, 50.0, 75.0, 95.0, 100.0)


def sample_workspace(robot: RobotModel, n_poses: int, *, rng=None) -> np.ndarray:
    """Controller readings ``(n_poses, n_joints)`` [rad], uniform within the robot's reading limits.

    Raises
    ------
    InputError
        ``n_poses`` not a positive integer, or a joint without finite limits.
    """
    rng = np.random.default_rng(rng)
    if isinstance(n_poses, bool) or int(n_poses) != n_poses or n_poses < 1:
        raise InputError(f"`n_poses` must be a positive integer; got {n_poses!r}")
    limits = robot.limits
    unbounded = np.flatnonzero(~np.all(np.isfinite(limits), axis=1))
    if unbounded.size:
        names = ", ".join(f"J{j + 1}" for j in unbounded)
        raise InputError(f"robot {robot.name!r}: {names} without finite `limits_deg`; cannot sample the workspace")
    return rng.uniform(limits[:, 0], limits[:, 1], size=(int(n_poses), robot.n_joints))


@dataclass(frozen=True, slots=True, kw_only=True)
class WorkspaceUncertainty:
    """TCP uncertainty over a sample of poses.

    Attributes
    ----------
    tcp : TCPUncertainty
        The full per-pose result (readings, nominal TCP, statistics, ellipsoids).
    seed : int or None
        Seed of the pose sample (None when the caller passed readings or a generator).
    percentiles : tuple of float
    position_uncertainty_percentiles : ndarray, shape (n_percentiles,)
        Of ``sqrt(trace V)`` over the poses [mm].
    max_semi_axis_percentiles : ndarray, shape (n_percentiles,)
        Of the largest 95 % ellipsoid semi-axis over the poses [mm].
    std_uncertainty_percentiles : ndarray, shape (n_percentiles, 6)
        Of each coordinate's standard uncertainty over the poses [mm, rad].
    """

    tcp: TCPUncertainty
    seed: int | None
    percentiles: tuple[float, ...]
    position_uncertainty_percentiles: np.ndarray
    max_semi_axis_percentiles: np.ndarray
    std_uncertainty_percentiles: np.ndarray

    @property
    def position_uncertainty(self) -> np.ndarray:
        """``sqrt(trace V)`` per pose ``(n_poses,)`` [mm]."""
        return self.tcp.position_uncertainty

    @property
    def max_semi_axis(self) -> np.ndarray:
        """Largest semi-axis of each pose's coverage ellipsoid ``(n_poses,)`` [mm]."""
        return self.tcp.ellipsoid.semi_axes[:, 0]


def workspace_uncertainty(
    robot: RobotModel,
    parameter_draws,
    n_poses: int | None = None,
    *,
    readings=None,
    rng=None,
    tool=None,
    coverage: float = 0.95,
    batch_size: int | None = None,
    max_bytes: int = 64 * 2**20,
    joint_model=None,
    extra_draws=None,
) -> WorkspaceUncertainty:
    """TCP uncertainty at ``n_poses`` random poses within the limits (or at given ``readings``).

    Parameters
    ----------
    robot : RobotModel
    parameter_draws : array_like, shape (n_draws, n_joints, 5)
        Monte Carlo parameter draws [mm, rad].
    n_poses : int, optional
        Size of the random sample (uniform within ``robot.limits``, drawn from ``rng``).
    readings : array_like, shape (n_poses, n_joints), optional
        Use these controller readings [rad] instead of a random sample.
    rng : numpy.random.Generator or int or None
        Seed or generator of the pose sample.
    tool, coverage, batch_size, max_bytes, joint_model, extra_draws
        As in :func:`~robotcal.uncertainty.tcp.propagate_to_tcp`.
    """
    with single_blas_thread():
        seed = int(rng) if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) else None
        if (readings is None) == (n_poses is None):
            raise InputError("give either `n_poses` (a random sample) or `readings`, not both or neither")
        if n_poses is not None:  # then readings is None (checked above)
            readings = sample_workspace(robot, n_poses, rng=rng)
        result = propagate_to_tcp(
            robot, parameter_draws, readings, tool=tool, coverage=coverage, batch_size=batch_size, max_bytes=max_bytes,
            joint_model=joint_model, extra_draws=extra_draws,
        )  # fmt: skip
        levels = PERCENTILES
        return WorkspaceUncertainty(
            tcp=result,
            seed=seed,
            percentiles=levels,
            position_uncertainty_percentiles=np.percentile(result.position_uncertainty, levels),
            max_semi_axis_percentiles=np.percentile(result.ellipsoid.semi_axes[:, 0], levels),
            std_uncertainty_percentiles=np.percentile(result.std_uncertainty, levels, axis=0),
        )
