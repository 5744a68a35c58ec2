"""A signal after the command's work is done, while the process exits (``tlm run`` has printed
``wrote ...``; then its threads are joined, its pools' workers ended by the exit handlers, its
modules torn down), is still the command's: the line says that it ran to its end (its output is
complete) and the exit status is 130 / 143. Before, :func:`tlm.cli_signals.signals` was left as
``main`` returned, and the default handlers took it: SIGTERM killed the process with no line
(returncode -15), SIGINT raised a KeyboardInterrupt (its traceback, or "Exception ignored" and exit 0).

Each test runs ``tlm params`` (the console script's ``sys.exit(main())``, or ``python -m tlm``)
in a fresh Python whose wrapper signals it at a set point after ``main`` returned: no timing."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers_interrupt import running
from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
SIGNALS = pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
LINE = {"SIGINT": "tlm: interrupted", "SIGTERM": "tlm: terminated (SIGTERM)"}
FINISHED = ", but the command ran to its end: its output is complete"

KILL = "os.kill(os.getpid(), signal.{sig})"
WHEN = {  # the wrapper's code before the command, and after ``status = main()`` (then sys.exit(status))
    # just after main returned, in the main thread
    "returned": ("", KILL),
    # while the interpreter joins the threads (a thread that signals once main returned)
    "threads": ("done = threading.Event()\n"
                "threading.Thread(target=lambda: (done.wait(), " + KILL + ")).start()", "done.set()"),
    # at the interpreter's exit handlers (registered first, so run last: after the command's)
    "exit-handlers": ("atexit.register(lambda: " + KILL + ")", ""),
}

WRAPPER = """
import atexit, os, signal, sys, threading
{before}
from tlm.cli import main
sys.argv[1:] = ["params"]
status = main()
{after}
sys.exit(status)
"""


def run(code: str, tmp_path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)


@pytest.fixture(scope="module")
def params_output() -> str:
    """What ``tlm params`` prints (more than stdout's buffer holds: its end is flushed at the exit)."""
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["params"]) == 0
    assert len(out.getvalue()) > 8192
    return out.getvalue()


@SIGNALS
@pytest.mark.parametrize("when", list(WHEN))
def test_a_signal_as_the_process_exits_says_the_command_ran_to_its_end(when, sig, tmp_path, params_output):
    before, after = WHEN[when]
    proc = run(WRAPPER.format(before=before.format(sig=sig), after=after.format(sig=sig)), tmp_path)
    assert (proc.returncode, proc.stderr) == (128 + getattr(signal, sig), LINE[sig] + FINISHED + "\n")
    assert proc.stdout == params_output  # whole: its end, still buffered, was flushed


@SIGNALS
def test_python_m_tlm_too(sig, tmp_path, params_output):
    """``python -m tlm`` (tlm/__main__.py), signalled at the interpreter's exit handlers."""
    code = (f"import atexit, os, runpy, signal, sys\natexit.register(lambda: {KILL.format(sig=sig)})\n"
            "sys.argv[1:] = ['params']\nrunpy.run_module('tlm', run_name='__main__', alter_sys=True)\n")
    proc = run(code, tmp_path)
    assert (proc.returncode, proc.stderr) == (128 + getattr(signal, sig), LINE[sig] + FINISHED + "\n")
    assert proc.stdout == params_output


def test_a_second_signal_at_the_exit_ends_it_at_once(tmp_path):
    """As during a command's clean-up: the second signal's line, and 128 + the first."""
    kills = f"{KILL.format(sig='SIGTERM')}, {KILL.format(sig='SIGINT')}"
    proc = run(WRAPPER.format(before=f"atexit.register(lambda: ({kills}))", after=""), tmp_path)
    assert proc.returncode == 143
    assert proc.stderr == LINE["SIGTERM"] + FINISHED + "\ntlm: interrupted again: stopping now\n"


def test_the_pools_clean_up_still_runs_after_the_signal(tmp_path):
    """The signal comes before the exit handler that ends a process pool's workers: they are
    ended all the same (the process does not die with them left running), and the exit is 143."""
    before = ("import multiprocessing, pathlib\n"
              "pool = multiprocessing.get_context('fork').Pool(2)\n"
              "pathlib.Path('workers').write_text(' '.join(str(p.pid) for p in pool._pool))\n"
              "atexit.register(lambda: " + KILL.format(sig="SIGTERM") + ")")  # (runs before the pool's)
    proc = run(WRAPPER.format(before=before, after=""), tmp_path)
    assert (proc.returncode, proc.stderr) == (143, LINE["SIGTERM"] + FINISHED + "\n")
    workers = [int(p) for p in (tmp_path / "workers").read_text().split()]
    deadline = time.monotonic() + 30  # (a hang guard: they are ended before the process exits)
    while time.monotonic() < deadline and any(map(running, workers)):
        time.sleep(0.05)
    assert len(workers) == 2 and not [p for p in workers if running(p)]
