"""Review of 2b56b42 (h422's claims fixes), h428.

* a refused sweep removed the guard ``.tlm-lock`` it made while another sweep waited for its lock: that
  sweep then held the lock of a removed file, and a third, opening the name anew, another: two sweeps in the
  guarded check at once. A sweep now holds the lock of the file the name gives (:func:`tlm.claims._guard`);
* a refused sweep that made the folder removed its ``sweep.yaml`` whatever else was in it by then (a sweep of
  the same points that came in and ended: its points kept, their marker gone); now only a folder holding
  nothing but what it made;
* another user's stale claim was removed under a shared lock, which two takers hold at once: the second could
  remove the first's new claim, and both wrote. The removal is now under an exclusive lock; one that finds it
  taken looks again (and is refused by the taker's new claim);
* a claim's look for a running sweep, no longer under the folder's guard (h422), holds a dead sweep's file's
  lock a moment: a sweep of other points coming in then was refused, naming the dead process;
* (checked, held) an API study that raises midway lets its claim go, twice in one process.

The other process is a child holding the lock (no timing), as in tests/test_folder_claims_h415.py."""

from __future__ import annotations

import fcntl
import os

import pytest

import tlm
from tests.test_folder_claims_h415 import beside, held, write_configs
from tests.test_review_h422 import _not_writable
from tlm import claims, storage


