"""The output-safety policy of every command that writes: what robotcal may replace, and how.

One policy, used by ``simulate``, ``identify``, ``refine``, ``evaluate``, ``joints``, ``uncertainty``,
``tcp``, ``run``, ``demo`` and ``report`` (docs/cli.md, "Output safety"):

* A **result folder** written by robotcal carries a marker file :data:`MARKER` (``.robotcal``, JSON
  naming the command and version). robotcal replaces only a folder that carries the marker, and only
  atomically (built in a hidden sibling, renamed into place; :func:`robotcal.io.atomic.atomic_directory`).
  A missing or empty folder is fine. Any other existing folder (a user's folder with files) is
  refused unless ``--force``.
* A **single-file output** replaces an existing file only when robotcal recognises it as its own
  (:func:`is_robotcal_file`: a JSON with robotcal's keys, an HTML report with robotcal's generator
  tag, a capture CSV in robotcal's exact layout, a text file whose first comment carries
  :data:`SIGNATURE` (URDF, UR YAML of ``robotcal export``), a DH/MDH table of ``robotcal export``),
  else only with ``--force``.
* **Never**, even with ``--force``: the file system root, the home folder, the current folder or one
  of its parents, an output that *is* an input of the same command, a folder output that *contains*
  an input.
* A **lock file** (``.NAME.robotcal-lock`` beside the output, created whole and atomically, holding the
  writer's pid and host) stops two processes writing one output; a lock whose process no longer runs is
  stale and taken over, and the temporaries a killed robotcal left for that output (``.partial``
  folders, ``.tmp`` files: :mod:`robotcal.io.atomic`) are removed then. A failure, a full disk
  included, leaves no lock and no temporary behind.

Every refusal is an :class:`robotcal.errors.InputError` (one line, exit status 2 in the CLI).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import socket
import tempfile
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from robotcal.errors import InputError, check_interrupt
from robotcal.io.atomic import (
    atomic_directory,
    atomic_write_text,
    describe_os_error,
    is_process_running,
    remove_stale_temporaries,
    temporary_prefix,
)

__all__ = [
    "MARKER",
    "SIGNATURE",
    "LOCK_SUFFIX",
    "check_output_folder",
    "check_output_file",
    "existing_inputs",
    "foreign_entries",
    "is_robotcal_folder",
    "is_robotcal_file",
    "output_lock",
    "result_file",
    "result_folder",
    "write_marker",
]

#: Marker file of a result folder written by robotcal.
MARKER = ".robotcal"
#: Suffix of the lock file beside an output being written.
LOCK_SUFFIX = ".robotcal-lock"

#: The capture header (docs/scenario.md), with its optional ``target`` and ``u95_mm`` columns.
_CAPTURE_HEADER = re.compile(r"^circle,direction,(q\d+,)+x,y,z(,target)?(,u95_mm)?$")
_CAPTURE_NUMBER = re.compile(r"^-?\d+\.\d{12}$")  # robotcal writes every reading and coordinate with 12 decimals
_GENERATOR = '<meta name="generator" content="robotcal'
#: The words of the first comment of a text file robotcal writes (``<!-- written by robotcal: ... -->``,
#: ``# written by robotcal: ...``), by which :func:`is_robotcal_file` recognises it.
SIGNATURE = "written by robotcal"
_COMMENT_SIGNATURE = re.compile(r"^(?:<\?xml[^>]*\?>\s*)?(?:<!--|#)\s*" + re.escape(SIGNATURE) + r"\b")
#: ``robotcal export --format dh|mdh``: the CSV header and first cells, and the Markdown title.
_TABLE_HEADER = re.compile(
    r"^joint,(?:theta_deg,d_mm,a_mm,alpha_deg|alpha_prev_deg,a_prev_mm,theta_deg,d_mm),reading_sign,reading_offset_deg$"
)
_TABLE_ROW = re.compile(r"^(?:J\d+|flange)(?:,[-+0-9.e]+|,inf|,-inf){6}$")
_TABLE_TITLE = re.compile(r"^# (?:Modified )?DH table of .+ \[mm, deg\]")


def _resolve(path) -> Path:
    return Path(os.path.abspath(os.path.expanduser(str(path)))).resolve(strict=False)


def existing_inputs(*paths) -> list[Path]:
    """The resolved paths among ``paths`` that exist (strings that name a built-in are skipped)."""
    found = []
    for path in paths:
        if path is None:
            continue
        candidate = Path(str(path))
        if candidate.exists():
            found.append(_resolve(candidate))
    return found


def _inside(child: Path, parent: Path) -> bool:
    return child == parent or parent in child.parents


def _same(a: Path, b: Path) -> bool:
    if a == b:
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _check_location(path: Path, option: str) -> Path:
    """Refuse the places no output may ever replace; returns the resolved path."""
    resolved = _resolve(path)
    if resolved == Path(resolved.anchor):
        raise InputError(f"{option} {path}: refusing to write over the file system root")
    home = _resolve(Path.home())
    if resolved == home or _inside(home, resolved):
        raise InputError(f"{option} {path}: refusing to write over the home folder or one of its parents")
    try:
        cwd = _resolve(Path.cwd())
    except OSError:  # the current folder was removed: nothing to protect there
        cwd = None
    if cwd is not None and _inside(cwd, resolved):
        raise InputError(f"{option} {path}: refusing to write over the current folder or one of its parents")
    parent = resolved.parent
    existing = parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{option} {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: cannot write in {existing} (permission denied or read-only)")
    return resolved


def _marker(path) -> dict | None:
    """The marker document of the folder ``path``, or None when it has no valid one."""
    marker = Path(path) / MARKER
    if not marker.is_file() or marker.is_symlink():
        return None
    try:
        data = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return data if isinstance(data, dict) and data.get("written_by") == "robotcal" else None


def is_robotcal_folder(path) -> bool:
    """Whether ``path`` is a folder carrying robotcal's marker file :data:`MARKER`."""
    return _marker(path) is not None


