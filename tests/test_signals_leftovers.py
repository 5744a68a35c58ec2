"""How a command ends, three leftovers.

An exit handler registered once the command ended (``weakref.finalize``'s, made then) ran twice:
the interpreter runs the last registered first, then :func:`tlm.cli_signals._end`, which runs the
handlers still registered (``atexit._run_exitfuncs``: no public call does) and ended the process,
ran it again. A command that failed (exit status 1 or 2) did not get the handler a successful one
gets until the process exits (:func:`tlm.cli_signals.until_exit`): a signal then killed it
(SIGTERM, returncode -15) or printed a KeyboardInterrupt's traceback. And a Ctrl-C about a second
into ``tlm sweep --jobs 2`` sometimes added multiprocessing's traceback from a worker: the
interrupt landed while the pool started it, before the pool knew its pid, so the sweep could not
kill it, and it failed to read its semaphores once the sweep had gone; and one a little earlier,
while the fork server started (SIGINT ignored, for the workers to inherit), was lost: exit status 0.

Each exit is a fresh Python whose wrapper signals it after ``main`` returned: no timing.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers_interrupt import running
from tlm import cli_signals
from tlm.experiments.executors import LocalPool

REPO = Path(__file__).resolve().parents[1]


def default_sigint() -> None:
    """(In the child, before Python starts: SIGINT as a terminal's shell leaves it. A test
    suite run from a background shell inherits it ignored, and Python then keeps ignoring it.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
LINE = {"SIGINT": "tlm: interrupted", "SIGTERM": "tlm: terminated (SIGTERM)"}
FINISHED = ", but the command ran to its end: its output is complete"

WRAPPER = """
import atexit, os, signal, sys, weakref
from pathlib import Path
def note(name):
    with open("ran", "a") as f:
        f.write(name + "\\n")
atexit.register(note, "before")
from tlm import cli
{patch}
sys.argv[1:] = {argv!r}
status = cli.main()
{after}
sys.exit(status)
"""


def run(tmp_path, argv: list[str], after: str = "", patch: str = "") -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    code = WRAPPER.format(argv=argv, after=after, patch=patch)
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          preexec_fn=default_sigint,
                          timeout=120)


def test_an_exit_handler_registered_after_the_command_ended_runs_once(tmp_path):
    after = ("def note_after():\n    note('after')\n"
             "atexit.register(note_after)\n"
             "class Held: pass\n"
             "held = Held()\n"
             "weakref.finalize(held, note, 'finalized')\n")  # (weakref.finalize registers its handler now)
    proc = run(tmp_path, ["params"], after)
    assert proc.returncode == 0, proc.stderr
    assert sorted((tmp_path / "ran").read_text().split()) == ["after", "before", "finalized"]


