"""The output lock and robotcal's temporary entries (robotcal.io.results.output, robotcal.io.atomic): a lock is created
whole or not at all, records its pid and host, refuses while its process runs and is taken over once it is gone;
the temporaries a killed robotcal left are recognised by name and writer and removed by the next writer of the
same output, and nothing else is."""

from __future__ import annotations

import errno
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from robotcal.errors import InputError
from robotcal.io.atomic import (
    atomic_directory,
    atomic_write_text,
    describe_os_error,
    final_path,
    remove_stale_temporaries,
    temporary_prefix,
)
from robotcal.io.results.output import LOCK_SUFFIX, output_lock, result_folder, write_marker

needs_dev_full = pytest.mark.skipif(not Path("/dev/full").exists(), reason="simulates a full disk with /dev/full")


@pytest.fixture(scope="module")
def dead_pid() -> int:
    """The pid of a process that has ended (a child that exited and was reaped)."""
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(child.stdout)


@pytest.fixture
def live_pid():
    """The pid of a running process other than this one."""
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    yield child.pid
    child.kill()
    child.wait()


def _names(folder: Path) -> list[str]:
    return sorted(entry.name for entry in folder.iterdir())


def _writes_fail_on_the_lock(monkeypatch) -> None:
    """The lock's content cannot be written, as on a full disk: its temporary file's descriptor is /dev/full's
    (the kernel answers ENOSPC), the file itself is real (so that its removal is checked)."""
    real = tempfile.mkstemp

    def mkstemp(*args, **kwargs):
        handle, name = real(*args, **kwargs)
        if LOCK_SUFFIX in Path(name).name:
            os.close(handle)
            handle = os.open("/dev/full", os.O_WRONLY)
        return handle, name

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)


@needs_dev_full
def test_a_lock_that_cannot_be_written_leaves_nothing(tmp_path, monkeypatch):
    # issue 24: a full disk left a 0-byte lock (created with O_EXCL, then the pid write failed)
    _writes_fail_on_the_lock(monkeypatch)
    with pytest.raises(InputError, match=r"cannot create the lock file .*No space left on device; free some space"):
        with output_lock(tmp_path / "res"):
            pytest.fail("the block must not run without the lock")
    assert _names(tmp_path) == []


def test_a_lock_refused_by_the_file_system_leaves_nothing(tmp_path, monkeypatch):
    def link(source, target, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(target))

    monkeypatch.setattr(os, "link", link)
    with pytest.raises(InputError, match="No space left on device; free some space and run again"):
        with output_lock(tmp_path / "a" / "res"):
            pass
    assert _names(tmp_path) == []  # neither the lock, its temporary, nor the folders made for it


def test_a_lock_is_never_seen_empty(tmp_path, monkeypatch):
    # the content is in the file before the lock's name appears (a hard link), so a reader never sees it empty
    seen = []
    real = os.link

    def link(source, target, **kwargs):
        seen.append(Path(source).read_text())
        return real(source, target, **kwargs)

    monkeypatch.setattr(os, "link", link)
    with output_lock(tmp_path / "res") as lock:
        pid, host, token = lock.read_text().splitlines()
        assert seen == [lock.read_text()] and pid == str(os.getpid()) and host == socket.gethostname() and token
    assert _names(tmp_path) == []


@pytest.mark.parametrize("fails", [False, True])
def test_without_hard_links_the_lock_is_written_in_place(tmp_path, monkeypatch, fails):
    # FAT, exFAT, some network shares: link() is refused; the lock is created with O_EXCL and then written
    def link(source, target, **kwargs):
        raise OSError(errno.EPERM, "Operation not permitted", str(source), None, str(target))

    monkeypatch.setattr(os, "link", link)
    if fails:
        real_write = os.write

        lock = tmp_path / f".res{LOCK_SUFFIX}"

        def write(handle, data):  # the lock's content does not fit on the disk
            if lock.exists() and os.path.samestat(os.fstat(handle), lock.stat()):
                raise OSError(errno.ENOSPC, "No space left on device")
            return real_write(handle, data)

        monkeypatch.setattr(os, "write", write)
        with pytest.raises(InputError, match="No space left on device"), output_lock(tmp_path / "res"):
            pass
    else:
        with output_lock(tmp_path / "res") as lock:
            assert lock.read_text().splitlines()[0] == str(os.getpid())
    assert _names(tmp_path) == []


