"""A sweep's leftovers (h88, h89): the rows of a sweep cut short, ``--jobs`` with a remote
scheduler, a bad ``--dask`` on a folder whose points are all done, and the library's warnings
(returned, not printed; ``tlm sweep`` prints them)."""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.executors import SweepStopped
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}
RUN_POINT = sweep_mod.run_point


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(tmp_path: Path, **body) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


def _csv(out: Path) -> tuple[list[str], list[dict]]:
    with open(out / "sweep.csv", newline="") as f:
        reader = csv.DictReader(f)
        return list(reader.fieldnames or []), list(reader)


def _jsonl(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]


def _stop_at(monkeypatch, call: int, *, after: bool) -> None:
    """Ctrl-C at the sweep's ``call``-th point (1 first): before it runs, or ``after`` it wrote
    its folder (done, its result not yet taken by the sweep)."""
    calls = []

    def point(task):
        calls.append(task.hash)
        if len(calls) == call and not after:
            raise KeyboardInterrupt
        got = RUN_POINT(task)
        if len(calls) == call:
            raise KeyboardInterrupt
        return got

    monkeypatch.setattr(sweep_mod, "run_point", point)


# ---------------------------------------------------------------- the rows of a sweep cut short


@pytest.mark.parametrize("after, rows", [(False, 2), (True, 3)])
def test_an_interrupted_sweep_writes_the_csv_of_its_points_done(tmp_path, monkeypatch, after, rows):
    """Cut short at its third point: sweep.csv holds the rows of the points done, as sweep.jsonl
    does (before, the CSV was the header the sweep wrote as it began); a point whose folder its
    worker wrote whole before the sweep took its result is done, and has its row."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2, 4, 8]})
    out = tmp_path / "o"
    _stop_at(monkeypatch, 3, after=after)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1)
    cols, got = _csv(out)
    assert [r["point"] for r in got] == [str(i) for i in range(rows)], got
    assert all(r["status"] == "ok" and r["fps"] for r in got)
    assert [r["point"] for r in _jsonl(out)] == list(range(rows))
    assert cols[4:7] == ["arch.fifo_depth", "scene", "mode"]
    monkeypatch.setattr(sweep_mod, "run_point", RUN_POINT)
    again = run_sweep(path, out, jobs=1)  # (the points done are kept: a rerun runs the others)
    assert (again.ok, again.skipped) == (4 - rows, rows)
    assert _csv(out)[0] == cols and len(_csv(out)[1]) == 4


def test_a_sweep_its_cluster_stopped_writes_the_csv_of_its_points_done(tmp_path, monkeypatch):
    """A sweep stopped by its cluster (SweepStopped: the scheduler lost, or without workers) keeps
    its rows as an interrupted one does."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2, 4]})
    out = tmp_path / "o"
    looks = []

    def checkpoint():
        looks.append(1)
        if len(looks) == 3:  # (the loop's third look: two points taken)
            raise SweepStopped("the Dask scheduler tcp://x:1 is gone")

    monkeypatch.setattr(sweep_mod, "checkpoint", checkpoint)
    with pytest.raises(SweepStopped):
        run_sweep(path, out, jobs=1)
    assert [r["point"] for r in _csv(out)[1]] == ["0", "1"] and len(_jsonl(out)) == 2


