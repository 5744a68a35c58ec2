"""An output folder replaced by one exchange (tlm.storage_lock.exchange, Linux's renameat2 with
RENAME_EXCHANGE), the two renames where the file system cannot, and tlm.storage_lock.folder_lock's
10 ms wait for a missing folder left out where no writer of this machine is ever between two renames."""

from __future__ import annotations

import ctypes
import errno
import os
import sys
import time
from pathlib import Path

import pytest

from tlm import storage, storage_lock
from tlm.storage import atomic_folder, folder_lock

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2 is Linux's")


def leftovers(folder: Path) -> list[str]:
    """Hidden temporary folders (``.X.tmp-...``, ``.X.old-...``) in ``folder``."""
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name or ".old-" in p.name)


@pytest.fixture(autouse=True)
def _nothing_known(monkeypatch):
    """Each test finds out afresh which file systems exchange."""
    monkeypatch.setattr(storage_lock, "_EXCHANGES", {})


@pytest.fixture
def exchanging(tmp_path):
    if not storage_lock.exchanges_in(tmp_path):
        pytest.skip("this file system does not exchange (renameat2 RENAME_EXCHANGE)")
    storage_lock._EXCHANGES.clear()


def cannot_exchange(monkeypatch, err: int | None) -> None:
    """renameat2 failing with ``err`` (the errno of a system or file system without the exchange),
    or (None) missing (another OS, no libc renameat2 or known system call number)."""
    def fails(a: bytes, b: bytes) -> int:
        ctypes.set_errno(err)
        return -1

    monkeypatch.setattr(storage_lock, "_renameat2", lambda: None if err is None else fails)


def renames(monkeypatch) -> list[tuple[str, str]]:
    """Every Path.rename (source and target names) from now on: tlm.storage's swaps."""
    seen: list[tuple[str, str]] = []
    rename = Path.rename

    def spy(self, target):
        seen.append((Path(self).name, Path(target).name))
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", spy)
    return seen


def earlier_output(out: Path) -> None:
    with atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("old")
        (tmp / "trace").write_text("old trace")
    (out / "notes.md").write_text("mine")


def test_an_earlier_folder_is_exchanged_for_the_new_one_in_one_call(tmp_path, monkeypatch, exchanging):
    """The new folder takes the old one's place by one exchange: the old folder is never renamed
    aside (no moment without ``out``); the new one's files are there, the user's notes carried over,
    an owned file the new output lacks gone, and the old folder removed."""
    out = tmp_path / "r"
    earlier_output(out)
    exchanged = []
    real = storage_lock.exchange

    def spy(a, b):
        exchanged.append((Path(a).name, Path(b).name, real(a, b)))
        return exchanged[-1][2]

    monkeypatch.setattr(storage_lock, "exchange", spy)
    seen = renames(monkeypatch)
    with atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    assert exchanged == [(tmp.name, "r", True)]
    assert not any(src == "r" for src, _ in seen), seen  # (never renamed aside)
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md"]
    assert (out / "m").read_text() == "new" and (out / "notes.md").read_text() == "mine"
    assert leftovers(tmp_path) == [] and not tmp.exists()
    assert storage_lock._EXCHANGES.get(os.stat(tmp_path).st_dev) is True


@pytest.mark.parametrize("err", [errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, None],
                         ids=["EINVAL", "ENOSYS", "ENOTSUP", "no-renameat2"])
def test_where_the_exchange_cannot_be_done_the_old_folder_is_renamed_aside_first(tmp_path, monkeypatch, err):
    """A file system without the exchange (NFS: EINVAL), a kernel without renameat2 (ENOSYS), another
    OS: the old folder is renamed aside, the new one renamed in, the old one removed, as before; and
    the file system is noted as one where a missing folder may be a writer between its renames."""
    out = tmp_path / "r"
    cannot_exchange(monkeypatch, err)
    earlier_output(out)
    seen = renames(monkeypatch)
    with atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    swaps = [(src, dst) for src, dst in seen if "r" in (src, dst)]
    assert len(swaps) == 2 and swaps[0][0] == "r" and swaps[0][1].startswith(".r.old-"), seen
    assert swaps[1] == (tmp.name, "r"), seen
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md"] and (out / "m").read_text() == "new"
    assert leftovers(tmp_path) == []
    assert storage_lock.exchanges_in(tmp_path) is False
    assert storage_lock._EXCHANGES.get(os.stat(tmp_path).st_dev) is False


def test_another_failure_of_the_exchange_leaves_the_old_folder_as_it_was(tmp_path, monkeypatch):
    """An exchange that fails otherwise (EIO) changed nothing: the error goes on, the old folder is
    where it was with the user's notes in it, the new one is removed, and no two renames are tried."""
    out = tmp_path / "r"
    earlier_output(out)
    cannot_exchange(monkeypatch, errno.EIO)
    seen = renames(monkeypatch)
    with pytest.raises(OSError), atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    assert not any(src == "r" or dst == "r" for src, dst in seen), seen
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md", "trace"]
    assert (out / "m").read_text() == "old" and (out / "notes.md").read_text() == "mine"
    assert leftovers(tmp_path) == []


def test_a_signal_before_the_exchange_leaves_the_old_folder_with_the_user_s_files(tmp_path, monkeypatch, exchanging):
    out = tmp_path / "r"
    earlier_output(out)

    def interrupted(a, b):
        raise KeyboardInterrupt

    monkeypatch.setattr(storage_lock, "exchange", interrupted)
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md", "trace"]
    assert (out / "m").read_text() == "old" and (out / "notes.md").read_text() == "mine"
    assert leftovers(tmp_path) == []