def foreign_entries(path) -> list[str]:
    """Entries of the robotcal folder ``path`` that robotcal did not write: not in its marker's ``files``.

    A marker without a ``files`` list (written before the list existed) vouches for the whole folder.
    """
    data = _marker(path)
    if data is None or not isinstance(data.get("files"), list):
        return []
    written = {str(name) for name in data["files"]} | {MARKER}
    return sorted(entry.name for entry in Path(path).iterdir() if entry.name not in written)


def is_robotcal_file(path) -> bool:
    """Whether the file ``path`` looks written by robotcal (so that it may be replaced without ``--force``).

    JSON: an object with robotcal's parameter keys (``robot``, ``units``, ``joints``, ``provenance``)
    or a ``format`` key starting with ``robotcal``; HTML: robotcal's ``<meta name="generator">``;
    CSV: the capture header and every value of the first rows with robotcal's 12 decimals, the
    header and rows of a DH/MDH table of ``robotcal export``, or a first comment carrying :data:`SIGNATURE`
    (a pose CSV of ``robotcal compensate``, a table with a note); Markdown: the title of such a table;
    any other text file: a first comment (after an XML declaration) carrying :data:`SIGNATURE`
    (the URDF and UR YAML of ``robotcal export``).
    """
    path = Path(path)
    try:
        with path.open("rb") as stream:
            head = stream.read(65536)
    except OSError:
        return False
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return False
    suffix = path.suffix.lower()
    if suffix in (".html", ".htm"):
        return _GENERATOR in text
    if suffix == ".json":
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            return False
        if not isinstance(data, dict):
            return False
        if str(data.get("format", "")).startswith("robotcal"):
            return True
        return {"robot", "units", "joints", "provenance"} <= set(data)
    if suffix == ".csv":
        lines = text.splitlines()
        if lines and _COMMENT_SIGNATURE.match(lines[0]):  # a table or pose CSV whose first comment signs it
            return True
        if lines and _TABLE_HEADER.match(lines[0].strip()):
            rows = [line.strip() for line in lines[1:50] if line.strip()]
            return bool(rows) and all(_TABLE_ROW.match(line) for line in rows)
        if not lines or not _CAPTURE_HEADER.match(lines[0].strip()):
            return False
        header = lines[0].strip().split(",")
        numbers = slice(2, header.index("z") + 1)  # the readings and coordinates (the 12-decimal columns)
        rows = [line for line in lines[1:50] if line.strip()]
        for line in rows:
            cells = line.split(",")
            if len(cells) != len(header) or not all(_CAPTURE_NUMBER.match(cell) for cell in cells[numbers]):
                return False
        return True
    if suffix in (".md", ".markdown"):
        return bool(_TABLE_TITLE.match(text))
    return bool(_COMMENT_SIGNATURE.match(text))


