"""Failures end with one line, the right exit status and nothing half written: a bare
``tlm``, ``--version``, a reader that goes away, a bug (its traceback in a file), a full
disk, a read-only or mount-point ``--out``, two runs into one folder, temporary folders
of dead processes.

The full disk is simulated in-process (a writer that raises ENOSPC, numpy's short write)
everywhere; where this process may mount a tmpfs (root with CAP_SYS_ADMIN), a real small
file system that fills and a real read-only mount point are tested too.
"""

from __future__ import annotations

import errno
import io
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import yaml

import tlm.cli as cli
import tlm.experiments.run as run_mod
from tests.helpers_storage import refuse_to_carry
from tlm import claims, storage, storage_lock
from tlm.cli import main
from tlm.errors import InputError
from tlm.storage import atomic_folder, folder_lock

REPO = Path(__file__).resolve().parents[1]
CORNELL = str(REPO / "configs" / "cornell.yaml")
# (packets of 16: at 256 a frame this small warns of coarse packets, and these runs want stderr to hold what they test)
SMALL = ["--set", "resolution=[24,16]", "--set", "render.light_samples=1", "--set", "arch.packet_size=16",
         "--no-progress"]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def leftovers(folder: Path) -> list[str]:
    """Hidden temporary folders (``.X.tmp-PID``, ``.X.old-PID-N``) anywhere below ``folder``."""
    return [str(p) for p in folder.rglob(".*") if ".tmp" in p.name or ".old-" in p.name]


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# ---------------------------------------------------------------- the command line


def test_a_bare_tlm_prints_its_usage(capsys):
    assert main([]) == 0  # (asked for, as tlm --help: not bad input)
    out = capsys.readouterr().out
    assert out.startswith("usage: tlm") and "run" in out and "sweep" in out and "--version" in out


def test_version(capsys):
    assert main(["--version"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("tlm 0.") and "Python" in out


class ClosedPipe(io.StringIO):
    def write(self, text):
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")


@pytest.mark.parametrize("argv", [["params"], ["scene", "show", "cornell"], ["scene", "list"]])
def test_a_reader_that_goes_away_ends_the_command_quietly(argv, monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert main(argv) == 141
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_head_of_params_in_a_shell():
    """The real pipe: ``tlm params | head -1`` shows one line and no traceback."""
    proc = subprocess.run(f"{sys.executable} -m tlm params | head -1", shell=True, capture_output=True, text=True,
                          cwd=REPO, timeout=120)
    assert proc.stdout.startswith("scene") and proc.stdout.count("\n") == 1
    assert proc.stderr == ""


def test_a_bug_prints_one_line_and_the_file_of_its_traceback(monkeypatch, capsys, cache):
    def boom(args):
        raise RuntimeError("something\nunexpected")

    monkeypatch.setattr(cli, "_cmd_params", boom)
    assert main(["params"]) == 1
    line = one_line(capsys.readouterr().err)
    assert line.startswith("tlm: internal error: RuntimeError: something unexpected (full traceback in ")
    path = Path(line.split("full traceback in ", 1)[1].rstrip(")"))
    assert path.parent == cache / "tracebacks"
    text = path.read_text()
    assert "Traceback (most recent call last)" in text and "in boom" in text and "tlm 0." in text


# ---------------------------------------------------------------- a full disk, a read-only --out


@pytest.mark.slow
@pytest.mark.parametrize("failure", ["errno", "numpy"])
def test_a_full_disk_is_one_line_exit_1_and_nothing_written(failure, tmp_path, monkeypatch, capsys):
    """Simulated: the radiance writer fails as a full disk makes it fail (ENOSPC, or
    numpy's short write with no errno)."""
    def full(path, *a, **k):
        if failure == "errno":
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        raise OSError("786432 requested and 4096 written")

    monkeypatch.setattr(np, "save", full)
    out = tmp_path / "runs" / "r"
    assert main(["run", CORNELL, "--out", str(out), *SMALL, "--no-report"]) == 1
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"tlm: error: {out}: cannot write: ")
    assert ("no space left on device" if failure == "errno" else "no space left on device?") in line
    assert not out.exists() and leftovers(tmp_path / "runs") == []


def test_an_unwritable_out_fails_before_the_render(tmp_path, monkeypatch, capsys):
    """(os.access is what says a folder is read-only; as root, a chmod does not, so it is
    made to say so here; the real read-only mount is tested below where it can be.)"""
    rendered = []
    monkeypatch.setattr(run_mod, "render", lambda *a, **k: rendered.append(1))
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **k: False if Path(p) == ro else real(p, mode, **k))
    assert main(["run", CORNELL, "--out", str(ro / "r"), *SMALL]) == 1
    assert one_line(capsys.readouterr().err) == (f"tlm: error: {ro / 'r'}: cannot write into {ro} "
                                                 "(read-only or not permitted)")
    assert rendered == []


def test_a_mount_point_as_out_is_refused_before_the_render(tmp_path, monkeypatch, capsys):
    rendered = []
    monkeypatch.setattr(run_mod, "render", lambda *a, **k: rendered.append(1))
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    real = os.path.ismount
    monkeypatch.setattr(os.path, "ismount", lambda p: Path(p) == mnt or real(p))
    assert main(["run", CORNELL, "--out", str(mnt), *SMALL]) == 2
    assert "is a mount point, which cannot be replaced" in one_line(capsys.readouterr().err)
    assert rendered == []


def _can_mount(folder: Path) -> bool:
    folder.mkdir(exist_ok=True)
    try:
        ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                            capture_output=True).returncode == 0
    except OSError:
        return False
    if ok:
        subprocess.run(["umount", str(folder)], check=True)
    return ok


