"""Memory limits, pipes and signals (a faults probe's findings).

* Under a limit on the address space (``ulimit -v 400000``) ``tlm run`` hung in OpenBLAS's start
  (its threads' buffers, as numba loads scipy's BLAS to check for it), ignoring SIGTERM; a
  MemoryError elsewhere was a ``tlm: internal error``. The command runs OpenBLAS on one thread
  (:func:`tlm.cli_signals.one_blas_thread`) and says a MemoryError as ``tlm: error: out of memory: ...``.
* A reader of stderr gone stopped the run (141, nothing written); one of stdout cost the report.
  Now neither stops the work (:func:`tlm.cli_signals.guard_streams`): 0 and 141, the report written.
* SIGHUP killed the command (129, no line, its temporary files left); now it is taken as SIGTERM is.
* An inherited SIGINT ignored (``tlm run ... &`` in a script) was replaced by the command's handler.
"""

from __future__ import annotations

import errno
import io
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from tlm import cli_failed, cli_streams
from tlm.cli import main

from .test_faults import CORNELL, SMALL, leftovers
from .test_signals import rows, sweep_file

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(REPO)}


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _closed_pipe() -> int:
    """The write end of a pipe whose reader is gone."""
    r, w = os.pipe()
    os.close(r)
    return w


def _hidden(folder: Path) -> list[str]:
    """What a command leaves behind it: temporary folders and its claims (``.X.tlm-running``)."""
    return leftovers(folder) + [str(p) for p in folder.rglob("*.tlm-running")]


