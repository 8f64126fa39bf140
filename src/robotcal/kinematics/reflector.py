"""Where the measured target sits on the robot (thesis eq. 5-1).

Its own module, below :mod:`robotcal.kinematics.forward` and :mod:`robotcal.kinematics.model`, so that forward
kinematics needs nothing of the robot model; :mod:`robotcal.kinematics.model` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError

__all__ = ["ReflectorMount"]


@dataclass(frozen=True, slots=True, kw_only=True)
class ReflectorMount:
    """Where the measured target sits on the robot.

    ``frame="joint"``: one position per circle, circle i's target given in DH frame {i-1} turned by
    joint i's variable (without the theta_i offset): ``base_p = F_{i-1} Rz(q_i) r_i`` (eq. 5-1, the
    thesis generator's way). ``positions`` has shape ``(n_joints, 3)``.

    ``frame="flange"``: one target on the flange (DH frame {n}) for every circle, the thesis's
    active target on the end effector: ``base_p = F_n r``. ``positions`` has shape ``(1, 3)``.
    """

    frame: str
    positions: np.ndarray

    def __post_init__(self):
        if self.frame not in ("joint", "flange"):
            raise InputError(f"reflector frame must be 'joint' or 'flange'; got {self.frame!r}")
        positions = np.asarray(self.positions, dtype=float)
        if positions.ndim == 1:
            positions = positions[None, :]
        if positions.ndim != 2 or positions.shape[1] != 3 or not np.all(np.isfinite(positions)):
            raise InputError(f"reflector positions must be finite (n, 3) [mm]; got shape {positions.shape}")
        if self.frame == "flange" and positions.shape[0] != 1:
            raise InputError(f"a flange reflector is one position (3,); got {positions.shape[0]}")
        object.__setattr__(self, "positions", _frozen(positions))
