"""Non-geometric joint-angle errors: gravity compliance and harmonic errors (issue 22; thesis ch. 4.6, 6.2).

A real robot does not turn its links by exactly the commanded joint variables. robotcal's extended model
evaluates the geometric chain (:mod:`robotcal.kinematics.forward`) at the effective joint variables

    q_eff = q + delta(q),    delta_i(q) = k_i tau_i(q)  +  sum_k (a_ik sin(k q_i) + b_ik cos(k q_i))

with ``q`` the commanded *model* joint variables [rad]:

**Compliance** (group ``compliance``): joint i deflects by ``k_i tau_i(q)``, ``k_i`` its compliance
[rad/(N m)] and ``tau_i`` the gravity torque about its axis,

    tau_i = z_{i-1} . sum_{j >= i} (c_j - o_{i-1}) x (m_j g)          [N m, positions in m]

the torque gravity exerts about ``+z_{i-1}`` (``tau_i = -dV/dq_i``, V the potential energy; a positive torque
tends to increase q_i, so a compliant joint sags the way gravity pulls). ``m_j`` and ``c_j`` are the mass and
centre of mass of the link joint j moves (:class:`LinkMasses`: ``com_mm`` in DH frame {j}; a payload rigidly on
the flange is folded into link n); g is gravity in the base frame, ``(0, 0, -9.81)`` m/s^2 for a floor-mounted
robot (base z up).

The torque is evaluated on the robot's *nominal* structure at the commanded q (first order). Both choices
leave out effects far below a laser tracker's noise: the deflection's own effect on the torque is about
``k dtau/dq ~ 0.5 %`` of the sag on a KR 5, and the identified geometry moves the lever arms by a few tenths of a
millimetre in 300, about 0.1 % of the sag (under 1 um). In exchange the deflection is an exact linear function
of the joint model's parameters whose columns depend on q alone, so the simulation, the fit and the
compensation all use one definition and the refinement's Jacobian stays exact.

The torque is linear in the masses and first moments ``phi_j = (m_j, m_j c_j)``: ``tau_i = Y_i(q) phi``
(:func:`gravity_regressor`). Where the masses are unknown, the deflection ``k_i Y_i(q) phi`` is still linear in
``k_i phi``; only the part of that vector the torque can see is identifiable, so the *lumped* form fits
``delta_i = sum_b g_ib f_ib(q)``, the ``f_ib = Y_i v_ib`` spanning the torques of the nominal structure
(:func:`lumped_terms`): ``g_ib`` are deflections [rad].

**Harmonic** (group ``harmonic``): the thesis's joint error model (eqs 5-2..5-4) read as angle errors periodic
in the joint's own variable, orders 1..K.

**Backlash** (thesis ch. 4.6): a joint lags its command by half its lash, ``-s b_i / 2`` with ``s`` the direction
of its last motion. Along the circles of a capture, in the order they were measured, every joint's last motion is
known (the turning joint's is the ``direction`` column; the others rest where the previous circles left them), so
the lash is a fixed correction of the circle points, with the angular lash measured by the joints stage from the
bidirectional circles (:func:`lash_turns`); it is not fitted, and it is not applied at free poses or by
``compensate`` (whose approach direction a pose does not say).

The deflection is linear in the model's parameters ``e``: ``delta(q) = C(q) e`` (:meth:`JointModel.columns`);
the refinement's Jacobian is ``dp/de = sum_i dp/dq_i C_i``, ``dp/dq_i`` that of theta_i
(:func:`robotcal.kinematics.jacobian.target_jacobian` with ``joint_variables=True``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.errors import InputError
from robotcal.kinematics.forward import forward_kinematics, joint_frames
from robotcal.kinematics.masses import LinkMasses


class _Robot(Protocol):
    """What a joint model reads of its robot (a :class:`robotcal.kinematics.model.RobotModel`, which this module
    does not import: the model module imports this one)."""

    @property
    def name(self) -> str: ...
    @property
    def nominal(self) -> np.ndarray: ...
    @property
    def limits(self) -> np.ndarray: ...
    @property
    def n_joints(self) -> int: ...
    def model_joint_variables(self, readings: ArrayLike) -> np.ndarray: ...


__all__ = [
    "GRAVITY_MPS2",
    "JOINT_MODEL_GROUPS",
    "MAX_DEFLECTION_DEG",
    "MAX_HARMONIC_ORDER",
    "Deflection",
    "JointModel",
    "largest_deflection",
    "parse_parameter_name",
    "gravity_regressor",
    "gravity_torques",
    "lumped_terms",
    "lumped_levels",
    "lash_turns",
    "motion_direction",
]

#: Gravity in the base frame of a floor-mounted robot (base z up) [m/s^2].
GRAVITY_MPS2 = (0.0, 0.0, -9.81)
#: The groups of non-geometric parameters, in the order of a model's parameter vector.
JOINT_MODEL_GROUPS = ("compliance", "harmonic")
#: Highest harmonic order of a joint model (a scenario's ``[joint_model] harmonic_order``, a parameter file's
#: ``J<i>.a<k>`` / ``J<i>.b<k>``): a gear's errors of higher orders are below a tracker's noise on a circle.
MAX_HARMONIC_ORDER = 4
#: Largest deflection [deg] that a joint model may give a joint at a pose within the limits (compliance and
#: harmonics together; :func:`largest_deflection`). Industrial joints have compliances of 1e-6..1e-4 rad/(N m)
#: (the kr5-demo's 1e-5 and 4e-5); under the gravity torques of their own robots (~50 N m on a KR 5's J2, ~1e4 N m
#: on a 200 kg robot's with stiffness to match) they sag by 0.03..0.2 deg, and gear harmonics are arc-minutes (the
#: thesis's ~0.01 deg). 1 deg is five times the softest of these, and moves the flange of a 650 mm arm by ~11 mm:
#: a value beyond it is a typing error or a unit slip (deg for rad, a stiffness for a compliance), not a robot.
MAX_DEFLECTION_DEG = 1.0
_MM = 1e-3  # mm -> m


def gravity_regressor(values: ArrayLike, q: ArrayLike, gravity: ArrayLike = GRAVITY_MPS2) -> np.ndarray:
    """``Y`` with ``tau_i = sum_j Y[p, i, j] . phi_j`` (module notes), shape ``(n_poses, n_joints, n_joints, 4)``.

    ``Y[p, i, j, 0] = z_{i-1} . ((o_j - o_{i-1}) x g)`` and ``Y[p, i, j, 1:] = R_j^T (g x z_{i-1})``, in m, for
    ``j >= i``; zero for ``j < i`` [N m per kg, N m per kg mm].

    Parameters
    ----------
    values : array_like, shape (n_joints, 5)
        ``d, theta, a, alpha, beta`` [mm, rad].
    q : array_like, shape (n_poses, n_joints)
        Model joint variables [rad].
    gravity : array_like, shape (3,)
        Gravity in the base frame [m/s^2].
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    g = np.asarray(gravity, dtype=float)
    frames = joint_frames(values, q)
    n = frames.shape[1] - 1
    axis = frames[:, :-1, :3, 2]  # z_{i-1}
    origin = frames[:, :, :3, 3]
    offset = origin[:, None, 1:, :] - origin[:, :-1, None, :]  # (P, i, j, 3): o_j - o_{i-1}
    mass_column = np.einsum("pia,pija->pij", axis, np.cross(offset, g))
    moment_columns = np.einsum("pjab,pia->pijb", frames[:, 1:, :3, :3], np.cross(g, axis))
    out = np.concatenate([mass_column[..., None], moment_columns], axis=-1) * _MM
    return out * np.triu(np.ones((n, n)))[None, :, :, None]  # link j is moved by joint i only if j >= i


