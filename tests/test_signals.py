"""SIGINT and SIGTERM: ``tlm run`` interrupted in each phase, and ``tlm sweep`` (its main
process alone signalled, as ``kill -INT`` or ``timeout`` do), end with 130 / 143, one
line, their workers gone and nothing half written; a second signal never hangs them."""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from contextlib import suppress
from pathlib import Path

import pytest
import yaml

import tlm.experiments.run as run_mod
import tlm.report as report_mod
from tlm import fingerprint, storage
from tlm.cli import main
from tlm.experiments.executors import LocalPool
from tlm.experiments.sweep import run_sweep

from .test_faults import CORNELL, SMALL, leftovers
from .test_sweep import _descendants, _running

REPO = Path(__file__).resolve().parents[1]
PHASES = {  # where in `tlm run` the signal arrives: (module, function)
    "render": (run_mod, "render"),
    "simulate": (run_mod, "simulate_run"),
    "write": (run_mod, "write_png"),
    "swap": (storage, "_swap_in"),
    "report": (report_mod, "sections"),
}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("phase", list(PHASES))
def test_a_run_signalled_in_each_phase(phase, sig, tmp_path, monkeypatch, capsys):
    module, name = PHASES[phase]
    real = getattr(module, name)

    def signalled(*a, **k):
        os.kill(os.getpid(), sig)  # (the handler raises at the next instruction)
        return real(*a, **k)

    monkeypatch.setattr(module, name, signalled)
    before = signal.getsignal(signal.SIGTERM)
    runs = tmp_path / "runs"
    out = runs / "r"
    assert main(["run", CORNELL, "--out", str(out), *SMALL]) == 128 + sig
    err = capsys.readouterr().err.strip()
    line = "tlm: interrupted" if sig == signal.SIGINT else "tlm: terminated (SIGTERM)"
    if phase == "report":  # (what was kept, and the command that writes the report)
        line += (f" while writing the report: the run in {out} is kept, whole (results.json and its files); no "
                 f"report was written (none is left half-written): write it with: tlm report {out}")
    assert err == line
    if phase == "report":  # the run folder was whole before its report began: it stays, without a report
        assert (out / "results.json").is_file() and not (out / "report").exists()
    else:
        assert not out.exists()
    assert leftovers(tmp_path) == []
    assert signal.getsignal(signal.SIGTERM) == before  # main's handlers are gone again


