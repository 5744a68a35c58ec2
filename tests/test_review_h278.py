"""h278's review of claims.drop_stale (``tlm report`` removing a dead run's claim beside its folder): a
claim file not provably stale is never locked by it, so a run starting into the folder at that moment is
not refused for the report; a dead run's file the report could not remove is taken by the run; a FIFO
put where the claim file goes does not hang the report."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tlm import claims, storage

REPO = Path(__file__).resolve().parents[1]


def _dead_pid() -> int:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait(timeout=60)
    return dead.pid


@pytest.mark.parametrize("record", ["live", "other host", "older tlm", "not written"])
def test_a_run_starting_while_a_report_looks_at_a_claim_not_provably_stale_is_not_refused(tmp_path, monkeypatch,
                                                                                            record):
    """Whenever drop_stale holds the lock of the claim file beside a run folder, a run claiming the folder
    from another process at that very moment is not refused (one whose record is a live or reused pid's,
    another machine's, an older tlm's or none: never locked by drop_stale at all)."""
    run = tmp_path / "r"
    beside = tmp_path / ".r.tlm-running"
    text = {"live": f"{storage._host()}-1", "other host": "hOTHERBOX-4242", "older tlm": "4242",
            "not written": ""}[record]
    beside.write_text(text.ljust(63) + "\n" if text else "")
    real = fcntl.flock
    refused: list[str] = []

    def flock(fd, op):
        real(fd, op)
        if op & fcntl.LOCK_EX and claims._same_file(fd, beside):  # (drop_stale holds it now: a run starts)
            code = ("import sys; from pathlib import Path; from tlm import claims\n"
                    f"with claims.claimed(Path({str(run)!r})): pass\n")
            done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                                  env={**os.environ, "PYTHONPATH": str(REPO)})
            if done.returncode:
                refused.append(done.stderr.strip().splitlines()[-1])

    monkeypatch.setattr(claims.fcntl, "flock", flock)
    assert claims.drop_stale(run) is False
    monkeypatch.undo()
    assert refused == [] and beside.is_file()


def test_a_run_takes_a_dead_runs_claim_that_a_report_could_not_remove(tmp_path):
    """drop_stale holds a dead run's claim file and cannot remove it (a parent it may not write): when it
    lets go, a run waiting on the file takes it, not refused naming the dead process."""
    run = tmp_path / "r"
    beside = tmp_path / ".r.tlm-running"
    beside.write_text(f"{storage._host()}-{_dead_pid()}".ljust(63) + "\n")
    fd = os.open(beside, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (as drop_stale holds it; its unlink then fails)
    letting_go = threading.Timer(0.05, os.close, (fd,))
    letting_go.start()
    try:
        with claims.claimed(run):
            assert storage._host() in beside.read_text() and str(os.getpid()) in beside.read_text()
    finally:
        letting_go.join()
    assert not beside.exists()


@pytest.mark.parametrize("kind", ["fifo", "folder", "link"])
def test_a_claim_file_that_is_no_plain_file_is_left_and_does_not_hang(tmp_path, kind):
    """A FIFO where the claim file goes would block drop_stale's open (tlm report hung): left, at once; a
    folder, and a link (to a dead run's record) left too."""
    run = tmp_path / "r"
    beside = tmp_path / ".r.tlm-running"
    if kind == "fifo":
        os.mkfifo(beside)
    elif kind == "folder":
        beside.mkdir()
    else:
        target = tmp_path / "elsewhere"
        target.write_text(f"{storage._host()}-{_dead_pid()}".ljust(63) + "\n")
        beside.symlink_to(target)
    code = f"from tlm import claims; print(claims.drop_stale({str(run)!r}))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert done.stdout.strip() == "False" and os.path.lexists(beside)


def test_a_sweep_folder_that_exists_needs_itself_writable_not_its_parent(tmp_path, monkeypatch):
    """A sweep writes into its existing folder in place (a mount point in a folder of root's, /media/usb):
    taken where that folder can be written though its parent cannot; a run's folder, swapped whole, still
    needs its parent, and a sweep folder that cannot itself be written is still refused, naming it."""
    from tlm.errors import EnvironmentFailure

    mount = tmp_path / "media" / "usb"
    mount.mkdir(parents=True)
    shut = {mount.parent}
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: Path(p) not in shut and real(p, mode, **kw))
    assert storage.check_destination(mount, "sweep.yaml") == mount.resolve()
    with pytest.raises(EnvironmentFailure, match="cannot write into"):
        storage.check_destination(mount.parent / "new_sweep", "sweep.yaml")  # (made in the parent)
    with pytest.raises(EnvironmentFailure, match="cannot write into"):
        storage.check_destination(mount, "results.json")
    shut.add(mount)
    with pytest.raises(EnvironmentFailure, match=f"cannot write into {mount}"):
        storage.check_destination(mount, "sweep.yaml")


def test_a_sweep_whose_points_two_codes_ran_says_how_many_each():
    """A sweep resumed after an upgrade, its points of two codes: each code names it with how many of its
    points it ran, not the same folder twice, alike; a sweep of one code is named alone."""
    from tlm.report import warnings as box
    from tlm.report.collect import Inputs, Run, Sweep

    def run(path: str, code: str, kind: str = "sweep-point") -> Run:
        return Run(Path(path), path, kind, {"mode": "rcast", "code_fingerprint": code}, {})

    points = [run("runs/sw/points/h1", "aaaa"), run("runs/sw/points/h2", "bbbb"), run("runs/sw/points/h3", "bbbb")]
    other = run("runs/x", "bbbb", "run")
    line = box.code_line(Inputs([Path("runs")], runs=[*points, other], sweeps=[Sweep(Path("runs/sw"), {}, [], points)]))
    assert "code aaaa: runs/sw (1 of 3 points); code bbbb: runs/sw (2 of 3 points) and runs/x" in line
    one = [run("runs/sw/points/h1", "aaaa")]
    line = box.code_line(Inputs([Path("runs")], runs=[*one, other], sweeps=[Sweep(Path("runs/sw"), {}, [], one)]))
    assert "code aaaa: runs/sw; code bbbb: runs/x" in line
