"""A folder a live tlm process is writing is refused to every other writer (h415, probe h409's D1 and D2).

Only ``tlm run`` claimed its folder (``.<name>.tlm-running``): a study (``tlm granularity``,
``error-vs-cost``, ...) or a sweep into the folder of a run in progress went ahead, and the run, finishing
later, was refused with all its work lost; two studies into one folder both "succeeded", the last
replacing the first unsaid. Now :func:`tlm.storage.check_destination` refuses a destination another live
process holds (its claim beside it, or a sweep running in it), naming it, exit 2, before any work; the
study commands hold their folder as ``tlm run`` does; a sweep is refused a folder a run or a study claims,
and a run or a study one a sweep runs in (two runs of one sweep still share theirs); a claim whose process
is gone is ignored; and a run refused at its final move keeps its output beside (``OUT.unsaved-<pid>``).

The other process is a child holding the lock (no timing: it says when it holds it, and lets go when its
stdin closes)."""

from __future__ import annotations

import os
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pytest

import tlm.experiments.run as run_mod
from tlm import claims, storage
from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--mode", "rcast", "--set", "resolution=[16,16]", "--set", "render.light_samples=1", "--no-progress",
         "--no-reference"]
HOLD = """
import fcntl, os, sys
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)
fcntl.flock(fd, fcntl.LOCK_SH if sys.argv[3] == "shared" else fcntl.LOCK_EX)
record = sys.argv[2].replace("PID", str(os.getpid())).replace("|", chr(10))
os.pwrite(fd, f"{record:<63}\\n".encode(), 0)
print("held", flush=True)
sys.stdin.read()
"""


