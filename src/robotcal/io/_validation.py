"""Turn pydantic validation errors into one clear :class:`InputError` naming the file and key."""

from __future__ import annotations

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
