"""Faults a probe found (h257, fixed in h267): ``tlm plots`` refuses a bad or unwritable ``--out`` before its
first step, not after every step ran; a sweep stops at its first point a full disk refused, that point left to
run, the rows of the points done written (``sweep.csv`` never left disagreeing with ``sweep.jsonl``); a folder
in place of a remembered scene fingerprint is a damaged entry, removed and written again (no cache-wide
warning); a report's default folder that cannot be written says ``give --out``."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
from tlm import api, storage
from tlm.caches import cache_root, cache_warnings
from tlm.cli import main
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments import frames, sweep_rows
from tlm.experiments.sweep_point import error_record
from tlm.report.regenerate import regenerate
from tlm.storage_errors import says_disk_full

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}
RUN_POINT = sweep_mod.run_point
FULL = "cannot write: no space left on device"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _read_only(monkeypatch, folder: Path) -> None:
    """``folder`` said read-only by os.access (as root, a chmod does not make it so)."""
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **k: False if Path(p) == folder else real(p, mode, **k))


# ------------------------------------------------------------------ 1: tlm plots checks --out first


@pytest.mark.parametrize("where", ["a file", "under a file", "read-only"])
def test_plots_refuses_a_bad_out_before_its_first_step(tmp_path, monkeypatch, where):
    """(It ran every step, 13.7 minutes for all of them, and then refused the folder.)"""
    configs, runs = tmp_path / "configs", tmp_path / "runs"
    configs.mkdir()
    (tmp_path / "afile").write_text("hi\n")
    ro = tmp_path / "ro"
    ro.mkdir()
    _read_only(monkeypatch, ro)
    out = {"a file": tmp_path / "afile", "under a file": tmp_path / "afile" / "sub", "read-only": ro / "plots"}[where]
    ran = []
    with pytest.raises(EnvironmentFailure if where == "read-only" else InputError) as got:
        regenerate(configs, runs, out, ["sweep_fifo"], run_command=lambda argv: ran.append(argv) or 0)
    assert ran == []
    assert str(got.value) == {
        "a file": f"--out: {str(out)!r} exists and is not a folder",
        "under a file": f"--out: {str(out)!r} cannot be made: {str(tmp_path / 'afile')!r} is a file, not a folder",
        "read-only": f"{out}: cannot write into {ro} (read-only or not permitted)"}[where]


def test_tlm_plots_with_a_file_as_out_exits_2_before_any_step(tmp_path, capsys):
    (tmp_path / "configs").mkdir()
    (tmp_path / "afile").write_text("hi\n")
    code = main(["plots", "--configs", str(tmp_path / "configs"), "--runs", str(tmp_path / "runs"), "--out",
                 str(tmp_path / "afile"), "--only", "sweep_fifo"])
    got = capsys.readouterr()
    assert code == 2 and "==" not in got.out, got.out
    assert got.err.strip() == f"tlm: error: --out: {str(tmp_path / 'afile')!r} exists and is not a folder"
    assert not (tmp_path / "runs").exists()


# ------------------------------------------------------------------ 4: a report's default folder, unwritable


def test_a_report_whose_default_folder_cannot_be_written_says_give_out(tmp_path, monkeypatch):
    """(Said before its inputs are read; an --out given that cannot be written is said without the hint.)"""
    ro = tmp_path / "ro"
    ro.mkdir()
    _read_only(monkeypatch, ro)
    with pytest.raises(EnvironmentFailure) as got:
        api.write_report([ro])
    assert str(got.value) == f"{ro / 'report'}: cannot write into {ro} (read-only or not permitted); give --out"
    with pytest.raises(EnvironmentFailure) as given:
        api.write_report([ro], ro / "mine")
    assert str(given.value) == f"{ro / 'mine'}: cannot write into {ro} (read-only or not permitted)"


# ------------------------------------------------------------------ 2: a full disk during a sweep


def _rows(out: Path) -> tuple[list[dict], list[dict]]:
    with open(out / "sweep.csv", newline="") as f:
        table = list(csv.DictReader(f))
    return [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()], table


@pytest.mark.parametrize("how", ["its record", "its worker's exception"])
def test_a_sweep_stops_at_its_first_point_that_a_full_disk_refused(tmp_path, monkeypatch, capsys, how):
    """The third point's folder does not fit: the sweep stops there (it tried every other point, each failing
    alike, and recorded them as failed; its rows' rewrite failed and left a sweep.csv of the header alone); the
    two done are its rows, sorted, in both files; the rerun, with room, runs the other four."""
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16, 256],
                                                           "bsp.levels": [4, 6]}}, sort_keys=False))
    out = tmp_path / "o"
    calls = []

    def point(task):
        calls.append(task.hash)
        if len(calls) <= 2:
            return RUN_POINT(task)
        full = EnvironmentFailure(FULL, source=task.out)
        if how == "its worker's exception":  # (its error.json did not fit either: run_point raised)
            raise full
        return {"status": "failed", "error": error_record(full, "write", ""), "worker": None}

    monkeypatch.setattr(sweep_mod, "run_point", point)
    argv = ["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(calls) == 3, calls
    assert err[-1] == (f"tlm: error: {out / 'points' / calls[2]}: {FULL}: the sweep stopped with 2 of 6 points "
                       f"done, kept in {out}; with room, run it again into that folder to run the others"), err
    jsonl, table = _rows(out)
    assert [r["hash"] for r in jsonl] == [r["hash"] for r in table] and len(jsonl) == 2
    assert {r["hash"] for r in jsonl} == set(calls[:2]) and all(r["status"] == "ok" for r in jsonl)
    assert [r["point"] for r in jsonl] == sorted(r["point"] for r in jsonl)
    assert not (out / "points" / calls[2]).exists()  # (no error.json: the point is to run)
    monkeypatch.setattr(sweep_mod, "run_point", RUN_POINT)
    assert main(argv) == 0
    assert "6 points: 4 ok, 0 failed, 2 skipped" in capsys.readouterr().out
    jsonl, table = _rows(out)
    assert len(jsonl) == len(table) == 6 and all(r["status"] == "ok" for r in jsonl)


@pytest.mark.parametrize("which", ["sweep.jsonl", "sweep.csv"])
def test_rows_that_do_not_fit_leave_no_csv_that_disagrees(tmp_path, monkeypatch, which):
    """(A CSV of the rows before, or of fewer rows than the JSONL appended since, was left as it was.)"""
    (tmp_path / "sweep.jsonl").write_text('{"point": 1}\n{"point": 0}\n')  # (as a sweep appended them)
    (tmp_path / "sweep.csv").write_text("point\n0\n")
    real = storage.write_atomic

    def full(path, *a, **k):
        if Path(path).name == which:
            raise EnvironmentFailure(FULL, source=str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(storage, "write_atomic", full)
    with pytest.raises(EnvironmentFailure):
        sweep_rows.write_rows(tmp_path, [{"point": 1}, {"point": 0}], ["x"])
    assert not (tmp_path / "sweep.csv").exists()
    jsonl = (tmp_path / "sweep.jsonl").read_text()  # (written whole, sorted, or left as it was)
    assert jsonl == ('{"point": 0}\n{"point": 1}\n' if which == "sweep.csv" else '{"point": 1}\n{"point": 0}\n')


@pytest.mark.parametrize(("kind", "message", "full"), [
    ("EnvironmentFailure", f"/o/points/ab: {FULL}", True),
    ("EnvironmentFailure", "/o/points/ab: cannot write: disk quota exceeded (on the Dask worker w)", True),
    ("EnvironmentFailure", "/o: cannot create the output folder (No space left on device)", True),
    ("OSError", "[Errno 28] No space left on device: '/o/points/ab/trace.json'", True),
    ("EnvironmentFailure", "/o/points/ab: cannot write: read-only file system", False),
    ("RuntimeError", "no space left on device", False),
])
def test_a_full_disk_is_told_from_a_point_s_record(kind, message, full):
    assert says_disk_full(kind, message) is full


# ------------------------------------------------------------------ 3: a remembered scene fingerprint, damaged


def test_a_folder_in_place_of_a_scene_fingerprint_is_removed_and_the_file_written(tmp_path):
    """(Its write failed, and the whole scene cache was said to be unwritable, in every run, for ever.)"""
    key = ("box.yaml", None, None, str(tmp_path), str(tmp_path / "box.yaml"), "code")
    checks = [["listed", "x"]]
    frames._keep_key(key, "abc", checks)
    path = next((cache_root("scenes")).glob("key-*.json"))
    path.unlink()
    path.mkdir()
    (path / "something").write_text("x")
    frames._keep_key(key, "abc", checks)
    assert path.is_file() and json.loads(path.read_text())["fingerprint"] == "abc"
    assert cache_warnings() == []


def test_tlm_report_whose_default_folder_cannot_be_written_says_give_out(tmp_path, monkeypatch, capsys):
    """tlm report DIR (no --out), DIR read-only: the line adds ``; give --out``, exit 1 (needs h267's patch of
    tlm/cli_report.py report_claimed); with --out given, the line is as it was."""
    ro = tmp_path / "ro"
    ro.mkdir()
    _read_only(monkeypatch, ro)
    assert main(["report", str(ro), "--no-progress"]) == 1
    assert capsys.readouterr().err.strip() == (f"tlm: error: {ro / 'report'}: cannot write into {ro} (read-only or "
                                               "not permitted); give --out")
    assert main(["report", str(ro), "--out", str(ro / "mine"), "--no-progress"]) == 1
    assert capsys.readouterr().err.strip() == f"tlm: error: {ro / 'mine'}: cannot write into {ro} (read-only or " \
                                              "not permitted)"


def test_a_point_a_full_disk_stopped_writes_no_error_json(tmp_path, monkeypatch, capsys):
    """run_point (needs h267's patch of tlm/experiments/sweep_point.py): a point whose error is a full disk writes
    no error.json (the sweep stops on it, and the point is to run, not a failed one)."""
    import tlm.arch.model as model

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16, 256]}}, sort_keys=False))
    out = tmp_path / "o"
    real, calls = model.simulate, []

    def simulate(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise EnvironmentFailure(FULL, source=str(tmp_path / "elsewhere"))
        return real(*a, **k)

    monkeypatch.setattr(model, "simulate", simulate)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 1
    assert f"{FULL}: the sweep stopped with 1 of 3 points done" in capsys.readouterr().err
    assert len(calls) == 2 and not list((out / "points").glob("*/error.json"))
    assert len(list((out / "points").iterdir())) == 1
