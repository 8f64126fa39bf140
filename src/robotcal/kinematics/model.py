"""Robot model (hybrid Denavit-Hartenberg / Hayati-Mirmirani) and parameter sets (thesis ch. 3.4-3.5).

Per joint i the parameters are ``d, theta, a, alpha, beta`` (columns of a ``(n_joints, 5)`` array,
in this order). A DH joint is ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)`` (eq. 3-72) with beta = 0 fixed;
a Hayati joint is ``Rz(theta + q) Tx(a) Rx(alpha) Ry(beta)`` (eq. 3-82 as a factor product) with
d = 0 fixed. The model's structure (which parameters exist and which are fixed) never depends on
the values. Lengths in mm, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError
from robotcal.kinematics.masses import LinkMasses
from robotcal.kinematics.reflector import ReflectorMount

if TYPE_CHECKING:
    from robotcal.kinematics.joint_model import JointModel

__all__ = [
    "PARAMETER_KINDS",
    "LENGTH_KINDS",
    "ANGLE_KINDS",
    "LENGTH_COLUMNS",
    "ANGLE_COLUMNS",
    "KIND_UNITS",
    "DISPLAY_UNITS",
    "LinkMasses",
    "RobotModel",
    "ParameterSet",
    "ReflectorMount",
    "check_parameter_array",
]

#: Column order of parameter arrays ``(..., n_joints, 5)``.
PARAMETER_KINDS = ("d", "theta", "a", "alpha", "beta")
#: Kinds measured in mm (the others are angles).
LENGTH_KINDS = ("d", "a")
#: Kinds that are angles: radians in the core, degrees in every file and table.
ANGLE_KINDS = ("theta", "alpha", "beta")
#: Columns of the length / angle kinds in parameter arrays, e.g. ``values[..., ANGLE_COLUMNS]``.
LENGTH_COLUMNS = tuple(PARAMETER_KINDS.index(kind) for kind in LENGTH_KINDS)
ANGLE_COLUMNS = tuple(PARAMETER_KINDS.index(kind) for kind in ANGLE_KINDS)
#: The units outside the core (every file, table and report; the ``units`` key of robotcal's documents).
DISPLAY_UNITS = MappingProxyType({"length": "mm", "angle": "deg"})
#: The unit each kind is shown in outside the core: ``"mm"`` or ``"deg"``.
KIND_UNITS = MappingProxyType(
    {kind: DISPLAY_UNITS["length" if kind in LENGTH_KINDS else "angle"] for kind in PARAMETER_KINDS}
)
_D, _BETA = PARAMETER_KINDS.index("d"), PARAMETER_KINDS.index("beta")


def check_parameter_array(values: ArrayLike, n_joints: int, name: str = "parameters") -> np.ndarray:
    """Coerce ``values`` to float ``(..., n_joints, 5)``, finite, or raise :class:`InputError`."""
    try:
        values = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"`{name}` must be numeric") from exc
    if values.ndim < 2 or values.shape[-2:] != (n_joints, 5):
        raise InputError(
            f"`{name}` must have shape (..., {n_joints}, 5) (d, theta, a, alpha, beta); got {values.shape}"
        )
    if not np.all(np.isfinite(values)):
        raise InputError(f"`{name}` contains NaN or infinite values")
    return values


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotModel:
    """A serial revolute robot: nominal parameters, joint types and the controller reading map.

    Attributes
    ----------
    name : str
    nominal : ndarray, shape (n_joints, 5)
        Nominal ``d, theta, a, alpha, beta`` [mm, rad]; theta is the offset added to the joint
        variable (Table 3.1).
    hayati : ndarray of bool, shape (n_joints,)
        True where the joint uses the Hayati-Mirmirani form (d fixed at 0, beta free).
    reading_sign, reading_offset : ndarray, shape (n_joints,)
        Map from controller readings to model joint variables:
        ``q_model = reading_sign * reading + reading_offset`` [rad]. Identity by default.
    reading_coupling : ndarray, shape (n_joints, n_joints)
        Off-diagonal coupling of the readings (zero diagonal; all zero by default, the uncoupled
        case above). With ``M = diag(reading_sign) + reading_coupling`` the readings are
        ``reading = M (q_model - reading_offset)``: the reading of joint k is a sum of coefficients
        times model variables, e.g. a Fanuc-style J3 reading that is the forearm's angle to the
        horizontal, ``reading_3 = -(q_3 - o_3) - (q_2 - o_2)`` (coupling[2, 1] = -1). ``M`` must be
        invertible; :meth:`model_joint_variables` and :meth:`readings_from_model` are the one place
        where readings and model variables are converted.
    limits : ndarray, shape (n_joints, 2)
        Software limits of the controller readings [rad] (lower, upper).
    description : str
    masses : LinkMasses or None
        Catalogue-level masses and centres of mass of the links, for the gravity compliance of the extended
        model (:mod:`robotcal.kinematics.joint_model`); None when unknown.
    flange_frame : ndarray, shape (4, 4), or None
        The controller's flange frame (the frame its tools are given in) in the model's last DH frame [mm]; None:
        the same frame. KUKA's flange has X along the flange normal where the DH frame has z (robot files
        ``flange_frame``, docs/deploy.md).
    """

    name: str
    nominal: np.ndarray
    hayati: np.ndarray
    reading_sign: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    reading_offset: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    limits: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    description: str = ""
    reading_coupling: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    masses: LinkMasses | None = None
    flange_frame: np.ndarray | None = None
    _model_from_reading: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        nominal = np.asarray(self.nominal, dtype=float)
        if nominal.ndim != 2 or nominal.shape[1] != 5 or nominal.shape[0] < 1:
            raise InputError(f"robot {self.name!r}: `nominal` must have shape (n_joints, 5); got {nominal.shape}")
        n = nominal.shape[0]
        check_parameter_array(nominal, n, f"robot {self.name!r} nominal parameters")
        hayati = np.asarray(self.hayati, dtype=bool)
        if hayati.shape != (n,):
            raise InputError(f"robot {self.name!r}: `hayati` must have {n} entries; got {hayati.shape}")
        nominal = nominal.copy()
        if np.any(nominal[hayati, _D] != 0.0):
            bad = [f"J{i + 1}" for i in np.flatnonzero(hayati & (nominal[:, _D] != 0.0))]
            raise InputError(
                f"robot {self.name!r}: Hayati joints have d = 0 by definition; {', '.join(bad)} give d != 0"
            )
        if np.any(nominal[~hayati, _BETA] != 0.0):
            bad = [f"J{i + 1}" for i in np.flatnonzero(~hayati & (nominal[:, _BETA] != 0.0))]
            raise InputError(f"robot {self.name!r}: DH joints have beta = 0; {', '.join(bad)} give beta != 0")
        sign = np.ones(n) if self.reading_sign is None else np.asarray(self.reading_sign, dtype=float)
        if sign.shape != (n,) or not np.all(np.isin(sign, (-1.0, 1.0))):
            raise InputError(f"robot {self.name!r}: `reading_sign` must be {n} values of +1 or -1; got {sign.tolist()}")
        offset = np.zeros(n) if self.reading_offset is None else np.asarray(self.reading_offset, dtype=float)
        if offset.shape != (n,) or not np.all(np.isfinite(offset)):
            raise InputError(f"robot {self.name!r}: `reading_offset` must be {n} finite values")
        limits = np.tile([-np.inf, np.inf], (n, 1)) if self.limits is None else np.asarray(self.limits, dtype=float)
        if limits.shape != (n, 2) or np.any(limits[:, 0] >= limits[:, 1]):
            raise InputError(f"robot {self.name!r}: `limits` must be {n} pairs (lower < upper)")
        coupling = self._check_coupling(n, sign)
        if self.masses is not None and self.masses.mass_kg.size != n:
            raise InputError(f"robot {self.name!r}: masses of {self.masses.mass_kg.size} links for {n} joints")
        object.__setattr__(self, "nominal", _frozen(nominal))
        object.__setattr__(self, "hayati", _frozen(hayati, bool))
        object.__setattr__(self, "reading_sign", _frozen(sign))
        object.__setattr__(self, "reading_offset", _frozen(offset))
        object.__setattr__(self, "limits", _frozen(limits))
        object.__setattr__(self, "reading_coupling", _frozen(coupling))
        if self.flange_frame is not None:
            flange = np.asarray(self.flange_frame, dtype=float)
            if flange.shape != (4, 4) or not np.all(np.isfinite(flange)) or not np.allclose(
                flange[:3, :3] @ flange[:3, :3].T, np.eye(3), atol=1e-9
            ):
                raise InputError(f"robot {self.name!r}: `flange_frame` must be a rigid 4x4 transform")
            object.__setattr__(self, "flange_frame", _frozen(flange))
        inverse = None if not np.any(coupling) else _frozen(np.linalg.inv(np.diag(sign) + coupling))
        object.__setattr__(self, "_model_from_reading", inverse)

    def _check_coupling(self, n: int, sign: np.ndarray) -> np.ndarray:
        """The ``(n, n)`` off-diagonal reading coupling, validated (finite, zero diagonal, invertible map)."""
        if self.reading_coupling is None:
            return np.zeros((n, n))
        try:
            coupling = np.array(self.reading_coupling, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"robot {self.name!r}: `reading_coupling` must be numeric") from exc
        if coupling.shape != (n, n):
            raise InputError(
                f"robot {self.name!r}: `reading_coupling` must have shape ({n}, {n}); got {coupling.shape}"
            )
        if not np.all(np.isfinite(coupling)):
            raise InputError(f"robot {self.name!r}: `reading_coupling` contains NaN or infinite values")
        if np.any(np.diag(coupling) != 0.0):
            joint = int(np.flatnonzero(np.diag(coupling))[0])
            raise InputError(
                f"robot {self.name!r}: J{joint + 1} is coupled to itself; its own coefficient is `reading_sign`"
            )
        matrix = np.diag(sign) + coupling
        condition = np.linalg.cond(matrix)
        if not np.isfinite(condition) or condition > 1e8:
            raise InputError(
                f"robot {self.name!r}: the reading map (reading_sign + reading_coupling) is not invertible "
                f"(condition number {condition:.3g}); the model joint variables could not be recovered from the readings"
            )
        return coupling

    @property
    def is_coupled(self) -> bool:
        """Whether some joint's reading depends on another joint's model variable."""
        return self._model_from_reading is not None

    @property
    def reading_matrix(self) -> np.ndarray:
        """``M = diag(reading_sign) + reading_coupling``: ``reading = M (q - reading_offset)``, shape (n, n)."""
        return np.diag(self.reading_sign) + self.reading_coupling

    @property
    def n_joints(self) -> int:
        return self.nominal.shape[0]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """``("J1.d", "J1.theta", ..., "Jn.beta")``, joint-major, matching ``values.reshape(-1)``."""
        return tuple(f"J{i + 1}.{kind}" for i in range(self.n_joints) for kind in PARAMETER_KINDS)

    @property
    def structurally_fixed(self) -> np.ndarray:
        """``(n_joints, 5)`` bool: d of Hayati joints and beta of DH joints, fixed by the model."""
        fixed = np.zeros((self.n_joints, 5), dtype=bool)
        fixed[:, _D] = self.hayati
        fixed[:, _BETA] = ~self.hayati
        return fixed

    def model_joint_variables(self, readings: ArrayLike) -> np.ndarray:
        """Model joint variables [rad] from controller readings ``(..., n_joints)`` [rad].

        ``q = sign * reading + offset``; with a coupling, ``q = M^-1 reading + offset`` (see
        :attr:`reading_matrix`).
        """
        readings = np.asarray(readings, dtype=float)
        if self._model_from_reading is None:
            return readings * self.reading_sign + self.reading_offset
        return readings @ self._model_from_reading.T + self.reading_offset

    def readings_from_model(self, q: ArrayLike) -> np.ndarray:
        """Controller readings [rad] from model joint variables ``(..., n_joints)`` [rad].

        ``reading = sign * (q - offset)``; with a coupling, ``reading = M (q - offset)``.
        """
        q = np.asarray(q, dtype=float)
        if self._model_from_reading is None:
            return (q - self.reading_offset) * self.reading_sign
        return (q - self.reading_offset) @ self.reading_matrix.T


@dataclass(frozen=True, slots=True, kw_only=True)
class ParameterSet:
    """Values of every parameter of a robot, with the record of which were determined by data.

    Attributes
    ----------
    robot : RobotModel
    values : ndarray, shape (n_joints, 5)
        ``d, theta, a, alpha, beta`` [mm, rad].
    identified : ndarray of bool, shape (n_joints, 5)
        True where the value was determined by data; False where it is nominal or fixed.
    joint_model : JointModel or None
        The non-geometric joint-angle errors (gravity compliance, harmonic errors) of the extended model,
        :mod:`robotcal.kinematics.joint_model`; None: the purely geometric model.
    """

    robot: RobotModel
    values: np.ndarray
    identified: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    joint_model: JointModel | None = None

    def __post_init__(self) -> None:
        values = check_parameter_array(self.values, self.robot.n_joints)
        if self.joint_model is not None and self.joint_model.nominal.shape != (self.robot.n_joints, 5):
            raise InputError(f"the joint model was built for another robot than {self.robot.name!r}")
        if values.ndim != 2:
            raise InputError(f"a ParameterSet holds one set of shape ({self.robot.n_joints}, 5); got {values.shape}")
        fixed = self.robot.structurally_fixed
        if np.any(values[fixed] != 0.0):
            names = [
                n
                for n, f, v in zip(self.robot.parameter_names, fixed.ravel(), values.ravel(), strict=True)
                if f and v != 0.0
            ]
            raise InputError(f"parameters fixed at 0 by the model have other values: {', '.join(names)}")
        identified = (
            np.zeros(values.shape, dtype=bool) if self.identified is None else np.asarray(self.identified, dtype=bool)
        )
        if identified.shape != values.shape:
            raise InputError(f"`identified` must have shape {values.shape}; got {identified.shape}")
        object.__setattr__(self, "values", _frozen(values))
        object.__setattr__(self, "identified", _frozen(identified, bool))

    @classmethod
    def nominal(cls, robot: RobotModel) -> ParameterSet:
        """The robot's nominal parameters, none identified."""
        return cls(robot=robot, values=robot.nominal)

    @property
    def is_extended(self) -> bool:
        """True when the set carries non-geometric parameters (a :class:`JointModel` with any parameter)."""
        return self.joint_model is not None and not self.joint_model.is_empty

    def joint_variables(self, q: ArrayLike) -> np.ndarray:
        """The joint variables the geometric chain is evaluated at: ``q + delta(q)`` of the joint model (``q`` itself
        for the geometric model) [rad], for commanded model joint variables ``q (n_poses, n_joints)``."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.joint_model is None or not self.is_extended:
            return q
        return q + self.joint_model.deflection(q)

    def model_joint_variables(self, readings: ArrayLike) -> np.ndarray:
        """The joint variables this robot's chain turns by at controller ``readings (n_poses, n_joints)`` [rad]:
        :meth:`RobotModel.model_joint_variables` plus the joint model's deflection (:meth:`joint_variables`).
        Every evaluation of a parameter set at readings goes through here."""
        return self.joint_variables(self.robot.model_joint_variables(readings))

    def geometric(self) -> ParameterSet:
        """The same set without its joint model (what a geometric-only format such as a URDF carries)."""
        return replace(self, joint_model=None)

    def __repr__(self) -> str:
        extended = ""
        if self.joint_model is not None and self.is_extended:
            extended = f", joint model {', '.join(self.joint_model.names)}"
        return f"ParameterSet({self.robot.name}, {int(self.identified.sum())} identified{extended})"

    def difference(self, other: ParameterSet) -> np.ndarray:
        """``self.values - other.values`` with angles wrapped to (-pi, pi] [mm, rad]."""
        diff = self.values - other.values
        angles = list(ANGLE_COLUMNS)
        diff[:, angles] = np.angle(np.exp(1j * diff[:, angles]))
        return diff

    def replace(self, **changes: Any) -> ParameterSet:
        return replace(self, **changes)
