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
offsets, e.g. ``kuka-kr5-sixx-r650-krc``), and checked against that file's limits. Numbers that
round to zero are written without a sign (``0.000000``, never ``-0.000000``).

Program names (:func:`check_program_name`, :func:`program_name`): an identifier of the language,
a letter then letters, digits or underscores, at most 24 characters in KRL, 32 in RAPID, and no
keyword of KRL. A KRL program's ``DEF`` name must equal its file name (the ``.src`` file's stem), so
:func:`program_name` takes it from the file for KRL.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from robotcal.errors import InputError
from robotcal.kinematics.model import RobotModel

__all__ = ["LANGUAGES", "NAME_LIMITS", "check_program_name", "program_name", "write_program", "controller_readings"]

LANGUAGES = ("krl", "rapid", "urscript")
#: Longest program/module name of each language [characters] (KUKA KRL: 24; ABB RAPID identifiers: 32;
#: URScript: none).
NAME_LIMITS = {"krl": 24, "rapid": 32, "urscript": None}
#: Default name of a RAPID module or URScript function (a KRL program is named after its file).
DEFAULT_NAME = "robotcal_capture"
#: KRL keywords, which cannot name a program.
_KRL_KEYWORDS = frozenset(
    """AND ANIN ANOUT B_AND B_EXOR B_NOT B_OR BOOL BRAKE CASE CAST_FROM CAST_TO CHAR CIRC CIRC_REL CONST CONTINUE
    DECL DEF DEFAULT DEFDAT DEFFCT DELAY DISTANCE DO ELSE END ENDDAT ENDFCT ENDFOR ENDIF ENDLOOP ENDSWITCH ENDWHILE
    ENUM EXIT EXOR EXT EXTFCT FALSE FOR GLOBAL GOTO HALT IF IMPORT INT INTERRUPT IS LIN LIN_REL LOOP MAXIMUM
    MINIMUM NOT OR PRIO PTP PTP_REL PUBLIC REAL REPEAT RESUME RETURN SEC SIGNAL STEP STRUC SWITCH THEN TO TRIGGER
    TRUE UNTIL WAIT WHEN WHILE""".split()
)
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def check_program_name(name: str, language: str, *, what: str = "program name") -> str:
    """``name`` if it can name a ``language`` program, else an :class:`InputError` saying why.

    A letter, then letters, digits or underscores (ASCII); at most :data:`NAME_LIMITS` characters;
    in KRL not a keyword (``END``, ``LOOP``, ...). ``what`` names the source in the message.
    """
    if language not in LANGUAGES:
        raise InputError(f"unknown language {language!r}; choose one of {', '.join(LANGUAGES)}")
    if not isinstance(name, str) or not _IDENTIFIER.fullmatch(name):
        raise InputError(
            f"{what} {_short(name)} is not a valid {language.upper()} name: it must start with a letter and hold only "
            "letters, digits and underscores"
        )
    limit = NAME_LIMITS[language]
    if limit is not None and len(name) > limit:
        raise InputError(
            f"{what} {_short(name)} has {len(name)} characters; {language.upper()} allows at most {limit}"
        )
    if language == "krl" and name.upper() in _KRL_KEYWORDS:
        raise InputError(f"{what} {name!r} is a KRL keyword; choose another name")
    return name


def program_name(language: str, path: str | Path, name: str | None = None) -> str:
    """The name of a ``language`` program written to ``path``, checked by :func:`check_program_name`.

    KRL: the file's stem (the controller expects ``DEF name`` in ``name.src``); a ``name`` given must
    equal it (KRL ignores case; the file's spelling is written). RAPID, URScript: ``name``, else
    :data:`DEFAULT_NAME`.
    """
    from pathlib import Path

    if language == "krl":
        stem = Path(path).stem
        if name is not None:
            check_program_name(name, language, what="--name")
        if name is not None and name.upper() != stem.upper():
            raise InputError(
                f"--name {_short(name)} differs from the file name {Path(path).name!r}: a KRL program's DEF name must "
                f"equal its file name; give --out {name}.src, or leave out --name"
            )
        return check_program_name(stem, language, what=f"KRL program name (the file name of {Path(path).name!r})")
    return check_program_name(DEFAULT_NAME if name is None else name, language)


def _short(text) -> str:
    """``repr`` of ``text``, cut to 40 characters."""
    text = repr(text)
    return text if len(text) <= 40 else text[:37] + "..."


def _fixed(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals, never ``-0.000``: a value that rounds to zero is written ``0.000``."""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def controller_readings(readings: ArrayLike, robot: RobotModel, controller: RobotModel | None = None) -> np.ndarray:
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
    circle: np.ndarray | None,
    direction: np.ndarray | None,
    readings: ArrayLike,
    *,
    language: str,
    dwell_s: float,
    name: str = "robotcal_capture",
    speed_percent: float = 10.0,
    header: str = "",
    labels: Sequence[str] | None = None,
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
        Program name (KRL ``DEF``), RAPID module or URScript function: :func:`check_program_name`. A
        KRL program must be saved as ``name.src`` (:func:`program_name` derives it from the file).
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
    dwell_s = float(dwell_s) + 0.0  # -0.0 -> 0.0
    check_program_name(name, language)
    readings = np.asarray(readings, dtype=float)
    if readings.ndim != 2 or not np.all(np.isfinite(readings)):
        raise InputError(f"`readings` must be finite, shape (n_points, n_joints); got shape {readings.shape}")
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
    counts: dict[tuple, int] = {}
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
    if labels is None and (circle is None or direction is None):
        raise InputError("write_program: give `labels`, or the `circle` and `direction` of every point")
    for index in range(readings.shape[0]):
        if labels is None:
            assert circle is not None and direction is not None  # checked above
            key = (int(circle[index]), int(direction[index]))
            counts[key] = counts.get(key, 0) + 1
            sweep = "forward" if key[1] > 0 else "return"
            lines.append(f"{indent}{comment} circle {key[0]} {sweep} point {counts[key]}")
        else:
            lines.append(f"{indent}{comment} {labels[index]}")
        degrees = np.rad2deg(readings[index])
        if language == "krl":
            axes = ", ".join(f"A{j + 1} {_fixed(value, 6)}" for j, value in enumerate(degrees))
            lines += [f"{indent}PTP {{{axes}}}", f"{indent}WAIT SEC {dwell_s:g}"]
        elif language == "rapid":
            axes = ",".join(_fixed(value, 6) for value in degrees)
            lines += [
                f"{indent}MoveAbsJ [[{axes}],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v100, fine, tool0;",
                f"{indent}WaitTime {dwell_s:g};",
            ]
        else:
            axes = ", ".join(_fixed(value, 9) for value in readings[index])
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