def gravity_torques(
    values: ArrayLike, q: ArrayLike, masses: LinkMasses, gravity: ArrayLike = GRAVITY_MPS2
) -> np.ndarray:
    """Gravity torque about every joint axis [N m], shape ``(n_poses, n_joints)`` (module notes).

    Examples
    --------
    A planar arm of two 1 kg links whose centres of mass sit at their ends (300 and 200 mm), gravity along -y
    and the arm stretched along x: joint 1 carries 9.81 (0.3 + 0.5) = 7.848 N m, joint 2 9.81 x 0.2 = 1.962 N m,
    both negative (gravity turns the arm about -z):

    >>> import numpy as np
    >>> from robotcal.kinematics.joint_model import LinkMasses, gravity_torques
    >>> values = [[0, 0, 300, 0, 0], [0, 0, 200, 0, 0]]
    >>> masses = LinkMasses(mass_kg=[1.0, 1.0], com_mm=[[0.0, 0, 0], [0.0, 0, 0]])
    >>> torques = gravity_torques(values, [[0.0, 0.0]], masses, gravity=(0.0, -9.81, 0.0))
    >>> np.round(torques, 4).tolist()
    [[-7.848, -1.962]]
    """
    regressor = gravity_regressor(values, q, gravity)
    return np.einsum("pijk,jk->pi", regressor, masses.moments)