@pytest.mark.parametrize("sig", ["", "SIGTERM"])
def test_a_function_registered_before_and_after_the_command_ended_runs_once_each_time(tmp_path, sig):
    """Its registration after the command cannot be unregistered alone: the interpreter runs them
    all, each once, as at any exit (a signal among them is said; the exit status is then the
    command's, which only the end of the exit handlers could change)."""
    kill = f"atexit.register(os.kill, os.getpid(), signal.{sig})\n" if sig else ""
    proc = run(tmp_path, ["params"], kill + "atexit.register(note, 'after')")
    assert (tmp_path / "ran").read_text().split() == ["after", "before"]
    if sig:
        assert proc.stderr == LINE[sig] + FINISHED + "\n"
    else:
        assert (proc.returncode, proc.stderr) == (0, "")


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("failure", ["bad-input", "internal-error"])
def test_a_signal_as_a_failed_command_exits_is_still_the_commands(tmp_path, sig, failure):
    """As after one that succeeded: the line says it ran to its end, and the status is 128 + it."""
    patch = ("def broken(args):\n    raise RuntimeError('a bug')\ncli._cmd_params = broken\n"
             if failure == "internal-error" else "")
    argv = ["params"] if failure == "internal-error" else ["run", str(tmp_path / "missing.yaml")]
    proc = run(tmp_path, argv, f"os.kill(os.getpid(), signal.{sig})", patch)
    first = "tlm: internal error: RuntimeError: a bug" if failure == "internal-error" else "tlm: error: "
    lines = proc.stderr.splitlines()
    assert proc.returncode == 128 + getattr(signal, sig), proc.stderr
    assert len(lines) == 2 and lines[0].startswith(first) and lines[1] == LINE[sig] + FINISHED, proc.stderr
    assert (tmp_path / "ran").read_text() == "before\n"  # (the exit handlers ran, once)


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(), reason="no forkserver")
def test_a_signal_while_the_pool_starts_a_worker_lets_the_sweep_kill_it(monkeypatch):
    """The interrupt waits until the pool knows the worker it started: stop() kills it (it did
    not know it before, and the worker outlived the sweep). A second signal meanwhile (``timeout
    -s INT`` signals the process and then its group) does not end the process before that."""
    from multiprocessing import popen_forkserver

    pool = LocalPool(1)
    started: list[int] = []
    real = popen_forkserver.Popen

    def signalled(process_obj):  # (the worker forked, its pid read, before the pool notes it)
        popen = real(process_obj)
        started.append(popen.pid)
        for sig in (signal.SIGTERM, signal.SIGINT):  # (the second, as timeout's to the group: the same one)
            os.kill(os.getpid(), sig)
            for _ in range(10**7):  # (the handler runs at one of these instructions)
                pass
        return popen

    monkeypatch.setattr(popen_forkserver, "Popen", signalled)
    try:
        with cli_signals.signals(), pytest.raises(KeyboardInterrupt):
            pool.submit(abs, -1)
        assert cli_signals.signalled() == signal.SIGTERM
    finally:
        killed = pool.stop()
    assert len(started) == 1 and started[0] in killed
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and running(started[0]):
        time.sleep(0.05)
    assert not running(started[0])


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="POSIX")
def test_a_ctrl_c_while_the_sweep_starts_its_workers_is_not_lost(tmp_path):
    """SIGINT is ignored while the workers start (they inherit it): one that came then was
    dropped, and the sweep ran to its end (exit status 0). Now it is taken as the start ends
    (in a fresh Python: the main thread's is blocked, and a thread of another test's could take it)."""
    code = ("import os, signal, time\n"
            "from tlm.experiments.executors import _sigint_ignored\n"
            "try:\n"
            "    with _sigint_ignored():\n"
            "        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN\n"
            "        os.kill(os.getpid(), signal.SIGINT)\n"
            "        time.sleep(0.05)\n"
            "        print('not taken there')\n"
            "except KeyboardInterrupt:\n"
            "    print('taken after')\n"
            "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler,\n"
            "      signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []))\n")
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          preexec_fn=default_sigint, timeout=120)
    assert (proc.returncode, proc.stdout.split("\n")) == (0, ["not taken there", "taken after", "True False", ""]), \
        proc.stderr


def _held(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def test_a_stopped_pool_has_closed_its_wake_up_pipe():
    """An interrupted sweep's pool, once ``stop`` returns, has closed its manager thread's wake-up
    pipe: CPython 3.11's exit handler (``concurrent.futures.process._python_exit``) writes to that
    pipe unguarded, and the manager thread, closing it meanwhile (it saw the killed workers), made
    the write fail: "Exception ignored in: <module 'threading'> ... OSError: [Errno 9] Bad file
    descriptor" after tlm's own line (CI, ``test_a_sweep_signalled_stops_its_workers[SIGINT-twice]``)."""
    pool = LocalPool(2)
    futures = [pool.submit(_held, 60) for _ in range(2)]
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(pool.pids) < 2:
        pool._read_started()
        time.sleep(0.01)
    assert len(pool.pids) == 2, "the workers did not start the points"
    manager, wakeup = pool.pool._executor_manager_thread, pool.pool._executor_manager_thread_wakeup
    killed = pool.stop()
    assert len(killed) == 2 and all(f.cancelled() for f in futures)
    assert not manager.is_alive() and wakeup._closed