@pytest.fixture
def tmpfs(tmp_path):
    """Mounts a tmpfs (``options``) at a new folder; unmounted at the end."""
    if os.geteuid() != 0 or not _can_mount(tmp_path / "probe"):
        pytest.skip("mounting a tmpfs needs root with CAP_SYS_ADMIN (the simulated tests above still run)")
    mounted = []

    def mount(name: str, options: str) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], check=True)
        mounted.append(folder)
        return folder

    yield mount
    for folder in mounted:
        subprocess.run(["umount", str(folder)], check=False)


@pytest.mark.slow
def test_a_real_file_system_that_fills(tmpfs, tmp_path):
    disk = tmpfs("disk", "size=128k")
    out = disk / "r"
    proc = subprocess.run([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(out), *SMALL,
                           "--set", "resolution=[48,48]"], capture_output=True, text=True, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=300)
    assert proc.returncode == 1, proc.stderr
    line = one_line(proc.stderr)  # (ENOSPC, or numpy's short write: which one depends on the file)
    assert line.startswith(f"tlm: error: {out}: cannot write: ") and "no space left on device" in line
    assert list(disk.iterdir()) == []


@pytest.mark.slow
def test_a_real_read_only_mount_point(tmpfs, tmp_path):
    ro = tmpfs("ro", "ro,size=64k")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    at = subprocess.run([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(ro), *SMALL],
                        capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    assert at.returncode == 2 and "is a mount point" in one_line(at.stderr)
    inside = subprocess.run([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(ro / "r"), *SMALL],
                            capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    assert inside.returncode == 1
    assert one_line(inside.stderr) == f"tlm: error: {ro / 'r'}: cannot write into {ro} (read-only or not permitted)"


# ---------------------------------------------------------------- concurrent writers, stale folders


@pytest.mark.slow
def test_a_folder_is_not_swapped_while_another_holds_its_lock(tmp_path):
    """What a report reading its run folder holds (:func:`folder_lock`): a second writer's
    swap waits for it, and then replaces the folder whole."""
    out = tmp_path / "r"
    with atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("first")
    events = []

    def second():
        with atomic_folder(out, "m") as tmp:
            (tmp / "m").write_text("second")
        events.append("swapped")

    with folder_lock(out):
        t = threading.Thread(target=second)
        t.start()
        t.join(1.0)
        events.append("released")  # the first writer's report is done
        assert (out / "m").read_text() == "first"
    t.join(30)
    assert events == ["released", "swapped"]
    assert (out / "m").read_text() == "second" and leftovers(tmp_path) == []


@pytest.mark.slow
def test_two_runs_into_one_folder_at_once_one_is_refused(tmp_path):
    """Two ``tlm run`` (with their reports) into one --out, at once: the second to claim the
    folder is refused before any work (exit 2, naming the other process), not left to replace
    the first's run in silence; the folder is one whole run with its report, and no temporary
    folder or claim is left. (Runs that do not overlap both succeed.)"""
    out = tmp_path / "runs" / "same"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    procs = [subprocess.Popen([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(out), *SMALL,
                               "--seed", str(seed)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for seed in (1, 2)]
    results = [p.communicate(timeout=600) for p in procs]
    codes = sorted(p.returncode for p in procs)
    assert codes in ([0, 0], [0, 2]), results
    for p, (_, err) in zip(procs, results):
        assert "Traceback" not in err
        if p.returncode == 2:
            assert "another run is writing into" in err and str(procs[0 if p is procs[1] else 1].pid) in err, err
    assert (out / "results.json").is_file() and (out / "report" / "report.html").is_file()
    assert leftovers(tmp_path / "runs") == []
    assert not any(f.name.endswith(".tlm-running") for f in (tmp_path / "runs").iterdir())


@pytest.mark.slow
def test_temporary_folders_of_dead_processes_are_removed(tmp_path, capsys):
    runs = tmp_path / "runs"
    runs.mkdir()
    dead = dead_pid()
    host = storage._host()
    for name in (f".r.tmp-{dead}", f".r.old-{dead}-0", f".other.tmp-{dead}", f".r.tmp-{host}-{dead}",
                 f".r.old-{host}-{dead}-1"):
        (runs / name).mkdir()
        (runs / name / "results.json").write_text("{")
    alive = runs / f".r.tmp-{os.getppid()}"  # a live process's: kept
    alive.mkdir()
    # another machine's writer on a shared disk: its process id means nothing here, kept
    remote = runs / f".r.tmp-hsomeotherhost-{dead}"
    remote.mkdir()
    assert main(["run", CORNELL, "--out", str(runs / "r"), *SMALL, "--no-report"]) == 0
    assert sorted(p.name for p in runs.iterdir()) == sorted([f".other.tmp-{dead}", alive.name, remote.name, "r"])


def test_an_interrupted_writer_leaves_the_old_folder(tmp_path):
    out = tmp_path / "r"
    with atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("new")
        raise KeyboardInterrupt
    assert (out / "m").read_text() == "old" and leftovers(tmp_path) == []


def test_swap_retries_when_another_writer_lands_first(tmp_path, monkeypatch):
    """A rename onto a folder another writer put there in between (ENOTEMPTY) is retried."""
    out = tmp_path / "r"
    rename = Path.rename
    calls = []

    def racing(self, target):
        if Path(target) == out and not calls:
            calls.append(1)
            out.mkdir()
            (out / "m").write_text("other writer")
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", racing)
    with atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("mine")
    assert calls == [1]
    assert (out / "m").read_text() == "mine" and leftovers(tmp_path) == []


def _interrupt_the_swap(monkeypatch, out: Path):
    """Path.rename patched to be interrupted (a signal) as the new folder is renamed onto
    ``out``, after the old one was moved aside, on a file system that cannot swap the two in one
    call (tlm.storage_lock.exchange; where it can: tests/test_folder_exchange_h208.py); returns the
    real rename, to restore."""
    monkeypatch.setattr(storage_lock, "_renameat2", lambda: None)
    monkeypatch.setattr(storage_lock, "_EXCHANGES", {})
    rename = Path.rename

    def interrupted(self, target):
        if Path(target) == out and ".tmp-" in self.name:
            raise KeyboardInterrupt
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", interrupted)
    return rename


def test_a_signal_between_the_two_renames_puts_the_old_folder_back(tmp_path, monkeypatch):
    """Interrupted after the old folder is moved aside and before the new one is renamed
    in, the writer puts the old folder back: ``out`` is never left missing."""
    out = tmp_path / "r"
    with atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("old")
    rename = _interrupt_the_swap(monkeypatch, out)
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("new")
    monkeypatch.setattr(Path, "rename", rename)
    assert (out / "m").read_text() == "old" and leftovers(tmp_path) == []


def test_the_user_s_own_files_in_a_replaced_folder_are_kept(tmp_path, monkeypatch):
    """A writer that names what it owns carries everything else of the folder it replaces
    (notes, an analysis folder, hidden files) into the new one; what it owns is replaced
    (an old output the new one lacks is gone). Interrupted at the swap, the old folder and
    every user file are back where they were."""
    out = tmp_path / "r"
    with atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("old")
        (tmp / "trace").write_text("old trace")
    (out / "notes.md").write_text("my analysis")
    (out / "analysis").mkdir()
    (out / "analysis" / "fig.py").write_text("x")
    (out / ".ipynb_checkpoints").mkdir()
    with atomic_folder(out, "m", owned=("m", "trace")) as tmp:
        (tmp / "m").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == [".ipynb_checkpoints", "analysis", "m", "notes.md"]
    assert (out / "notes.md").read_text() == "my analysis" and (out / "analysis" / "fig.py").read_text() == "x"
    assert (out / "m").read_text() == "new" and leftovers(tmp_path) == []
    rename = _interrupt_the_swap(monkeypatch, out)
    with pytest.raises(KeyboardInterrupt), atomic_folder(out, "m", owned=("m",)) as tmp:
        (tmp / "m").write_text("newer")
    monkeypatch.setattr(Path, "rename", rename)
    assert sorted(p.name for p in out.iterdir()) == [".ipynb_checkpoints", "analysis", "m", "notes.md"]
    assert (out / "m").read_text() == "new" and leftovers(tmp_path) == []


def test_a_user_file_that_cannot_be_moved_keeps_both_folders(tmp_path, monkeypatch):
    """A user's entry that cannot be carried over (a read-only folder of theirs, a mount
    point) leaves the earlier folder as it was, every user file in it, and keeps the
    finished output beside it, named: neither is thrown away."""
    out = tmp_path / "r"
    with atomic_folder(out, "m", owned=("m",)) as tmp:
        (tmp / "m").write_text("old")
    (out / "a_notes.md").write_text("mine")
    (out / "b_locked").mkdir()
    rename = refuse_to_carry(monkeypatch, "b_locked")
    with (pytest.raises(storage.EnvironmentFailure, match=r"cannot carry .*b_locked.* kept in .*r\.unsaved-"),
          atomic_folder(out, "m", owned=("m",)) as tmp):
        (tmp / "m").write_text("new")
    monkeypatch.setattr(Path, "rename", rename)
    assert sorted(p.name for p in out.iterdir()) == ["a_notes.md", "b_locked", "m"] and (out / "m").read_text() == "old"
    (kept,) = tmp_path.glob("r.unsaved-*")
    assert (kept / "m").read_text() == "new" and sorted(p.name for p in kept.iterdir()) == ["m"]


def test_a_run_into_its_own_earlier_folder_keeps_the_user_s_files(tmp_path):
    out = tmp_path / "run"
    assert main(["run", CORNELL, "--out", str(out), *SMALL, "--no-report"]) == 0
    (out / "notes.md").write_text("my analysis")
    assert main(["run", CORNELL, "--out", str(out), *SMALL, "--no-report", "--outputs", "images"]) == 0
    assert (out / "notes.md").read_text() == "my analysis"
    assert not (out / "trace.json").exists() and not (out / "aov").exists()  # (the new run's outputs only)


def test_a_destination_taken_meanwhile_keeps_the_finished_output(tmp_path):
    """When the destination turns into something else during the run (a user's own files),
    the refusal keeps the finished output beside it and names it, instead of deleting it."""
    out = tmp_path / "r"
    with pytest.raises(InputError, match=r"kept in .*r\.unsaved-\d+"), atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("finished")
        out.mkdir()
        (out / "notes.txt").write_text("the user's")
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("r.unsaved-")]
    assert len(kept) == 1 and (kept[0] / "m").read_text() == "finished"
    assert (out / "notes.txt").read_text() == "the user's"


def test_a_folder_is_shared_by_one_identity_and_refused_to_another(tmp_path):
    """claims.sharing: processes of one identity (one sweep's points) share a folder; another
    identity is refused while any holds it, naming the process; the last holder's file goes
    on the way out, and a file whose holders ended (no lock on it) is stale and removed."""
    out = tmp_path / "o"
    out.mkdir()
    with claims.sharing(out, "a", "sweep"):
        with claims.sharing(out, "a", "sweep"):  # (a second open file: as another process's)
            pass
        assert (out / ".tlm-running-a").is_file()  # the first holder still holds it
        refused = rf"another sweep of other points is writing into .*process {os.getpid()}"
        with pytest.raises(InputError, match=refused), claims.sharing(out, "b", "sweep"):
            pytest.fail("a second identity got the folder")
    assert not (out / ".tlm-running-a").exists()
    (out / ".tlm-running-dead").write_text(f"{dead_pid()}\n")  # left by a killed process: no lock on it
    with claims.sharing(out, "b", "sweep"):
        assert not (out / ".tlm-running-dead").exists()
    assert [p.name for p in out.iterdir()] == [".tlm-lock"]
    storage.check_destination(out, "sweep.yaml")  # (a folder holding only the lock file is still ours to claim)


def test_a_sweep_of_other_points_is_refused_while_one_runs_into_its_folder(tmp_path, capsys):
    """Two different sweeps into one folder at once: the second is refused (exit 2, one line)
    and leaves the first's folder as it was; once the first ends, it runs."""
    base = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1},
            "arch": {"frames": 2, "trace": False}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.page_miss_cycles": [0, 12]}}))
    out = tmp_path / "o"
    out.mkdir()
    (out / "sweep.yaml").write_text("theirs")  # another sweep's folder, that sweep running
    with claims.sharing(out, "theirs", "sweep"):
        assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 2
        line = one_line(capsys.readouterr().err)
        assert line.startswith("tlm: error: --out: another sweep of other points is writing into") and "process" in line
        assert sorted(p.name for p in out.iterdir()) == [".tlm-lock", ".tlm-running-theirs", "sweep.yaml"]
        assert (out / "sweep.yaml").read_text() == "theirs"
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 0
    assert "theirs" not in (out / "sweep.yaml").read_text()
    assert not list(out.glob(".tlm-running-*"))