@dataclass(frozen=True, slots=True, kw_only=True)
class JointModel:
    """The non-geometric joint-angle errors of a robot: structure (which parameters, how they act) and values.

    The deflection is linear in the parameter vector ``values (m,)``: the compliance part through
    ``compliance_map (n, 4 n, m)`` (joint i's deflection is ``Y_i(q) . (compliance_map[i] @ values)``, Y the
    gravity regressor on the nominal structure, flattened), the harmonic part through ``harmonic_map (n, K, 2,
    m)`` (joint i's is ``sum_k [sin(k q_i), cos(k q_i)] . (harmonic_map[i, k - 1] @ values)``). Build one with
    :meth:`build` (every parameter at zero) or :meth:`assemble` (from names, as a parameter file lists them).

    Attributes
    ----------
    names : tuple of str
        ``"J2.k"`` (compliance, known masses) [rad/(N m)]; ``"J2.g1"``... (lumped compliance terms) [rad];
        ``"J4.a1"``, ``"J4.b1"``... (harmonic sine and cosine amplitudes of order 1...) [rad].
    values : ndarray, shape (m,)
        In the core's units: rad/(N m) for ``k``, rad for the others.
    identified : ndarray of bool, shape (m,)
        True where the value was determined by data.
    nominal : ndarray, shape (n_joints, 5)
        The nominal structure the gravity torques are computed on [mm, rad].
    compliance_map, harmonic_map : ndarray
    lumped : dict
        ``{name: vector (4 n,)}`` of the lumped terms (``f = Y_i v``, module notes).
    masses : LinkMasses or None
        The masses of the known-mass compliance form (None: lumped form, or no compliance).
    gravity : ndarray, shape (3,)
        Gravity in the base frame [m/s^2].
    backlash : ndarray, shape (n_joints,)
        Angular lash of every joint [rad] used to correct the circle points (module notes; zeros: none).
    backlash_source : str
        Where the lash values come from (the joints stage's file).
    """

    names: tuple[str, ...]
    values: np.ndarray
    identified: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    nominal: np.ndarray
    compliance_map: np.ndarray
    harmonic_map: np.ndarray
    lumped: dict = field(default_factory=dict)
    masses: LinkMasses | None = None
    gravity: np.ndarray = field(default_factory=lambda: np.array(GRAVITY_MPS2))
    backlash: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None: the default, set in __post_init__
    backlash_source: str = ""

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=float)
        m = len(self.names)
        if values.shape != (m,) or not np.all(np.isfinite(values)):
            raise InputError(f"joint model: {m} finite values expected for {', '.join(self.names)}; got {values.shape}")
        identified = np.zeros(m, bool) if self.identified is None else np.asarray(self.identified, dtype=bool)
        if identified.shape != (m,):
            raise InputError(f"joint model: {m} `identified` flags expected; got {identified.shape}")
        object.__setattr__(self, "values", _frozen(values))
        object.__setattr__(self, "identified", _frozen(identified, bool))
        for name in ("nominal", "compliance_map", "harmonic_map", "gravity"):
            object.__setattr__(self, name, _frozen(np.asarray(getattr(self, name), dtype=float)))
        n = self.nominal.shape[0]
        backlash = np.zeros(n) if self.backlash is None else np.asarray(self.backlash, dtype=float)
        if backlash.shape != (n,) or not np.all(np.isfinite(backlash)):
            raise InputError(f"joint model: `backlash` must be {n} finite angles [rad]; got {backlash.shape}")
        object.__setattr__(self, "backlash", _frozen(backlash))

    @classmethod
    def build(
        cls,
        robot: _Robot,
        *,
        compliance_joints: Iterable[int] = (),
        masses: LinkMasses | None = None,
        harmonic_joints: Iterable[int] = (),
        harmonic_order: int = 1,
        gravity: ArrayLike = GRAVITY_MPS2,
    ) -> JointModel:
        """A model with every parameter at zero.

        Parameters
        ----------
        robot : RobotModel
        compliance_joints : sequence of int
            0-based joints that deflect under gravity. With ``masses`` one compliance ``k`` each; without,
            the lumped terms that span their torques on the nominal structure (:func:`lumped_terms`).
        masses : LinkMasses, optional
        harmonic_joints : sequence of int
            0-based joints with harmonic angle errors, orders 1..``harmonic_order``.
        gravity : array_like, shape (3,)
            In the base frame [m/s^2].
        """
        order = int(harmonic_order)
        if order < 1 or order > MAX_HARMONIC_ORDER:
            raise InputError(f"joint model: harmonic order must be 1..{MAX_HARMONIC_ORDER}; got {harmonic_order!r}")
        names, lumped = [], {}
        compliance = sorted({int(j) for j in compliance_joints})
        harmonic = sorted({int(j) for j in harmonic_joints})
        for joint in compliance + harmonic:
            if not 0 <= joint < robot.n_joints:
                raise InputError(f"joint model: joint {joint + 1} does not exist on {robot.name!r}")
        if masses is None and compliance:
            lumped = lumped_terms(robot, compliance, gravity)
        for joint in compliance:
            if masses is not None:
                names.append(f"J{joint + 1}.k")
            else:
                names.extend(name for name in lumped if name.startswith(f"J{joint + 1}."))
        names += [f"J{joint + 1}.{letter}{k}" for joint in harmonic for k in range(1, order + 1) for letter in "ab"]
        return cls.assemble(robot, names, np.zeros(len(names)), masses=masses, lumped=lumped, gravity=gravity)

    @classmethod
    def assemble(
        cls,
        robot: _Robot,
        names: Iterable[str],
        values: ArrayLike,
        *,
        identified: ArrayLike | None = None,
        masses: LinkMasses | None = None,
        lumped: Mapping[str, np.ndarray] | None = None,
        gravity: ArrayLike = GRAVITY_MPS2,
    ) -> JointModel:
        """The model of the parameters ``names`` (``J<i>.k``, ``J<i>.g<b>``, ``J<i>.a<k>``, ``J<i>.b<k>``) with
        their ``values``; ``masses`` for the ``k`` form, ``lumped {name: vector (4 n,)}`` for the ``g`` form."""
        n = robot.n_joints
        lumped = dict(lumped or {})
        names = tuple(names)
        parsed = [parse_parameter_name(name, n) for name in names]
        if len(set(names)) != len(names):
            raise InputError(f"joint model: a parameter is named twice in {', '.join(names)}")
        if masses is not None and masses.mass_kg.size != n:
            raise InputError(f"link masses: {masses.mass_kg.size} links for robot {robot.name!r} of {n} joints")
        order = max([k for _, kind, k in parsed if kind in "ab"], default=1)
        compliance_map = np.zeros((n, 4 * n, len(names)))
        harmonic_map = np.zeros((n, order, 2, len(names)))
        for column, (name, (joint, kind, k)) in enumerate(zip(names, parsed, strict=True)):
            if kind == "k":
                if masses is None:
                    raise InputError(f"joint model: {name} is a compliance with known masses; the robot has none")
                compliance_map[joint, :, column] = masses.moments.ravel()
            elif kind == "g":
                vector = np.asarray(lumped.get(name, ()), dtype=float)
                if vector.shape != (4 * n,) or not np.all(np.isfinite(vector)):
                    raise InputError(f"joint model: lumped term {name} needs its vector of {4 * n} finite numbers")
                compliance_map[joint, :, column] = vector
            else:
                harmonic_map[joint, k - 1, "ab".index(kind), column] = 1.0
        kept = {name: lumped[name] for name, (_, kind, _) in zip(names, parsed, strict=True) if kind == "g"}
        return cls(
            names=names,
            values=np.asarray(values),
            identified=np.zeros(len(names), bool) if identified is None else np.asarray(identified),
            nominal=robot.nominal,
            compliance_map=compliance_map,
            harmonic_map=harmonic_map,
            lumped=kept,
            masses=masses if any(kind == "k" for _, kind, _ in parsed) else None,
            gravity=np.asarray(gravity, dtype=float),
        )

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def is_empty(self) -> bool:
        return not self.names

    @property
    def groups(self) -> tuple[str, ...]:
        """``"compliance"`` or ``"harmonic"`` per parameter."""
        return tuple("harmonic" if name.split(".")[1][0] in "ab" else "compliance" for name in self.names)

    @property
    def units(self) -> tuple[str, ...]:
        """The core unit of every parameter: ``rad/(N m)`` for a compliance ``k``, ``rad`` otherwise."""
        return tuple("rad/(N m)" if name.endswith(".k") else "rad" for name in self.names)

    @property
    def display_units(self) -> tuple[str, ...]:
        """The unit of every parameter in files, tables and reports: ``rad/(N m)`` for a compliance ``k`` (the unit
        stiffness figures are quoted in), ``deg`` for the deflections and harmonic amplitudes."""
        return tuple("rad/(N m)" if name.endswith(".k") else "deg" for name in self.names)

    def to_display(self, values: ArrayLike) -> np.ndarray:
        """Core values ``(..., m)`` in :attr:`display_units` (NaN stays NaN)."""
        factor = np.array([1.0 if name.endswith(".k") else 180.0 / np.pi for name in self.names])
        return np.asarray(values, dtype=float) * factor

    def from_display(self, values: ArrayLike) -> np.ndarray:
        """Values ``(..., m)`` in :attr:`display_units` back to the core's units."""
        factor = np.array([1.0 if name.endswith(".k") else np.pi / 180.0 for name in self.names])
        return np.asarray(values, dtype=float) * factor

    def with_values(self, values: ArrayLike, identified: ArrayLike | None = None) -> JointModel:
        return replace(
            self, values=np.asarray(values), identified=self.identified if identified is None else np.asarray(identified)
        )

    def with_backlash(self, backlash: ArrayLike | None, source: str = "") -> JointModel:
        """The same model correcting the circle points for the angular lash ``backlash (n,)`` [rad]."""
        lash = np.zeros(self.nominal.shape[0]) if backlash is None else np.asarray(backlash)  # None: no lash
        return replace(self, backlash=lash, backlash_source=source)

    @property
    def has_backlash(self) -> bool:
        return bool(np.any(self.backlash != 0.0))

    def columns(self, q: ArrayLike) -> np.ndarray:
        """``C(q)`` with ``delta = C(q) @ values``, shape ``(n_poses, n_joints, m)`` [rad per unit of each value]."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        n = q.shape[1]
        out = np.zeros(q.shape + (self.size,))
        if np.any(self.compliance_map):
            regressor = gravity_regressor(self.nominal, q, self.gravity).reshape(q.shape[0], n, 4 * n)
            out += np.einsum("pik,ikm->pim", regressor, self.compliance_map)
        if np.any(self.harmonic_map):
            k = np.arange(1, self.harmonic_map.shape[1] + 1)
            angle = q[:, :, None] * k  # (P, n, K)
            waves = np.stack([np.sin(angle), np.cos(angle)], axis=-1)  # (P, n, K, 2)
            out += np.einsum("piks,iksm->pim", waves, self.harmonic_map)
        return out

    def deflection(self, q: ArrayLike, values: ArrayLike | None = None) -> np.ndarray:
        """``delta(q)`` [rad], shape ``(n_poses, n_joints)``; ``values (..., m)``: other values (a batch of draws:
        then shape ``(..., n_poses, n_joints)``)."""
        values = self.values if values is None else np.asarray(values, dtype=float)
        return np.einsum("pim,...m->...pi", self.columns(q), values)

    def compliance(self) -> np.ndarray:
        """``k_i`` [rad/(N m)] per joint (zeros where rigid, and for the lumped form)."""
        k = np.zeros(self.compliance_map.shape[0])
        for name, value in zip(self.names, self.values, strict=True):
            joint, kind = name.split(".")
            if kind == "k":
                k[int(joint[1:]) - 1] = value
        return k


def motion_direction(q: ArrayLike) -> np.ndarray:
    """Direction of each joint's last motion along a sequence of configurations.

    Parameters
    ----------
    q : array_like, shape (n_points, n_joints)
        Joint variables in the order the robot visits them [rad].

    Returns
    -------
    ndarray of int, shape (n_points, n_joints)
        ``+1`` if the joint last moved towards larger values before (or on reaching) the row,
        ``-1`` towards smaller ones. A row equal to the previous one keeps its state; a joint that
        has not moved yet is taken to have approached its first value from below (``+1``).
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 2:
        raise InputError(f"`q` must have shape (n_points, n_joints); got {q.shape}")
    step = np.sign(np.diff(q, axis=0))
    step = np.concatenate([np.ones((1, q.shape[1])), step], axis=0)  # first row: approached from below
    rows = np.arange(q.shape[0])[:, None]
    last_moved = np.maximum.accumulate(np.where(step != 0.0, rows, 0), axis=0)
    return step[last_moved, np.arange(q.shape[1])].astype(int)


