"""Atomic file writes: write a temporary file beside the target, then rename it into place."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from robotcal.errors import InputError

__all__ = ["atomic_write_text", "atomic_write_bytes", "atomic_directory"]


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one, never half."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {directory}: {exc.strerror}") from exc
    if path.is_dir():
        raise InputError(f"cannot write {path}: it is a folder")
    try:
        handle, temp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temp_name, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual mode
        os.replace(temp_name, path)
    except BaseException as exc:
        try:
            os.unlink(temp_name)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path, text: str) -> Path:
    """Atomic UTF-8 text write (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


@contextmanager
def atomic_directory(path, *, overwrite: bool = True) -> Iterator[Path]:
    """Build an output folder in a hidden sibling and rename it into place only on success.

    Yields the temporary folder to write into. If the block raises (an error, Ctrl-C), the temporary
    folder is removed and ``path`` is left exactly as it was: no half-written result directory.
    An existing ``path`` is replaced only after the new one is complete (``overwrite=False`` refuses).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"cannot write results to {path}: it is a file, not a folder")
    if path.exists() and not overwrite:
        raise InputError(f"{path} already exists; choose another --out or remove it")
    parent = path.parent if str(path.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        temp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".partial", dir=parent))
    except OSError as exc:
        raise InputError(f"cannot create folder {path}: {exc.strerror or exc}") from None
    backup = None
    try:
        yield temp
        os.chmod(temp, 0o777 & ~_umask())
        if path.exists():
            backup = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old", dir=parent))
            os.replace(path, backup / path.name)
            os.replace(temp, path)
        else:
            os.replace(temp, path)
    except BaseException:
        # an error or an interrupt between the two renames: put the old folder back
        if backup is not None and not path.exists() and (backup / path.name).exists():
            os.replace(backup / path.name, path)
        shutil.rmtree(temp, ignore_errors=True)
        if backup is not None:
            shutil.rmtree(backup, ignore_errors=True)
        raise
    if backup is not None:
        shutil.rmtree(backup, ignore_errors=True)
