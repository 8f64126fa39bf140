"""A full file system (issue 24): every command that writes ends with one line naming the path and saying what to
do (exit status 2), and leaves no lock, no temporary file, no partial folder, and the outputs that were there
untouched.

The full disk is simulated in this process (the commands run in-process through Typer's CliRunner), one way it
shows at a time and all at once: a new file's writes fail (its descriptor is /dev/full's, so the kernel itself
answers ENOSPC) for the lock or for the data, or ``link``, ``rename`` or ``mkdir`` fail with ENOSPC. A last test
mounts a real 64 KiB tmpfs, where it may (root); it is skipped elsewhere.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest
from typer.testing import CliRunner

from robotcal.cli import app
from robotcal.io.results.output import LOCK_SUFFIX, write_marker

pytestmark = pytest.mark.skipif(not Path("/dev/full").exists(), reason="simulates a full disk with /dev/full")

runner = CliRunner()
#: The ways a full disk shows, simulated one at a time; "full" is all of them at once.
POINTS = ("lock", "link", "write", "rename", "mkdir", "full")
ADVICE = "No space left on device; free some space and run again"


class FullDisk:
    """The folder ``root`` on a simulated full file system; :meth:`fill` arms the ways it fails."""

    def __init__(self, root: Path, monkeypatch):
        self.root = root.resolve()
        self.monkeypatch = monkeypatch
        self.hits: list[str] = []

    def _inside(self, path) -> bool:
        path = Path(os.path.abspath(os.fspath(path)))
        return path == self.root or self.root in path.parents

    def _full(self, point: str, path) -> OSError:
        self.hits.append(point)
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(path))

    def fill(self, point: str) -> None:
        points = set(POINTS) if point == "full" else {point}
        real_mkstemp, real_link, real_replace, real_rename, real_mkdir = (
            tempfile.mkstemp,
            os.link,
            os.replace,
            os.rename,
            os.mkdir,
        )

        def mkstemp(*args, **kwargs):
            handle, name = real_mkstemp(*args, **kwargs)
            kind = "lock" if LOCK_SUFFIX in Path(name).name else "write"
            if kind in points and self._inside(name):
                self.hits.append(kind)
                os.close(handle)
                handle = os.open("/dev/full", os.O_WRONLY)  # its writes fail with ENOSPC, from the kernel
            return handle, name

        def link(source, target, **kwargs):
            if "link" in points and self._inside(target):
                raise self._full("link", target)
            return real_link(source, target, **kwargs)

        def rename(real):
            def moved(source, target, **kwargs):
                if "rename" in points and self._inside(target):
                    raise self._full("rename", source)
                return real(source, target, **kwargs)

            return moved

        def mkdir(path, *args, **kwargs):
            if "mkdir" in points and self._inside(path) and not os.path.lexists(path):
                raise self._full("mkdir", path)
            return real_mkdir(path, *args, **kwargs)

        self.monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
        self.monkeypatch.setattr(os, "link", link)
        self.monkeypatch.setattr(os, "replace", rename(real_replace))
        self.monkeypatch.setattr(os, "rename", rename(real_rename))
        self.monkeypatch.setattr(os, "mkdir", mkdir)

    def empty(self) -> None:
        self.monkeypatch.undo()


def _tree(folder: Path) -> dict[str, bytes | None]:
    """Every entry under ``folder``: file -> bytes, folder -> None."""
    return {
        path.relative_to(folder).as_posix(): None if path.is_dir() else path.read_bytes()
        for path in sorted(folder.rglob("*"))
    }


@pytest.fixture(scope="module")
def previous(tmp_path_factory) -> Path:
    """Good outputs of each command, made once (copied into each test's disk as "the outputs that were there")."""
    folder = tmp_path_factory.mktemp("previous")
    for arguments in (
        ["simulate", "thesis-noise-free", "--out", folder / "capture.csv"],
        ["identify", folder / "capture.csv", "-s", "thesis-noise-free", "--out", folder / "params.json"],
        ["export", "--nominal", "kuka-kr5-sixx-r650", "-f", "urdf", "--out", folder / "robot.urdf"],
        ["uncertainty", "thesis-noise-free", "-n", "200", "--save-draws", "--out", folder / "mc"],
        ["iso9283-plan", "-s", "kr5-demo", "--cycles", "2", "--out", folder / "iso_poses.csv"],
        ["simulate", "kr5-demo", "--poses", folder / "iso_poses.csv", "--out", folder / "iso_capture.csv"],
    ):
        result = runner.invoke(app, list(map(str, arguments)))
        assert result.exit_code == 0, result.output
    run = folder / "run"  # a run folder of robotcal's (its marker and record): `run` may replace it
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"status": "done"}))
    write_marker(run, command="robotcal run", files=["run.json"])
    (folder / "report_run").mkdir()  # a run folder with its capture only: `report` renders what there is
    shutil.copy2(folder / "capture.csv", folder / "report_run" / "capture.csv")
    (folder / "poses.csv").write_text("q1,q2,q3,q4,q5,q6\n0,10,20,0,30,0\n")
    (folder / "export.csv").write_text("Point ID,X [mm],Y [mm],Z [mm]\nP1,1234.5,470.6,750.2\nP2,1250,-487.5,800\n")
    (folder / "log.csv").write_text("name,q1,q2,q3,q4,q5,q6\nP1,10,-20,30,0,45,0\nP2,11.5,-20,30,0,45,0\n")
    scenario = (Path(__file__).parents[2] / "src/robotcal/data/scenarios/thesis-noise-free.toml").read_text()
    # its plan within the joint limits (J5 swept 100 deg instead of 200), as `program` needs
    feasible = scenario.replace(
        "sweep_deg = [45.0, 80.0, 100.0, 50.0, 200.0, 300.0]", "sweep_deg = [45.0, 80.0, 100.0, 50.0, 100.0, 300.0]"
    )
    assert feasible != scenario
    (folder / "feasible.toml").write_text(feasible)
    return folder