def lash_turns(backlash: ArrayLike, q: ArrayLike, circle: ArrayLike) -> np.ndarray:
    """The backlash correction of a capture's joint variables ``(n_points, n_joints)`` [rad] (module notes):
    ``-s_i b_i / 2`` on every joint of every circle point, ``s_i`` the direction of joint i's last motion along the
    circle points in capture order (the order the robot visited them: :func:`motion_direction` of the commanded model variables ``q``); 0 at free poses (``circle = 0``), whose approach
    the capture does not record."""
    backlash = np.asarray(backlash, dtype=float)
    q = np.asarray(q, dtype=float)
    out = np.zeros(q.shape)
    rows = np.flatnonzero(np.asarray(circle) > 0)
    if rows.size and np.any(backlash):
        out[rows] = -0.5 * motion_direction(q[rows]) * backlash
    return out


def parse_parameter_name(name: str, n_joints: int) -> tuple[int, str, int]:
    """``"J2.k"`` -> ``(1, "k", 0)``; ``"J4.b2"`` -> ``(3, "b", 2)``; an :class:`InputError` for any other text,
    and for a harmonic order above :data:`MAX_HARMONIC_ORDER`."""
    joint, _, term = str(name).partition(".")
    kind, number = term[:1], term[1:]
    valid = (
        joint[:1] == "J"
        and joint[1:].isdigit()
        and 1 <= int(joint[1:]) <= n_joints
        and ((kind == "k" and not number) or (kind in "gab" and kind and number.isdigit() and int(number) >= 1))
    )
    if not valid:
        raise InputError(
            f"joint model: unknown parameter {name!r}; expected J<i>.k (compliance), J<i>.g<b> (lumped compliance) "
            f"or J<i>.a<k> / J<i>.b<k> (harmonic) with i in 1..{n_joints}"
        )
    if kind in "ab" and int(number) > MAX_HARMONIC_ORDER:
        raise InputError(f"{name}: harmonic order {int(number)} is outside 1..{MAX_HARMONIC_ORDER}")
    return int(joint[1:]) - 1, kind, int(number) if number else 0


