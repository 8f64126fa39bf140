"""Harmonic model of joint errors in the joint angle, and its compensation (beyond thesis ch. 4.6).

The thesis measures backlash and eccentricity (ch. 4.6) and asks, as future work (ch. 6.2), to model
and compensate them. Its own generator models joint errors as sinusoids of the joint angle
(eq. 5-2: ``A sin(2 pi / T q + phi)``). robotcal fits, per joint and per quantity, the low-order
Fourier series

    ``y(theta) = c0 + sum_{k=1..K} (a_k cos k theta + b_k sin k theta)
               = c0 + sum_k C_k sin(k theta + phi_k)``

by linear least squares, with ``theta`` the turning joint's reading [rad]. Quantities: ``axial`` and
``radial`` eccentricity of every point, and the backlash vector's ``backlash_axial``,
``backlash_radial`` and ``backlash_tangential`` components of every matched pair (turnaround pairs
excluded). Uncertainties come from the least-squares covariance ``s^2 (X^T X)^-1`` and, for
amplitude and phase, from the delta method (GUM 5.1.2).

Orders 0 and 1 of ``axial`` and ``radial`` are absorbed by the plane and circle fits (axis position,
tilt and radius); only orders >= 2 are properties of the joint. They stay in the model because, on
an arc shorter than a full turn, the fits leave their trace there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from robotcal._arrays import frozen_array as _frozen
from robotcal.diagnostics.joints import JointDiagnostics, local_frame
from robotcal.errors import InputError, check_count
from robotcal.kinematics.model import DISPLAY_UNITS

__all__ = [
    "QUANTITIES",
    "HarmonicFit",
    "CircleGeometry",
    "HarmonicModel",
    "fit_harmonic_series",
    "fit_harmonics",
    "HARMONICS_FORMAT",
]

#: Quantities the model describes, per joint [mm].
QUANTITIES = ("axial", "radial", "backlash_axial", "backlash_radial", "backlash_tangential")
#: ``format`` key of the exported JSON document.
HARMONICS_FORMAT = "robotcal-joint-harmonics/1"


def _design(theta: np.ndarray, order: int) -> np.ndarray:
    """Columns ``1, cos theta, sin theta, ..., cos K theta, sin K theta``: shape ``(n, 2K + 1)``."""
    k = np.arange(1, order + 1)
    angles = theta[:, None] * k
    columns = np.empty((theta.size, 2 * order + 1))
    columns[:, 0] = 1.0
    columns[:, 1::2] = np.cos(angles)
    columns[:, 2::2] = np.sin(angles)
    return columns


@dataclass(frozen=True, slots=True, kw_only=True)
class HarmonicFit:
    """A least-squares Fourier series of one quantity of one joint.

    Attributes
    ----------
    joint : int
        1-based joint (0 when fitted outside a joint model).
    quantity : str
    order : int
        K, the highest harmonic.
    coefficients : ndarray, shape (2K + 1,)
        ``c0, a_1, b_1, ..., a_K, b_K`` [mm].
    covariance : ndarray, shape (2K + 1, 2K + 1)
        ``s^2 (X^T X)^-1`` [mm^2].
    n : int
        Number of values fitted; ``dof = n - (2K + 1)``.
    sigma : float
        Residual standard deviation ``s = sqrt(RSS / dof)`` [mm].
    rms_before, rms_after : float
        RMS of the values, and of what the model leaves of them [mm].
    explained : float
        ``1 - RSS / sum(y^2)``: the share of the measured mean square that the model explains.
    f_statistic, p_value : float
        F test of the model against ``y = 0`` (pure noise): ``F = ((sum y^2 - RSS) / p) / s^2`` with
        ``(p, dof)`` degrees of freedom. Approximate for fit residuals (the circle fit used some).
    """

    joint: int
    quantity: str
    order: int
    coefficients: np.ndarray
    covariance: np.ndarray
    n: int
    sigma: float
    rms_before: float
    rms_after: float
    explained: float
    f_statistic: float
    p_value: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "coefficients", _frozen(self.coefficients))
        object.__setattr__(self, "covariance", _frozen(self.covariance))

    @property
    def dof(self) -> int:
        return self.n - self.coefficients.size

    @property
    def offset(self) -> float:
        """c0 [mm]."""
        return float(self.coefficients[0])

    @property
    def offset_uncertainty(self) -> float:
        return float(np.sqrt(self.covariance[0, 0]))

    def _ab(self):
        a = self.coefficients[1::2]
        b = self.coefficients[2::2]
        var_a = np.diag(self.covariance)[1::2]
        var_b = np.diag(self.covariance)[2::2]
        cov_ab = np.array([self.covariance[2 * k + 1, 2 * k + 2] for k in range(self.order)])
        return a, b, var_a, var_b, cov_ab

    @property
    def amplitude(self) -> np.ndarray:
        """``C_k = sqrt(a_k^2 + b_k^2)``, shape (K,) [mm]."""
        a, b, *_ = self._ab()
        return np.hypot(a, b)

    @property
    def phase(self) -> np.ndarray:
        """``phi_k = atan2(a_k, b_k)`` in ``C_k sin(k theta + phi_k)``, shape (K,) [rad]."""
        a, b, *_ = self._ab()
        return np.arctan2(a, b)

    @property
    def amplitude_uncertainty(self) -> np.ndarray:
        """Standard uncertainty of ``C_k`` by the delta method, shape (K,) [mm] (NaN where C_k = 0)."""
        a, b, var_a, var_b, cov_ab = self._ab()
        c2 = a**2 + b**2
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.sqrt((a**2 * var_a + b**2 * var_b + 2 * a * b * cov_ab) / c2)

    @property
    def phase_uncertainty(self) -> np.ndarray:
        """Standard uncertainty of ``phi_k`` by the delta method, shape (K,) [rad] (NaN where C_k = 0)."""
        a, b, var_a, var_b, cov_ab = self._ab()
        c2 = a**2 + b**2
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.sqrt(np.maximum(b**2 * var_a + a**2 * var_b - 2 * a * b * cov_ab, 0.0)) / c2

    def evaluate(self, theta) -> np.ndarray:
        """The series at readings ``theta (...)`` [rad]: values [mm] of the same shape."""
        theta = np.asarray(theta, dtype=float)
        return (_design(theta.reshape(-1), self.order) @ self.coefficients).reshape(theta.shape)

    def to_dict(self) -> dict:
        """Plain, JSON-ready form in mm and degrees (non-finite numbers become ``None``)."""

        def number(value, scale=1.0):
            value = float(value) * scale
            return value if math.isfinite(value) else None

        to_deg = 180.0 / np.pi
        return {
            "quantity": self.quantity,
            "order": self.order,
            "offset_mm": number(self.offset),
            "offset_u_mm": number(self.offset_uncertainty),
            "harmonics": [
                {
                    "k": k + 1,
                    "amplitude_mm": number(self.amplitude[k]),
                    "amplitude_u_mm": number(self.amplitude_uncertainty[k]),
                    "phase_deg": number(self.phase[k], to_deg),
                    "phase_u_deg": number(self.phase_uncertainty[k], to_deg),
                }
                for k in range(self.order)
            ],
            "coefficients_mm": [number(v) for v in self.coefficients],
            "covariance_mm2": [[number(v) for v in row] for row in self.covariance],
            "n": self.n,
            "dof": self.dof,
            "sigma_mm": number(self.sigma),
            "rms_before_mm": number(self.rms_before),
            "rms_after_mm": number(self.rms_after),
            "explained": number(self.explained),
            "f_statistic": number(self.f_statistic),
            "p_value": number(self.p_value),
        }

    @classmethod
    def from_dict(cls, data: dict, *, joint: int = 0, where: str = "harmonic fit") -> HarmonicFit:
        """Inverse of :meth:`to_dict` (uses ``coefficients_mm`` and ``covariance_mm2``)."""

        def number(value):
            return float("nan") if value is None else float(value)

        try:
            order = int(data["order"])
            coefficients = np.array([number(v) for v in data["coefficients_mm"]])
            covariance = np.array([[number(v) for v in row] for row in data["covariance_mm2"]])
            fields = {
                key: number(data[name])
                for key, name in (
                    ("sigma", "sigma_mm"),
                    ("rms_before", "rms_before_mm"),
                    ("rms_after", "rms_after_mm"),
                    ("explained", "explained"),
                    ("f_statistic", "f_statistic"),
                    ("p_value", "p_value"),
                )
            }
            quantity, n = str(data["quantity"]), int(data["n"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: missing or invalid key {exc}") from None
        p = 2 * order + 1
        if (
            order < 1
            or coefficients.shape != (p,)
            or covariance.shape != (p, p)
            or not np.all(np.isfinite(coefficients))
        ):
            raise InputError(
                f"{where}: order {order} needs {p} finite `coefficients_mm` and a {p}x{p} `covariance_mm2`; "
                f"got {coefficients.shape} and {covariance.shape}"
            )
        if quantity not in QUANTITIES:
            raise InputError(f"{where}: unknown quantity {quantity!r}; expected one of {', '.join(QUANTITIES)}")
        return cls(joint=joint, quantity=quantity, order=order, coefficients=coefficients, covariance=covariance, n=n, **fields)


def fit_harmonic_series(
    theta: ArrayLike, values: ArrayLike, *, order: int = 2, joint: int = 0, quantity: str = "radial",
) -> HarmonicFit:
    """Least-squares Fourier series of ``values`` in ``theta``.

    Minimises ``sum_i (y_i - c0 - sum_k (a_k cos k theta_i + b_k sin k theta_i))^2`` (linear least
    squares, solved by QR).

    Parameters
    ----------
    theta : array_like, shape (n,)
        Joint readings [rad].
    values : array_like, shape (n,)
        Deviations [mm].
    order : int
        Highest harmonic K >= 1; needs ``n > 2K + 1``.
    joint, quantity
        Labels carried by the result.

    Returns
    -------
    HarmonicFit
    """
    theta = np.asarray(theta, dtype=float)
    values = np.asarray(values, dtype=float)
    order = check_count(order, "order")
    if theta.ndim != 1 or values.shape != theta.shape:
        raise InputError(f"`theta` and `values` must have the same shape (n,); got {theta.shape} and {values.shape}")
    p = 2 * order + 1
    if theta.size <= p:
        raise InputError(
            f"J{joint} {quantity}: a harmonic model of order {order} has {p} coefficients and needs more than "
            f"{p} values; got {theta.size}"
        )
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(values))):
        raise InputError("`theta` and `values` must be finite")
    if quantity not in QUANTITIES:
        raise InputError(f"`quantity` must be one of {', '.join(QUANTITIES)}; got {quantity!r}")
    design = _design(theta, order)
    q, r = np.linalg.qr(design)
    singular = np.abs(np.diag(r)) <= 1e-12 * np.max(np.abs(np.diag(r)))
    if np.any(singular):
        raise InputError(
            f"J{joint} {quantity}: the readings do not determine a harmonic model of order {order} "
            "(too few distinct angles)"
        )
    coefficients = np.linalg.solve(r, q.T @ values)
    residual = values - design @ coefficients
    rss = float(residual @ residual)
    total = float(values @ values)
    dof = theta.size - p
    sigma2 = rss / dof
    r_inv = np.linalg.inv(r)
    covariance = sigma2 * (r_inv @ r_inv.T)
    with np.errstate(divide="ignore", invalid="ignore"):
        f_statistic = ((total - rss) / p) / sigma2 if sigma2 > 0 else (np.inf if total > 0 else np.nan)
        explained = 1.0 - rss / total if total > 0 else np.nan
    from scipy.special import fdtrc  # F survival function; imported here, scipy.special is slow to import

    p_value = float(fdtrc(p, dof, f_statistic)) if np.isfinite(f_statistic) else (0.0 if total > 0 else np.nan)
    return HarmonicFit(
        joint=joint,
        quantity=quantity,
        order=order,
        coefficients=coefficients,
        covariance=covariance,
        n=int(theta.size),
        sigma=float(np.sqrt(sigma2)),
        rms_before=float(np.sqrt(total / theta.size)),
        rms_after=float(np.sqrt(rss / theta.size)),
        explained=float(explained),
        f_statistic=float(f_statistic),
        p_value=p_value,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class CircleGeometry:
    """The fitted circle a joint's model refers to (tracker frame, mm), with the joint's noise level.

    ``noise_sigma`` is the instrument noise per coordinate estimated from the capture and
    ``backlash_noise_floor`` the backlash magnitude that noise alone gives (mm, NaN when unknown;
    :attr:`robotcal.diagnostics.CircleDiagnostics.noise_sigma`, ``backlash_noise_floor``).
    """

    joint: int
    centre: np.ndarray
    normal: np.ndarray
    radius: float
    noise_sigma: float = float("nan")
    backlash_noise_floor: float = float("nan")

    def __post_init__(self):
        centre = np.asarray(self.centre, dtype=float)
        normal = np.asarray(self.normal, dtype=float)
        if (
            centre.shape != (3,)
            or normal.shape != (3,)
            or not (np.all(np.isfinite(centre)) and np.all(np.isfinite(normal)))
        ):
            raise InputError(f"J{self.joint}: `centre` and `normal` must be 3 finite numbers each")
        length = np.linalg.norm(normal)
        if abs(length - 1.0) > 1e-6:
            raise InputError(f"J{self.joint}: `normal` must be a unit vector; got length {length:.6g}")
        object.__setattr__(self, "centre", _frozen(centre))
        object.__setattr__(self, "normal", _frozen(normal / length))


@dataclass(frozen=True, slots=True, kw_only=True)
class HarmonicModel:
    """Per-joint harmonic models of eccentricity and backlash, with the circles they refer to.

    Attributes
    ----------
    fits : tuple of HarmonicFit
        At most one per joint and quantity.
    circles : tuple of CircleGeometry
        One per joint modelled.
    order : int
    messages : tuple of str
        Quantities that could not be modelled, and why.
    """

    fits: tuple[HarmonicFit, ...]
    circles: tuple[CircleGeometry, ...]
    order: int
    messages: tuple[str, ...] = ()

    def fit(self, joint: int, quantity: str) -> HarmonicFit | None:
        """The fit of ``quantity`` for ``joint`` (1-based), or None if it was not modelled."""
        for item in self.fits:
            if item.joint == joint and item.quantity == quantity:
                return item
        return None

    def geometry(self, joint: int) -> CircleGeometry:
        for item in self.circles:
            if item.joint == joint:
                return item
        raise InputError(f"the harmonic model has no circle for joint J{joint}")

    def predict(self, joint: int, quantity: str, theta) -> np.ndarray:
        """Modelled ``quantity`` of ``joint`` at readings ``theta`` [rad]; zeros if not modelled [mm]."""
        if quantity not in QUANTITIES:
            raise InputError(f"`quantity` must be one of {', '.join(QUANTITIES)}; got {quantity!r}")
        item = self.fit(joint, quantity)
        theta = np.asarray(theta, dtype=float)
        return np.zeros(theta.shape) if item is None else item.evaluate(theta)

    def correction(self, joint: int, theta, points, state=None) -> np.ndarray:
        """Displacement the model predicts for points of ``joint``'s circle [mm], shape ``(n, 3)``.

        ``axial(theta) n + radial(theta) u - s / 2 (b_axial n + b_radial u + b_tangential t)`` with
        ``(n, u, t)`` the axial, radial and tangential directions at each point
        (:func:`robotcal.diagnostics.joints.local_frame`) and ``s`` the lash state: a point reached by
        the forward sweep lies half a backlash vector before the mean path, a return point half a
        vector after it. ``state=None`` (or 0) leaves backlash out.

        Parameters
        ----------
        joint : int
            1-based joint whose circle the points belong to.
        theta : array_like, shape (n,)
            Readings of the turning joint [rad].
        points : array_like, shape (n, 3)
            Predicted target positions, tracker frame [mm].
        state : array_like of int, shape (n,), optional
            +1 / -1: the sweep by which the joint reached each point
            (:func:`robotcal.diagnostics.joints.lash_state`).
        """
        theta = np.asarray(theta, dtype=float).reshape(-1)
        points = np.asarray(points, dtype=float)
        if points.shape != (theta.size, 3) or not np.all(np.isfinite(points)):
            raise InputError(f"`points` must be finite with shape ({theta.size}, 3); got {points.shape}")
        s = np.zeros(theta.size) if state is None else np.asarray(state, dtype=float).reshape(-1)
        if s.shape != theta.shape or not np.all(np.isin(s, (-1.0, 0.0, 1.0))):
            raise InputError(f"`state` must hold +1, -1 or 0 for each of the {theta.size} points")
        circle = self.geometry(joint)
        frames = local_frame(circle.centre, circle.normal, points, joint=joint)
        local = np.stack(
            [
                self.predict(joint, "axial", theta) - 0.5 * s * self.predict(joint, "backlash_axial", theta),
                self.predict(joint, "radial", theta) - 0.5 * s * self.predict(joint, "backlash_radial", theta),
                -0.5 * s * self.predict(joint, "backlash_tangential", theta),
            ],
            axis=-1,
        )
        return np.einsum("ki,kij->kj", local, frames)

    def apply(self, joint: int, theta, points, state=None) -> np.ndarray:
        """Compensated positions ``points + correction(...)`` [mm]: where the model says the target is."""
        return np.asarray(points, dtype=float) + self.correction(joint, theta, points, state)

    def to_dict(self) -> dict:
        """JSON-ready document (format ``robotcal-joint-harmonics/1``; mm and degrees)."""
        joints = []
        for circle in self.circles:
            joints.append(
                {
                    "joint": circle.joint,
                    "centre_mm": circle.centre.tolist(),
                    "normal": circle.normal.tolist(),
                    "radius_mm": float(circle.radius),
                    "noise_sigma_um": _um_or_none(circle.noise_sigma),
                    "noise_floor_um": _um_or_none(circle.backlash_noise_floor),
                    "terms": {f.quantity: f.to_dict() for f in self.fits if f.joint == circle.joint},
                }
            )
        return {
            "format": HARMONICS_FORMAT,
            "units": dict(DISPLAY_UNITS),
            "model": "y(theta) = offset + sum_k amplitude_k * sin(k * theta + phase_k); theta = reading of the turning joint",
            "order": self.order,
            "quantities": list(QUANTITIES),
            "joints": joints,
            "messages": list(self.messages),
        }

    @classmethod
    def from_dict(cls, data: dict, *, source: str = "harmonic model") -> HarmonicModel:
        """Read a document written by :meth:`to_dict`; errors name ``source`` and the joint."""
        if not isinstance(data, dict) or data.get("format") != HARMONICS_FORMAT:
            raise InputError(f"{source}: not a robotcal harmonic model (expected format {HARMONICS_FORMAT!r})")
        units = data.get("units", dict(DISPLAY_UNITS))
        if units != dict(DISPLAY_UNITS):
            raise InputError(f"{source}: `units` must be {{'length': 'mm', 'angle': 'deg'}}; got {units!r}")
        fits, circles = [], []
        try:
            order = int(data["order"])
            for entry in data["joints"]:
                joint = int(entry["joint"])
                noise = {
                    name: float("nan") if entry.get(key) is None else float(entry[key]) / 1000.0
                    for name, key in (("noise_sigma", "noise_sigma_um"), ("backlash_noise_floor", "noise_floor_um"))
                }  # optional: documents written before the noise floor lack them
                circles.append(
                    CircleGeometry(
                        joint=joint,
                        centre=entry["centre_mm"],
                        normal=entry["normal"],
                        radius=float(entry["radius_mm"]),
                        **noise,
                    )
                )
                for quantity, term in entry.get("terms", {}).items():
                    fit = HarmonicFit.from_dict(term, joint=joint, where=f"{source}: J{joint} {quantity}")
                    if fit.quantity != quantity:
                        raise InputError(f"{source}: J{joint}: term {quantity!r} holds quantity {fit.quantity!r}")
                    fits.append(fit)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"{source}: missing or invalid key {exc}") from None
        return cls(fits=tuple(fits), circles=tuple(circles), order=order, messages=tuple(data.get("messages", ())))


def _um_or_none(value_mm: float) -> float | None:
    """A length in µm for JSON, rounded to 1e-4 µm; None when not finite (strict JSON)."""
    value = float(value_mm)
    return round(value * 1000.0, 4) if np.isfinite(value) else None


def fit_harmonics(diagnostics: JointDiagnostics, *, order: int = 2) -> HarmonicModel:
    """Fit the harmonic model of every joint of ``diagnostics`` (see the module docstring).

    ``axial`` and ``radial`` use every point of the circle (both sweeps); the backlash components
    use the matched pairs that are not turnarounds. A quantity with too few values for ``order``
    is left out with a message.
    """
    if not isinstance(diagnostics, JointDiagnostics):
        raise InputError(f"`diagnostics` must be JointDiagnostics; got {type(diagnostics).__name__}")
    check_count(order, "order")
    fits, circles, messages = [], [], []
    for c in diagnostics.circles:
        circles.append(
            CircleGeometry(
                joint=c.joint,
                centre=c.centre,
                normal=c.normal,
                radius=c.radius,
                noise_sigma=c.noise_sigma,
                backlash_noise_floor=c.backlash_noise_floor if c.n_pairs else float("nan"),
            )
        )
        series = [("axial", c.reading, c.axial), ("radial", c.reading, c.radial)]
        if diagnostics.backlash:
            keep = ~c.turnaround
            for k, name in enumerate(("backlash_axial", "backlash_radial", "backlash_tangential")):
                series.append((name, c.pair_reading[keep], c.backlash_local[keep, k]))
        for quantity, theta, values in series:
            try:
                fits.append(fit_harmonic_series(theta, values, order=int(order), joint=c.joint, quantity=quantity))
            except InputError as exc:
                messages.append(str(exc))
    return HarmonicModel(fits=tuple(fits), circles=tuple(circles), order=int(order), messages=tuple(messages))
