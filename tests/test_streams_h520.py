"""A stream that cannot be written stops nothing it should not (h520, from the scripting probe h518).

* stderr that cannot be written (``2>/dev/full``: ENOSPC; ``2</dev/null``: EBADF, open for reading only)
  ended ``tlm run`` with exit status 1, its results.json written and no report, a sweep with its rows and no
  report, and bad input with 1, not 2: only a BrokenPipeError was swallowed (:class:`tlm.cli_streams._Guarded`,
  :func:`tlm.cli_signals._line`, :func:`tlm.cli_report.say_err`). Now any OSError writing stderr is: stderr is
  the human's channel, and losing it changes neither the work nor the exit status.
* stdout on a full disk (``> /dev/full``) ended ``tlm run`` with ``tlm: error: no space left on device``, exit 1,
  naming no stream, and no report. Now a command that writes files runs to its end (its stdout is the summary of
  its files) and then says ``tlm: error: cannot write stdout: no space left on device``, exit 1; one that only
  prints (``tlm params``: its stdout is its output) ends at once with the same line.
* ``--out`` refused a folder holding a log written into it (``> lg/tlm.log``, Snakemake's ``log:``) with no word
  of what to do; the refusal stays, and says it.
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tlm import cli_failed, cli_report, cli_signals, cli_streams, storage
from tlm.errors import EnvironmentFailure, InputError

REPO = Path(__file__).resolve().parents[1]
FULL = "/dev/full"
needs_full = pytest.mark.skipif(not os.path.exists(FULL), reason="no /dev/full")
# (the built-in experiment by its name: its first line, which one it is, is on stderr; packets of 16, one frame)
RUN = ["run", "cornell", "--set", "resolution=[16,16]", "--set", "render.light_samples=1", "--set",
       "arch.packet_size=16", "--set", "arch.frames=1", "--no-progress"]
NO_SPACE = "tlm: error: cannot write stdout: no space left on device"


class _Failing:
    """A stream each write and flush of which raises ``OSError(code)``; no file descriptor (none is led to
    /dev/null)."""

    encoding = "utf-8"

    def __init__(self, code: int = errno.ENOSPC) -> None:
        self.code = code
        self.tries = 0

    def write(self, text):
        self.tries += 1
        raise OSError(self.code, os.strerror(self.code))

    def flush(self):
        raise OSError(self.code, os.strerror(self.code))


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EBADF, errno.EIO])
def test_stderr_that_cannot_be_written_drops_the_text_and_raises_nothing(code):
    guarded = cli_streams._Guarded(_Failing(code), "stderr")
    assert guarded.write("tlm: warning: lost\n") == len("tlm: warning: lost\n")
    guarded.flush()
    guarded.writelines(["a\n", "b\n"])
    assert guarded.error is None and not cli_streams._GONE.get("stderr")


@pytest.mark.parametrize(("code", "said"), [(errno.ENOSPC, "no space left on device"),
                                            (errno.EBADF, "bad file descriptor")])
def test_stdout_that_cannot_be_written_names_stdout(code, said):
    # a command that only prints: its stdout is its output, ended at once
    guarded = cli_streams._Guarded(_Failing(code), "stdout")
    with pytest.raises(EnvironmentFailure) as got:
        guarded.write("scene cornell\n")
    assert str(got.value) == f"cannot write stdout: {said}"
    # one that writes files: it goes on, what it prints dropped, and the failure is raised at its end
    guarded = cli_streams._Guarded(_Failing(code), "stdout")
    with cli_streams.writes_files(True):
        assert guarded.write("wrote r\n") == len("wrote r\n")
        guarded.flush()
    assert str(guarded.error) == f"cannot write stdout: {said}"
    assert not cli_streams._GONE.get("stdout")  # (not a reader gone: exit status 1, not 141)


def test_the_failure_raised_at_the_end_is_one_line_and_exit_status_1(capsys):
    failure = cli_streams.stdout_failure(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    assert cli_failed.exit_status(failure, ["run"]) == 1
    assert capsys.readouterr().err == NO_SPACE + "\n"
    assert cli_streams.stdout_failure(failure) is failure  # (said once, not "cannot write stdout: cannot ...")


def test_stdout_that_fails_at_the_exits_flush_names_stdout(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdout", _Failing())
    assert cli_signals._flushed(0) == 1
    assert capsys.readouterr().err == NO_SPACE + "\n"


def test_the_last_line_and_a_progress_line_on_a_stderr_that_cannot_be_written(monkeypatch):
    monkeypatch.setattr(sys, "stderr", _Failing())
    cli_signals._line("tlm: error: x")  # (raised OSError: ENOSPC)
    cli_report.say_err("note: y")
    # bad input is still exit status 2 (was 1: its line's OSError took the place of the InputError)
    assert cli_failed.exit_status(InputError("bogus_key: not a parameter"), ["run"]) == 2


def test_a_folder_holding_a_log_is_refused_saying_what_to_do(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "lg").mkdir()
    (tmp_path / "lg" / "tlm.log").write_text("")
    with pytest.raises(InputError) as got:
        storage.check_destination("lg", "results.json")
    said = str(got.value)
    assert said.startswith("--out: 'lg' exists and is not an earlier tlm output (no results.json; it holds "
                           "'tlm.log': write a log beside it, 'lg.log', not in it; a new or an empty folder is "
                           "taken, and a folder tlm wrote keeps files added to it)"), said
    assert said.endswith("refusing to replace it")
    for name in ("a", "b", "c"):
        (tmp_path / "lg" / name).write_text("")
    with pytest.raises(InputError, match=r"it holds 'a', 'b' and 2 more: write a log beside it"):
        storage.check_destination("lg", "results.json")
    # a report's folder is replaced whole: no word of keeping what is added
    with pytest.raises(InputError) as got:
        storage.check_destination("lg", "report.html")
    assert "keeps" not in str(got.value) and "a new or an empty folder is taken)" in str(got.value)
    (tmp_path / "empty").mkdir()
    storage.check_destination("empty", "results.json")  # (taken)


def _tlm(tmp_path: Path, argv: list[str], **streams) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tlm", *argv], cwd=tmp_path, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")},
                          **streams)


@pytest.mark.slow
@needs_full
def test_a_run_with_stderr_that_cannot_be_written_is_whole(tmp_path):
    with open(FULL, "w") as full:
        proc = _tlm(tmp_path, [*RUN, "--out", "full"], stdout=subprocess.PIPE, stderr=full)
    assert proc.returncode == 0 and "report:" in proc.stdout, proc.stdout
    assert (tmp_path / "full" / "report" / "report.html").is_file()
    with open(os.devnull) as read_only:  # (2</dev/null: every write EBADF)
        proc = _tlm(tmp_path, [*RUN, "--out", "ro"], stdout=subprocess.PIPE, stderr=read_only)
    assert proc.returncode == 0 and (tmp_path / "ro" / "report" / "report.html").is_file(), proc.stdout
    (tmp_path / "bad.yaml").write_text("scene: cornell\nbogus_key: 1\n")
    with open(FULL, "w") as full:
        proc = _tlm(tmp_path, ["run", "bad.yaml", "--out", "bad"], stdout=subprocess.PIPE, stderr=full)
    assert proc.returncode == 2 and not (tmp_path / "bad").exists()


@pytest.mark.slow
@needs_full
def test_a_sweep_with_stderr_that_cannot_be_written_writes_its_report(tmp_path):
    (tmp_path / "sw.yaml").write_text("base: cornell\nset:\n  mode: rcast\n  resolution: [16, 16]\n"
                                      "  arch.frames: 1\ngrid:\n  arch.pipelines: [1, 2]\n")
    with open(FULL, "w") as full:
        proc = _tlm(tmp_path, ["sweep", "sw.yaml", "--out", "s", "--no-progress"], stdout=subprocess.PIPE,
                    stderr=full)
    assert proc.returncode == 0, proc.stdout
    assert len((tmp_path / "s" / "sweep.jsonl").read_text().splitlines()) == 2
    assert (tmp_path / "s" / "report" / "report.html").is_file()


@pytest.mark.slow
@needs_full
def test_a_run_with_stdout_on_a_full_disk_is_whole_and_says_stdout(tmp_path):
    with open(FULL, "w") as full:
        proc = _tlm(tmp_path, [*RUN, "--out", "r"], stdout=full, stderr=subprocess.PIPE)
    lines = proc.stderr.splitlines()
    assert proc.returncode == 1 and lines[-1] == NO_SPACE, proc.stderr
    assert "tlm: cornell:" in proc.stderr  # (the command writes stderr: what the tests above drop)
    assert (tmp_path / "r" / "results.json").is_file() and (tmp_path / "r" / "report" / "report.html").is_file()
    with open(FULL, "w") as full:  # a command whose stdout is its output: the same line, at once
        proc = _tlm(tmp_path, ["params"], stdout=full, stderr=subprocess.PIPE)
    assert proc.returncode == 1 and proc.stderr == NO_SPACE + "\n", proc.stderr
