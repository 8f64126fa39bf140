"""Robot programs as the robot runs them (KUKA KRL, ABB RAPID, URScript): read their motion targets, write them back
with new numbers and nothing else changed (issue 28). :mod:`robotcal.programs.base` holds what the readers share,
:mod:`robotcal.programs.filter` compensates a program with a calibrated model."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from robotcal.errors import InputError

if TYPE_CHECKING:
    from robotcal.programs.base import Program

__all__ = ["LANGUAGE_OF_SUFFIX", "LANGUAGES", "read_program"]

#: The program languages robotcal reads and writes.
LANGUAGES = ("krl", "rapid", "urscript")
#: The language of a program file, by its suffix (lower case).
LANGUAGE_OF_SUFFIX = {
    ".src": "krl",
    ".mod": "rapid",
    ".modx": "rapid",
    ".prg": "rapid",
    ".sys": "rapid",
    ".sysx": "rapid",
    ".script": "urscript",
    ".urscript": "urscript",
}


def read_program(
    path: str | os.PathLike[str], *, language: str | None = None, dat: str | os.PathLike[str] | None = None,
    config_dat: str | os.PathLike[str] | None = None, encoding: str = "utf-8",
) -> Program:
    """Read a robot program with the reader of its language (from the suffix unless ``language`` is given).

    ``dat`` and ``config_dat`` are KRL's: the program's ``.dat`` (default: beside the ``.src``) and the cell's
    ``$config.dat`` with ``TOOL_DATA`` and ``BASE_DATA``. Returns a :class:`robotcal.programs.base.Program`.
    """
    path = Path(path)
    language = language or LANGUAGE_OF_SUFFIX.get(path.suffix.lower())
    if language is None:
        raise InputError(
            f"{path}: cannot tell the language from the suffix {path.suffix!r}; give the language: krl, rapid or "
            "urscript"
        )
    if language not in LANGUAGES:
        raise InputError(f"unknown program language {language!r}; choose krl, rapid or urscript")
    if language != "krl" and (dat is not None or config_dat is not None):
        raise InputError(f"{path}: a .dat and a $config.dat belong to KRL programs, not to {language}")
    if language == "krl":
        from robotcal.programs.krl import read_program as read_krl

        return read_krl(path, dat_path=dat, config_dat=config_dat, encoding=encoding)
    if language == "rapid":
        from robotcal.programs.rapid import read_program as read_rapid

        return read_rapid(path, encoding=encoding)
    from robotcal.programs.urscript import read_program as read_urscript

    return read_urscript(path, encoding=encoding)
