"""Review of 7007438 (folder claims for every writer, h415), and its loose ends (h422).

* a sweep whose check passed just as a run or a study claimed the folder made the folder and its
  ``sweep.yaml`` (and the guard ``.tlm-lock``), then was refused, and left them behind: the run, finishing,
  was then refused its own folder ("exists and is not an earlier tlm output"); now nothing it made is left;
* the Python API's studies (``tlm.granularity``, ``tlm.thesis``, ...) held no claim, so two of them into one
  folder ended last-wins: each now holds its folder as its command does (shared, not a second claim, when the
  command calls it);
* a thread's check of a folder (``check_destination``) as another thread of its process took the folder's
  claim refused the folder naming its own process; and a check's moment of shared lock on a claim file made
  a run taking the claim that instant refused, naming ``process ?``;
* an older tlm's claim (its record names no kind) was said to be a sweep's or a study's by the kind of the
  folder looked at: an older tlm's claims were a run's or a report's only.

The other process is a child holding the lock (no timing: it says when it holds it, and lets go when its
stdin closes), as in tests/test_folder_claims_h415.py."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

import pytest

import tlm
import tlm.experiments.sweep as sweep_mod
from tests.test_folder_claims_h415 import beside, held, write_configs
from tlm import claims, storage
from tlm.cli import main


@pytest.mark.parametrize("existing", [False, True])
def test_a_sweep_refused_by_a_claim_taken_after_its_check_leaves_nothing_it_made(tmp_path, cache, monkeypatch,
                                                                               capsys, existing):
    """A run claims the sweep's folder between the sweep's check and its share of the folder: the sweep is
    refused (exit 2, naming the run) and leaves no folder, ``sweep.yaml`` or ``.tlm-lock`` of its own; a folder
    that was there (empty) is left as it was (was: the folder and sweep.yaml made and left, which the run then
    found in its way at its end)."""
    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    out = tmp_path / "sx"
    if existing:
        out.mkdir()
    real = sweep_mod.claim_folder
    holders = []

    def claim_folder(*a, **k):  # (the sweep's check passed: a run claims the folder now)
        holders.append(held(beside(out), kind="run"))
        pid = holders[-1].__enter__()
        holders.append(pid)
        return real(*a, **k)

    monkeypatch.setattr(sweep_mod, "claim_folder", claim_folder)
    try:
        assert main(["sweep", "sw.yaml", "--out", str(out), "--no-progress", "--no-report", "--jobs", "1"]) == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith(f"tlm: error: --out: another run is writing into {str(out)!r} "
                              f"(process {holders[1]} on this machine, "), err
        if existing:
            assert os.listdir(out) == []
        else:
            assert not out.exists()
        assert sorted(os.listdir(tmp_path)) == sorted([beside(out).name, "run.yaml", "g.yaml", "sw.yaml",
                                                       *(["sx"] if existing else [])])
    finally:
        if holders:
            holders[0].__exit__(None, None, None)


def test_a_sweep_refused_by_an_older_tlms_claim_names_a_run(tmp_path):
    """An older tlm's claim (a record of its host and pid alone) is a ``tlm run``'s, or a report's in a report
    folder: a sweep (or a study) refused by one names a run (was: "another sweep is writing", "another study")."""
    out = tmp_path / "sw"
    out.mkdir()
    with held(beside(out), kind=None) as pid:
        with pytest.raises(claims.FolderHeld) as e, claims.sharing(out, "mine", "sweep"):
            pytest.fail("the sweep shared a folder a run claims")
        assert str(e.value).startswith(f"--out: another run is writing into {str(out)!r} (process {pid} on "), e.value
        with pytest.raises(claims.FolderHeld, match="another run is writing"):
            storage.check_destination(out, "granularity.jsonl")
    assert os.listdir(out) == []  # (no guard left either: this sweep made it)


STUDIES = {  # the API's study, the experiment function it calls, and its arguments
    "granularity": ("tlm.experiments.granularity", "run_granularity", lambda out: ("g.yaml", out)),
    "thesis": ("tlm.experiments.thesis", "run_thesis", lambda out: ("thesis", out)),
    "error_vs_cost": ("tlm.experiments.error_cost", "run_error_vs_cost", lambda out: ("error_vs_cost", out)),
    "extreme": ("tlm.experiments.extreme", "run_extreme", lambda out: ("extreme", out)),
    "scaling": ("tlm.experiments.scaling", "analyse", lambda out: (["swp"], out)),
}


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_an_api_study_holds_its_folder_as_its_command_does(tmp_path, monkeypatch, study):
    """``tlm.granularity`` (``thesis``, ``error_vs_cost``, ``extreme``, ``scaling``) from Python holds its
    folder while the study runs: its claim file beside it, locked, recording this process and a study, so that
    another process's study into it is refused (was: none held, two studies into one folder last-wins); none
    is left after it."""
    import importlib

    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    (tmp_path / "swp").mkdir()
    module, name, arguments = STUDIES[study]
    out = tmp_path / "o"
    seen = []

    def stub(*a, **k):
        fd = os.open(beside(out), os.O_RDONLY)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        finally:
            os.close(fd)
        seen.append([line.strip() for line in beside(out).read_text().splitlines()])
        return {} if name in ("run_thesis", "analyse") else []

    monkeypatch.setattr(importlib.import_module(module), name, stub)
    getattr(tlm, study)(*arguments("o"))
    assert seen == [[storage.process_tag(), "study"]]
    assert not beside(out).exists()


def test_an_api_study_into_a_folder_another_process_holds_is_refused_naming_it(tmp_path, monkeypatch):
    """The check before the claim: refused at once, the argument named as the caller gave it (``out``)."""
    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    with held(beside(tmp_path / "o"), kind="study") as pid, pytest.raises(tlm.InputError) as e:
        tlm.granularity("g.yaml", "o")
    assert str(e.value).startswith(f"out: another study is writing into 'o' (process {pid} on this machine, "), e.value


def test_a_study_command_calling_the_api_shares_its_claim(tmp_path, cache, monkeypatch):
    """``tlm granularity`` holds its folder to the end of its report and calls ``tlm.api.granularity``, which
    holds it too: the one claim, shared (its file and lock, this process's), never refused by itself."""
    import tlm.experiments.granularity as gran

    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    out = tmp_path / "gd"
    real = gran.run_study
    seen = []

    def run_study(*a, **k):
        taken = claims._CLAIMS[os.fsdecode(out.resolve())]
        seen.append((taken[1], taken[3]))
        return real(*a, **k)

    monkeypatch.setattr(gran, "run_study", run_study)
    assert main(["granularity", "g.yaml", "--out", "gd", "--no-progress", "--no-report"]) == 0
    assert seen == [(beside(out).resolve(), 2)]  # (the command's and the API's holds of one claim)
    assert (out / "granularity.jsonl").is_file() and not beside(out).exists()


def test_a_check_as_another_thread_takes_the_claim_is_not_refused_by_its_own_process(tmp_path, monkeypatch):
    """A thread's check of a folder (:func:`tlm.storage.check_destination`) that finds the claim file locked,
    another thread of its process having just taken it, is not refused naming its own process (was: 'another
    run is writing into ... (process <its own pid> ...)')."""
    out = tmp_path / "o"
    real = claims._held_claim
    taken = []

    def held_claim(path):  # (between the check's look at this process's claims and its look at the file)
        block = claims.claimed(out, "run")
        block.__enter__()
        taken.append(block)
        return real(path)

    monkeypatch.setattr(claims, "_held_claim", held_claim)
    try:
        assert storage.check_destination(out, "results.json") == out.resolve()
    finally:
        for block in taken:
            block.__exit__(None, None, None)
    assert len(taken) == 1 and not beside(out).exists()


def test_a_claim_taken_as_another_writer_checks_the_folder_is_not_refused(tmp_path, monkeypatch):
    """Another writer's check holds the claim file's shared lock for as long as it looks (:func:`tlm.claims.
    refuse_held`): a run taking the claim that instant waits for it to let go, and takes it (was: refused,
    'another run is writing into ... (process ?)', though none held it)."""
    out = tmp_path / "o"
    beside(out).write_text("")  # (the file the taker just made, its record not written yet)
    looking = os.open(beside(out), os.O_RDONLY)
    fcntl.flock(looking, fcntl.LOCK_SH | fcntl.LOCK_NB)
    real = claims.time.sleep

    def sleep(seconds):  # (the check lets go as the taker waits)
        nonlocal looking
        if looking is not None:
            os.close(looking)
            looking = None
        real(0)

    monkeypatch.setattr(claims.time, "sleep", sleep)
    try:
        with claims.claimed(out, "run"):
            assert beside(out).read_text().splitlines()[0].strip() == storage.process_tag()
    finally:
        if looking is not None:
            os.close(looking)
    assert not beside(out).exists()


def test_the_api_runs_and_studies_twice_in_a_row_into_one_folder(tmp_path, cache, monkeypatch):
    """The same process, one call after the other into the same folder: never refused by itself (its claims
    let go), and none is left."""
    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    cfg = tlm.load_config("run.yaml")
    for _ in range(2):
        tlm.run(cfg, "r")
        tlm.granularity("g.yaml", "g")
    assert not claims.holding()
    assert not [p for p in Path(tmp_path).iterdir() if p.name.endswith(".tlm-running")]
    assert (tmp_path / "r" / "results.json").is_file() and (tmp_path / "g" / "granularity.jsonl").is_file()


def _not_writable(monkeypatch, path: Path) -> None:
    """``path`` (as it is now: that file) not to be opened for writing by this process, as another user's
    ``0644`` file is not (the tests run as root, whom no mode stops)."""
    inode = path.stat().st_ino
    real = os.open

    def open_(file, flags, *a, **k):
        if Path(file) == path and flags & os.O_RDWR and path.exists() and path.stat().st_ino == inode:
            raise PermissionError(13, "Permission denied", str(file))
        return real(file, flags, *a, **k)

    monkeypatch.setattr(claims.os, "open", open_)


def test_another_users_stale_claim_is_taken_over(tmp_path, monkeypatch):
    """A claim file another user's killed run left beside the folder (this user may not write it; its lock
    free): removed, and a new one taken (was: 'cannot write into DIR (read-only or not permitted)', exit 2,
    though the folder above could be written: a stale claim blocked every later run)."""
    out = tmp_path / "o"
    beside(out).write_text("hother-4242\nrun\n")
    _not_writable(monkeypatch, beside(out))
    with claims.claimed(out, "run"):
        assert beside(out).read_text().splitlines()[0].strip() == storage.process_tag()
    assert not beside(out).exists()


def test_another_users_live_claim_is_refused_naming_its_holder(tmp_path, monkeypatch):
    """Another user's live run's claim (its lock held) that this user may not write: refused as any holder's,
    naming it (was: 'cannot write into DIR (read-only or not permitted)')."""
    out = tmp_path / "o"
    with held(beside(out), kind="study") as pid:
        _not_writable(monkeypatch, beside(out))
        with pytest.raises(claims.FolderHeld) as e, claims.claimed(out, "run"):
            pytest.fail("claimed a folder another user's study holds")
        assert str(e.value).startswith(f"--out: another study is writing into {str(out)!r} (process {pid} on "), e.value
        assert beside(out).is_file()


def test_a_claim_taken_as_a_sweep_of_this_process_comes_in_does_not_wait_for_its_guard(tmp_path):
    """A thread taking a folder's claim (holding this process's claims' lock) looked for a sweep running in it
    under the folder's guard, waiting for it; a sweep of this process coming in holds that guard and asks for
    the claims' lock (:func:`tlm.claims.refuse_held`): the two threads waited for each other for ever. The guard
    is held here as that sweep holds it: the claim is taken, naming the sweep running there, without it."""
    import threading

    out = tmp_path / "sw"
    out.mkdir()
    (out / ".tlm-lock").write_text("")
    guard = os.open(out / ".tlm-lock", os.O_RDWR)
    fcntl.flock(guard, fcntl.LOCK_EX)  # (the sweep coming in)
    got = []

    def take():
        try:
            with claims.claimed(out, "run"):
                got.append("claimed")
        except claims.FolderHeld as e:
            got.append(str(e))

    try:
        with held(out / ".tlm-running-abc", kind=None, mode="shared") as pid:
            thread = threading.Thread(target=take, daemon=True)
            thread.start()
            thread.join(timeout=30)  # (a bound on a hang, not a measure: it ends at once)
            alive = thread.is_alive()
    finally:
        os.close(guard)  # (a thread that waits for it ends now)
    assert not alive, "the claim waited for the sweep's guard"
    assert len(got) == 1, got
    assert got[0].startswith(f"--out: another sweep is writing into {str(out)!r} (process {pid} "), got
    assert not beside(out).exists()