def check_output_folder(
    out, *, inputs: Iterable = (), force: bool = False, option: str = "--out", keeps_other_files: bool = False
) -> Path:
    """Check that the result folder ``out`` may be (re)written; returns its resolved path.

    Raises :class:`InputError` when ``out`` is a forbidden location, a file, an input of the command or
    a folder containing one (never allowed), an existing non-empty folder without robotcal's marker, or
    a robotcal folder holding files robotcal did not write (both allowed with ``force``; the second
    also for a command that ``keeps_other_files``, as ``run`` does: it replaces only its own entries).
    """
    resolved = _check_location(out, option)
    for source in inputs:
        source = _resolve(source)
        if _inside(source, resolved) or _same(source, resolved):
            raise InputError(
                f"{option} {out}: refusing to replace a folder that holds an input of this command ({source}); "
                "choose another output folder"
            )
    if resolved.exists() or resolved.is_symlink():
        if not resolved.is_dir():
            raise InputError(f"{option} {out}: exists and is not a folder; choose another output folder")
        if not force and any(resolved.iterdir()) and not is_robotcal_folder(resolved):
            raise InputError(
                f"{option} {out}: the folder exists and was not written by robotcal (no {MARKER} marker); "
                "choose another output folder, empty it, or pass --force to replace it"
            )
        foreign = [] if force or keeps_other_files else foreign_entries(resolved)
        if foreign:
            shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
            raise InputError(
                f"{option} {out}: the folder holds files robotcal did not write ({shown}) and would be replaced "
                "whole; move them, choose another output folder, or pass --force"
            )
    return resolved


def check_output_file(out, *, inputs: Iterable = (), force: bool = False, option: str = "--out") -> Path:
    """Check that the single-file output ``out`` may be (re)written; returns its resolved path.

    Never an input of the command (even with ``force``); an existing file must look written by
    robotcal (:func:`is_robotcal_file`) unless ``force``.
    """
    resolved = _check_location(out, option)
    for source in inputs:
        source = _resolve(source)
        if _same(source, resolved):
            raise InputError(
                f"{option} {out}: refusing to overwrite an input of this command ({source}); choose another file"
            )
    if resolved.is_dir():
        raise InputError(f"{option} {out}: is a folder; give a file name")
    if resolved.exists() and not force and not is_robotcal_file(resolved):
        raise InputError(
            f"{option} {out}: the file exists and was not written by robotcal; choose another file or pass --force "
            "to replace it"
        )
    return resolved


def _lock_path(resolved: Path) -> Path:
    return resolved.parent / f".{resolved.name}{LOCK_SUFFIX}"


#: Seconds an empty lock file may be young and still being written (on a file system without hard links a
#: lock is created empty and then written; an older empty lock was left by a process killed in between).
_LOCK_BEING_WRITTEN_S = 2.0
#: Errors of :func:`os.link` on file systems without hard links (FAT, exFAT, some network shares).
_NO_HARD_LINKS = frozenset({errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.ENOSYS})


def _lock_text() -> bytes:
    """The lock's content: this process's pid, its host, and a token that tells this lock from any other."""
    return f"{os.getpid()}\n{socket.gethostname()}\n{secrets.token_hex(8)}\n".encode("ascii", "replace")


