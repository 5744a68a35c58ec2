"""The command line's edges: a signal while ``--help`` or ``--version`` exits, a signal before the
command began (the process's imports), how the API knows that the command line called it, and
``tlm sweep``'s ``--no-progress`` made as every command's is.

A signal after ``tlm --version`` (or a command's ``--help``) printed, while the process exits,
killed it (SIGTERM: returncode -15, no line) or printed a KeyboardInterrupt's traceback: that
exit (argparse's SystemExit) had no late handler (:func:`tlm.cli_signals.until_exit`). A Ctrl-C
in about the first second of ``tlm ...`` (its imports, before the command's handler) printed a
traceback of the import it cut, and a SIGTERM killed the process without a line
(:func:`tlm.cli_signals.early_signals`). The API renamed ``--out`` to ``out`` in its errors unless
the calling frame's module was named ``tlm.cli*``, so a plugin module of such a name got the
command line's flags (:func:`tlm.api_common.argument_names`, now told by ``main``)."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import tlm
import tlm.cli as cli
import tlm.cli_parser as cli_parser
from tlm import cli_signals

REPO = Path(__file__).resolve().parents[1]


def default_sigint() -> None:
    """(In the child, before Python starts: SIGINT as a terminal's shell leaves it. A test
    suite run from a background shell inherits it ignored, and Python then keeps ignoring it.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
SIGNALS = pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
LINE = {"SIGINT": "tlm: interrupted", "SIGTERM": "tlm: terminated (SIGTERM)"}
FINISHED = ", but the command ran to its end: its output is complete"


def python(tmp_path, *args: str) -> subprocess.CompletedProcess:
    """A fresh Python with this checkout's tlm, in ``tmp_path``."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    return subprocess.run([sys.executable, *args], cwd=tmp_path, env=env, capture_output=True, text=True,
                          preexec_fn=default_sigint,
                          timeout=120)


EXITING = """
import os, signal, sys
from tlm import cli
sys.argv[1:] = {argv!r}
status = cli.main()
os.kill(os.getpid(), signal.{sig})  # (as the process exits: main returned)
sys.exit(status)
"""


@SIGNALS
@pytest.mark.parametrize("argv", [["--version"], ["run", "--help"]], ids=["version", "help"])
def test_a_signal_as_help_or_version_exits_is_still_the_commands(tmp_path, sig, argv):
    """As after any command that ended: the line says it ran to its end, the status is 128 + it
    (it was killed by SIGTERM, or printed a KeyboardInterrupt's traceback)."""
    proc = python(tmp_path, "-c", EXITING.format(argv=argv, sig=sig))
    assert proc.returncode == 128 + getattr(signal, sig), (proc.returncode, proc.stderr)
    assert proc.stderr == LINE[sig] + FINISHED + "\n"
    assert proc.stdout.startswith("tlm " if argv == ["--version"] else "usage: tlm run")


# an import hook that signals the process while tlm.api is being imported (tlm.cli's imports: the
# first second of a command under load), then the command's entry: {entry}
SIGNAL_IN_IMPORTS = """
import importlib.abc, os, signal, sys

class SignalInImport(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "tlm.api":
            os.kill(os.getpid(), signal.{sig})
        return None

sys.meta_path.insert(0, SignalInImport())
{entry}
"""
SCRIPT = "from tlm.cli import main\nsys.exit(main())\n"  # (the installed tlm script's body)
MINUS_M = "import runpy\nrunpy.run_module('tlm', run_name='__main__', alter_sys=True)\n"  # python -m tlm
# a child of the tlm script (multiprocessing's spawn: it runs the script as __mp_main__, importing tlm.cli)
CHILD = """
import multiprocessing, signal, sys
from tlm.cli import main

def handlers():
    defaults = (signal.default_int_handler, signal.SIG_DFL)
    return [signal.getsignal(s) in defaults for s in (signal.SIGINT, signal.SIGTERM)]

if __name__ == "__main__":
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        print(pool.apply(handlers))
"""


@SIGNALS
@pytest.mark.parametrize("entry", ["script", "python -m"])
def test_a_signal_during_the_imports_is_the_commands(tmp_path, sig, entry):
    """One line and 130 / 143, nothing printed by the command (it stops as it begins), no
    traceback (there was one of the import it cut, or for SIGTERM no line at all). The ``tlm``
    script is a file of that name; ``python -m tlm`` is runpy's. A process that imports tlm is
    not the command's (this one, the test's), nor is a child the tlm script spawns."""
    if entry == "script":
        (tmp_path / "tlm").write_text(SIGNAL_IN_IMPORTS.format(sig=sig, entry=SCRIPT))
        proc = python(tmp_path, str(tmp_path / "tlm"), "params")
    else:
        proc = python(tmp_path, "-c", SIGNAL_IN_IMPORTS.format(sig=sig, entry=MINUS_M), "params")
    assert proc.returncode == 128 + getattr(signal, sig), (proc.returncode, proc.stderr)
    assert proc.stderr == LINE[sig] + "\n"
    assert proc.stdout == ""
    # (not where tlm is imported: a notebook's, a test's Ctrl-C stays Python's)
    assert not cli_signals.command_process()
    assert signal.getsignal(signal.SIGINT) is not cli_signals._early_signal
    (tmp_path / "tlm").write_text(CHILD)
    proc = python(tmp_path, str(tmp_path / "tlm"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[True, True]"


PLUGIN = """
import tlm

def report(folder):
    tlm.write_report([folder, folder])
"""


def test_a_module_named_tlm_cli_something_gets_argument_names(tmp_path, capsys):
    """Only ``tlm.cli.main``'s command keeps the flags (it says so), not a library call from a
    module whose name starts with ``tlm.cli`` (a plugin, a test helper); ``python -m tlm`` and
    ``main([...])`` keep them, and a library call after ``main`` returned gets the names again."""
    (tmp_path / "plugin.py").write_text(PLUGIN)
    spec = importlib.util.spec_from_file_location("tlm.cli_plugin", tmp_path / "plugin.py")
    plugin = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plugin)
    with pytest.raises(tlm.InputError) as e:
        plugin.report(tmp_path)
    assert str(e.value) == "out: several folders: name the report folder"
    proc = python(tmp_path, "-m", "tlm", "report", str(tmp_path), str(tmp_path))
    assert proc.returncode == 2
    assert proc.stderr.startswith("tlm: error: --out: several folders: name the report folder"), proc.stderr
    assert cli.main(["report", str(tmp_path), str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("tlm: error: --out: several folders")
    with pytest.raises(tlm.InputError, match=r"^out: several folders"):
        tlm.write_report([tmp_path, tmp_path])


def test_every_no_progress_is_made_by_the_shared_option(monkeypatch):
    """``tlm sweep``'s had its own copy of the argument and its help."""
    made = []
    real = cli_parser.no_progress  # (the commands' arguments: tlm.cli_parser, out of tlm.cli, h487)

    def recorded(parser, *args):
        made.append(parser.prog)
        return real(parser, *args)

    monkeypatch.setattr(cli_parser, "no_progress", recorded)
    parser = cli.build_parser()
    commands = parser._subparsers._group_actions[0].choices  # (argparse's: the subcommands' parsers)
    taking = [p.prog for p in commands.values() if any("--no-progress" in a.option_strings for a in p._actions)]
    assert "tlm sweep" in taking
    assert sorted(made) == sorted(taking)
    help_text = commands["sweep"].format_help()
    assert "no progress bar (none either when stderr is not a terminal)" in " ".join(help_text.split())

