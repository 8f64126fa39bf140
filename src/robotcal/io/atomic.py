"""Atomic file writes: write a temporary file beside the target, then rename it into place.

Every temporary entry robotcal makes is named ``.NAME.robotcal-PID-RANDOM.KIND``: ``NAME`` the output it
becomes, ``PID`` the writing process, ``KIND`` one of ``tmp`` (a file being written), ``partial`` (a result
folder being built) and ``old`` (the previous folder, moved aside for the moment of the swap). A process
that ends normally, by an error or by a signal it can catch removes its own; one killed outright (SIGKILL,
power loss) cannot, and :func:`remove_stale_temporaries` recognises them by that name and by their writer
being gone, so the next robotcal command writing the same output removes them (never anything else).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from robotcal.errors import InputError

__all__ = [
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_directory",
    "describe_os_error",
    "final_path",
    "is_process_running",
    "remove_stale_temporaries",
    "temporary_prefix",
]

#: The name of a temporary entry of robotcal: ``.NAME.robotcal-PID-RANDOM.KIND`` (module docstring).
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.robotcal-(?P<pid>[0-9]{1,10})-[A-Za-z0-9_]{1,32}\.(?P<kind>tmp|partial|old)")

#: What to do after the errors a full, read-only or forbidden place gives (:func:`describe_os_error`).
_ADVICE = {
    errno.ENOSPC: "free some space and run again",
    errno.EDQUOT: "free some space (or ask for a larger quota) and run again",
    errno.EFBIG: "choose a file system that takes larger files",
    errno.EROFS: "choose a folder on a writable file system",
    errno.EACCES: "choose a folder you may write in",
    errno.EPERM: "choose a folder you may write in",
}


def describe_os_error(exc: OSError) -> str:
    """The reason of ``exc`` for a one-line message, with what to do where that is known
    ("No space left on device; free some space and run again")."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    advice = None if exc.errno is None else _ADVICE.get(exc.errno)
    return f"{reason}; {advice}" if advice else reason


def temporary_prefix(name: str) -> str:
    """The start of the name of a temporary entry that becomes ``name``: ``.NAME.robotcal-PID-``."""
    return f".{name}.robotcal-{os.getpid()}-"


def final_path(path) -> Path:
    """``path`` as the user knows it: every temporary entry in it (``.NAME.robotcal-PID-X.partial``, ``.tmp``,
    ``.old``) named as the output it stands for (``NAME``), so that a message names the output, not a hidden
    temporary."""
    path = Path(path)
    parts = [match["name"] if (match := _TEMPORARY.fullmatch(part)) else part for part in path.parts]
    return Path(*parts) if parts else path


def is_process_running(pid: int) -> bool:
    """Whether a process ``pid`` exists on this machine (one we may not signal exists too)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def remove_stale_temporaries(folder: str | os.PathLike[str], *, names: Iterable[str] | None = None, recursive: bool = False) -> list[Path]:
    """Remove the temporary entries robotcal left in ``folder`` when it was killed; returns those removed.

    An entry is removed only when its name is robotcal's temporary name (module docstring), for one of
    ``names`` (default: any), and its writer (the pid in the name) is not this process and no longer
    runs. A stale ``.old`` folder whose output is missing (killed between the two renames of
    :func:`atomic_directory`) is first put back in place: the previous result is restored, not lost.
    ``recursive``: also look in the sub-folders (never following links). Errors are ignored: cleaning up
    is a courtesy, the command's own writes report their errors.
    """
    folder = Path(folder)
    wanted = None if names is None else set(names)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = _TEMPORARY.fullmatch(entry.name)
        if match is None:
            if recursive and entry.is_dir(follow_symlinks=False):
                removed += remove_stale_temporaries(entry.path, recursive=True)
            continue
        pid = int(match["pid"])
        if (wanted is not None and match["name"] not in wanted) or pid == os.getpid() or is_process_running(pid):
            continue
        path = Path(entry.path)
        with contextlib.suppress(OSError):
            if match["kind"] == "old" and entry.is_dir(follow_symlinks=False):
                target = folder / match["name"]
                kept = path / match["name"]
                if not target.exists() and not target.is_symlink() and kept.is_dir() and not kept.is_symlink():
                    os.replace(kept, target)
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
            removed.append(path)
    return removed


def _cannot_write(path: Path, exc: OSError) -> InputError:
    return InputError(f"cannot write {final_path(path)}: {describe_os_error(exc)}")


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one, never half.

    The bytes go to a temporary file beside ``path`` (:func:`temporary_prefix`), flushed to the disk and
    renamed over ``path``; on any failure (a full disk, an interrupt) the temporary file is removed and
    ``path`` is left as it was. An :class:`OSError` becomes an :class:`InputError` naming ``path``.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {final_path(directory)}: {describe_os_error(exc)}") from None
    if path.is_dir():
        raise InputError(f"cannot write {final_path(path)}: it is a folder")
    try:
        handle, temp_name = tempfile.mkstemp(prefix=temporary_prefix(path.name), suffix=".tmp", dir=directory)
    except OSError as exc:
        raise _cannot_write(path, exc) from None
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temp_name, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual mode
        os.replace(temp_name, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(temp_name)
        if isinstance(exc, OSError):
            raise _cannot_write(path, exc) from None
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

    Yields the temporary folder to write into (``.NAME.robotcal-PID-X.partial``). If the block raises (an
    error, Ctrl-C, a full disk), the temporary folder is removed and ``path`` is left exactly as it was: no
    half-written result directory. An existing ``path`` is replaced only after the new one is complete
    (``overwrite=False`` refuses). An :class:`OSError` naming a file of the temporary folder names it as
    it would have been in ``path`` (:func:`final_path`).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"cannot write results to {path}: it is a file, not a folder")
    if path.exists() and not overwrite:
        raise InputError(f"{path} already exists; choose another --out or remove it")
    parent = path.parent if str(path.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        temp = Path(tempfile.mkdtemp(prefix=temporary_prefix(path.name), suffix=".partial", dir=parent))
    except OSError as exc:
        raise InputError(f"cannot create folder {final_path(path)}: {describe_os_error(exc)}") from None
    backup = None
    try:
        yield temp
        os.chmod(temp, 0o777 & ~_umask())
        if path.exists():
            backup = Path(tempfile.mkdtemp(prefix=temporary_prefix(path.name), suffix=".old", dir=parent))
            os.replace(path, backup / path.name)
            os.replace(temp, path)
        else:
            os.replace(temp, path)
    except BaseException as exc:
        # an error or an interrupt between the two renames: put the old folder back
        if backup is not None and not path.exists() and (backup / path.name).exists():
            os.replace(backup / path.name, path)
        shutil.rmtree(temp, ignore_errors=True)
        if backup is not None:
            shutil.rmtree(backup, ignore_errors=True)
        if isinstance(exc, OSError) and exc.filename is not None:
            exc.filename = str(final_path(exc.filename))  # the file as the user knows it
        raise
    if backup is not None:
        shutil.rmtree(backup, ignore_errors=True)
