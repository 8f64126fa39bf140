"""Monte Carlo parameter draws as ``draws.npz`` (numpy arrays only, loaded with ``allow_pickle=False``).

Keys (format ``robotcal-draws/1``):

``values``       (n_draws, n_params) float64, every parameter ``J1.d .. Jn.beta`` in mm / deg
``names``        (n_params,) str, ``"J1.d"`` ...
``units``        (n_params,) str, ``"mm"`` or ``"deg"``
``nominal``      (n_params,) float64, the robot's nominal values [mm, deg]
``identified``   (n_params,) bool, True where CPA determines the parameter (others stay nominal)
``robot_json``   0-d str, the robot file (``robot_to_dict``) as JSON, so the file is self-contained
``seed``         0-d int64, the Monte Carlo seed
``model``        0-d str, ``"cpa"`` or ``"refined"``: the model the draws belong to (optional; absent = cpa)
``format``       0-d str
``joint_model_values``  (n_draws, m) float64, an extended refined model's joint-model values (``J2.k``
                 [rad/(N m)], ``J4.a1`` [deg], issue 22), with ``joint_model_json`` (0-d str) its joint model as
                 the parameter JSON's ``joint_model`` key; both absent for a geometric model

The archive is written uncompressed (``np.savez``): 8 bytes per parameter and draw, 24 MB per 10^5
draws of a 6-joint robot. ``np.savez_compressed`` saves only about a third (the random digits of the
draws do not compress; the constant columns of parameters CPA does not identify do) and takes longer than
the rest of ``robotcal uncertainty --save-draws`` outside its draws (benchmarks/bench_uncertainty_command.py).
Files written compressed by earlier versions read the same.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robotcal.errors import InputError
from robotcal.io.atomic import atomic_write_bytes
from robotcal.io.schema._validation import parse_json_text
from robotcal.io.schema.robots import robot_from_dict, robot_to_dict
from robotcal.kinematics.joint_model import JointModel
from robotcal.kinematics.model import ANGLE_COLUMNS, KIND_UNITS, PARAMETER_KINDS, RobotModel

__all__ = ["FORMAT", "ParameterDraws", "write_draws", "read_draws", "parameter_units"]

FORMAT = "robotcal-draws/1"
_ANGLE_COLUMNS = list(ANGLE_COLUMNS)


def parameter_units(robot: RobotModel) -> list[str]:
    """``"mm"`` or ``"deg"`` for each of ``robot.parameter_names``."""
    return [KIND_UNITS[kind] for _ in range(robot.n_joints) for kind in PARAMETER_KINDS]


def _to_file_units(values: np.ndarray) -> np.ndarray:
    converted = np.array(values, dtype=float)
    converted[..., _ANGLE_COLUMNS] = np.rad2deg(converted[..., _ANGLE_COLUMNS])
    return converted


def _to_core_units(values: np.ndarray) -> np.ndarray:
    converted = np.array(values, dtype=float)
    converted[..., _ANGLE_COLUMNS] = np.deg2rad(converted[..., _ANGLE_COLUMNS])
    return converted


@dataclass(frozen=True, slots=True, kw_only=True)
class ParameterDraws:
    """Parameter draws read back from a file.

    Attributes
    ----------
    robot : RobotModel
    values : ndarray, shape (n_draws, n_joints, 5)
        ``d, theta, a, alpha, beta`` of every draw [mm, rad].
    identified : ndarray of bool, shape (n_joints, 5)
    seed : int
    source : str
    joint_model : JointModel or None
        An extended model's joint model; with ``extras (n_draws, m)`` its values in every draw [core units].
    """

    robot: RobotModel
    values: np.ndarray
    identified: np.ndarray
    seed: int
    source: str = field(default="")
    joint_model: JointModel | None = None
    extras: np.ndarray | None = None

    @property
    def n_draws(self) -> int:
        return self.values.shape[0]


def write_draws(
    path, robot: RobotModel, values, identified, *, seed: int, model: str = "cpa", joint_model=None, extras=None
) -> Path:
    """Write draws ``values (n_draws, n_joints, 5)`` [mm, rad] of ``model`` to ``path`` atomically; an extended
    model's ``joint_model`` and its values ``extras (n_draws, m)`` [core units] with them."""
    values = np.asarray(values, dtype=float)
    n = robot.n_joints
    if values.ndim != 3 or values.shape[1:] != (n, 5):
        raise InputError(f"draws must have shape (n_draws, {n}, 5); got {values.shape}")
    more = {}
    if joint_model is not None and extras is not None:
        from robotcal.io.formats.parameters_json import joint_model_to_dict

        extras = np.asarray(extras, dtype=float)
        if extras.shape != (values.shape[0], joint_model.size):
            raise InputError(f"joint-model draws must have shape ({values.shape[0]}, {joint_model.size}); got {extras.shape}")
        more = {
            "joint_model_values": joint_model.to_display(extras),
            "joint_model_json": np.array(json.dumps(joint_model_to_dict(joint_model))),
        }
    buffer = io.BytesIO()
    np.savez(  # uncompressed: see the module docstring
        buffer,
        values=_to_file_units(values).reshape(values.shape[0], n * 5),
        names=np.array(robot.parameter_names),
        units=np.array(parameter_units(robot)),
        nominal=_to_file_units(robot.nominal).reshape(-1),
        identified=np.asarray(identified, dtype=bool).reshape(-1),
        robot_json=np.array(json.dumps(robot_to_dict(robot))),
        seed=np.array(int(seed), dtype=np.int64),
        model=np.array(str(model)),
        format=np.array(FORMAT),
        **more,
    )
    return atomic_write_bytes(path, buffer.getvalue())


