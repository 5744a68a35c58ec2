"""A run's output folder is the run's while it works (tlm.claims.claimed): a second ``tlm run``
into it from another process is refused at once (exit 2, one line naming the first's process,
nothing written, no render), not accepted to be silently replaced by the first's at its end, as
two ``tlm run --out conc2`` at once were (both exit 0, "wrote conc2", one output gone). A claim a
killed run left is taken over; the threads of one process share their claim."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import tlm.experiments.run as run_mod
from tlm import claims, storage
from tlm.cli import main
from tlm.config import RunConfig
from tlm.errors import InputError

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--mode", "rcast", "--set", "resolution=[16,16]", "--set", "render.light_samples=1", "--no-progress",
         "--no-reference"]


class Reached(Exception):
    """The run got past its claim to the render."""


def claim_file(out: Path) -> Path:
    return out.parent / f".{out.name}.tlm-running"


def dead_pid() -> int:
    """A process id no process has now (a child that ended, reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.parametrize("record, named", [
    (f"{storage._host()}-4242", "(process 4242 on this machine, "),
    ("hOtherbox-77", "(process 77 on host Otherbox, another machine: its processes cannot be checked from this one)"),
])
def test_a_run_into_a_folder_another_process_is_writing_is_refused_at_once(
        tmp_path, cache, elsewhere, monkeypatch, capsys, record, named):
    """The claim is held (its lock taken by another open file, as another process holds it):
    ``tlm run`` into the folder exits 2 before the render, with one line naming the holder, and
    writes nothing; the holder's claim is left as it was."""
    out = tmp_path / "o" / "conc2"
    out.parent.mkdir()
    held = os.open(claim_file(out), os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(held, fcntl.LOCK_EX)
        os.pwrite(held, f"{record:<63}\n".encode(), 0)

        def rendered(*a, **k):
            raise AssertionError("the refused run rendered")

        monkeypatch.setattr(run_mod, "render", rendered)
        assert main(["run", "cornell", *SMALL, "--out", str(out), "--no-report"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 2 and "built-in experiment" in err[0], err  # (the first: which file 'cornell' is)
        assert err[1].startswith(f"tlm: error: --out: another run is writing into {str(out)!r} "), err
        assert named in err[1] and err[1].endswith("wait for it to end, or give another folder"), err
        assert os.listdir(out.parent) == [claim_file(out).name]
        with pytest.raises(BlockingIOError):  # (still the holder's)
            fcntl.flock(os.open(claim_file(out), os.O_RDWR), fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(held)


def test_a_claim_a_killed_run_left_is_taken_over_and_removed(tmp_path, cache, monkeypatch):
    """A claim file whose process ended (no lock on it): the run takes it over, holding it with
    its own host and pid while it works, and removes it at the end (here an error in the render)."""
    out = tmp_path / "o" / "r"
    out.parent.mkdir()
    claim_file(out).write_text(f"{storage._host()}-{dead_pid()}\n")
    seen = []

    def render(*a, **k):
        seen.append(claim_file(out).read_text().splitlines()[0].strip())  # (its second line: what writes, h415)
        fd = os.open(claim_file(out), os.O_RDWR)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
        raise Reached

    monkeypatch.setattr(run_mod, "render", render)
    with pytest.raises(Reached):
        run_mod.run(RunConfig(), out)
    assert seen == [storage.process_tag()]
    assert os.listdir(out.parent) == []


def test_the_folders_made_for_the_claim_go_when_the_run_writes_nothing(tmp_path, cache, monkeypatch):
    """``--out a/b/r`` of folders that do not exist: the claim beside ``r`` is made while the run
    works, and a run that fails leaves neither it nor ``a/b``."""
    out = tmp_path / "a" / "b" / "r"
    seen = []

    def render(*a, **k):
        seen.append(claim_file(out).read_text().splitlines()[0].strip())  # (its second line: what writes, h415)
        raise Reached

    monkeypatch.setattr(run_mod, "render", render)
    with pytest.raises(Reached):
        run_mod.run(RunConfig(), out)
    assert seen == [storage.process_tag()]
    assert not (tmp_path / "a").exists()


def test_threads_of_one_process_share_a_claim(tmp_path):
    """Two threads in one claim at once both enter (their writes of one folder were always
    safe: the last wins); the claim file stays until the last of them leaves."""
    out = tmp_path / "r"
    barrier = threading.Barrier(2, timeout=30)
    inside = []

    def hold(n: int) -> None:
        with claims.claimed(out):
            inside.append(claim_file(out).is_file())
            barrier.wait()
            if n == 1:
                time.sleep(0.2)
                inside.append(claim_file(out).is_file())  # (the other thread left first)
            else:
                return

    threads = [threading.Thread(target=hold, args=(n,)) for n in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert inside == [True, True, True]
    assert os.listdir(tmp_path) == []


CHILD = """
import sys, time
from pathlib import Path
import tlm.experiments.run as run_mod
from tlm.cli import main

real = run_mod.render
started, go = Path(sys.argv[1]), Path(sys.argv[2])

def render(*a, **k):
    started.write_text("")
    deadline = time.monotonic() + 120
    while not go.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    return real(*a, **k)

run_mod.render = render
sys.exit(main(sys.argv[3:]))
"""


@pytest.mark.slow
def test_two_tlm_runs_into_one_folder_at_once_one_is_refused_the_other_writes_it_whole(tmp_path, cache):
    """The probe's case, the first run held inside its render while the second starts: the
    second exits 2 naming the first's process, the first writes its folder, report and all,
    and leaves no claim; a run into the folder after it replaces it as ever."""
    out, started, go = tmp_path / "conc2", tmp_path / "started", tmp_path / "go"
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(cache)}
    first = subprocess.Popen([sys.executable, "-c", CHILD, str(started), str(go), "run", "cornell", *SMALL,
                              "--seed", "1", "--out", str(out)],
                             cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not started.exists() and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert started.exists(), first.communicate()
        second = subprocess.run([sys.executable, "-m", "tlm", "run", "cornell", *SMALL, "--seed", "2", "--out",
                                 str(out), "--no-report"], cwd=tmp_path, env=env, capture_output=True, text=True,
                                timeout=120)
        assert second.returncode == 2, second.stderr
        assert second.stderr.splitlines()[-1].startswith("tlm: error: --out: another run is writing into"), second
        assert f"(process {first.pid} on this machine, " in second.stderr
        assert not out.exists()
    finally:
        go.write_text("")
        stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert f"wrote {out}" in stdout and "report: " in stdout
    assert json.loads((out / "results.json").read_text())["seed"] == 1
    assert (out / "report" / "report.html").is_file()
    assert {p.name for p in tmp_path.iterdir()} - {"cache"} == {"conc2", "go", "started"}  # (no claim left)
    third = subprocess.run([sys.executable, "-m", "tlm", "run", "cornell", *SMALL, "--seed", "3", "--out", str(out),
                            "--no-report"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert third.returncode == 0, third.stderr
    assert json.loads((out / "results.json").read_text())["seed"] == 3


def test_the_claim_lasts_through_the_runs_report(tmp_path, monkeypatch, capsys):
    """``tlm run`` holds its folder until its report is written too: another process's claim of
    it while the report is drawn is refused (the claim had ended when ``tlm.run`` returned,
    leaving the report's time open to a second run)."""
    from tlm import api

    out = tmp_path / "runs" / "r"
    seen: list[str] = []
    probe = ("import sys\nfrom pathlib import Path\nfrom tlm import claims\nfrom tlm.errors import InputError\n"
             "try:\n    with claims.claimed(Path(sys.argv[1])):\n        print('claimed')\n"
             "except InputError as e:\n    print('refused:', e)\n")

    def report(dirs, *a, **k):  # (while the report would be drawn: another process tries the folder)
        got = subprocess.run([sys.executable, "-c", probe, str(out)], capture_output=True, text=True,
                             env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=120)
        seen.append(got.stdout.strip() + got.stderr.strip())
        return Path(dirs[0]) / "report" / "report.html"

    monkeypatch.setattr(api, "write_report", report)
    assert main(["run", "cornell", "--out", str(out), *SMALL]) == 0
    assert len(seen) == 1 and seen[0].startswith("refused:") and "another run is writing into" in seen[0], seen
    assert not claim_file(out).exists()


def test_a_bad_out_is_said_as_such_before_the_claim(tmp_path, capsys):
    """``tlm run --out AFILE/x``: the destination's own message (exit 2), not the claim file's
    ("cannot write beside the output folder (File exists)", exit 1): checked before the claim."""
    (tmp_path / "afile").write_text("")
    assert main(["run", "cornell", "--out", str(tmp_path / "afile" / "x"), *SMALL]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith(f"{str(tmp_path / 'afile')!r} is a file, not a folder"), err


def test_a_file_system_without_locks_is_said_and_leaves_nothing(tmp_path, monkeypatch):
    """flock refused (ENOLCK, EOPNOTSUPP: a file system that takes no locks): one line naming the
    claim file and why, the claim file and the folders made for it removed (it was an internal
    error, the descriptor leaked and the file left)."""
    import errno

    def no_locks(fd, op):
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(claims.fcntl, "flock", no_locks)
    out = tmp_path / "a" / "b" / "r"
    with pytest.raises(claims.EnvironmentFailure, match="takes no locks"), claims.claimed(out):
        raise AssertionError("claimed")
    assert list(tmp_path.iterdir()) == []


def test_a_forked_child_holds_none_of_its_parents_claims(tmp_path):
    """A child forked while a claim is held (a render's forked workers) neither holds nor drops it:
    its claims start empty (tlm.claims._forget_claims), so a claim it made of the same folder is
    refused, and the parent's claim outlives the child's exit."""
    out = tmp_path / "r"
    with claims.claimed(out):
        pid = os.fork()
        if pid == 0:  # (the child: 0 when its claims are empty and its own claim of the folder is refused)
            code = 1
            try:
                if not claims._CLAIMS:
                    try:
                        with claims.claimed(out):
                            code = 2
                    except InputError:
                        code = 0
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0
        assert claim_file(out).exists()
        probe = ("import sys\nfrom pathlib import Path\nfrom tlm import claims\nfrom tlm.errors import InputError\n"
                 "try:\n    with claims.claimed(Path(sys.argv[1])):\n        print('claimed')\n"
                 "except InputError:\n    print('refused')\n")
        got = subprocess.run([sys.executable, "-c", probe, str(out)], capture_output=True, text=True,
                             env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=120)
        assert got.stdout.strip() == "refused", got
    assert not claim_file(out).exists()