def test_a_sweep_interrupted_before_any_point_finished_has_the_factor_columns(tmp_path, monkeypatch):
    """No row: the CSV's header is a sweep's, its factors, scene and mode included (they were missing)."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2]}, zip={"seed": [0, 1]})
    out = tmp_path / "o"
    _stop_at(monkeypatch, 1, after=False)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1)
    cols, got = _csv(out)
    assert got == [] and _jsonl(out) == []
    assert cols[:8] == ["point", "hash", "status", "error", "arch.fifo_depth", "seed", "scene", "mode"], cols
    assert {"fps", "cycles.throughput"} <= set(cols)


# ---------------------------------------------------------------- --jobs and --dask


def test_jobs_with_a_remote_scheduler_is_refused_not_ignored(tmp_path, capsys):
    """The points of a remote scheduler run on its workers, as many at once as they have threads:
    ``--jobs`` would change nothing there (both points ran at once with --jobs 1), so it is refused,
    exit 2, before anything is written; ``--dask local`` takes it (its cluster's workers)."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2]})
    out = tmp_path / "o"
    t0 = time.monotonic()
    rc = main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--dask", "tcp://127.0.0.1:9", "--no-report"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("tlm: error: --jobs: 1 with --dask tcp://127.0.0.1:9: ") and "leave --jobs out" in err
    assert time.monotonic() - t0 < 5 and not out.exists()  # (no scheduler was reached)
    with pytest.raises(InputError, match=r"^--jobs: 2 with --dask tcp://127\.0\.0\.1:9: "):
        run_sweep(path, out, jobs=2, dask="tcp://127.0.0.1:9")
    assert not out.exists()


@pytest.mark.parametrize("dask, why", [("foo", "is not a Dask scheduler's address"),
                                       ("", "is not a Dask scheduler's address"),
                                       ("LOCAL", "is not local, the only name --dask takes"),
                                       ("tcp://127.0.0.1:99999", "its port 99999 is not a port (1 to 65535)"),
                                       ("tcp://:8786", "is not a Dask scheduler's address"),
                                       ("tcp://host:port", "is not a Dask scheduler's address")])
def test_a_bad_dask_is_refused_even_where_every_point_is_done(tmp_path, capsys, dask, why):
    """The address's form is checked before the sweep sees there is nothing to run (it exited 0
    then); a well-formed address is not reached where nothing is to run (exit 0 at once)."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2]})
    out = tmp_path / "o"
    assert run_sweep(path, out, jobs=1).ok == 2
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    capsys.readouterr()
    rc = main(["sweep", str(path), "--out", str(out), "--dask", dask, "--no-progress", "--no-report"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"tlm: error: --dask: {dask!r}") and why in err and "tcp://HOST:PORT" in err, err
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    t0 = time.monotonic()
    assert main(["sweep", str(path), "--out", str(out), "--dask", "tcp://127.0.0.1:9", "--no-progress",
                 "--no-report"]) == 0
    assert time.monotonic() - t0 < 5  # (every point done: no scheduler to reach, nor a wait for one)
    assert "2 points: 0 ok, 0 failed, 2 skipped" in capsys.readouterr().out



@pytest.mark.parametrize("dask", ["ucxx://127.0.0.1:9", "TCP://127.0.0.1:9", "127.0.0.1:9", "[::1]:9"])
def test_a_transport_the_check_does_not_know_is_left_to_dask(tmp_path, capsys, dask):
    """Only the address's form is checked: a plugin's transport (ucxx) or a scheme in capitals is
    Dask's to take or refuse when there are points to run, not refused by tlm beforehand."""
    path = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2]})
    out = tmp_path / "o"
    assert run_sweep(path, out, jobs=1).ok == 2
    capsys.readouterr()
    assert main(["sweep", str(path), "--out", str(out), "--dask", dask, "--no-progress", "--no-report"]) == 0
    assert "2 points: 0 ok, 0 failed, 2 skipped" in capsys.readouterr().out

# ---------------------------------------------------------------- warnings: returned by the library, printed by the CLI


def test_the_library_returns_the_sweeps_warnings_and_prints_none(tmp_path, capsys, monkeypatch):
    """``run_sweep`` (``tlm.run_sweep``, ``tlm.sweep``) returns its lines in ``warnings`` and
    prints none (a notebook showed each twice); ``warn`` gets each as it is known, the factors'
    before any point runs; ``tlm sweep`` prints each once, as before."""
    path = _sweep(tmp_path, grid={"arch.swap_cycles": [2, 9], "photons.count": [500, 1000]})
    out = tmp_path / "o"
    assert run_sweep(path, out, jobs=1).ok == 4
    (out / "points" / "0123456789abcdef").mkdir()  # (an earlier run's point folder)
    done = run_sweep(path, out, jobs=1)
    assert done.skipped == 4 and len(done.warnings) == 3, done.warnings
    inert, unread, stale = done.warnings
    assert "the factor photons.count changes nothing in any point" in inert
    assert "the factor arch.swap_cycles changed nothing in any of the 4 points" in unread
    assert stale.startswith(f"1 point folder in {out / 'points'} is not this sweep's")
    assert "warning" not in capsys.readouterr().err

    heard: list[str] = []
    seen_at_first_point: list[int] = []

    def point(task):
        seen_at_first_point.append(len(heard))
        return RUN_POINT(task)

    monkeypatch.setattr(sweep_mod, "run_point", point)
    again = run_sweep(path, tmp_path / "o2", jobs=1, warn=heard.append)
    assert heard == again.warnings and seen_at_first_point[0] == 1  # (the factor's line before the points)
    assert "warning" not in capsys.readouterr().err

    assert main(["sweep", str(path), "--out", str(out), "--no-progress", "--no-report"]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if line.startswith("tlm: warning: ")]
    assert said == [f"tlm: warning: {line}" for line in done.warnings]