def test_a_sweep_whose_guard_is_removed_as_it_waits_locks_the_one_its_name_gives(tmp_path, monkeypatch):
    """The guard this sweep opened is removed (a refused sweep's, :func:`tlm.claims._unmake`) before its lock is
    taken: its check runs under the lock of the file ``.tlm-lock`` names, which another sweep opening it now
    waits for (was: the removed file's lock, which excludes no one)."""
    out = tmp_path / "sw"
    out.mkdir()
    guard = out / ".tlm-lock"
    guard.write_text("")
    real_open, real_refuse = os.open, claims.refuse_held
    removed, seen = [], []

    def open_(file, flags, *a, **k):
        fd = real_open(file, flags, *a, **k)
        if str(file) == str(guard) and not removed:  # (the refused sweep removes it now)
            removed.append(True)
            guard.unlink()
        return fd

    def refuse_held(*a, **k):  # (under the guard: another sweep opening .tlm-lock now would wait)
        fd = real_open(guard, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            seen.append("free")
        except BlockingIOError:
            seen.append("held")
        finally:
            os.close(fd)
        return real_refuse(*a, **k)

    monkeypatch.setattr(claims.os, "open", open_)
    monkeypatch.setattr(claims, "refuse_held", refuse_held)
    with claims.sharing(out, "mine", "sweep"):
        pass
    assert removed and seen == ["held"]


def test_a_refused_sweep_that_made_the_folder_keeps_what_another_sweep_put_in_it(tmp_path):
    """The folder this sweep made (``made``: its ``sweep.yaml``) holds points by the time a run's claim refuses
    it (a sweep of these points came in and ended meanwhile): nothing there is removed (was: its sweep.yaml)."""
    out = tmp_path / "sw"
    out.mkdir()
    (out / "sweep.yaml").write_text("points: ...\n")
    (out / "points" / "abc").mkdir(parents=True)
    (out / "points" / "abc" / "results.json").write_text("{}")
    with held(beside(out), kind="run") as pid, pytest.raises(claims.FolderHeld) as e, \
            claims.sharing(out, "mine", "sweep", made="sweep.yaml"):
        pytest.fail("the sweep shared a folder a run claims")
    assert f"another run is writing into {str(out)!r} (process {pid} " in str(e.value), e.value
    assert (out / "sweep.yaml").read_text() == "points: ...\n"
    assert (out / "points" / "abc" / "results.json").is_file()


def test_another_users_stale_claim_that_another_taker_holds_is_not_removed_under_it(tmp_path, monkeypatch):
    """Another user's stale claim file that another taker holds the lock of as this one looks (about to remove
    it, and to take a new claim): this one does not remove it under that lock, and is refused by the new claim
    (was: both held a shared lock, both removed 'the stale file', the second the first's new claim: both wrote)."""
    out = tmp_path / "o"
    beside(out).write_text("hother-4242\nrun\n")
    _not_writable(monkeypatch, beside(out))
    other = os.open(beside(out), os.O_RDONLY)  # (the other taker, its lock taken)
    fcntl.flock(other, fcntl.LOCK_SH | fcntl.LOCK_NB)
    real_sleep = claims.time.sleep
    holders = []

    def sleep(seconds):  # (this one waits: the other removes the file, and takes its own claim)
        nonlocal other
        if other is not None:
            beside(out).unlink()
            os.close(other)
            other = None
            holders.append(held(beside(out), kind="run"))
            holders.append(holders[0].__enter__())
        real_sleep(0)

    monkeypatch.setattr(claims.time, "sleep", sleep)
    try:
        with pytest.raises(claims.FolderHeld) as e, claims.claimed(out, "run"):
            pytest.fail("claimed the folder another taker took")
        assert f"(process {holders[1]} on this machine" in str(e.value), e.value
        assert beside(out).is_file()  # (the other's claim, left to it)
    finally:
        if other is not None:
            os.close(other)
        if holders:
            holders[0].__exit__(None, None, None)


def test_a_dead_sweeps_file_a_claim_looks_at_does_not_refuse_a_sweep_coming_in(tmp_path, monkeypatch):
    """A dead sweep's running file (of other points), its lock held a moment by a claim's unguarded look for a
    running sweep (:func:`tlm.claims._sweep_holder`): a sweep coming in waits for the look, removes the file and
    shares the folder (was: refused, 'another sweep of other points is writing', naming the dead process)."""
    out = tmp_path / "sw"
    out.mkdir()
    dead = out / ".tlm-running-other"
    dead.write_text(f"{storage._host()}-999999\n")
    look = os.open(dead, os.O_RDWR)
    fcntl.flock(look, fcntl.LOCK_EX | fcntl.LOCK_NB)
    real_sleep = claims.time.sleep

    def sleep(seconds):  # (the look lets go)
        nonlocal look
        if look is not None:
            os.close(look)
            look = None
        real_sleep(0)

    monkeypatch.setattr(claims.time, "sleep", sleep)
    try:
        with claims.sharing(out, "mine", "sweep"):
            assert not dead.exists() and (out / ".tlm-running-mine").is_file()
    finally:
        if look is not None:
            os.close(look)


def test_an_api_study_that_raises_midway_lets_its_claim_go_twice_in_a_row(tmp_path, monkeypatch):
    """``tlm.granularity`` whose study raises an InputError midway: its claim let go (none held, none beside the
    folder, another process may claim it), and a second call alike."""
    import subprocess
    import sys

    import tlm.experiments.granularity as gran

    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)

    def boom(*a, **k):
        assert claims.holding()
        raise tlm.InputError("midway", key="x")

    monkeypatch.setattr(gran, "run_granularity", boom)
    for _ in range(2):
        with pytest.raises(tlm.InputError, match="midway"):
            tlm.granularity("g.yaml", "o")
        assert not claims.holding() and not beside(tmp_path / "o").exists()
    code = "import sys; from tlm import claims\nwith claims.claimed(sys.argv[1]): print('ok')"
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "o")], capture_output=True, text=True,
                          cwd=os.path.dirname(os.path.dirname(__file__)), timeout=120)
    assert done.stdout.strip() == "ok", done.stderr


def test_a_refused_second_sweep_into_a_finished_sweeps_folder_deletes_nothing(tmp_path, cache, monkeypatch, capsys):
    """(checked, held) A sweep's folder with its finished points; a second sweep into it, refused by a run that
    claims the folder after the second's check: exit 2, and every file there as it was, byte for byte."""
    import tlm.experiments.sweep as sweep_mod
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    out = tmp_path / "sx"
    argv = ["sweep", "sw.yaml", "--out", str(out), "--no-progress", "--no-report", "--jobs", "1"]
    assert main(argv) == 0
    before = {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    assert any(p.parts[0] == "points" for p in before) and "sweep.yaml" in map(str, before)
    real, holders = sweep_mod.claim_folder, []

    def claim_folder(*a, **k):  # (the second sweep's check passed: a run claims the folder now)
        holders.append(held(beside(out), kind="run"))
        holders.append(holders[0].__enter__())
        return real(*a, **k)

    monkeypatch.setattr(sweep_mod, "claim_folder", claim_folder)
    capsys.readouterr()
    try:
        assert main(argv) == 2
        assert f"another run is writing into {str(out)!r} (process {holders[1]} " in capsys.readouterr().err
    finally:
        if holders:
            holders[0].__exit__(None, None, None)
    assert {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before
