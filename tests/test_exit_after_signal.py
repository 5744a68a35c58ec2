"""A signal is never lost from the exit status. SIGINT / SIGTERM turn into a KeyboardInterrupt
(:func:`tlm.cli_signals.on_signal`); where it is raised inside code whose exceptions CPython
ignores (an at-fork hook, an llvmlite ctypes callback during a numba compilation) the command
runs to its end, and ``tlm`` still exits 130 / 143, saying that its output is complete. And
``python -m tlm`` exits with the status ``main`` returned even when the interrupt left an
``exec`` of a string (numba's generated source), which otherwise makes CPython end the
process by SIGINT at exit (130 for a SIGTERM, or "killed by SIGINT" rather than exit 130)."""

from __future__ import annotations

import os
import runpy
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pytest

import tlm.cli as cli
from tlm import api, cli_signals
from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
SIGNALS = pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
LINE = {signal.SIGINT: "tlm: interrupted", signal.SIGTERM: "tlm: terminated (SIGTERM)"}
FINISHED = ", but the command ran to its end: its output is complete"


def swallowing(sig: int, calls: list | None = None):
    """A command that signals itself where its KeyboardInterrupt is swallowed (as CPython does
    in an at-fork hook or a ctypes callback), prints its output and returns 0. ``calls``: the
    argv of each call, made to signal only at the first (a second signal ends the process)."""
    def command(args) -> int:
        if calls is not None:
            calls.append(args.argv)
            if len(calls) > 1:
                return 0
        try:
            os.kill(os.getpid(), sig)
            for _ in range(10**7):  # (the handler raises at one of these instructions)
                pass
        except KeyboardInterrupt:
            pass
        print("the whole output")
        return 0
    return command


@SIGNALS
def test_a_signal_whose_interrupt_was_swallowed_still_exits_128_plus_it(sig, monkeypatch, capsys):
    monkeypatch.setattr(cli, "_cmd_params", swallowing(sig))
    before = signal.getsignal(sig)
    assert main(["params"]) == 128 + sig  # (0 before: the command returned 0)
    out, err = capsys.readouterr()
    assert out == "the whole output\n"
    assert err == LINE[sig] + FINISHED + "\n"
    assert signal.getsignal(sig) == before


def test_an_interrupt_a_ctypes_callback_ignored_prints_no_traceback(monkeypatch, capsys):
    """CPython ignores an exception raised in a ctypes callback (llvmlite's, during a numba
    compilation): it prints "Exception ignored on calling ctypes callback function" and the
    traceback. Here the exit's one line says it all; the hook is the one before once done."""
    import ctypes

    @ctypes.CFUNCTYPE(None)
    def callback():
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(10**7):  # (the handler raises at one of these instructions)
            pass

    def command(args) -> int:
        callback()
        print("the whole output")
        return 0

    monkeypatch.setattr(cli, "_cmd_params", command)
    ignored = []  # (what would print "Exception ignored ...": pytest's own hook makes it a warning)
    monkeypatch.setattr(sys, "unraisablehook", ignored.append)
    assert main(["params"]) == 143
    assert capsys.readouterr() == ("the whole output\n", LINE[signal.SIGTERM] + FINISHED + "\n")
    assert ignored == [] and sys.unraisablehook == ignored.append


@SIGNALS
def test_a_signal_as_the_command_returns_says_its_output_is_complete(sig, monkeypatch, capsys):
    """The command returned, its handlers not yet restored: the interrupt comes out of no
    command, so nothing is half written: the line says the output is complete."""
    real = cli_signals.signals

    @contextmanager
    def late():
        with real():
            yield
            os.kill(os.getpid(), sig)

    monkeypatch.setattr(cli, "signals", late)
    monkeypatch.setattr(cli, "_cmd_params", lambda args: print("the whole output") or 0)
    assert main(["params"]) == 128 + sig
    out, err = capsys.readouterr()
    assert (out, err) == ("the whole output\n", LINE[sig] + FINISHED + "\n")


def test_plots_begins_no_step_after_a_lost_interrupt(tmp_path, monkeypatch, capsys):
    """``tlm plots`` runs its steps in its own process: a step whose interrupt was lost ran to
    its end, and the next one is not begun (stopped as by a Ctrl-C that landed)."""
    calls: list = []
    monkeypatch.setattr(cli, "_cmd_params", swallowing(signal.SIGTERM, calls))
    began = []

    def plots(configs, runs, out, only, run_command, say, formats, dpi):
        for _ in range(3):
            began.append(len(calls))
            run_command(["params"])
        return tmp_path / "report.html"

    monkeypatch.setattr(api, "plots", plots)
    assert main(["plots"]) == 143  # (0 before, with the three steps run)
    assert calls == [["params"]] and began == [0, 1]
    assert capsys.readouterr().err == "tlm: terminated (SIGTERM)\n"


def _run_module_with_exec_interrupt(sig_name: str) -> None:
    """``python -m tests.test_exit_after_signal SIG params``: ``tlm/__main__.py`` run as
    ``python -m tlm`` runs it, with ``tlm params`` signalled inside an ``exec`` of a string,
    as a signal landing in numba's (or a dataclass's) generated source is."""
    sig = getattr(signal, sig_name)

    def command(args) -> int:
        exec(f"import os\nos.kill(os.getpid(), {int(sig)})\nfor _ in range(10**7): pass")
        raise AssertionError("the signal raised nothing")

    cli._cmd_params = command
    runpy.run_module("tlm", run_name="__main__", alter_sys=True)


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_python_m_tlm_exits_with_mains_status_after_an_interrupt_through_exec(sig, tmp_path):
    """The interrupt left the ``exec``: CPython's flag for an unhandled KeyboardInterrupt is
    set, and ``python -m`` then ended the process by SIGINT at exit (returncode -2: a shell's
    130, after "terminated (SIGTERM)"). Now the status is ``main``'s: 143, and 130 for a
    Ctrl-C, an exit status as where the interrupt passed through no ``exec``."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-m", "tests.test_exit_after_signal", sig, "params"], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    number = getattr(signal, sig)
    assert (proc.returncode, proc.stderr) == (128 + number, LINE[number] + "\n")


if __name__ == "__main__":
    _run_module_with_exec_interrupt(sys.argv.pop(1))
