"""The settings of the refinement and of the model choice: each built once (from a scenario or from arguments),
checked when it is made, and passed through unchanged (issue 31).

:class:`RefinementSettings` are the options of one least-squares refinement
(:func:`robotcal.identification.refine.refine_parameters`); what a refinement is *of* (the capture, the start, the
targets, the base frame, the joint model) are its inputs, not settings. :class:`ModelChoiceSettings` say which
model is fitted and how it is cross-validated (:mod:`robotcal.identification.model_choice`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robotcal._arrays import frozen_array
from robotcal.errors import InputError, check_count

__all__ = [
    "CRITERIA",
    "MODELS",
    "MODEL_CHOICES",
    "DEFAULT_FOLDS",
    "RefinementSettings",
    "ModelChoiceSettings",
]

#: The two objectives of thesis ch. 4.5.7.
CRITERIA = ("points", "distances")
#: The models, simplest first.
MODELS = ("geometric", "compliance", "harmonic", "compliance+harmonic")
#: What ``refine --model`` accepts.
MODEL_CHOICES = (*MODELS, "auto")
#: Folds of the cross-validation by pose.
DEFAULT_FOLDS = 5


def _one_of(name: str, value, allowed: Sequence) -> None:
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"`{name}` must be one of {', '.join(map(repr, allowed))}; got {value!r}")


def _positive(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating) or not 0.0 < value < 1.0:
        raise InputError(f"`{name}` must be a number in (0, 1); got {value!r}")


def _joints(name: str, value) -> tuple[int, ...] | None:
    if value is None:
        return None
    try:
        joints = tuple(value)
    except TypeError:
        joints = None
    if joints is None or any(isinstance(j, bool) or not isinstance(j, int | np.integer) or j < 0 for j in joints):
        raise InputError(f"`{name}` must be None or 0-based joint indices; got {value!r}")
    return tuple(int(j) for j in joints)


@dataclass(frozen=True, slots=True, kw_only=True)
class RefinementSettings:
    """The options of one refinement (thesis ch. 4.5.7; :mod:`robotcal.identification.refine`).

    Attributes
    ----------
    criterion : {"points", "distances"}
        Eq. 4-101 (point positions in the tracker frame) or eq. 4-102 (all pairwise distances).
    estimate_base : bool or None
        Points criterion: estimate the base-frame corrections the data determine with the parameters. None: only
        when no ``tracker_from_base`` is given. False needs a ``tracker_from_base``.
    free : None, tuple of str, or ndarray of bool, shape (n_joints, 5)
        Parameters to estimate (names like ``"J2.beta"``, checked against the robot when the fit starts). None:
        every parameter the model allows and the data determine.
    on_unidentifiable : {"fix", "raise"}
        With ``free=None``: hold what the data cannot determine with a warning, or raise.
    method : {"auto", "lm", "trf"}
        ``auto``: ``"lm"`` when there are at least as many residuals as unknowns, else ``"trf"``.
    max_nfev : int or None
        Residual-evaluation limit of each fit (None: ``100 * (n_unknowns + 1)``, SciPy's for ``"lm"``).
    tolerance : float
        ``ftol = xtol = gtol`` of ``scipy.optimize.least_squares``, in (0, 1).
    rank_tolerance : float
        Of the rank test (:func:`robotcal.identification.observability.select_identifiable`), in (0, 1).
    weights : {"auto", "none"}
        ``auto``: with a ``u95_mm`` column, weight each point by ``1 / u^2`` (u = U(95) / 2); ``none``: equal.
    repeatability_mm : float or None
        The robot's ISO 9283 pose repeatability RP [mm], >= 0 (the scenario's ``repeatability_mm``): the noise
        budget's robot part, added in quadrature to every point's u of the weights and to the fit health's expected
        noise (:func:`robotcal.identification.health.stated_noise`); None: not stated.
    """

    criterion: str = "points"
    estimate_base: bool | None = None
    free: tuple[str, ...] | np.ndarray | None = None
    on_unidentifiable: str = "fix"
    method: str = "auto"
    max_nfev: int | None = None
    tolerance: float = 1e-12
    rank_tolerance: float = 1e-7
    weights: str = "auto"
    repeatability_mm: float | None = None

    def __post_init__(self) -> None:
        _one_of("criterion", self.criterion, CRITERIA)
        if self.estimate_base not in (None, True, False) or isinstance(self.estimate_base, np.ndarray):
            raise InputError(f"`estimate_base` must be None, True or False; got {self.estimate_base!r}")
        object.__setattr__(self, "estimate_base", None if self.estimate_base is None else bool(self.estimate_base))
        object.__setattr__(self, "free", _check_free_setting(self.free))
        _one_of("on_unidentifiable", self.on_unidentifiable, ("fix", "raise"))
        _one_of("method", self.method, ("auto", "lm", "trf"))
        if self.max_nfev is not None:
            check_count(self.max_nfev, "max_nfev")
        _positive("tolerance", self.tolerance)
        _positive("rank_tolerance", self.rank_tolerance)
        _one_of("weights", self.weights, ("auto", "none"))
        if self.repeatability_mm is not None:
            value = self.repeatability_mm
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value < float("inf"):
                raise InputError(f"`repeatability_mm` must be a finite length >= 0 [mm]; got {value!r}")

    @property
    def strict(self) -> bool:
        """Whether what the data cannot determine is an error: an explicit free set, or ``on_unidentifiable``."""
        return self.free is not None or self.on_unidentifiable == "raise"


def _check_free_setting(free):
    """``free`` as a tuple of names or a read-only bool array (its shape is checked against the robot later)."""
    if free is None:
        return None
    if isinstance(free, str):
        raise InputError(f"`free` must be None, parameter names, or a bool array of shape (n_joints, 5); got {free!r}")
    if isinstance(free, list | tuple) and all(isinstance(name, str) for name in free):
        return tuple(free)
    mask = np.asarray(free)
    if mask.dtype != bool or mask.ndim != 2 or mask.shape[1] != 5:
        raise InputError(
            f"`free` must be None, parameter names, or a bool array of shape (n_joints, 5); got {mask.shape}"
        )
    return frozen_array(mask, bool)


@dataclass(frozen=True, slots=True, kw_only=True)
class ModelChoiceSettings:
    """Which model a refinement fits and how every fit is cross-validated
    (:mod:`robotcal.identification.model_choice`).

    Attributes
    ----------
    model : {"geometric", "compliance", "harmonic", "compliance+harmonic", "auto"}
        ``auto`` fits each of :data:`MODELS` and keeps the one cross-validation chooses.
    folds : int
        k of the cross-validation by pose every fit reports; 0: none (not with ``auto``).
    seed : int
        Seed of the deal of poses into folds.
    compliance_joints, harmonic_joints : tuple of int or None
        0-based joints of the compliance and harmonic terms (None: the defaults of
        :func:`robotcal.identification.model_choice.joint_model_for`).
    harmonic_order : int
    """

    model: str = "geometric"
    folds: int = DEFAULT_FOLDS
    seed: int = 0
    compliance_joints: tuple[int, ...] | None = None
    harmonic_joints: tuple[int, ...] | None = None
    harmonic_order: int = 1

    def __post_init__(self) -> None:
        if self.model not in MODEL_CHOICES:
            raise InputError(f"unknown model {self.model!r}; expected one of {', '.join(MODEL_CHOICES)}")
        folds = self.folds
        if isinstance(folds, bool) or not isinstance(folds, int | np.integer) or folds < 0 or folds == 1:
            raise InputError(f"`folds` must be 0 (no cross-validation) or at least 2; got {self.folds!r}")
        if self.model == "auto" and not self.folds:
            raise InputError("model 'auto' chooses by cross-validation: give at least 2 folds")
        check_count(self.seed, "seed", minimum=0)
        check_count(self.harmonic_order, "harmonic_order")
        object.__setattr__(self, "compliance_joints", _joints("compliance_joints", self.compliance_joints))
        object.__setattr__(self, "harmonic_joints", _joints("harmonic_joints", self.harmonic_joints))

    @property
    def candidates(self) -> tuple[str, ...]:
        """The models fitted: every one of :data:`MODELS` for ``auto``, else the one named."""
        return MODELS if self.model == "auto" else (self.model,)
