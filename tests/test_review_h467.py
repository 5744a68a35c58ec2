"""Review of 2c18b48 (h467): :func:`tlm.kernels.threads.result` polls its future with a timeout, and a
call that itself raised TimeoutError (an OSError of errno ETIMEDOUT: a network disk's read) looked like
the poll's own timeout: the wait took it again and again, for ever, where the error was raised before."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from concurrent.futures import Future
from pathlib import Path

import pytest

from tlm.kernels import threads

from .test_memory_end import ending

REPO = Path(__file__).resolve().parents[1]


class _Asked(Future):
    """A future that says how often its outcome was asked for: a wait that asks again and again fails."""

    def __init__(self) -> None:
        super().__init__()
        self.asked = 0

    def result(self, timeout=None):
        self.asked += 1
        if self.asked > 3:
            raise AssertionError("the outcome asked for again and again: a wait for ever")
        return super().result(timeout)


def test_a_call_that_raised_timeout_error_raises_it():
    future = _Asked()
    future.set_exception(TimeoutError(110, "Connection timed out"))
    with pytest.raises(TimeoutError, match="Connection timed out"):
        threads.result(future)



LOST_TWICE = textwrap.dedent("""
    from concurrent.futures import _base
    from tlm.kernels import threads
    kept = _base.Future.set_exception
    def unset(self, exc):  # (the outcome of a call cannot be set: a MemoryError, as under ulimit -v)
        raise MemoryError("no memory to set the outcome")
    _base.Future.set_exception = unset
    with threads.using(2):
        for _ in range(2):  # (each of the pool's two threads ends so)
            try:
                threads.result(threads.background(lambda: 1 / 0))
            except MemoryError as e:
                print("raised:", e)
        _base.Future.set_exception = kept
        print("then:", threads.result(threads.background(lambda: 2)))
""")


def test_a_pool_whose_threads_all_ended_is_not_used_again(tmp_path):
    """The pool's threads all ended without their calls' outcomes: the next call (a notebook's next run,
    an in-process sweep's next point) ran on that pool, whose queue no thread reads: a wait for ever."""
    proc = subprocess.run([sys.executable, "-c", LOST_TWICE], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["raised: no memory to set the outcome"] * 2 + ["then: 2"], proc.stdout


NO_THREAD = ending('RuntimeError("can\'t start new thread")')  # (a call still in flight, as out of memory)


def test_a_run_that_could_start_no_thread_ends_with_its_line_and_joins_no_thread(tmp_path):
    """``tlm run`` under ``ulimit -v 443000``: ``no new thread could be started`` (a thread's stack not
    mapped), then the interpreter's exit joined the pool's calls still in flight, which went on loading
    kernels and ended the process in a segmentation fault (exit status 139) after tlm's line."""
    from .test_faults import CORNELL, SMALL

    out = tmp_path / "r"
    proc = subprocess.run([sys.executable, "-c", NO_THREAD, "run", CORNELL, "--out", str(out), "--no-reference",
                           *SMALL], cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)}, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("tlm: error: no new thread could be started"), proc.stderr
    assert "Traceback" not in proc.stderr and not out.exists(), proc.stderr