class Deflection(NamedTuple):
    """The largest deflection of a joint model over a sample of poses (:func:`largest_deflection`)."""

    #: ``|delta_i(q)|`` [rad].
    angle: float
    #: The joint (0-based) and the parameter (index into the model's names) that contributes most to it.
    joint: int
    parameter: int
    #: The controller readings of the pose [rad], and how far the deflection moves the flange there [mm].
    readings: np.ndarray
    flange_shift_mm: float


def largest_deflection(model: JointModel, robot: _Robot, *, poses: int = 400, seed: int = 0) -> Deflection:
    """The largest deflection ``|delta_i(q)|`` of any joint over ``poses`` seeded random poses within the joint
    limits (compliance and harmonics together), where it happens and what it does to the flange of the nominal
    structure. Compare it with :data:`MAX_DEFLECTION_DEG`."""
    n = robot.n_joints
    limits = np.where(np.isfinite(robot.limits), robot.limits, np.array([-np.pi, np.pi]))
    readings = np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(poses, n))
    q = robot.model_joint_variables(readings)
    columns = model.columns(q)  # (P, n, m)
    delta = columns @ model.values
    pose, joint = np.unravel_index(int(np.argmax(np.abs(delta))), delta.shape)
    parameter = int(np.argmax(np.abs(columns[pose, joint] * model.values))) if model.size else 0
    shifted = forward_kinematics(robot.nominal, np.stack([q[pose], q[pose] + delta[pose]]))[:, :3, 3]
    return Deflection(
        angle=float(abs(delta[pose, joint])),
        joint=int(joint),
        parameter=parameter,
        readings=readings[pose],
        flange_shift_mm=float(np.linalg.norm(shifted[1] - shifted[0])),
    )


