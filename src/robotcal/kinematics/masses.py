"""Masses and centres of mass of a robot's links (the gravity compliance of :mod:`robotcal.kinematics.joint_model`).

Its own module, below :mod:`robotcal.kinematics.model` and :mod:`robotcal.kinematics.joint_model`, so that the
robot model can name the joint model without an import circle; :mod:`robotcal.kinematics.model` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError

__all__ = ["LinkMasses"]


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkMasses:
    """Masses and centres of mass of the links, and a payload on the flange.

    Attributes
    ----------
    mass_kg : ndarray, shape (n_joints,)
        Mass of the link joint i moves (everything rigidly on frame {i} up to joint i+1) [kg].
    com_mm : ndarray, shape (n_joints, 3)
        Its centre of mass in DH frame {i} [mm].
    payload_kg : float
        A point mass on the flange [kg].
    payload_com_mm : ndarray, shape (3,)
        Its position in the flange frame {n} [mm].
    source : str
        Where the numbers come from (a catalogue, a CAD model, an estimate).
    """

    mass_kg: np.ndarray
    com_mm: np.ndarray
    payload_kg: float = 0.0
    payload_com_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    source: str = ""

    def __post_init__(self):
        mass = np.asarray(self.mass_kg, dtype=float)
        com = np.asarray(self.com_mm, dtype=float)
        payload = np.asarray(self.payload_com_mm, dtype=float)
        if mass.ndim != 1 or com.shape != (mass.size, 3) or payload.shape != (3,):
            raise InputError(
                f"link masses: `mass_kg` (n,) and `com_mm` (n, 3) must agree and the payload's `com_mm` be (3,); "
                f"got {mass.shape}, {com.shape}, {payload.shape}"
            )
        if not (np.all(np.isfinite(mass)) and np.all(np.isfinite(com)) and np.all(np.isfinite(payload))):
            raise InputError("link masses: every mass and centre of mass must be finite")
        if np.any(mass < 0) or not (np.isfinite(self.payload_kg) and self.payload_kg >= 0):
            raise InputError("link masses: masses must be >= 0 kg")
        object.__setattr__(self, "mass_kg", _frozen(mass))
        object.__setattr__(self, "com_mm", _frozen(com))
        object.__setattr__(self, "payload_com_mm", _frozen(payload))
        object.__setattr__(self, "payload_kg", float(self.payload_kg))

    @property
    def moments(self) -> np.ndarray:
        """``phi (n_joints, 4)``: per link ``(m, m c_x, m c_y, m c_z)`` [kg, kg mm], the payload in link n."""
        phi = np.column_stack([self.mass_kg, self.mass_kg[:, None] * self.com_mm])
        phi[-1] += self.payload_kg * np.r_[1.0, self.payload_com_mm]
        return phi

    def with_payload(self, mass_kg: float, com_mm) -> LinkMasses:
        return replace(self, payload_kg=float(mass_kg), payload_com_mm=np.asarray(com_mm, dtype=float))
