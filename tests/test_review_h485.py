"""h485: review of 15c0c88 (h480, the forked pool's manager thread that ends).

h480 had :func:`tlm.kernels.threads_forked._outcome` kill and reap the workers of a forked pool whose
manager thread ended, where a wait on a call noticed it. A caller that stopped taking results first
(its own error, Ctrl-C: the generator closed, as ``contextlib.closing`` in the render's batches does)
had the pool shut down as a healthy one: its shutdown told no worker to stop (that is the manager's
work), the workers stayed (``multiprocessing.active_children``), and the interpreter's exit, which
joins them, waited for ever. And a pool whose manager thread could not start (the corner
:func:`~tlm.kernels.threads_forked._end_forked` names) raised the error of its shutdown's join, not
the refusal. Each runs in a fresh interpreter with a timeout: the hazard is a hang.
"""

from __future__ import annotations

import pytest

from tests.test_threads_forked_h480 import _run, needs_fork  # (a fresh interpreter, a hang killed; fork or skip)

STOPPED_EARLY = """
    import contextlib, multiprocessing
    from concurrent.futures import process
    from tlm.kernels import threads
    kept = process._ExecutorManagerThread.process_result_item
    def once(self, item):  # (the first call's outcome set, then the manager thread ends: a MemoryError)
        kept(self, item)
        raise MemoryError("no memory for the next call")
    process._ExecutorManagerThread.process_result_item = once
    with threads.using(2):
        try:
            # (one worker: the calls' outcomes come in order, so the manager sets the first and ends)
            with contextlib.closing(threads.forked(lambda i: i * 10, range(5), 1)) as results:
                for got in results:
                    print("took", got, flush=True)
                    if HOW == "close":
                        break  # (the caller takes no more: closing ends the generator)
                    raise (KeyboardInterrupt if HOW == "interrupt" else ValueError)("the caller stops")
        except (ValueError, KeyboardInterrupt) as e:
            print("raised:", type(e).__name__)
    print("workers left:", len(multiprocessing.active_children()), flush=True)
    process._ExecutorManagerThread.process_result_item = kept
    with threads.using(2):  # (a later call forks a pool of its own, and finishes)
        print("then:", list(threads.forked(lambda i: i * 10, range(5), 2)), flush=True)
"""


@needs_fork
@pytest.mark.parametrize("how", ["close", "error", "interrupt"])
def test_a_generator_closed_after_its_manager_thread_ended_leaves_no_worker(how):
    proc = _run(STOPPED_EARLY.replace("HOW", repr(how)), TLM_FORK_WORKERS="1")
    assert proc.returncode == 0, proc
    said = [] if how == "close" else [f"raised: {'KeyboardInterrupt' if how == 'interrupt' else 'ValueError'}"]
    assert proc.stdout.splitlines() == ["took 0", *said, "workers left: 0", "then: [0, 10, 20, 30, 40]"], proc
    assert "Traceback" not in proc.stderr and "Exception in thread" not in proc.stderr, proc.stderr


NOT_STARTED = """
    import multiprocessing
    from concurrent.futures import process
    from tlm.kernels import threads
    kept = process._ExecutorManagerThread.start
    def refused(self):  # (the pool's manager thread cannot start, as under ulimit -v: the workers forked)
        raise RuntimeError("can't start new thread")
    process._ExecutorManagerThread.start = refused
    with threads.using(2):
        try:
            print("returned", list(threads.forked(lambda i: i * 10, range(5), 2)))
        except RuntimeError as e:
            print("raised:", e)
    print("workers left:", len(multiprocessing.active_children()), flush=True)
    process._ExecutorManagerThread.start = kept
    with threads.using(2):
        print("then:", list(threads.forked(lambda i: i * 10, range(5), 2)), flush=True)
"""


@needs_fork
def test_a_manager_thread_that_could_not_start_is_what_the_call_raises():
    """Not "cannot join thread before it is started", which the shutdown of the half-made pool raised over
    it (the command line found the refusal in its context; a caller of the API saw the join's error)."""
    proc = _run(NOT_STARTED, TLM_FORK_WORKERS="1")
    assert proc.returncode == 0, proc
    assert proc.stdout.splitlines() == ["raised: can't start new thread", "workers left: 0",
                                        "then: [0, 10, 20, 30, 40]"], proc
