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
* A **lock file** (``.NAME.robotcal-lock`` beside the output, created with ``O_EXCL`` and holding the
  writer's pid) stops two processes writing one output; a lock whose pid is no longer alive is stale
  and taken over.

Every refusal is an :class:`robotcal.errors.InputError` (one line, exit status 2 in the CLI).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from robotcal.errors import InputError
from robotcal.io.atomic import atomic_directory, atomic_write_text

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


def _alive(pid: int) -> bool:
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


@contextmanager
def output_lock(out, *, option: str = "--out") -> Iterator[Path]:
    """Hold the lock file of the output ``out`` for the duration of the block.

    The lock is ``.NAME.robotcal-lock`` beside ``out``, created with ``O_CREAT | O_EXCL`` and holding
    this process's pid. A second writer gets an :class:`InputError` naming the holder's pid; a lock
    left by a process that no longer exists is stale and taken over.
    """
    resolved = _resolve(out)
    lock = _lock_path(resolved)
    created = [folder for folder in (lock.parent, *lock.parent.parents) if not folder.exists()]
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_empty(created)
        raise InputError(f"{option} {out}: cannot create folder {lock.parent}: {exc.strerror or exc}") from None
    try:
        with _held(lock, out, option):
            yield lock
    finally:
        _remove_empty(created)  # folders made for an output that was not written


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:  # deepest first
        with contextlib.suppress(OSError):
            folder.rmdir()


@contextmanager
def _held(lock: Path, out, option: str) -> Iterator[Path]:
    for _ in range(3):
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                pid = int(lock.read_text(encoding="ascii").strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid == os.getpid() or _alive(pid):
                raise InputError(
                    f"{option} {out}: another robotcal process (pid {pid}) is writing this output (lock {lock}); "
                    "wait for it to finish or choose another output"
                ) from None
            with contextlib.suppress(FileNotFoundError):
                lock.unlink()  # stale: its process is gone
            continue
        except OSError as exc:
            if exc.errno in (errno.EACCES, errno.EROFS, errno.EPERM):
                raise InputError(f"{option} {out}: cannot write in {lock.parent} ({exc.strerror})") from None
            raise InputError(f"{option} {out}: cannot create lock file {lock}: {exc.strerror or exc}") from None
        with os.fdopen(handle, "w", encoding="ascii") as stream:
            stream.write(f"{os.getpid()}\n")
        break
    else:
        raise InputError(f"{option} {out}: cannot take the lock {lock}; remove it if no robotcal process runs")
    try:
        yield lock
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()


def write_marker(folder, *, command: str, files: Iterable[str] | None = None) -> Path:
    """Write robotcal's marker :data:`MARKER` into ``folder``, listing the entries robotcal wrote there.

    ``files``: the top-level names robotcal writes into the folder (a run folder names them up front);
    default the folder's entries now (a result folder is complete when its marker is written).
    """
    import robotcal

    folder = Path(folder)
    names = sorted(entry.name for entry in folder.iterdir() if entry.name != MARKER) if files is None else sorted(files)
    document = {"written_by": "robotcal", "version": robotcal.__version__, "command": command, "files": names}
    return atomic_write_text(Path(folder) / MARKER, json.dumps(document) + "\n")


@contextmanager
def result_folder(out, *, inputs: Iterable = (), force: bool = False, command: str, option: str = "--out"):
    """Lock, check and atomically (re)write the result folder ``out``; yields the temporary folder.

    The block writes into the yielded hidden sibling; on success the marker is added and the folder is
    renamed into place, replacing the old one; on any exception (including Ctrl-C and SIGTERM) the
    temporary folder is removed and ``out`` is left as it was.
    """
    inputs = list(inputs)
    with output_lock(out, option=option):
        check_output_folder(out, inputs=inputs, force=force, option=option)
        with atomic_directory(out) as folder:
            yield folder
            write_marker(folder, command=command)


@contextmanager
def result_file(out, *, inputs: Iterable = (), force: bool = False, option: str = "--out"):
    """Lock and check the single-file output ``out`` for the block that writes it (atomically)."""
    inputs = list(inputs)
    with output_lock(out, option=option):
        check_output_file(out, inputs=inputs, force=force, option=option)
        yield Path(out)