def test_a_live_holder_is_refused_by_pid_and_a_dead_one_taken_over(tmp_path, live_pid, dead_pid):
    out = tmp_path / "res"
    lock = tmp_path / f".res{LOCK_SUFFIX}"
    lock.write_text(f"{live_pid}\n{socket.gethostname()}\nabc\n")
    with pytest.raises(InputError, match=rf"in use by another robotcal process \(pid {live_pid}\)"), output_lock(out):
        pass
    assert lock.is_file()  # a live process's lock is never removed
    lock.write_text(f"{dead_pid}\n")  # an older robotcal's lock: the pid alone
    with output_lock(out) as held:
        assert held.read_text().splitlines()[0] == str(os.getpid())
    assert _names(tmp_path) == []


def test_a_lock_of_another_host_is_refused_naming_the_host(tmp_path, dead_pid):
    # a shared network folder: a pid of another machine cannot be checked here, so its lock is never stale
    (tmp_path / f".res{LOCK_SUFFIX}").write_text(f"{dead_pid}\nother-machine\nabc\n")
    with pytest.raises(InputError, match=rf"\(pid {dead_pid}\) on host other-machine"), output_lock(tmp_path / "res"):
        pass


def test_an_empty_lock_is_stale_once_old_and_waited_for_while_young(tmp_path, monkeypatch):
    lock = tmp_path / f".res{LOCK_SUFFIX}"
    lock.touch()
    old = time.time() - 60
    os.utime(lock, (old, old))  # left by an older robotcal killed between creating and writing it
    with output_lock(tmp_path / "res") as held:
        assert held.read_text().splitlines()[0] == str(os.getpid())
    # a young empty lock is being written by a process on a file system without hard links: wait for it
    lock.touch()
    sleeps = []

    def sleep(seconds):
        sleeps.append(seconds)
        lock.write_text("1\n" if len(sleeps) == 1 else "")  # pid 1 (init) is alive: the holder now shows

    monkeypatch.setattr(time, "sleep", sleep)
    with pytest.raises(InputError, match=r"\(pid 1\)"), output_lock(tmp_path / "res"):
        pass
    assert sleeps


def test_a_stale_lock_replaced_meanwhile_is_put_back(tmp_path, dead_pid):
    # two processes found one stale lock; the first took over; the second must not remove the first's lock
    from robotcal.io.results.output import _take_over

    lock = tmp_path / f".res{LOCK_SUFFIX}"
    lock.write_text(f"{os.getpid()}\n{socket.gethostname()}\nfresh\n")  # the first process's new lock
    _take_over(lock, f"{dead_pid}\n".encode())  # the second process still holds the stale content it read
    assert lock.read_text().endswith("fresh\n") and _names(tmp_path) == [lock.name]


def test_stale_temporaries_of_the_output_are_removed_and_nothing_else(tmp_path, dead_pid, live_pid):
    out = tmp_path / "res"
    stale = [
        f".res.robotcal-{dead_pid}-abc12345.partial",  # a result folder being built when robotcal was killed
        f".res.robotcal-{dead_pid}-x_y9.tmp",
        f"..res{LOCK_SUFFIX}.robotcal-{dead_pid}-q1w2e3r4.tmp",  # a lock being made
    ]
    kept = [
        f".res.robotcal-{live_pid}-abc12345.partial",  # its writer still runs
        f".res.robotcal-{os.getpid()}-abc12345.tmp",  # this process's own
        f".other.robotcal-{dead_pid}-abc12345.partial",  # another output's (its own writer cleans it)
        ".res.abc12345.partial",  # not robotcal's name
        "res.robotcal-1-a.partial",
        f".res.robotcal-{dead_pid}-abc.partial.bak",
        "notes.txt",
    ]
    for name in stale + kept:
        if name.endswith(".partial"):
            (tmp_path / name).mkdir()
            (tmp_path / name / "a.csv").write_text("1")
        else:
            (tmp_path / name).write_text("1")
    with output_lock(out):
        assert set(_names(tmp_path)) == {*kept, f".res{LOCK_SUFFIX}"}
    assert _names(tmp_path) == sorted(kept)


