"""Built-in data shipped with robotcal: robots, instrument presets and thesis scenarios (TOML)."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from robotcal.errors import InputError

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
    try:
        with path.open("rb") as stream:
            return tomllib.load(stream)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML: {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