def _wrapped_interrupt(sig):
    """What a signal does when it arrives while a compiled numba kernel calls back into
    Python: the handler's KeyboardInterrupt comes out as a SystemError caused by it."""
    def render(*a, **k):
        try:
            os.kill(os.getpid(), sig)
        except KeyboardInterrupt as e:
            raise SystemError("CPUDispatcher(<function trace>) returned a result with an exception set") from e
    return render


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupt_a_kernel_wrapped_is_still_an_interrupt(sig, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(run_mod, "render", _wrapped_interrupt(sig))
    out = tmp_path / "runs" / "r"
    assert main(["run", CORNELL, "--out", str(out), *SMALL]) == 128 + sig
    assert capsys.readouterr().err.strip() == ("tlm: interrupted" if sig == signal.SIGINT
                                               else "tlm: terminated (SIGTERM)")
    assert not out.exists() and leftovers(tmp_path) == []


def test_a_sweep_point_interrupted_inside_a_kernel_stops_the_sweep(tmp_path, monkeypatch, capsys):
    """Not a failed point that the sweep goes on after: the sweep stops with 130 and keeps
    no row or error for the point."""
    import tlm.experiments.sweep_point as sweep_point

    monkeypatch.setattr(sweep_point, "cached_render", _wrapped_interrupt(signal.SIGINT))
    out = tmp_path / "sw"
    assert main(["sweep", str(sweep_file(tmp_path, 2)), "--out", str(out), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "tlm: interrupted before any point finished"
    assert rows(out) == [] and not list(out.rglob("error.json"))


SECOND = """
import os, signal, sys
from tlm import cli_signals
from tlm.experiments.executors import LocalPool

pool = LocalPool(2)  # (its queues' named semaphores, registered with the resource tracker)
with cli_signals.signals():
    try:
        os.kill(os.getpid(), signal.{sig})
    except KeyboardInterrupt:  # the first: the clean-up begins ...
        os.kill(os.getpid(), signal.{sig})  # ... and a second ends the process
sys.exit("the second signal did not end the process")
"""


@pytest.mark.parametrize(("sig", "tty"), [("SIGINT", False), ("SIGTERM", False), ("SIGINT", True)],
                         ids=["SIGINT", "SIGTERM", "SIGINT-terminal"])
def test_a_second_signal_leaves_no_semaphore_to_the_resource_tracker(sig, tty, tmp_path):
    """A second signal ends the process at once with tlm's line alone: the local pool's
    semaphores are released first, so that the resource tracker (which shares the
    process's stderr, and outlives it) has no "leaked semaphore objects" to warn about. At
    a terminal the line is a line of its own, not glued to the ^C echoed or a progress bar."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    master, slave = os.openpty() if tty else (None, subprocess.PIPE)
    proc = subprocess.Popen([sys.executable, "-c", SECOND.format(sig=sig)], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=slave)
    if tty:
        os.close(slave)
        err = b""
        with suppress(OSError):  # (EIO: every process holding the terminal ended, the tracker too)
            while select.select([master], [], [], 60)[0] and (chunk := os.read(master, 4096)):
                err += chunk
        os.close(master)
        assert err.decode() == "\r\ntlm: interrupted again: stopping now\r\n"  # (a terminal writes \n as \r\n)
    else:
        err = proc.communicate(timeout=120)[1].decode()
        assert err == "tlm: interrupted again: stopping now\n"
    assert proc.wait(timeout=60) == 128 + getattr(signal, sig)


def test_a_local_pools_workers_ignore_sigint():
    """Ctrl-C at a terminal signals the whole process group: a local pool's workers ignore
    it (the sweep's process kills them), so that none prints a KeyboardInterrupt's traceback."""
    pool = LocalPool(1)
    try:
        handler = pool.submit(signal.getsignal, signal.SIGINT)
        pool.run_next()
        assert handler.result(timeout=60) == signal.SIG_IGN
    finally:
        pool.shutdown()


def sweep_file(tmp_path: Path, n: int = 8) -> Path:
    base = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
            "arch": {"frames": 2, "trace": False, "packet_size": 4}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.page_miss_cycles": list(range(0, 10 * n, 10))}}))
    return path


def rows(out: Path) -> list[dict]:
    path = out / "sweep.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


# tlm's lines of a signalled sweep: the first signal's, which says how many of its points the folder keeps
# (h450: a bare "tlm: interrupted" before), and a second's; nothing else (no traceback, no resource tracker's)
TLM_LINE = re.compile(r"tlm: (?:interrupted|terminated \(SIGTERM\))(?: with (?P<kept>\d+) of (?P<total>\d+) points "
                      r"finished(?: \((?P<failed>\d+) failed, to run again\))? and kept in (?P<folder>.+); "
                      r"run the same command to go on"
                      r"| with all (?P<all>\d+) points finished and kept in (?P<all_folder>.+)"
                      r"| before any point finished)?|tlm: interrupted again: stopping now")


def tlm_lines(err: str, out: Path, n: int) -> list[str]:
    """The lines of ``err``, each one of tlm's (:data:`TLM_LINE`), two at most; the numbers a first signal's
    line says agree with the rows in ``out`` (``sweep.jsonl``) and the ``n`` points of the sweep."""
    lines = err.strip().splitlines()
    assert lines and len(lines) <= 2 and all(TLM_LINE.fullmatch(line) for line in lines), err
    for line in lines:
        said = TLM_LINE.fullmatch(line).groupdict()
        if said["kept"] is not None:
            assert (int(said["kept"]), int(said["total"]), int(said["failed"] or 0), said["folder"]) == (
                len(rows(out)), n, sum(r["status"] != "ok" for r in rows(out)), str(out)), (line, len(rows(out)))
        elif said["all"] is not None:  # (every point finished, none failed: nothing to go on with)
            assert (int(said["all"]), said["all_folder"]) == (len(rows(out)), str(out)) and int(said["all"]) == n
            assert all(r["status"] == "ok" for r in rows(out)), line
        elif "before any point finished" in line:
            assert rows(out) == [], line
    return lines


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "twice", "executor"),
                         [(signal.SIGINT, False, []), (signal.SIGINT, True, []), (signal.SIGTERM, False, []),
                          (signal.SIGINT, True, ["group"]),
                          (signal.SIGINT, False, ["--dask", "local"]), (signal.SIGTERM, False, ["--dask", "local"]),
                          (signal.SIGINT, False, ["--dask", "local", "group"])],
                         ids=["SIGINT", "SIGINT-twice", "SIGTERM", "SIGINT-twice-group", "dask-SIGINT", "dask-SIGTERM",
                              "dask-SIGINT-group"])
def test_a_sweep_signalled_stops_its_workers(sig, twice, executor, tmp_path, monkeypatch):
    """Signalled once two points are done (twice: again at once, during the clean-up), the
    sweep exits 128 + signal with tlm's own line (two at most: the second signal's), the
    points not done are not run, its worker processes end, no temporary folder is left, and
    a rerun resumes. "group": the signal goes to the whole process group, as Ctrl-C at a
    terminal does, the workers too (Dask's printed a page of tracebacks before they started
    with SIGINT ignored). Twice, the resource tracker, which writes to the same stderr, had
    the local pool's semaphores to clean up and warned of them (they are released first)."""
    group = "group" in executor
    executor = [a for a in executor if a != "group"]
    # (points enough that some are left when the signal's clean-up ends: a --dask local cluster's
    # workers, which ignore SIGINT, run points until it has closed, 6 of 8 on a loaded machine, and on a clean
    # clone's CI all 16 of 16 once)
    n = 48 if executor else 16
    path, out = sweep_file(tmp_path, n), tmp_path / "o"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(out), "--jobs", "2",
                             "--no-report", *executor], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=group)
    below: set[tuple[int, str]] = set()
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None and len(rows(out)) < 2:
            below |= _descendants(proc.pid)
            time.sleep(0.01)
        assert proc.poll() is None, "the sweep ended before it was signalled"
        below |= _descendants(proc.pid)
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        if twice:
            time.sleep(0.05)
            if proc.poll() is None:
                if group:
                    with suppress(ProcessLookupError):  # (the whole group ended meanwhile)
                        os.killpg(proc.pid, sig)
                else:
                    proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)  # (a hang guard, not a timing)
    finally:
        if proc.poll() is None:
            proc.kill()
    # (a second signal in the interpreter's last moments, after its handlers are gone, ends it
    # by the signal itself: -sig here, 128 + sig to a shell all the same)
    assert proc.returncode == 128 + sig or (twice and proc.returncode == -sig)
    lines = tlm_lines(err, out, n)
    assert twice or "points finished and kept in" in lines[0], err  # (two done, at least, and rows written)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(map(_running, below)):
        time.sleep(0.05)
    assert len(below) >= 3 and not [p for p in below if _running(p)]
    done = {p.name for p in (out / "points").iterdir() if (p / "results.json").is_file()}
    assert 2 <= len(done) < n
    if not twice:  # (a second signal ends the process at once: the next sweep removes what it left)
        assert leftovers(out) == []
    # the points' keys hold the code's fingerprint: the rerun keys them with the signalled sweep's
    # own (that of the checkout when it started, not when this session did: it may be edited since)
    codes = {json.loads((out / "points" / h / "results.json").read_text())["code_fingerprint"] for h in done}
    assert len(codes) == 1
    monkeypatch.setattr(fingerprint, "_CODE", codes.pop())
    again = run_sweep(path, out, jobs=1)
    assert again.skipped == len(done) and again.ok == n - len(done) and again.failed == 0
    assert leftovers(out) == []