def test_inside_a_robotcal_folder_stale_temporaries_are_removed_at_any_depth(tmp_path, dead_pid):
    # a run folder: each stage is built in a .partial inside it
    out = tmp_path / "run"
    (out / "tcp").mkdir(parents=True)
    write_marker(out, command="robotcal run", files=["run.json", "tcp"])
    (out / "run.json").write_text("{}")
    (out / f".refine.robotcal-{dead_pid}-k3j4h5g6.partial").mkdir()
    (out / f".run.json.robotcal-{dead_pid}-k3j4h5g6.tmp").write_text("{")
    (out / "tcp" / f".pose.robotcal-{dead_pid}-k3j4h5g6.partial").mkdir()
    user = tmp_path / "user"  # not robotcal's folder: nothing inside it is touched
    user.mkdir()
    (user / f".refine.robotcal-{dead_pid}-k3j4h5g6.partial").mkdir()
    with output_lock(out):
        pass
    with output_lock(user):
        pass
    assert _names(out) == [".robotcal", "run.json", "tcp"] and _names(out / "tcp") == []
    assert _names(user) == [f".refine.robotcal-{dead_pid}-k3j4h5g6.partial"]


def test_a_result_killed_between_its_two_renames_is_restored(tmp_path, dead_pid):
    # atomic_directory moves the old folder aside, then the new one in; a SIGKILL in between left neither in place
    old = tmp_path / f".res.robotcal-{dead_pid}-abcdefgh.old"
    (old / "res").mkdir(parents=True)
    (old / "res" / "a.txt").write_text("previous result")
    new = tmp_path / f".res.robotcal-{dead_pid}-abcdefgh.partial"
    new.mkdir()
    assert remove_stale_temporaries(tmp_path, names=["res"]) != []
    assert _names(tmp_path) == ["res"] and (tmp_path / "res" / "a.txt").read_text() == "previous result"


def test_temporary_names_carry_the_output_and_the_writer(tmp_path):
    with atomic_directory(tmp_path / "res") as folder:
        assert folder.name.startswith(temporary_prefix("res")) and folder.name.endswith(".partial")
        assert final_path(folder / "sub" / "a.csv") == tmp_path / "res" / "sub" / "a.csv"
    assert temporary_prefix("res") == f".res.robotcal-{os.getpid()}-"
    assert final_path(tmp_path / "a.csv") == tmp_path / "a.csv"


@needs_dev_full
def test_a_full_disk_names_the_output_not_the_temporary(tmp_path, monkeypatch):
    real = tempfile.mkstemp

    def mkstemp(*args, **kwargs):  # the lock fits, the data file does not
        handle, name = real(*args, **kwargs)
        if LOCK_SUFFIX not in name:
            os.close(handle)
            handle = os.open("/dev/full", os.O_WRONLY)
        return handle, name

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    with pytest.raises(InputError) as info, result_folder(tmp_path / "res", command="test") as folder:
        atomic_write_text(folder / "a.csv", "1,2,3\n")
    assert (
        str(info.value)
        == f"cannot write {tmp_path / 'res' / 'a.csv'}: No space left on device; free some space and run again"
    )
    assert _names(tmp_path) == []


def test_os_errors_say_what_to_do():
    assert describe_os_error(OSError(errno.ENOSPC, "No space left on device")) == (
        "No space left on device; free some space and run again"
    )
    assert describe_os_error(OSError(errno.EROFS, "Read-only file system")).endswith("writable file system")
    assert describe_os_error(OSError(errno.ENOENT, "No such file or directory")) == "No such file or directory"


def test_a_refused_writer_leaves_the_holders_new_folder(tmp_path, monkeypatch, live_pid):
    # the holder made the (still empty) output folder while the refused process waited for the lock: the refused
    # process must not remove it as "a folder made for an output that was not written"
    import robotcal.io.results.output as output

    out = tmp_path / "run"
    (tmp_path / f".run{LOCK_SUFFIX}").write_text(f"{live_pid}\n{socket.gethostname()}\nabc\n")
    real = output._acquire

    def acquire(*args):
        out.mkdir()  # meanwhile, the holder creates its run folder
        return real(*args)

    monkeypatch.setattr(output, "_acquire", acquire)
    with pytest.raises(InputError, match="in use"), output_lock(out):
        pass
    assert out.is_dir()


def test_a_folder_made_for_an_output_not_written_is_removed(tmp_path):
    out = tmp_path / "a" / "b" / "run"
    with pytest.raises(KeyboardInterrupt), output_lock(out):
        out.mkdir()  # as `run` makes its folder, then is interrupted before writing anything
        raise KeyboardInterrupt
    assert _names(tmp_path) == []