def lumped_terms(
    robot: _Robot, joints: Iterable[int], gravity: ArrayLike = GRAVITY_MPS2, *, poses: int = 400, seed: int = 0
) -> dict[str, np.ndarray]:
    """The lumped compliance terms of ``joints`` (0-based): ``{"J<i>.g<b>": v (4 n,)}``, the torques ``f_b = Y_i
    v_b`` spanning joint i's gravity torques on the nominal structure over ``poses`` seeded random poses within
    the limits (right singular vectors of the regressor), each scaled to unit RMS torque over that sample, so that
    ``g_ib`` is the RMS deflection its term causes [rad]. The structure depends only on the robot and the seed."""
    n = robot.n_joints
    generator = np.random.default_rng(seed)
    limits = np.where(np.isfinite(robot.limits), robot.limits, np.array([-np.pi, np.pi]))
    readings = generator.uniform(limits[:, 0], limits[:, 1], size=(poses, n))
    q = robot.model_joint_variables(readings)
    regressor = gravity_regressor(robot.nominal, q, gravity).reshape(poses, n, 4 * n)
    out = {}
    for joint in sorted({int(j) for j in joints}):
        _, s, vt = np.linalg.svd(regressor[:, joint], full_matrices=False)
        keep = s > s[0] * 1e-8 if s.size and s[0] > 0 else np.zeros(s.size, bool)
        for b, (vector, value) in enumerate(zip(vt[keep], s[keep], strict=True)):
            out[f"J{joint + 1}.g{b + 1}"] = vector * (np.sqrt(poses) / value)  # unit RMS torque over the sample
    return out


def lumped_levels(model: JointModel, robot: _Robot) -> list[JointModel]:
    """The nested lumped forms of ``model`` (:func:`lumped_terms`): level b keeps the first b terms of every compliant
    joint (its b largest torque shapes) and every other parameter, with their values; the last level is ``model``'s
    set. A model without lumped terms is its only level."""
    depth = max((int(name.split(".g")[1]) for name in model.lumped), default=0)
    if not depth:
        return [model]
    levels = []
    for level in range(1, depth + 1):
        keep = [k for k, name in enumerate(model.names) if name not in model.lumped or int(name.split(".g")[1]) <= level]
        subset = JointModel.assemble(
            robot, [model.names[k] for k in keep], model.values[keep], identified=model.identified[keep],
            masses=model.masses, lumped=model.lumped, gravity=model.gravity,
        )  # fmt: skip
        levels.append(subset.with_backlash(model.backlash, model.backlash_source) if model.has_backlash else subset)
    return levels