def test_a_memory_error_is_out_of_memory_on_one_line(capsys):
    e = MemoryError("Unable to allocate 8.24 MiB for an array with shape (1080000,) and data type float64")
    assert cli_failed.exit_status(e, ["run"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("tlm: error: out of memory: Unable to allocate 8.24 MiB for an array")
    assert "internal" not in err
    assert len(err.strip().splitlines()) == 1
    try:  # (wrapped, as a compiled kernel's callback wraps it)
        try:
            raise MemoryError()
        except MemoryError as inner:
            raise SystemError("<built-in function x> returned a result with an exception set") from inner
    except SystemError as wrapped:
        assert cli_failed.exit_status(wrapped, ["run"]) == 1
    assert capsys.readouterr().err.startswith("tlm: error: out of memory")


def test_a_broken_pipe_not_of_stdout_or_stderr_is_not_a_reader_gone(capsys, monkeypatch):
    """(A worker's pipe: an error of its own, with its traceback kept, not a quiet 141.)"""
    monkeypatch.setattr(cli_streams, "_GONE", {})  # (not a stream an earlier test of this worker left gone)
    monkeypatch.setattr(cli_streams, "_reader_gone", lambda fd: False)
    assert cli_failed.exit_status(BrokenPipeError(32, "Broken pipe"), ["run"]) == 1
    assert "BrokenPipeError" in capsys.readouterr().err


def test_a_guarded_stream_whose_reader_went_away_drops_what_it_is_given(monkeypatch):
    monkeypatch.setattr(cli_streams, "_GONE", {})
    monkeypatch.setattr(cli_streams, "_writing", lambda: True)  # (a command writing its destination)
    w = _closed_pipe()
    stream = os.fdopen(w, "w", buffering=1)
    try:
        guarded = cli_streams._Guarded(stream, "stdout")
        assert cli_streams._reader_gone(w)
        guarded.write("lost\n")  # (no BrokenPipeError)
        guarded.flush()
        assert cli_streams._GONE["stdout"] and isinstance(guarded.error, BrokenPipeError)
        assert not cli_streams._reader_gone(w) and os.path.samestat(os.fstat(w), os.stat(os.devnull))
    finally:
        stream.close()


def test_a_command_whose_stdout_reader_went_away_runs_to_its_end(tmp_path, monkeypatch, capsys):
    """While it writes a destination (as if ``tlm params`` did: :func:`tlm.cli_streams._writing`) the
    command runs to its end, what it prints dropped; then 141, quietly. (One that only prints stops at
    once, tests/test_faults.py.)"""
    class ClosedPipe(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    import tlm.cli as cli

    done = []
    real = cli._cmd_params

    def params(args):
        status = real(args)
        done.append(status)
        return status

    monkeypatch.setattr(cli, "_cmd_params", params)
    monkeypatch.setattr(cli_streams, "_writing", lambda: True)
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert main(["params"]) == 141 and done == [0]
    assert capsys.readouterr().err == "" and isinstance(sys.stdout, ClosedPipe)


def test_sighup_is_said_as_sigterm_is(tmp_path, capsys, monkeypatch):
    import tlm.experiments.run as run_mod

    real = run_mod.render

    def hung_up(*a, **k):
        os.kill(os.getpid(), signal.SIGHUP)
        return real(*a, **k)

    monkeypatch.setattr(run_mod, "render", hung_up)
    # the test's own handler while it runs: a command that did not take SIGHUP leaves it to this
    # one (the test fails), not to the default, which would end the whole test process
    missed: list[int] = []
    previous = signal.signal(signal.SIGHUP, lambda sig, frame: missed.append(sig))
    try:
        before = signal.getsignal(signal.SIGHUP)
        out = tmp_path / "r"
        assert main(["run", CORNELL, "--out", str(out), *SMALL]) == 128 + signal.SIGHUP, missed
        assert capsys.readouterr().err.strip() == "tlm: hung up (SIGHUP)"
        assert not out.exists() and _hidden(tmp_path) == []
        assert signal.getsignal(signal.SIGHUP) == before and missed == []
    finally:
        signal.signal(signal.SIGHUP, previous)


def _run(tmp_path: Path, **kw) -> subprocess.CompletedProcess:
    """``tlm run`` of the built-in experiment by its name: its first line (which one it is) is on stderr."""
    return subprocess.run([sys.executable, "-m", "tlm", "run", "cornell", "--out", str(tmp_path / "r"), *SMALL],
                          cwd=tmp_path, env=_env(), text=True, timeout=300, preexec_fn=_default_sigint, **kw)


@pytest.mark.slow
def test_a_reader_of_stderr_gone_stops_nothing(tmp_path):
    w = _closed_pipe()
    try:
        proc = _run(tmp_path, stdout=subprocess.PIPE, stderr=w)
    finally:
        os.close(w)
    assert proc.returncode == 0 and "report:" in proc.stdout
    assert (tmp_path / "r" / "report" / "report.html").is_file() and _hidden(tmp_path) == []


@pytest.mark.slow
def test_a_reader_of_stdout_gone_costs_no_report(tmp_path):
    w = _closed_pipe()
    try:
        proc = _run(tmp_path, stdout=w, stderr=subprocess.PIPE)
    finally:
        os.close(w)
    assert proc.returncode == 128 + signal.SIGPIPE and "tlm: cornell:" in proc.stderr, proc.stderr
    assert (tmp_path / "r" / "report" / "report.html").is_file() and _hidden(tmp_path) == []


@pytest.mark.slow
@pytest.mark.parametrize("command", ["sweep", "scaling"])
def test_a_reader_of_stdout_gone_costs_a_sweep_or_a_fit_no_report(tmp_path, command):
    """With stdout unbuffered (``PYTHONUNBUFFERED=1``, ``python -u``, as containers and CI set it) a
    sweep's summary line, printed before its report, met the closed pipe at once: the sweep holds
    its folder by sharing, a fit holds none, so both stopped with 141 and no report, saying nothing."""
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
            "arch": {"frames": 1, "trace": False}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.pipelines": [1, 2]}}))
    env = {**_env(), "PYTHONUNBUFFERED": "1"}
    sweep = [sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(tmp_path / "s"), "--no-progress"]
    if command == "scaling":
        subprocess.run([*sweep, "--no-report"], cwd=tmp_path, env=env, check=True, capture_output=True, timeout=300)
        argv, out = [sys.executable, "-m", "tlm", "scaling", str(tmp_path / "s"), "--out", str(tmp_path / "e")], "e"
    else:
        argv, out = sweep, "s"
    w = _closed_pipe()
    try:
        proc = subprocess.run(argv, cwd=tmp_path, env=env, text=True, timeout=300, preexec_fn=_default_sigint,
                              stdout=w, stderr=subprocess.PIPE)
    finally:
        os.close(w)
    assert proc.returncode == 128 + signal.SIGPIPE, proc.stderr
    assert (tmp_path / out / "report" / "report.html").is_file(), proc.stderr


def _started(tmp_path: Path, preexec) -> subprocess.Popen:
    """``tlm run`` in a fresh process, once its command has begun (its folder claimed)."""
    proc = subprocess.Popen([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(tmp_path / "r"), *SMALL],
                            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=preexec)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and not list(tmp_path.glob(".r*")):
        time.sleep(0.005)
    assert proc.poll() is None, "the run ended before it was signalled"
    return proc


@pytest.mark.slow
def test_a_run_hung_up_exits_129_with_its_line_and_no_leftovers(tmp_path):
    proc = _started(tmp_path, _default_sigint)
    proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGHUP, err
    assert err.strip().splitlines()[-1].startswith("tlm: hung up (SIGHUP)")
    assert _hidden(tmp_path) == []


@pytest.mark.slow
def test_a_sigint_the_parent_ignored_stays_ignored(tmp_path):
    proc = _started(tmp_path, lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert (tmp_path / "r" / "report" / "report.html").is_file()


@pytest.mark.slow
def test_a_sweep_hung_up_writes_its_csv_of_the_points_done(tmp_path):
    path, out = sweep_file(tmp_path), tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(out), "--jobs", "1",
                             "--no-report", "--no-progress"], cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None and len(rows(out)) < 2:
            time.sleep(0.01)
        assert proc.poll() is None, "the sweep ended before it was signalled"
        proc.send_signal(signal.SIGHUP)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGHUP, err
    assert err.strip().splitlines()[-1].startswith("tlm: hung up (SIGHUP)")
    assert (out / "sweep.csv").is_file() and len((out / "sweep.csv").read_text().splitlines()) >= 3
    assert _hidden(out) == []


def _limited():
    _default_sigint()
    resource.setrlimit(resource.RLIMIT_AS, (400_000 * 1024, 400_000 * 1024))  # (ulimit -v 400000)


@pytest.mark.slow
def test_a_small_address_space_is_out_of_memory_not_a_hang(tmp_path):
    """(OpenBLAS's threads' buffers at ``ulimit -v 400000``: the run hung, for ever, at 88% CPU.)
    Where the limit leaves too little for OpenBLAS's one buffer (128 MiB, taken at its first call:
    the render's exposure product; the shading has none since tests/test_faults_h133.py)
    OpenBLAS itself ends the process with its own line
    and exit status 1, and where numba compiles the kernels (a fresh clone's first run) LLVM aborts with
    its own (SIGABRT: "LLVM ERROR: out of memory", or C++'s std::bad_alloc): no Python code can catch
    either, so those lines are allowed here; a hang or a traceback is not."""
    env = {k: v for k, v in _env().items() if k != "OPENBLAS_NUM_THREADS"}
    proc = subprocess.run([sys.executable, "-m", "tlm", "run", CORNELL, "--out", str(tmp_path / "r"), *SMALL],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, preexec_fn=_limited)
    lines = proc.stderr.strip().splitlines()
    if proc.returncode == -signal.SIGABRT:  # (LLVM compiling a kernel: "LLVM ERROR: out of memory", std::bad_alloc)
        assert any("out of memory" in line or "bad_alloc" in line for line in lines), proc.stderr
    else:
        assert proc.returncode == 1, proc.stderr
        assert lines[-1].startswith(("tlm: error: out of memory", "OpenBLAS error: Memory allocation")), proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
