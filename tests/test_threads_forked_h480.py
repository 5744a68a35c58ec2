"""h480: the forked pool's waits notice a manager thread that ended, and the thread pools' lost errors are
their own pool's.

With ``TLM_FORK_WORKERS=1`` a ``tlm run`` under ``ulimit -v`` 444-450 MB hung: the process pool's manager
thread (which queues the calls for the forked workers and sets their outcomes) died ("can't start new
thread", a MemoryError), and :func:`tlm.kernels.threads.forked` waited on a future that never finished.
Its waits are polled now (:func:`tlm.kernels.threads_forked._outcome`) and raise what ended that thread.

:func:`tlm.kernels.threads.result` raised the last error that ended any pool's worker (one list for all):
a wait could raise another pool's error, and an error nobody waited for was kept for ever (its frames,
the call's arrays, with it). Each runs in a fresh interpreter with a timeout: the hazard is a hang.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

needs_fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")


def _run(script: str, timeout: float = 60, **env: str) -> subprocess.CompletedProcess:
    """``script`` in a fresh interpreter; a hang fails the test (its process group killed: its workers too)."""
    environ = {k: v for k, v in os.environ.items() if k != "TLM_FORK_WORKERS"}
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(script)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=REPO,
                            env={**environ, "PYTHONPATH": str(REPO), **env}, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"waited for ever (killed after {timeout} s): {out!r} {err!r}")
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


MANAGER_ENDS = """
    import sys
    from concurrent.futures import process
    from tlm.kernels import threads
    def queue(self):  # (the manager thread cannot queue a call: a MemoryError, as under ulimit -v)
        raise MemoryError("no memory to queue the call")
    def nothing(self):  # (the manager thread ends at once, nothing said: its calls never finish)
        pass
    if sys.argv[1] == "memory":
        process._ExecutorManagerThread.add_call_item_to_queue = queue
    else:
        process._ExecutorManagerThread.run = nothing
    with threads.using(2):
        assert threads.can_fork()
        try:
            print("returned", list(threads.forked(lambda i: i, range(5), 2)))
        except (MemoryError, RuntimeError) as e:
            print("raised:", type(e).__name__, e)
"""


@needs_fork
@pytest.mark.parametrize("how", ["memory", "silent"])
def test_a_forked_pool_whose_manager_thread_ended_raises_not_waits_for_ever(how):
    """The workers are killed and reaped too: the interpreter's exit, which joins them, ends."""
    proc = _run(MANAGER_ENDS.replace("sys.argv[1]", repr(how)), TLM_FORK_WORKERS="1")
    assert proc.returncode == 0, proc.stderr
    said = {"memory": "raised: MemoryError no memory to queue the call",
            "silent": "raised: RuntimeError the forked workers' manager thread ended without finishing a call"}
    assert proc.stdout.strip() == said[how], proc
    assert "Traceback" not in proc.stderr and "Exception in thread" not in proc.stderr, proc.stderr


LOST_ELSEWHERE = """
    import time
    from concurrent.futures import _base
    from tlm.kernels import threads
    kept = _base.Future.set_exception
    def unset(self, exc):  # (the outcome of a call cannot be set: its worker thread ends)
        raise MemoryError(f"no memory to set the outcome {exc}")
    def lost(n, fn):
        with threads.using(n):
            future = threads.background(fn)
        while not future._tlm_thread or future._tlm_thread[0].is_alive():
            time.sleep(0.01)
        return future
    _base.Future.set_exception = unset
    mine = lost(2, lambda: 1 / 0)
    other = lost(3, lambda: [][1])  # (another pool's worker ends after: its error is not mine)
    _base.Future.set_exception = kept
    for future in (mine, other):
        try:
            threads.result(future)
        except MemoryError as e:
            print("raised:", e)
"""


def test_a_wait_raises_what_ended_its_own_worker_not_another_pools():
    proc = _run(LOST_ELSEWHERE)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["raised: no memory to set the outcome division by zero",
                                        "raised: no memory to set the outcome list index out of range"], proc
    assert "Traceback" not in proc.stderr, proc.stderr


LOST_UNWAITED = """
    import gc, time, weakref
    from concurrent.futures import _base
    from tlm.kernels import threads
    kept = _base.Future.set_exception
    def unset(self, exc):
        raise MemoryError("no memory to set the outcome")
    class Held:  # (an array the call holds: its frame is in the lost error's traceback)
        pass
    refs = []
    def call():
        held = Held()
        refs.append(weakref.ref(held))
        return 1 / 0
    _base.Future.set_exception = unset
    with threads.using(2):
        future = threads.background(call)
    while not future._tlm_thread or future._tlm_thread[0].is_alive():
        time.sleep(0.01)
    _base.Future.set_exception = kept
    del future  # (nobody waits for it)
    with threads.using(2):  # (the next call runs on live threads)
        print("then:", threads.result(threads.background(lambda: 2)))
    gc.collect()
    print("kept:", refs[0]() is not None)
"""


def test_a_lost_error_nobody_waits_for_is_not_kept():
    proc = _run(LOST_UNWAITED)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["then: 2", "kept: False"], proc