#: Each command writing into the disk (``{disk}``, the output; ``{inputs}``, a folder outside it).
COMMANDS = {
    "simulate": (["simulate", "thesis-noise-free", "--out", "{disk}/capture.csv"], "capture.csv"),
    "identify": (
        ["identify", "{inputs}/capture.csv", "-s", "thesis-noise-free", "--out", "{disk}/params.json"],
        "params.json",
    ),
    "export": (["export", "--nominal", "kuka-kr5-sixx-r650", "-f", "urdf", "--out", "{disk}/robot.urdf"], "robot.urdf"),
    "uncertainty": (["uncertainty", "thesis-noise-free", "-n", "200", "--out", "{disk}/mc"], "mc"),
    "run": (["run", "kr5-demo", "--draws", "200", "--workspace", "5", "--workers", "1", "--out", "{disk}/run"], "run"),
}


def _leftovers(folder: Path) -> list[str]:
    return sorted(
        p.name
        for p in folder.rglob("*")
        if p.name.endswith((".partial", ".old", LOCK_SUFFIX, ".tmp")) or "robotcal-" in p.name
    )


def _one_error_line(result, disk: Path) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and not isinstance(result.exception, OSError)
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    assert str(disk) in errors[0] and ADVICE in errors[0], errors[0]
    assert ".partial" not in errors[0] and ".tmp" not in errors[0], errors[0]  # the output named, not a temporary
    return errors[0]


@pytest.mark.parametrize("existing", [False, True], ids=["new", "existing"])
@pytest.mark.parametrize("point", POINTS)
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_full_disk_is_one_line_and_leaves_everything_as_it_was(
    tmp_path, monkeypatch, previous, command, point, existing
):
    arguments, output = COMMANDS[command]
    disk = tmp_path / "disk"
    disk.mkdir()
    if existing:
        source = previous / output
        (shutil.copytree if source.is_dir() else shutil.copy2)(source, disk / output)
    before = _tree(disk)
    full = FullDisk(disk, monkeypatch)
    full.fill(point)
    result = runner.invoke(app, [a.format(disk=disk, inputs=previous) for a in arguments])
    full.empty()
    assert _leftovers(tmp_path) == [], result.output
    if command == "run" and existing and _tree(disk) != before:
        # `run` rewrites its folder stage by stage once it has started (docs/results.md): then run.json records
        # the failure, the stage that failed left nothing
        record = json.loads((disk / "run" / "run.json").read_text())
        assert record["status"] == "failed" and ADVICE in record["error"], record
        _one_error_line(result, disk)
        return
    if result.exit_code == 0:  # this way of failing is not met by this command (e.g. no folder to make)
        assert not full.hits and point == "mkdir" and command in ("simulate", "identify", "export"), result.output
        return
    assert full.hits
    _one_error_line(result, disk)
    assert _tree(disk) == before  # the outputs that were there untouched, nothing new (no empty folder either)


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A real, completely full 64 KiB tmpfs at ``tmp_path / "disk"`` (root only; skipped where it cannot be mounted)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        handle = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT)
        try:
            while os.write(handle, b"\0" * 4096):  # fill it up
                pass
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
        finally:
            os.close(handle)
        yield disk
    finally:
        if subprocess.run(["umount", str(disk)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(disk)], capture_output=True)


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_real_full_file_system(tiny_tmpfs, previous, command):
    arguments, _ = COMMANDS[command]
    result = runner.invoke(app, [a.format(disk=tiny_tmpfs, inputs=previous) for a in arguments])
    _one_error_line(result, tiny_tmpfs)
    assert sorted(p.name for p in tiny_tmpfs.iterdir()) == ["filler"]  # no lock (not even empty), nothing else


