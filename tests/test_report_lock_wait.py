"""``tlm report DIR`` holds DIR's lock while it reads it (no run replaces the folder meanwhile,
:func:`tlm.storage.folder_lock`), and so waits while another process holds it: a ``tlm run --out
DIR`` swapping its folder in or reading it for its own report, another ``tlm report DIR``. It waited
without a word (25 s of nothing, where an older tlm read at once). Now it says, once, on stderr,
that it waits and for which process (:func:`tlm.claims.lock_holder`: ``process PID on this
machine, HOST (its command line)``), and goes on when the folder is free.

The lock is held here by the test itself, as a reviewer held it: ``flock`` on the folder's
descriptor. No sleep is a timing assertion: the child's line is awaited with a generous deadline,
and the child cannot end while the test holds the lock."""

from __future__ import annotations

import fcntl
import os
import queue
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tlm import claims, storage
from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
RUN = ["run", str(REPO / "configs" / "cornell.yaml"), "--out", "out dir", "--mode", "rcast", "--no-progress",
       "--no-reference", "--no-report", "--set", "resolution=[16,16]", "--set", "render.spp=1", "--set",
       "render.light_samples=1", "--set", "arch.frames=2", "--set", "arch.trace=false"]
WAITS = "a run replacing it or a report reading it: the report waits for it to end"


def held(folder: Path) -> int:
    """A descriptor of ``folder`` holding its exclusive lock (closing it lets go), as a writer holds it."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    return fd


@pytest.mark.slow
def test_tlm_report_says_once_that_it_waits_for_the_folders_lock_and_for_which_process(tmp_path, monkeypatch, cache):
    monkeypatch.chdir(tmp_path)
    assert main(RUN) == 0
    fd = held(tmp_path / "out dir")
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(cache)}
    child = subprocess.Popen([sys.executable, "-m", "tlm", "report", "out dir", "--out", "rep"], cwd=tmp_path,
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue[str] = queue.Queue()
    said: list[str] = []

    def read() -> None:
        for line in child.stderr:
            lines.put(line)
        lines.put("")  # (its stderr closed: it ended)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        while not (said and said[-1].startswith("tlm: note: 'out dir' is held")):
            try:
                line = lines.get(timeout=120)  # (a deadline for a line said before any work: generous)
            except queue.Empty:
                pytest.fail(f"tlm report waited for the folder's lock without saying so: {said}")
            assert line, f"tlm report ended without waiting for the folder's lock: {said}"
            said.append(line)
        assert re.fullmatch(rf"tlm: note: 'out dir' is held by process {os.getpid()} on this machine, \S+ "
                            rf"\(.+\), {re.escape(WAITS)}\n", said[-1]), said
        assert child.poll() is None and not (tmp_path / "rep").exists()  # (it waits: nothing written)
    finally:
        os.close(fd)  # (lets go: the report goes on)
        try:
            child.wait(timeout=300)
        finally:
            if child.poll() is None:
                child.kill()
    reader.join(timeout=60)
    while not lines.empty():
        said.append(lines.get())
    stdout = child.stdout.read()
    assert child.returncode == 0, "".join(said)
    assert stdout == "wrote rep/report.html\n"
    assert (tmp_path / "rep" / "report.html").is_file()
    assert sum("is held by" in line for line in said) == 1, said  # (once)


def test_the_folder_lock_says_once_that_it_waits_and_nothing_when_it_is_free(tmp_path):
    """:func:`tlm.storage.folder_lock`'s ``waiting``: called once, before it waits, where another
    holds the lock (another descriptor's ``flock``, here of this process: flock's locks are the open
    file's); not called when the folder is free; the lock then taken all the same."""
    folder = tmp_path / "d"
    folder.mkdir()
    told: list[str] = []
    with storage.folder_lock(folder, waiting=lambda: told.append("waits")):
        assert told == []  # (free: nothing said)
    fd = held(folder)
    waiting, inside = threading.Event(), threading.Event()

    def lock() -> None:
        with storage.folder_lock(folder, waiting=lambda: told.append("waits") or waiting.set()):
            inside.set()

    t = threading.Thread(target=lock, daemon=True)
    try:
        t.start()
        assert waiting.wait(timeout=60), "folder_lock waited without saying so"
        assert not inside.is_set()  # (said before it waits, and it waits: the lock is held)
    finally:
        os.close(fd)
    t.join(timeout=60)
    assert inside.is_set() and told == ["waits"]


def test_the_lock_holder_is_the_process_holding_the_folders_flock(tmp_path):
    """:func:`tlm.claims.lock_holder`: the process named as a claim's refusal names one, with its
    command line; this process where it is the holder; None where no process holds it."""
    folder = tmp_path / "d"
    folder.mkdir()
    assert claims.lock_holder(folder) is None
    fd = held(folder)
    try:
        assert claims.lock_holder(folder) == f"this process ({os.getpid()})"
    finally:
        os.close(fd)
    hold = ("import fcntl, os, sys\nfd = os.open(sys.argv[1], os.O_RDONLY | os.O_DIRECTORY)\n"
            "fcntl.flock(fd, fcntl.LOCK_EX)\nprint('held', flush=True)\nsys.stdin.read()\n")
    other = subprocess.Popen([sys.executable, "-c", hold, str(folder)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
    try:
        assert other.stdout.readline() == "held\n"
        holder = claims.lock_holder(folder)
        assert re.fullmatch(rf"process {other.pid} on this machine, \S+ \(\S*python\S* -c .*\)", holder, re.S), holder
    finally:
        other.communicate("", timeout=60)
    assert claims.lock_holder(folder) is None
