"""One home for the parameter kinds: only kinematics/model.py spells out which kinds are angles (issue 13).

The check reads every module under ``src/robotcal`` with :mod:`ast` (comments and docstrings do not count)
and flags a literal collection of exactly the angle kinds, ``("theta", "alpha", "beta")`` in any order,
of their column numbers ``(1, 3, 4)``, or of all five kinds: such a literal restates :data:`ANGLE_KINDS`,
:data:`ANGLE_COLUMNS` or :data:`PARAMETER_KINDS` and would silently disagree if the column order changed.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import robotcal
from robotcal.kinematics.model import (
    ANGLE_COLUMNS,
    ANGLE_KINDS,
    DISPLAY_UNITS,
    KIND_UNITS,
    LENGTH_COLUMNS,
    LENGTH_KINDS,
    PARAMETER_KINDS,
    ParameterSet,
    RobotModel,
)

SOURCE = Path(robotcal.__file__).parent
HOME = SOURCE / "kinematics" / "model.py"
#: Modules still restating the kinds, owned by other work in progress (issue 13): this list may only
#: shrink; the test fails when a listed module no longer needs its entry, so that it is removed.
NOT_YET_MOVED: set[str] = set()


def _restatements(tree: ast.AST) -> list[int]:
    """Line numbers of tuple/list/set literals holding exactly the angle kinds, their columns or all kinds."""
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Tuple | ast.List | ast.Set):
            continue
        if not all(isinstance(element, ast.Constant) for element in node.elts):
            continue
        values = [element.value for element in node.elts]
        if sorted(map(str, values)) in (sorted(ANGLE_KINDS), sorted(PARAMETER_KINDS)) or values == [1, 3, 4]:
            lines.append(node.lineno)
    return sorted(lines)


def _offenders() -> dict[str, list[int]]:
    found = {}
    for path in sorted(SOURCE.rglob("*.py")):
        if path == HOME:
            continue
        lines = _restatements(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
        if lines:
            found[path.relative_to(SOURCE).as_posix()] = lines
    return found


def test_the_detector_finds_a_restatement_and_ignores_text():
    code = (
        'A = ("beta", "theta", "alpha")\nB = x[:, [1, 3, 4]]\n"""("theta", "alpha", "beta")"""\nC = (1, 3)\n'
        'D = ["d", "theta", "a", "alpha", "beta"]\nE = ("d", "a", "theta")\n'
    )
    assert _restatements(ast.parse(code)) == [1, 2, 5]
    assert _restatements(ast.parse(HOME.read_text(encoding="utf-8")))  # the home itself does state them


def test_no_module_restates_the_angle_kinds():
    offenders = _offenders()
    new = {name: lines for name, lines in offenders.items() if name not in NOT_YET_MOVED}
    assert not new, f"use robotcal.kinematics.model.ANGLE_KINDS / ANGLE_COLUMNS instead of literals: {new}"
    moved = sorted(NOT_YET_MOVED - set(offenders))
    assert not moved, f"no longer restating the kinds: remove from NOT_YET_MOVED: {moved}"


def test_kind_constants_agree_with_the_column_order():
    assert sorted(LENGTH_KINDS + ANGLE_KINDS) == sorted(PARAMETER_KINDS)
    assert [PARAMETER_KINDS[k] for k in ANGLE_COLUMNS] == list(ANGLE_KINDS)
    assert [PARAMETER_KINDS[k] for k in LENGTH_COLUMNS] == list(LENGTH_KINDS)
    assert dict(KIND_UNITS) == {"d": "mm", "theta": "deg", "a": "mm", "alpha": "deg", "beta": "deg"}
    assert dict(DISPLAY_UNITS) == {"length": "mm", "angle": "deg"}


def test_difference_wraps_exactly_the_angle_columns():
    robot = RobotModel(name="two", nominal=np.zeros((2, 5)), hayati=np.array([False, True]))
    # 2 pi everywhere the model is free: a full turn (no change) for an angle, 2 pi mm for a length;
    # J1 (DH) has beta fixed at 0, J2 (Hayati) has d fixed at 0.
    values = np.array([[2 * np.pi, 2 * np.pi, 1.0, 2 * np.pi, 0.0], [0.0, 2 * np.pi, 1.0, 2 * np.pi, 2 * np.pi]])
    difference = ParameterSet(robot=robot, values=values).difference(ParameterSet.nominal(robot))
    np.testing.assert_allclose(difference[:, ANGLE_COLUMNS], 0.0, atol=1e-12)
    np.testing.assert_array_equal(difference[:, LENGTH_COLUMNS], [[2 * np.pi, 1.0], [0.0, 1.0]])
