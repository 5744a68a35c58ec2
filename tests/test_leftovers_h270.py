"""h270's leftovers: a report of inputs from different tlm code says so; a sweep may write into a
mount point (a run may not); ``tlm report`` removes the claim a killed run left beside its folder; a
sweep point whose error.json cannot be written keeps its own error; a pmap run whose photon-map pass
a setting left out says so."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

from tlm import claims, storage
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments import sweep_point
from tlm.report import warnings as box
from tlm.report.collect import Inputs, Run, Sweep

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--set", "resolution=[8,8]", "--set", "render.spp=1", "--set", "render.light_samples=1", "--no-progress"]


def _run(path: str, code: str | None, kind: str = "run") -> Run:
    results = {"mode": "rcast", **({"code_fingerprint": code} if code else {})}
    return Run(Path(path), path, kind, results, {})


def test_inputs_of_other_code_are_named_in_the_warnings_box():
    """A run of older code (no fingerprint) beside runs and a sweep of this code: one line naming which
    folders are of which code; inputs all of one code say nothing."""
    new, old = _run("runs/new_run", "aaaa"), _run("runs/old_run", None)
    point = _run("runs/sw/points/h1", None, "sweep-point")
    inputs = Inputs([Path("runs")], runs=[point, old, new], sweeps=[Sweep(Path("runs/sw"), {}, [], [point])])
    line = box.code_line(inputs)
    assert line is not None and "different tlm code" in line
    assert "code aaaa: runs/new_run" in line
    assert "no code recorded (an older tlm): runs/sw and runs/old_run" in line
    assert "<strong>Different code.</strong>" in box.warnings_html(inputs)
    same = Inputs([Path("runs")], runs=[new, _run("runs/other", "aaaa")])
    assert box.code_line(same) is None and box.warnings_html(same) == ""
    two = Inputs([Path("runs")], runs=[new, _run("runs/other", "bbbb")])
    assert "code aaaa: runs/new_run; code bbbb: runs/other" in box.code_line(two)


def test_a_report_of_an_older_run_beside_a_new_one_says_so(tmp_path, cache):
    new = tmp_path / "new"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(new), "--outputs", "images",
                 "--no-report", *SMALL]) == 0
    old = tmp_path / "old"
    shutil.copytree(new, old)
    results = json.loads((old / "results.json").read_text())
    assert results.pop("code_fingerprint")
    (old / "results.json").write_text(json.dumps(results))
    assert main(["report", str(new), str(old), "--out", str(tmp_path / "rep"), "--no-progress"]) == 0
    page = (tmp_path / "rep" / "report.html").read_text()
    assert "<strong>Different code.</strong>" in page and f"no code recorded (an older tlm): {old}" in page


def _sweep_file(tmp_path: Path) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                             "render": {"light_samples": 1, "spp": 1}},
                                    "grid": {"arch.fifo_depth": [16]}}))
    return path


def test_a_sweep_may_write_into_a_mount_point_a_run_may_not(tmp_path, cache, monkeypatch, capsys):
    """A sweep writes into its folder in place, never replacing it: an --out that is a mount point is
    taken (with --dry-run too); a run, whose folder is replaced whole, still refuses one."""
    mount = tmp_path / "mnt"
    mount.mkdir()
    real = storage.is_mount
    monkeypatch.setattr(storage, "is_mount", lambda p: Path(p) == mount.resolve() or real(p))
    sweep = _sweep_file(tmp_path)
    assert main(["sweep", str(sweep), "--out", str(mount), "--dry-run", "--no-progress"]) == 0
    assert main(["sweep", str(sweep), "--out", str(mount), "--no-progress", "--no-report"]) == 0
    assert (mount / "sweep.yaml").is_file() and len(list((mount / "points").iterdir())) == 1
    capsys.readouterr()
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(mount), *SMALL]) == 2
    assert "is a mount point, which cannot be replaced" in capsys.readouterr().err


def _claim_and(folder: Path, then: str) -> subprocess.Popen:
    """A process that claims ``folder`` as a run does, then kills itself (``kill``) or sleeps (``hold``)."""
    code = ("import os, sys, time; from pathlib import Path; from tlm import claims\n"
            f"with claims.claimed(Path({str(folder)!r})):\n"
            "    print('held', flush=True)\n"
            f"    os.kill(os.getpid(), 9) if {then == 'kill'} else time.sleep(60)\n")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=env, text=True)
    assert child.stdout.readline().strip() == "held"
    return child


def test_tlm_report_removes_the_claim_a_killed_run_left_beside_its_folder(tmp_path, cache):
    run = tmp_path / "kr" / "r2"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(run), "--outputs", "images",
                 "--no-report", *SMALL]) == 0
    beside = run.parent / ".r2.tlm-running"
    child = _claim_and(run, "kill")
    assert child.wait(timeout=60) == -signal.SIGKILL and beside.is_file()
    assert main(["report", str(run), "--no-progress"]) == 0
    assert not beside.exists()


def test_a_claim_still_held_is_left(tmp_path):
    run = tmp_path / "r"
    run.mkdir()
    child = _claim_and(run, "hold")
    try:
        beside = tmp_path / ".r.tlm-running"
        assert claims.drop_stale(run) is False and beside.is_file()
    finally:
        child.kill()
        child.wait(timeout=60)
    deadline = time.monotonic() + 10
    while claims._gone(beside.read_text()) is False and time.monotonic() < deadline:
        time.sleep(0.01)
    assert claims.drop_stale(run) is True and not beside.exists()
    with claims.claimed(run):  # (this process's own: left)
        assert claims.drop_stale(run) is False and beside.is_file()


def test_a_point_whose_error_json_cannot_be_written_keeps_its_own_error(tmp_path, monkeypatch):
    """run_point's docstring: an exception never leaves the worker; the row is the point's error."""
    def refuse(task, error, *who):  # (who ran it, since 81ec1d4)
        raise InputError("is an older tlm's results.json", source=str(tmp_path / "points" / "h"))

    monkeypatch.setattr(sweep_point, "write_error", refuse)
    task = sweep_point.Task("h", {"scene": "cornell", "nonsense_key": 1}, {}, str(tmp_path), "s.yaml",
                            str(tmp_path / "points" / "h"), {})
    got = sweep_point.run_point(task)
    assert got["status"] == "failed"
    assert "nonsense_key" in got["error"]["message"]
    assert "its error.json could not be written" in got["error"]["message"]
    assert "older tlm's results.json" in got["error"]["message"]


def test_a_pmap_run_without_photons_says_so(tmp_path, cache):
    out = tmp_path / "pm0"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--mode", "pmap", "--set", "photons.count=0",
                 "--out", str(out), "--outputs", "images", "--no-report", *SMALL]) == 0
    said = [w for w in json.loads((out / "results.json").read_text())["warnings"] if "photon-map pass" in w]
    assert len(said) == 1 and "photons.count is 0" in said[0] and "no pmap frame" in said[0]


def test_a_run_is_not_refused_for_a_stale_claim_being_dropped(tmp_path):
    """drop_stale holds a dead run's claim file's lock while it removes it: a run that opened that file
    meanwhile takes a new one, never refused naming the dead process."""
    import fcntl
    import threading

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait(timeout=60)
    run = tmp_path / "r"
    beside = tmp_path / ".r.tlm-running"
    beside.write_text(f"{storage._host()}-{dead.pid}".ljust(63) + "\n")
    fd = os.open(beside, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (as drop_stale holds it)

    def drop() -> None:
        time.sleep(0.05)
        beside.unlink()
        os.close(fd)

    dropping = threading.Thread(target=drop)
    dropping.start()
    try:
        with claims.claimed(run):
            assert beside.is_file()  # (its own, new)
    finally:
        dropping.join()
    assert not beside.exists()