#: The other commands that write, each into the disk (``{disk}``) from inputs outside it (``{inputs}``).
OTHER_COMMANDS = {
    "refine": ["refine", "{inputs}/capture.csv", "-s", "thesis-noise-free", "--out", "{disk}/refined.json"],
    "evaluate": [
        "evaluate",
        "-s",
        "thesis-noise-free",
        "-p",
        "{inputs}/params.json",
        "-c",
        "{inputs}/capture.csv",
        "--out",
        "{disk}/evaluation",
    ],
    "joints": ["joints", "{inputs}/capture.csv", "-s", "thesis-noise-free", "--no-backlash", "--out", "{disk}/joints"],
    "uncertainty --capture": [
        "uncertainty",
        "thesis-noise-free",
        "--capture",
        "{inputs}/capture.csv",
        "--params",
        "{inputs}/params.json",
        "-n",
        "100",
        "--out",
        "{disk}/mc",
    ],
    "tcp": ["tcp", "--run", "{inputs}/mc", "--pose", "0,10,20,0,30,0", "--out", "{disk}/tcp"],
    "report": ["report", "{inputs}/report_run", "--out", "{disk}/report.html"],
    "import": ["import", "{inputs}/export.csv", "--joints", "{inputs}/log.csv", "--out", "{disk}/imported.csv"],
    "iso9283": ["iso9283", "{inputs}/iso_capture.csv", "-s", "kr5-demo", "--out", "{disk}/iso.csv"],
    "iso9283-plan": [
        "iso9283-plan",
        "-s",
        "kr5-demo",
        "--cycles",
        "2",
        "--program",
        "krl",
        "--out",
        "{disk}/poses.csv",
    ],
    "predict": ["predict", "{inputs}/params.json", "--poses", "{inputs}/poses.csv", "--out", "{disk}/predicted.csv"],
    "program": ["program", "{inputs}/feasible.toml", "--out", "{disk}/prog.src"],
    "plan check": ["plan", "check", "kr5-demo", "--out", "{disk}/check"],
    "sensitivity": [
        "sensitivity",
        "thesis-noise-free",
        "--vary",
        "capture.points=10,20",
        "-n",
        "50",
        "--out",
        "{disk}/s",
    ],
    "export json": ["export", "{inputs}/params.json", "--out", "{disk}/params.json"],
}


@pytest.mark.filterwarnings("ignore::robotcal.errors.RobotcalWarning")  # e.g. J6 held: the inputs' own, expected
@pytest.mark.parametrize("point", ["full", "write"])
@pytest.mark.parametrize("command", list(OTHER_COMMANDS))
def test_every_command_that_writes_fails_on_a_full_disk_in_one_line(tmp_path, monkeypatch, previous, command, point):
    # "full": nothing fits (the lock is the first write); "write": the lock fits, the results do not
    disk = tmp_path / "disk"
    disk.mkdir()
    full = FullDisk(disk, monkeypatch)
    full.fill(point)
    result = runner.invoke(app, [a.format(disk=disk, inputs=previous) for a in OTHER_COMMANDS[command]])
    full.empty()
    assert full.hits, (result.exit_code, repr(result.exception), result.output)
    _one_error_line(result, disk)
    assert _tree(disk) == {} and _leftovers(tmp_path) == []