def test_a_signal_after_the_exchange_keeps_the_new_folder_and_removes_the_old(tmp_path, monkeypatch, capsys,
                                                                             exchanging):
    """The exchange done, then a signal (before the call returned to the writer): the new folder stays
    whole, the user's notes in it (not "moved back" into the old folder, nor the old folder kept beside
    as an unsaved output), and the old one is removed."""
    out = tmp_path / "r"
    earlier_output(out)
    real = storage_lock.exchange

    def interrupted_after(a, b):
        real(a, b)
        raise KeyboardInterrupt

    monkeypatch.setattr(storage_lock, "exchange", interrupted_after)
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md"]
    assert (out / "m").read_text() == "new" and (out / "notes.md").read_text() == "mine"
    assert leftovers(tmp_path) == [] and list(tmp_path.glob("r.unsaved-*")) == []
    assert "could not be moved back" not in capsys.readouterr().err


def test_a_signal_between_the_two_renames_still_puts_the_old_folder_back(tmp_path, monkeypatch):
    """Where the file system cannot exchange, a signal after the old folder was renamed aside puts it
    back, the user's notes in it."""
    out = tmp_path / "r"
    earlier_output(out)
    cannot_exchange(monkeypatch, errno.EINVAL)
    rename = Path.rename

    def interrupted(self, target):
        if Path(target) == out and ".tmp-" in self.name:
            raise KeyboardInterrupt
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", interrupted)
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    monkeypatch.setattr(Path, "rename", rename)
    assert sorted(p.name for p in out.iterdir()) == ["m", "notes.md", "trace"]
    assert (out / "m").read_text() == "old" and leftovers(tmp_path) == []


def sleeps(monkeypatch) -> list[float]:
    seen: list[float] = []
    monkeypatch.setattr(time, "sleep", seen.append)
    return seen


def test_a_missing_folder_is_not_waited_for_where_the_file_system_exchanges(tmp_path, monkeypatch, exchanging):
    """No writer here is ever between two renames: folder_lock of a folder not there yet (each new
    point of a sweep) returns at once, no 10 ms sleep; the file system is probed once, its two probe
    folders removed."""
    slept = sleeps(monkeypatch)
    made = []
    mkdir = os.mkdir

    def spy(path, *a, **kw):
        made.append(os.path.basename(path))
        return mkdir(path, *a, **kw)

    monkeypatch.setattr(os, "mkdir", spy)
    for name in ("a", "b", "c"):
        with folder_lock(tmp_path / name):
            pass
    assert slept == [] and len(made) == 2 and all(n.startswith(".a.old-") for n in made), made
    assert list(tmp_path.iterdir()) == []
    with atomic_folder(tmp_path / "d", "m") as tmp:  # (a new folder written: no sleep either)
        (tmp / "m").write_text("new")
    assert slept == [] and (tmp_path / "d" / "m").read_text() == "new"


@pytest.mark.parametrize("err", [errno.EINVAL, None], ids=["EINVAL", "no-renameat2"])
def test_a_missing_folder_is_waited_for_where_the_file_system_cannot_exchange(tmp_path, monkeypatch, err):
    """NFS (EINVAL), another OS: a writer may be between its two renames, so a missing folder is
    looked for again after 10 ms, as before; the probe leaves nothing behind."""
    cannot_exchange(monkeypatch, err)
    slept = sleeps(monkeypatch)
    with folder_lock(tmp_path / "a"):
        pass
    assert slept == [0.01] and list(tmp_path.iterdir()) == []


def test_a_probe_that_cannot_make_its_folders_tells_nothing_and_waits(tmp_path, monkeypatch):
    """A parent the probe cannot write into (read-only): no verdict kept, the 10 ms wait as before."""
    def refused(path, *a, **kw):
        raise OSError(errno.EROFS, "Read-only file system", path)

    monkeypatch.setattr(os, "mkdir", refused)
    slept = sleeps(monkeypatch)
    with folder_lock(tmp_path / "a"):
        pass
    assert slept == [0.01] and storage_lock._EXCHANGES == {}


def test_storage_still_names_the_host_it_did():
    """``_host`` moved to tlm.storage_lock: the same function where tlm.claims imports it."""
    assert storage._host is storage_lock._host and storage._host().startswith("h")


def test_a_file_system_s_yes_is_asked_again_after_a_while(tmp_path, monkeypatch, exchanging):
    """A long-lived process (a Dask worker, a notebook) may outlive a mount, and a tmpfs or NFS mounted later
    may get its device number: a yes is trusted for a while (tlm.storage_lock.TRUST_S, 30 s), then asked again,
    so that an NFS mount there now (EINVAL) is told, and folder_lock waits for a writer between its two
    renames again (h218)."""
    assert storage_lock.exchanges_in(tmp_path) is True
    cannot_exchange(monkeypatch, errno.EINVAL)  # (the device number another mount's now: NFS)
    assert storage_lock.exchanges_in(tmp_path) is True  # (within the while: no probe)
    now = time.monotonic()
    monkeypatch.setattr(time, "monotonic", lambda: now + 31)
    assert storage_lock.exchanges_in(tmp_path) is False
    assert leftovers(tmp_path) == []  # (the probe's two folders removed)
    slept = []
    monkeypatch.setattr(time, "sleep", slept.append)
    with folder_lock(tmp_path / "missing"):
        pass
    assert slept == [0.01]
