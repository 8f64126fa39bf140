"""Robot programs of a capture plan (thesis 4.5.2: "genera los códigos en el lenguaje del robot"),
and of any other sequence of joint moves with a comment per move (the ISO 9283 pose test).

One joint move per measuring point, in the plan's order (forward sweep, then the return sweep when
bidirectional), each followed by a dwell for the tracker to settle and measure, and preceded by a
comment naming the circle, the direction and the point. Three controller languages:

- ``krl`` (KUKA KRL): ``PTP {A1 .., A2 .., ...}`` axis angles [deg] and ``WAIT SEC s``;
- ``rapid`` (ABB RAPID): ``MoveAbsJ [[j1..j6],[9E9,..]], v, fine, tool0;`` [deg] and ``WaitTime s;``;
- ``urscript`` (Universal Robots): ``movej([..], a=.., v=..)`` [rad] and ``sleep(s)``.

The angles are controller readings: the plan's readings converted, through the model joint
variables, to the readings of ``controller`` (a robot file with the controller's reading signs and
offsets, e.g. ``kuka-kr5-sixx-r650-krc``), and checked against that file's limits.
"""

from __future__ import annotations

import numpy as np

from robotcal.errors import InputError
from robotcal.kinematics.model import RobotModel

__all__ = ["LANGUAGES", "write_program", "controller_readings"]

LANGUAGES = ("krl", "rapid", "urscript")


def controller_readings(readings, robot: RobotModel, controller: RobotModel | None = None) -> np.ndarray:
    """Readings of ``robot`` [rad] as readings of ``controller`` [rad] (same model), limit-checked.

    Raises
    ------
    InputError
        The robots do not share the model, or a reading is outside the controller's limits.
    """
    readings = np.asarray(readings, dtype=float)
    if controller is None:
        out = readings
        controller = robot
    else:
        if controller.n_joints != robot.n_joints or not np.allclose(controller.nominal, robot.nominal, atol=1e-9):
            raise InputError(f"controller robot {controller.name!r} does not share the model of {robot.name!r}")
        out = controller.readings_from_model(robot.model_joint_variables(readings))
    lower, upper = controller.limits[:, 0], controller.limits[:, 1]
    outside = np.argwhere((out < lower - 1e-9) | (out > upper + 1e-9))
    if outside.size:
        point, joint = outside[0]
        raise InputError(
            f"point {point + 1}: A{joint + 1} = {np.rad2deg(out[point, joint]):.3f} deg is outside the limits "
            f"[{np.rad2deg(lower[joint]):g}, {np.rad2deg(upper[joint]):g}] deg of {controller.name!r} "
            f"({int(len(outside))} readings outside); run `robotcal plan check` and fix the plan"
        )
    return out


def write_program(
    circle,
    direction,
    readings,
    *,
    language: str,
    dwell_s: float,
    name: str = "robotcal_capture",
    speed_percent: float = 10.0,
    header: str = "",
    labels=None,
) -> str:
    """The program text.

    Parameters
    ----------
    circle, direction : array_like of int, shape (n_points,), or None
        Circle (1-based turning joint) and sweep direction (+1/-1) of every point (for the comment
        before each move; unused, and may be None, when ``labels`` is given).
    readings : array_like, shape (n_points, n_joints)
        Controller readings [rad].
    language : {"krl", "rapid", "urscript"}
    dwell_s : float
        Dwell at every point [s], >= 0.
    name : str
        Program / procedure name (letters, digits, underscore).
    speed_percent : float
        Joint speed as a percentage of the maximum (KRL ``$VEL_AXIS``, URScript ``v`` of 3.14 rad/s,
        RAPID speed data ``v`` of 1000 mm/s ... as a rough equivalent).
    header : str
        Comment lines placed at the top (one per line).
    labels : sequence of str, shape (n_points,), optional
        The comment before each move instead of "circle i forward|return point k" (e.g. the ISO
        9283 plan's "cycle 3 P2"); one line each.
    """
    if language not in LANGUAGES:
        raise InputError(f"unknown language {language!r}; choose one of {', '.join(LANGUAGES)}")
    if not np.isfinite(dwell_s) or dwell_s < 0:
        raise InputError(f"--dwell must be a non-negative number of seconds; got {dwell_s}")
    if not name.replace("_", "a").isalnum() or not name[0].isalpha():
        raise InputError(f"program name must start with a letter and hold letters, digits, underscores; got {name!r}")
    readings = np.asarray(readings, dtype=float)
    n_joints = readings.shape[1]
    if language in ("rapid", "urscript") and n_joints != 6:
        raise InputError(f"{language} programs need a 6-axis robot; this robot has {n_joints} joints")
    if labels is None:
        circle = np.asarray(circle, dtype=int)
        direction = np.asarray(direction, dtype=int)
    else:
        labels = [str(label) for label in labels]
        if len(labels) != readings.shape[0] or any("\n" in label or "\r" in label for label in labels):
            raise InputError(
                f"`labels` must be {readings.shape[0]} one-line comments, one per point; got {len(labels)}"
            )
    counts = {}
    comment = {"krl": ";", "rapid": "!", "urscript": "#"}[language]
    indent = "  "
    lines = [f"{comment} {line}" for line in header.splitlines()] if header else []
    if language == "krl":
        lines += [f"DEF {name}()", f"{indent}BAS(#INITMOV, 0)", f"{indent}BAS(#VEL_PTP, {speed_percent:g})"]
    elif language == "rapid":
        lines += [f"MODULE {name}", f"{indent}PROC main()"]
        indent = "    "
    else:
        lines += [f"def {name}():"]
    for index in range(readings.shape[0]):
        if labels is None:
            key = (int(circle[index]), int(direction[index]))
            counts[key] = counts.get(key, 0) + 1
            sweep = "forward" if key[1] > 0 else "return"
            lines.append(f"{indent}{comment} circle {key[0]} {sweep} point {counts[key]}")
        else:
            lines.append(f"{indent}{comment} {labels[index]}")
        degrees = np.rad2deg(readings[index])
        if language == "krl":
            axes = ", ".join(f"A{j + 1} {value:.6f}" for j, value in enumerate(degrees))
            lines += [f"{indent}PTP {{{axes}}}", f"{indent}WAIT SEC {dwell_s:g}"]
        elif language == "rapid":
            axes = ",".join(f"{value:.6f}" for value in degrees)
            lines += [
                f"{indent}MoveAbsJ [[{axes}],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v100, fine, tool0;",
                f"{indent}WaitTime {dwell_s:g};",
            ]
        else:
            axes = ", ".join(f"{value:.9f}" for value in readings[index])
            lines += [
                f"{indent}movej([{axes}], a=1.0, v={3.14 * speed_percent / 100.0:.3f})",
                f"{indent}sleep({dwell_s:g})",
            ]
    if language == "krl":
        lines.append("END")
    elif language == "rapid":
        lines += ["  ENDPROC", "ENDMODULE"]
    else:
        lines.append("end")
    return "\n".join(lines) + "\n"