def _create_lock(lock: Path, data: bytes) -> None:
    """Create ``lock`` holding ``data`` (:func:`_lock_text`), whole or not at all; :class:`FileExistsError` if it
    exists.

    The content is written to a temporary file first and hard-linked to the lock's name (``link`` fails if the
    name exists, atomically): no other process ever sees the lock empty or half written, and a full disk leaves
    nothing. Where the file system has no hard links, the lock is created with ``O_EXCL`` and then written; a
    failed write removes it.
    """
    handle, temp = tempfile.mkstemp(prefix=temporary_prefix(lock.name), suffix=".tmp", dir=lock.parent)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
        os.chmod(temp, 0o644)  # other users' robotcal must be able to read the holder's pid
        try:
            os.link(temp, lock)
        except OSError as exc:
            if exc.errno not in _NO_HARD_LINKS:
                raise
            _create_lock_in_place(lock, data)
    finally:
        with contextlib.suppress(OSError):
            os.unlink(temp)


def _create_lock_in_place(lock: Path, data: bytes) -> None:
    handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    try:
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(handle, view) :]
        finally:
            os.close(handle)
    except BaseException:
        with contextlib.suppress(OSError):
            lock.unlink()
        raise


def _holder(content: bytes) -> tuple[int, str | None]:
    """The pid (0 when unreadable) and host (None: not recorded, as by an older robotcal: this host) of a lock."""
    lines = content.decode("ascii", "replace").split("\n")
    try:
        pid = int(lines[0].strip())
    except ValueError:
        pid = 0
    host = lines[1].strip() if len(lines) > 1 and lines[1].strip() else None
    return pid, host


def _take_over(lock: Path, seen: bytes) -> None:
    """Remove the stale lock ``lock`` whose content was ``seen``, unless another process replaced it meanwhile.

    The lock is renamed aside first and its content compared: when two processes find one stale lock at once,
    the second never removes the lock the first has just taken (it finds it changed and puts it back).
    """
    aside = lock.parent / f"{temporary_prefix(lock.name)}{secrets.token_hex(4)}.tmp"
    try:
        os.rename(lock, aside)
    except FileNotFoundError:
        return  # released by its owner or taken over by another process: look again
    try:
        if aside.read_bytes() != seen:  # a live lock taken since the stale one was read: put it back
            with contextlib.suppress(OSError):
                os.link(aside, lock)
    finally:
        with contextlib.suppress(OSError):
            aside.unlink()


def _acquire(lock: Path, out, option: str, data: bytes) -> None:
    """Take the lock file ``lock`` of the output ``out`` for this process (its content ``data``), or raise
    :class:`InputError`."""
    for _ in range(100):  # each turn takes the lock, refuses, or follows another process's move
        try:
            _create_lock(lock, data)
            return
        except FileExistsError:
            pass
        except OSError as exc:
            raise InputError(f"{option} {out}: cannot create the lock file {lock}: {describe_os_error(exc)}") from None
        try:
            content = lock.read_bytes()
        except FileNotFoundError:
            continue  # released meanwhile
        except OSError as exc:
            raise InputError(
                f"{option} {out}: cannot read the lock file {lock} ({describe_os_error(exc)}); remove it if no "
                "robotcal process writes this output"
            ) from None
        pid, host = _holder(content)
        here = socket.gethostname()
        if pid <= 0:  # empty: being written where there are no hard links, or left by a process killed then
            with contextlib.suppress(OSError):
                if time.time() - lock.stat().st_mtime < _LOCK_BEING_WRITTEN_S:
                    time.sleep(0.05)
                    continue
        elif (host is not None and host != here) or pid == os.getpid() or is_process_running(pid):
            where = "" if host is None or host == here else f" on host {host}"
            raise InputError(
                f"{option} {out}: in use by another robotcal process (pid {pid}){where}, lock {lock}; wait for it to "
                "finish or choose another output (remove the lock only if no robotcal process writes this output)"
            )
        try:
            _take_over(lock, content)  # stale: its process is gone
        except OSError as exc:
            raise InputError(
                f"{option} {out}: cannot remove the stale lock file {lock}: {describe_os_error(exc)}"
            ) from None
    raise InputError(
        f"{option} {out}: cannot take the lock {lock}; remove it if no robotcal process writes this output"
    )