@contextmanager
def held(path: Path, kind: str | None = "run", mode: str = "exclusive"):
    """``path`` held by a child process (a claim's exclusive lock, or a sweep's shared one), its record
    naming it (and, with ``kind``, what it writes, as this tlm records it); the child's pid."""
    record = f"{storage._host()}-PID" + (f"|{kind}" if kind else "")
    child = subprocess.Popen([sys.executable, "-c", HOLD, str(path), record, mode], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "held"
        yield child.pid
    finally:
        child.stdin.close()
        child.wait(timeout=60)


def beside(out: Path) -> Path:
    return out.parent / f".{out.name}.tlm-running"


def write_configs(folder: Path) -> None:
    (folder / "run.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [16, 16]\n"
                                     "render: {spp: 1, light_samples: 1}\narch: {frames: 1}\n")
    (folder / "g.yaml").write_text("base:\n  scene: cornell\n  mode: rcast\n  resolution: [16, 16]\n"
                                   "  render: {light_samples: 1, spp: 1}\n  arch: {frames: 1}\npacket_sizes: [4]\n")
    (folder / "sw.yaml").write_text("base: run.yaml\ngrid:\n  arch.packet_size: [4]\n")


COMMANDS = {  # a command writing a folder, and its arguments (those that name an input, in tmp_path)
    "granularity": ["granularity", "g.yaml"],
    "error-vs-cost": ["error-vs-cost", "error_vs_cost"],
    "thesis": ["thesis", "thesis"],
    "extreme": ["extreme", "extreme"],
    "scaling": ["scaling", "nosweep"],
    "sweep": ["sweep", "sw.yaml"],
    "report": ["report", "nofolder", "--out"],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_writer_into_a_folder_a_live_run_claims_is_refused_at_once(tmp_path, cache, monkeypatch, capsys,
                                                                    command):
    """D1: every command that writes a folder (a study, a sweep, a report's --out), into the folder a live
    ``tlm run`` of another process claims, exits 2 with one line naming the folder and that process, before
    any work; nothing is written, the claim is left to its holder (was: rc 0, and the run lost its work)."""
    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    (tmp_path / "nofolder").mkdir()
    out = tmp_path / "rx2"
    argv = [*COMMANDS[command], *([] if command == "report" else ["--out"]), str(out), "--no-progress"]
    with held(beside(out)) as pid:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1].startswith(f"tlm: error: --out: another run is writing into {str(out)!r} "
                                  f"(process {pid} on this machine, "), err
        assert err[-1].endswith("wait for it to end, or give another folder"), err
        assert not out.exists()
        assert (tmp_path / beside(out).name).is_file()  # (the holder's, as it was)


def test_two_studies_into_one_folder_the_second_is_refused_naming_the_first(tmp_path, cache, monkeypatch, capsys):
    """D2: ``tlm granularity`` holds its folder from before its work to the end of its report (its claim
    beside it, recording a study): a second ``tlm granularity`` of another process into it meanwhile exits 2
    naming the first; the first writes its folder whole and leaves no claim (was: both rc 0, the last's rows
    replacing the first's)."""
    import tlm.experiments.granularity as gran

    monkeypatch.chdir(tmp_path)
    write_configs(tmp_path)
    out = tmp_path / "gd"
    seen = []
    real = gran.run_study

    def run_study(*a, **k):  # (during the first's work: the second starts)
        seen.append(beside(out).read_text().splitlines())
        seen.append(subprocess.run([sys.executable, "-m", "tlm", "granularity", "g.yaml", "--out", "gd",
                                    "--no-progress", "--no-report"], cwd=tmp_path, capture_output=True, text=True,
                                   env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=300))
        return real(*a, **k)

    monkeypatch.setattr(gran, "run_study", run_study)
    assert main(["granularity", "g.yaml", "--out", "gd", "--no-progress", "--no-report"]) == 0
    record, second = seen
    assert record[0].strip() == storage.process_tag() and record[1].strip() == "study", record
    assert second.returncode == 2, second.stderr
    assert second.stderr.splitlines()[-1].startswith(
        f"tlm: error: --out: another study is writing into 'gd' (process {os.getpid()} on this machine, "), second
    assert (out / "granularity.jsonl").is_file()
    assert not beside(out).exists()


def test_a_study_into_a_folder_a_sweep_runs_in_is_refused_naming_the_sweep(tmp_path):
    """A sweep running in a folder (its shared lock on ``.tlm-running-<identity>``) refuses a run, a study
    or a report into it, naming the sweep's process (was: "exists and is not an earlier tlm output")."""
    out = tmp_path / "sw"
    out.mkdir()
    (out / "sweep.yaml").write_text("x\n")
    (out / ".tlm-lock").write_text("")
    with held(out / ".tlm-running-abc", kind=None, mode="shared") as pid:
        for marker in ("granularity.jsonl", "rows.jsonl", "results.json"):
            with pytest.raises(claims.FolderHeld) as e:
                storage.check_destination(out, marker)
            assert str(e.value).startswith(f"--out: another sweep is writing into {str(out)!r} (process {pid} on this "
                                           "machine, "), e.value
        with pytest.raises(claims.FolderHeld, match="another sweep is writing into"), claims.claimed(out, "run"):
            pytest.fail("a run claimed a folder a sweep runs in")
        assert not beside(out).exists()
        storage.check_destination(out, "sweep.yaml")  # (another run of the sweep: shared, as documented)


def test_a_sweep_is_refused_a_folder_a_run_or_study_claims_as_it_comes_in(tmp_path):
    """A sweep's share of its folder (tlm.claims.sharing) is refused where a live run or study claims the
    folder (one that claimed it after the sweep's first check), and leaves no running file of its own."""
    out = tmp_path / "sw"
    out.mkdir()
    with held(beside(out), kind="study") as pid:
        with pytest.raises(claims.FolderHeld) as e, claims.sharing(out, "mine", "sweep"):
            pytest.fail("the sweep shared a folder a study claims")
        assert str(e.value).startswith(f"--out: another study is writing into {str(out)!r} (process {pid} on "), e.value
    assert not list(out.glob(".tlm-running-*"))


@pytest.mark.parametrize("marker", ["granularity.jsonl", "rows.jsonl", "thesis_comparison.csv", "extreme.jsonl",
                                    "eq52.json", "report.html", "sweep.yaml", "results.json"])
def test_every_writers_check_refuses_a_live_claim_and_ignores_a_stale_one(tmp_path, marker):
    """storage.check_destination, which every writer calls before its work: a live claim of another process
    refused, naming it (an older tlm's record, which says not what it writes: a run's, or in a report's folder
    a report's, the only claims an older tlm took, h422); one whose process is gone (its lock free) ignored."""
    out = tmp_path / "o"
    with held(beside(out), kind=None) as pid, pytest.raises(claims.FolderHeld) as e:
        storage.check_destination(out, marker)
    what = "report" if marker == "report.html" else "run"  # (an older tlm's claims: a run's or a report's, h422)
    line = f"--out: another {what} is writing into {str(out)!r} (process {pid} on this machine, "
    assert str(e.value).startswith(line), e.value
    beside(out).write_text(f"{storage._host()}-{pid}\n")  # (left by it, now gone)
    assert storage.check_destination(out, marker) == out.resolve()


def test_a_finished_run_refused_at_its_final_move_keeps_its_output_beside(tmp_path, cache, monkeypatch, capsys):
    """A folder of another program's put at the run's ``--out`` while it worked: the run is refused at its
    end (exit 2) and its output kept beside, ``OUT.unsaved-<pid>``, which the line names (was: refused with
    no folder kept, the render and simulation lost); the other folder left as it was."""
    out = tmp_path / "rx"
    real = run_mod.simulate_render

    def simulate(*a, **k):  # (as the run works: another program's folder there)
        out.mkdir()
        (out / "notes.txt").write_text("mine\n")
        return real(*a, **k)

    monkeypatch.setattr(run_mod, "simulate_render", simulate)
    assert main(["run", "cornell", *SMALL, "--out", str(out), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    kept = tmp_path / f"rx.unsaved-{os.getpid()}"
    assert "exists and is not an earlier tlm output" in err and err.endswith(
        f"this run's output is kept in {str(kept)!r}"), err
    assert (kept / "results.json").is_file() and (kept / "images" / "composite.png").is_file()
    assert os.listdir(out) == ["notes.txt"]
    assert not beside(out).exists()