@pytest.mark.slow
def test_two_sweeps_into_one_folder(tmp_path):
    """Two ``tlm sweep`` of one file into one folder at once: both exit 0 with every point
    ok, and the folder holds each point once, whole, with its report."""
    path, out = sweep_file(tmp_path, n=4), tmp_path / "o"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    procs = [subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(out), "--jobs", "1",
                               "--no-progress"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        assert "Traceback" not in err
    got = rows(out)
    assert [r["point"] for r in got] == [0, 1, 2, 3] and {r["status"] for r in got} == {"ok"}
    assert sorted(p.name for p in (out / "points").iterdir()) == sorted(r["hash"] for r in got)
    assert all((out / "points" / r["hash"] / "results.json").is_file() for r in got)
    assert (out / "report" / "report.html").is_file() and leftovers(out) == []


def test_claiming_a_folder_races_safely(tmp_path, monkeypatch):
    """The race behind ``test_two_sweeps_into_one_folder``, made deterministic: a folder
    another process is claiming this instant (only the marker's temporary file in it) is
    not refused, a claim that loses the rename to another claim still succeeds, and a
    folder with anything else in it and no marker is still refused."""
    out = tmp_path / "o"
    out.mkdir()
    (out / ".sweep.yaml.tmp4242").write_text("half")  # another sweep writing its marker
    storage.check_destination(out, "sweep.yaml")
    (out / "points").mkdir()  # ... but a folder with work in it and no marker is refused
    with pytest.raises(storage.InputError, match="not an earlier tlm output"):
        storage.check_destination(out, "sweep.yaml")

    won = tmp_path / "w"
    rename = os.rename

    def other_wins(src, dst):  # another process claims the folder first
        if Path(dst) == won:
            won.mkdir()
            (won / "sweep.yaml").write_text("theirs")
        return rename(src, dst)

    monkeypatch.setattr(storage.os, "rename", other_wins)
    storage.claim_folder(won, "sweep.yaml", "ours")
    assert (won / "sweep.yaml").read_text() == "ours"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o", "w"]  # no claim folder left
    monkeypatch.setattr(storage.os, "rename", rename)
    fresh = tmp_path / "f" / "g"
    storage.claim_folder(fresh, "sweep.yaml", "x")
    assert [p.name for p in fresh.iterdir()] == ["sweep.yaml"]


@pytest.mark.slow
def test_a_run_whose_interrupt_was_lost_exits_143_with_its_folder_whole(tmp_path, monkeypatch, capsys):
    """SIGTERM as the run writes its folder, after its last checkpoint (tlm.progress.checkpoint:
    one before stops the run there, tests/test_lost_interrupt.py), its KeyboardInterrupt raised
    where CPython ignores it (an at-fork hook, a ctypes callback): the run goes on to its end, and
    exits 143 (not 0), saying its folder is whole; the folder stays, with nothing half written."""
    real = run_mod.write_png
    signalled: list[bool] = []

    def lost(*a, **k):
        if not signalled:  # (the first image only: a second signal ends the process)
            signalled.append(True)
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                for _ in range(10**7):  # (the handler raises at one of these instructions)
                    pass
            except KeyboardInterrupt:
                pass
        return real(*a, **k)

    monkeypatch.setattr(run_mod, "write_png", lost)
    out = tmp_path / "runs" / "r"
    assert main(["run", CORNELL, "--out", str(out), *SMALL]) == 143
    err = capsys.readouterr().err.strip()
    assert err == "tlm: terminated (SIGTERM), but the command ran to its end: its output is complete"
    assert (out / "results.json").is_file() and leftovers(tmp_path) == []