def read_draws(path) -> ParameterDraws:
    """Read a ``draws.npz`` written by :func:`write_draws` (errors name the file and the key)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such draws file (write one with `robotcal uncertainty --save-draws`)")
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not a readable .npz file (not a zip archive; write one with `--save-draws`)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            contents = {key: archive[key] for key in archive.files}
    except (OSError, ValueError, EOFError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc})") from None
    missing = [key for key in ("values", "names", "identified", "robot_json", "seed", "format") if key not in contents]
    if missing:
        raise InputError(f"{path}: missing key(s) {', '.join(missing)}; is this a robotcal draws file?")
    if str(contents["format"]) != FORMAT:
        raise InputError(f"{path}: format {str(contents['format'])!r} is not {FORMAT!r}")
    try:
        robot_text = str(contents["robot_json"].item()) if contents["robot_json"].size == 1 else None
        seed = int(contents["seed"].item()) if contents["seed"].size == 1 else None
    except (TypeError, ValueError, OverflowError):
        robot_text = seed = None
    if robot_text is None or seed is None:
        raise InputError(
            f"{path}: keys `robot_json` and `seed` must each hold one value; is this a robotcal draws file?"
        )
    robot = robot_from_dict(parse_json_text(robot_text, f"{path}: key `robot_json`"), f"{path}: key `robot_json`")
    names = [str(name) for name in np.ravel(contents["names"])]
    if names != list(robot.parameter_names):
        raise InputError(f"{path}: `names` do not match the robot's parameters {robot.parameter_names[:2]}...")
    try:
        flat = np.asarray(contents["values"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: `values` must hold numbers; got dtype {contents['values'].dtype}") from None
    if flat.ndim != 2 or flat.shape[1] != robot.n_joints * 5 or flat.shape[0] < 1:
        raise InputError(f"{path}: `values` must have shape (n_draws, {robot.n_joints * 5}); got {flat.shape}")
    if not np.all(np.isfinite(flat)):
        row = int(np.nonzero(~np.isfinite(flat))[0][0])
        raise InputError(f"{path}: `values` holds a non-finite number in draw {row}")
    values = _to_core_units(flat.reshape(-1, robot.n_joints, 5))
    identified = np.asarray(contents["identified"])
    if identified.dtype != bool or identified.size != robot.n_joints * 5:
        raise InputError(f"{path}: `identified` must hold {robot.n_joints * 5} booleans; got {identified.shape}")
    identified = identified.reshape(robot.n_joints, 5)
    joint_model = extras = None
    if "joint_model_json" in contents:
        from robotcal.io.formats.parameters_json import read_joint_model

        text = str(contents["joint_model_json"].item())
        joint_model = read_joint_model(parse_json_text(text, f"{path}: key `joint_model_json`"), robot, path)
        shown = np.asarray(contents.get("joint_model_values", np.zeros((0, 0))), dtype=float)
        if shown.shape != (values.shape[0], joint_model.size) or not np.all(np.isfinite(shown)):
            raise InputError(
                f"{path}: `joint_model_values` must be finite, shape ({values.shape[0]}, {joint_model.size}); "
                f"got {shown.shape}"
            )
        extras = joint_model.from_display(shown)
    return ParameterDraws(
        robot=robot, values=values, identified=identified, seed=seed, source=str(path), joint_model=joint_model,
        extras=extras,
    )  # fmt: skip
