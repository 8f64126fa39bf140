"""Validation helpers of the I/O edge: pydantic errors and CSV cells become one clear :class:`InputError`
naming the file, line and key or column."""

from __future__ import annotations

import math

from pydantic import BaseModel, ValidationError

from robotcal.errors import InputError


def _location(loc) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(top level)"


def validate_model(model: type[BaseModel], data: dict, source: str) -> BaseModel:
    """``model.model_validate(data)`` with errors as ``InputError("<source>: key <k>: <why>")``."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        problems = []
        for error in exc.errors():
            message = error["msg"]
            if error["type"] == "extra_forbidden":
                message = "unknown key"
            elif error["type"] == "missing":
                message = "missing required key"
            problems.append(f"key `{_location(error['loc'])}`: {message}")
        raise InputError(f"{source}: " + "; ".join(problems)) from None


def parse_finite(cell: str, where: str) -> float:
    """A CSV cell as a finite float, else ``InputError("<where>: '<cell>' is not a (finite) number")``.

    ``where`` names the place, e.g. ``"capture.csv: line 7, column `x`"``.
    """
    text = cell.strip()
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"{where}: {text!r} is not a finite number")
    return value
