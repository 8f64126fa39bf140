"""Built-in data shipped with robotcal: robots, instrument presets and thesis scenarios (TOML)."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from robotcal.errors import InputError
from robotcal.io.schema._validation import check_nesting, read_text_file

__all__ = ["data_path", "builtin_names", "read_toml"]


def data_path(*parts: str) -> Path:
    """Path of a file inside ``robotcal/data``."""
    return Path(str(resources.files("robotcal").joinpath("data", *parts)))


def builtin_names(kind: str) -> list[str]:
    """Names of the built-in ``robots`` or ``scenarios`` (file stems), sorted."""
    return sorted(p.stem for p in data_path(kind).glob("*.toml"))


def read_toml(path) -> dict:
    """Parse a TOML file, turning I/O and syntax errors into :class:`InputError` naming the file."""
    path = Path(path)
    text = read_text_file(path, kind="TOML file")
    check_nesting(text, str(path), kind="TOML")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML: {exc}") from None
    except (ValueError, RecursionError) as exc:  # e.g. an integer past Python's digit limit
        raise InputError(f"{path}: invalid TOML: {exc}") from None