@contextmanager
def output_lock(out, *, option: str = "--out") -> Iterator[Path]:
    """Hold the lock file of the output ``out`` for the duration of the block.

    The lock is ``.NAME.robotcal-lock`` beside ``out``, created whole (never empty, nothing left when its
    creation fails, e.g. on a full disk) and holding this process's pid and host. A second writer gets an
    :class:`InputError` naming the holder's pid; a lock left by a process that no longer runs on this host is
    stale and taken over. Once the lock is held, the temporaries a killed robotcal process left for ``out``
    (beside it, and inside it when it is a robotcal folder) are removed
    (:func:`~robotcal.io.atomic.remove_stale_temporaries`). The lock is removed when the block ends, however it
    ends (an interrupt as the lock is being taken included: this process's lock is recognised by its content), and
    so are the folders made for ``out`` (``out`` included) that the block left empty.
    """
    resolved = _resolve(out)
    lock = _lock_path(resolved)
    created = [folder for folder in (lock.parent, *lock.parent.parents) if not folder.exists()]
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_empty(created)
        raise InputError(f"{option} {out}: cannot create folder {lock.parent}: {describe_os_error(exc)}") from None
    data = _lock_text()
    existed = True
    try:
        try:
            _acquire(lock, out, option, data)
            remove_stale_temporaries(resolved.parent, names=(resolved.name, lock.name))
            if resolved.is_dir() and not resolved.is_symlink() and is_robotcal_folder(resolved):
                remove_stale_temporaries(resolved, recursive=True)
            existed = resolved.exists() or resolved.is_symlink()
            yield lock
        finally:
            if not existed:
                _remove_empty([resolved])  # a folder made for the output, left empty (still under the lock)
            _release(lock, data)
    finally:
        _remove_empty(created)  # folders made for the lock, left empty


def _release(lock: Path, data: bytes) -> None:
    """Remove ``lock`` if it is this process's (its content is ``data``): also when an interrupt came as it was taken,
    never another process's lock."""
    with contextlib.suppress(OSError):
        if lock.read_bytes() == data:
            lock.unlink()


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:  # deepest first
        with contextlib.suppress(OSError):
            folder.rmdir()


def write_marker(folder, *, command: str, files: Iterable[str] | None = None) -> Path:
    """Write robotcal's marker :data:`MARKER` into ``folder``, listing the entries robotcal wrote there.

    ``files``: the top-level names robotcal writes into the folder (a run folder names them up front);
    default the folder's entries now (a result folder is complete when its marker is written).
    """
    from robotcal._version import installed_version

    folder = Path(folder)
    names = sorted(entry.name for entry in folder.iterdir() if entry.name != MARKER) if files is None else sorted(files)
    document = {"written_by": "robotcal", "version": installed_version(), "command": command, "files": names}
    return atomic_write_text(Path(folder) / MARKER, json.dumps(document) + "\n")


@contextmanager
def result_folder(out, *, inputs: Iterable = (), force: bool = False, command: str, option: str = "--out"):
    """Lock, check and atomically (re)write the result folder ``out``; yields the temporary folder.

    The block writes into the yielded hidden sibling; on success the marker is added and the folder is
    renamed into place, replacing the old one; on any exception (including Ctrl-C and SIGTERM) the
    temporary folder is removed and ``out`` is left as it was. So is it after an interrupt whose exception Python
    dropped (:func:`robotcal.errors.check_interrupt`, raised before the rename): an interrupted command keeps no
    result.
    """
    inputs = list(inputs)
    with output_lock(out, option=option):
        check_output_folder(out, inputs=inputs, force=force, option=option)
        with atomic_directory(out) as folder:
            yield folder
            write_marker(folder, command=command)
            check_interrupt()


@contextmanager
def result_file(out, *, inputs: Iterable = (), force: bool = False, option: str = "--out"):
    """Lock and check the single-file output ``out`` for the block that writes it (atomically)."""
    inputs = list(inputs)
    with output_lock(out, option=option):
        check_output_file(out, inputs=inputs, force=force, option=option)
        yield Path(out)
