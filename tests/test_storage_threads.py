"""Threads of one process writing one output as two processes do (tlm.storage): each writer has
temporary names of its own, so two ``tlm.run`` into one folder from two threads both succeed and
the folder is one whole run (the last to finish); a stale-folder cleanup never removes a folder
another thread of the process is writing, and does remove what an earlier process of the same
process id left."""

from __future__ import annotations

import json
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

import tlm
from tlm import storage
from tlm.storage import atomic_folder, clean_stale, write_atomic

THREADS = 4


def leftovers(folder: Path) -> list[str]:
    """Hidden temporary folders and files (``.X.tmp-...``, ``.X.tmpPID``, ``.X.old-...``) below ``folder``."""
    return [str(p) for p in folder.rglob(".*") if ".tmp" in p.name or ".old-" in p.name]


def test_threads_writing_one_folder_at_once_all_succeed_and_one_wins_whole(tmp_path):
    """Every thread's temporary folder exists at once (a barrier inside the block): none is
    removed or taken by another, each swap succeeds, and the folder is one thread's, whole."""
    out = tmp_path / "r"
    barrier = threading.Barrier(THREADS, timeout=30)

    def write(n: int) -> str:
        with atomic_folder(out, "m") as tmp:
            (tmp / "m").write_text(str(n))
            (tmp / "also").write_text(str(n))
            barrier.wait()
        return "ok"

    with ThreadPoolExecutor(THREADS) as ex:
        done = list(ex.map(write, range(THREADS)))
    assert done == ["ok"] * THREADS
    assert sorted(os.listdir(out)) == ["also", "m"]
    assert (out / "m").read_text() == (out / "also").read_text() in {str(n) for n in range(THREADS)}
    assert leftovers(tmp_path) == []


def test_threads_writing_one_file_at_once_all_succeed(tmp_path):
    """write_atomic from several threads into one path: each has its own temporary file."""
    path = tmp_path / "f.json"
    barrier = threading.Barrier(THREADS, timeout=30)

    def write(n: int) -> str:
        with write_atomic(path) as fh:
            fh.write(json.dumps({"writer": n, "pad": "x" * 10000 * (n + 1)}))
            barrier.wait()
        return "ok"

    with ThreadPoolExecutor(THREADS) as ex:
        done = list(ex.map(write, range(THREADS)))
    assert done == ["ok"] * THREADS
    got = json.loads(path.read_text())
    assert got["pad"] == "x" * 10000 * (got["writer"] + 1)
    assert leftovers(tmp_path) == []


def test_the_cleanup_keeps_another_thread_s_folder_and_removes_this_pid_s_leftovers(tmp_path):
    """While a thread writes ``r``, the cleanup another thread runs keeps that thread's
    temporary folder; folders of this process id that no writer of the process uses (a killed
    earlier process that had the same id) are removed."""
    out = tmp_path / "r"
    inside, finish = threading.Event(), threading.Event()
    seen: list[Path] = []

    def write() -> None:
        with atomic_folder(out, "m") as tmp:
            (tmp / "m").write_text("thread")
            seen.append(tmp)
            inside.set()
            assert finish.wait(30)

    t = threading.Thread(target=write)
    t.start()
    try:
        assert inside.wait(30)
        owner = f"{storage._host()}-{os.getpid()}"
        left = [tmp_path / f".r.tmp-{owner}", tmp_path / f".r.tmp-{owner}-999999",
                tmp_path / f".r.old-{owner}-999999-0"]
        for d in left:
            d.mkdir()
            (d / "m").write_text("stale")
        clean_stale(tmp_path, "r")
        assert (seen[0] / "m").read_text() == "thread"  # the live one: kept
        assert [d for d in left if d.exists()] == []
    finally:
        finish.set()
        t.join(30)
    assert (out / "m").read_text() == "thread" and leftovers(tmp_path) == []


@pytest.mark.slow
def test_two_threads_running_tlm_run_into_one_folder_both_succeed(tmp_path):
    """The probe's script: ``tlm.run`` of seeds 1 and 2 into one folder from two threads."""
    out = tmp_path / "same"
    small = {"mode": "rcast", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1,
             "arch.packet_size": 16}

    def job(seed: int):
        return tlm.run(tlm.load_config("cornell", {**small, "seed": seed}), out, outputs="images")

    with ThreadPoolExecutor(2) as ex:
        results = list(ex.map(job, [1, 2]))
    written = json.loads((out / "results.json").read_text())
    assert written["seed"] in (1, 2)
    assert written == json.loads(json.dumps(results[written["seed"] - 1]))
    assert leftovers(tmp_path) == []


def test_a_forked_child_forgets_the_parent_s_folders_in_use(tmp_path):
    """A child forked while a thread of the parent held a temporary folder: its own writes
    work (the bookkeeping's lock is fresh in the child) and leave nothing behind."""
    if not hasattr(os, "fork"):
        pytest.skip("no fork here")
    out, n = tmp_path / "r", 2
    with atomic_folder(out, "m") as tmp:
        (tmp / "m").write_text("parent")
        with storage._LIVE_LOCK:  # (held across the fork, as another thread of the parent may hold it)
            pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            code = 1
            try:
                for i in range(n):
                    with atomic_folder(tmp_path / f"c{i}", "m") as t:
                        (t / "m").write_text("child")
                code = 0
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert [(tmp_path / f"c{i}" / "m").read_text() for i in range(n)] == ["child"] * n
    assert (out / "m").read_text() == "parent" and leftovers(tmp_path) == []


def test_a_folder_moved_away_while_it_is_checked_is_as_if_none(tmp_path, monkeypatch):
    """Another writer renames the old output aside and its own into place; a writer checking
    the destination between the two (it existed a moment ago, now it does not) goes on as if
    there were none, where it said "No such file or directory" (a FileNotFoundError from
    listing the folder) and lost its finished output."""
    out = tmp_path / "r"
    out.mkdir()
    (out / "x").write_text("someone's")
    real = storage.is_mount

    def moved_meanwhile(path):  # (looked at after the folder was seen to exist, before it is listed)
        answer = real(path)
        if path == out.resolve() and out.exists():
            out.rename(tmp_path / ".r.old-elsewhere")
        return answer

    monkeypatch.setattr(storage, "is_mount", moved_meanwhile)
    assert storage.check_destination(out, "m") == out.resolve()
