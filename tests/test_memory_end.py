"""The process's own command that ran out of memory ends after its line, before the threads are joined.

A ``tlm run`` under ``ulimit -v 430000`` (tests/test_faults_h141.py) sometimes printed CPython's own
"Exception ignored in: <module 'threading'> ... MemoryError" after tlm's out-of-memory line, or never
ended (the CI run's 120 s timeout): the interpreter's exit joins the threads (a pool's workers) and runs
the exit handlers, with the memory still short. Now :func:`tlm.cli_failed.exit_status` ends such a
process itself (:func:`tlm.cli_failed._memory_end`). A thread that never ends stands for a join that
cannot finish: before, the process waited for it for ever."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from tlm import cli_failed

from .test_faults import CORNELL, SMALL

REPO = Path(__file__).resolve().parents[1]

def ending(raised: str) -> str:
    """A ``tlm`` command line whose ``api.run`` raises ``raised`` (an expression) while a pool's call never ends
    (a worker the interpreter's exit would join: a wait for ever, unless the command ends before that join)."""
    return textwrap.dedent("""
        import sys, threading
        from concurrent.futures import ThreadPoolExecutor
        import tlm.cli_signals
        from tlm import api, cli
        pool = ThreadPoolExecutor(1)
        pool.submit(threading.Event().wait)  # (a worker that never ends: the interpreter's exit would join it)
        def run(*args, **kwargs):
            raise RAISED
        api.run = run
        sys.argv = ["tlm", *sys.argv[1:]]
        sys.exit(cli.main())
    """).replace("RAISED", raised)


SCRIPT = ending('MemoryError("Unable to allocate 1.00 GiB for an array with shape (134217728,) and data type float64")')


def test_a_run_out_of_memory_ends_with_its_line_and_joins_no_thread(tmp_path):
    out = tmp_path / "r"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "run", CORNELL, "--out", str(out), "--no-reference", *SMALL],
                          cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)}, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines[-1].startswith("tlm: error: out of memory: Unable to allocate 1.00 GiB"), proc.stderr
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert not out.exists()  # (nothing half written)


def test_a_library_call_out_of_memory_ends_nothing():
    """``main`` given its argv (a library call): the status, and the process goes on."""
    assert cli_failed.exit_status(MemoryError("Unable to allocate 8.00 GiB"), ["run"]) == 1


def test_what_is_out_of_memory():
    assert cli_failed._out_of_memory(MemoryError("Unable to allocate 8.00 GiB"))
    assert not cli_failed._out_of_memory(ValueError("bad"))


LOST_WORKER = textwrap.dedent("""
    from concurrent.futures import _base
    from tlm.kernels import threads
    def unset(self, exc):  # (the outcome of a call cannot be set: a MemoryError, as under ulimit -v)
        raise MemoryError("no memory to set the outcome")
    _base.Future.set_exception = unset
    with threads.using(2):
        future = threads.background(lambda: 1 / 0)
        try:
            threads.result(future)
        except MemoryError as e:
            print("raised:", e)
""")


def test_a_kernel_thread_that_ended_without_its_result_is_an_error_not_a_wait_for_ever(tmp_path):
    """concurrent.futures ends a worker whose call's outcome could not be set, leaving the call's future
    running for ever: the caller waited for ever. Now its wait raises what ended the worker, and the
    worker's logged traceback is not printed."""
    proc = subprocess.run([sys.executable, "-c", LOST_WORKER], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "raised: no memory to set the outcome", proc
    assert "Traceback" not in proc.stderr and "Exception in worker" not in proc.stderr, proc.stderr


def test_an_out_of_memory_error_said_off_the_main_thread_ends_nothing():
    """exit_status of the process's own command (argv None) on another thread: its line and 1, the process left
    running (before: _memory_end read an exit status until_exit had not recorded there, an IndexError)."""
    import threading

    got: list = []
    worker = threading.Thread(target=lambda: got.append(cli_failed.exit_status(MemoryError("x"), None)))
    worker.start()
    worker.join()
    assert got == [1]
