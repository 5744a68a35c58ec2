"""``tlm sweep FILE --dry-run`` (``run_sweep(dry_run=True)``): what a sweep would do, told before it spends
anything. The counts of a folder half done (points skipped, to run, folders replaced), the frames the points
to run share and how many of them are cached, the references ``--reference`` would compute, the stale and
foreign folders, the warnings; the same one-line errors as the sweep on bad input (exit status 2); and
nothing written: no output folder, no cache entry, no claim, no report (h200)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
import yaml

from tlm import api, storage
from tlm.cli import main
from tlm.experiments.sweep_file import load_sweep
from tlm.experiments.sweep_plan import SweepPlan

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}
# 8 points, 2 frames (bsp.levels: the frame reads it; arch.fifo_depth and estimate.k in mode rcast: it does not)
GRID = {"bsp.levels": [3, 4], "arch.fifo_depth": [1, 16], "estimate.k": [4, 8]}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32},
        "reference": {"photons": 1500, "k_nearest": 20, "max_rounds": 8, "min_rounds": 4, "spp": 2}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(folder: Path, base: dict = BASE, grid: dict = GRID, name: str = "s.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({"base": base, "grid": grid}, sort_keys=False))
    return path


def _listing(*folders: Path) -> dict[str, tuple[int, int]]:
    """Every file and folder under ``folders``, with its size and modification time."""
    out = {}
    for top in folders:
        for root, dirs, files in os.walk(top):
            for name in [*dirs, *files]:
                p = Path(root) / name
                st = p.stat()
                out[str(p)] = (st.st_size if p.is_file() else 0, st.st_mtime_ns)
    return out


def _dry(capsys, *args: str) -> tuple[int, str, str]:
    status = main(["sweep", *args, "--dry-run"])
    got = capsys.readouterr()
    return status, got.out, got.err


def test_a_dry_run_writes_nothing_and_says_what_the_sweep_would_do(tmp_path, cache, capsys):
    path = _sweep(tmp_path)
    out = tmp_path / "o"
    before = _listing(tmp_path)
    status, said, err = _dry(capsys, str(path), "--out", str(out))
    assert status == 0, err
    assert _listing(tmp_path) == before  # (no output folder, no claim file beside it, no cache entry, no report)
    assert not out.exists() and not cache.exists()
    assert said.splitlines()[:3] == [
        f"dry run of {path} into {out}: nothing run, nothing written",
        "  8 points: 0 done already (skipped), 8 to run",
        "  2 frames for the points to run: 0 cached, 2 to render"]
    # the warning the sweep gives before its points, on stderr as it gives it
    assert "tlm: warning: " in err and "the factor estimate.k changes nothing in any point" in err


def test_the_json_plan_holds_the_counts_and_the_warnings(tmp_path, capsys):
    path = _sweep(tmp_path)
    status, said, _ = _dry(capsys, str(path), "--out", str(tmp_path / "o"), "--json")
    assert status == 0
    record = json.loads(said)
    assert {k: record[k] for k in ("points", "done", "to_run", "frames", "frames_cached", "renders", "replaced",
                                   "stale", "other_folders", "references")} == {
        "points": 8, "done": 0, "to_run": 8, "frames": 2, "frames_cached": 0, "renders": 2, "replaced": 0,
        "stale": 0, "other_folders": 0, "references": None}
    assert record["dry_run"] is True and any("estimate.k" in w for w in record["warnings"])
    plan = api.run_sweep(path, tmp_path / "o", dry_run=True)  # (the API's: the same plan)
    assert isinstance(plan, SweepPlan) and plan.record() == record
    assert not (tmp_path / "o").exists()


def test_json_without_dry_run_is_refused(tmp_path, capsys):
    path = _sweep(tmp_path)
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--json"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--json" in err and "--dry-run" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("body, key", [
    ({"base": BASE, "grid": {"arch.fifo_depth": [0, 16]}}, "arch.fifo_depth"),
    ({"base": BASE, "grid": {"arch.fifo_depth": [1]}, "nonesuch": 1}, "nonesuch"),
    ({"base": BASE}, "grid"),
])
def test_bad_input_is_the_sweeps_own_one_line_error_exit_2_and_nothing_written(tmp_path, capsys, body, key):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(body, sort_keys=False))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--no-report"]) == 2
    real = capsys.readouterr().err
    before = _listing(tmp_path)
    status, said, err = _dry(capsys, str(path), "--out", str(tmp_path / "o"))
    assert (status, said, err) == (2, "", real)  # (the sweep's line, word for word: unknown flag no more)
    assert len(err.strip().splitlines()) == 1 and str(path) in err and key in err
    assert _listing(tmp_path) == before


def test_a_bad_out_and_set_are_refused_as_by_the_sweep(tmp_path, capsys):
    path = _sweep(tmp_path, grid={"bsp.levels": [3, 4], "arch.fifo_depth": [1, 16]})  # (no warning before the error)
    (tmp_path / "file").write_text("not a folder")
    for args in (["--out", str(tmp_path / "file")], ["--out", str(tmp_path / "o"), "--set", "arch.fifo_depth=4"],
                 ["--out", str(tmp_path / "o"), "--set", "nonesuch=1"]):
        assert main(["sweep", str(path), *args, "--no-report"]) == 2
        real = capsys.readouterr().err
        assert _dry(capsys, str(path), *args) == (2, "", real), args
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_counts_on_a_folder_half_done_are_those_the_sweep_then_has(tmp_path, cache, capsys):
    """Points done are skipped, a failed point's folder replaced, a folder of no point kept (a warning), a killed
    sweep's temporary folder removed; the frames of the points to run are cached: none rendered."""
    path = _sweep(tmp_path)
    out = tmp_path / "o"
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress"]) == 0
    capsys.readouterr()
    hashes = sorted(p.name for p in (out / "points").iterdir())
    for h in hashes[:3]:  # (3 not done: 2 never run, 1 failed, its folder left)
        shutil.rmtree(out / "points" / h)
    (out / "points" / hashes[0]).mkdir()
    (out / "points" / hashes[0] / "error.json").write_text("{}")
    (out / "points" / "0123456789abcdef").mkdir()  # (another sweep's point)
    host = storage.process_tag().rpartition("-")[0]
    killed = out / "points" / f".0123456789abcdef.tmp-{host}-999999999-1"  # (a killed sweep's: its process gone)
    killed.mkdir()
    before = _listing(tmp_path)
    status, said, err = _dry(capsys, str(path), "--out", str(out), "--json")
    assert status == 0 and _listing(tmp_path) == before
    plan = json.loads(said)
    frames = len({p.functional for p in load_sweep(path).points if p.hash in hashes[:3]})
    assert {k: plan[k] for k in ("points", "done", "to_run", "replaced", "frames", "frames_cached", "renders",
                                 "stale", "other_folders")} == {
        "points": 8, "done": 5, "to_run": 3, "replaced": 1, "frames": frames, "frames_cached": frames,
        "renders": 0, "stale": 1, "other_folders": 1}
    assert "1 point folder in" in err and "is not this sweep's" in err
    done = api.run_sweep(path, out, jobs=1)  # what the sweep then does
    assert (done.skipped, done.ok, done.renders, done.other_folders) == (5, 3, 0, 1)
    assert not killed.exists()


@pytest.mark.slow
def test_a_cached_frame_is_counted_and_not_rendered(tmp_path, capsys):
    """Another sweep rendered one of the two frames (its points differ only in arch.*): the plan says 1 cached, 1 to
    render, and the sweep renders 1."""
    first = _sweep(tmp_path, grid={"bsp.levels": [3], "arch.fifo_depth": [2]}, name="one.yaml")
    assert main(["sweep", str(first), "--out", str(tmp_path / "a"), "--jobs", "1", "--no-report",
                 "--no-progress"]) == 0
    path = _sweep(tmp_path)
    status, said, _ = _dry(capsys, str(path), "--out", str(tmp_path / "o"))
    assert status == 0
    assert "  8 points: 0 done already (skipped), 8 to run" in said.splitlines()
    assert "  2 frames for the points to run: 1 cached, 1 to render" in said.splitlines()
    assert api.run_sweep(path, tmp_path / "o", jobs=1).renders == 1


@pytest.mark.slow
def test_reference_lists_the_references_the_sweep_would_compute(tmp_path, cache, capsys):
    path = _sweep(tmp_path, base=PMAP, grid={"arch.fifo_depth": [1, 16], "resolution": [[8, 8], [8, 6]]})
    out = tmp_path / "o"
    status, said, _ = _dry(capsys, str(path), "--out", str(out), "--reference", "--json")
    assert status == 0 and not out.exists() and not (cache / "references").exists()
    plan = json.loads(said)
    assert sorted((r["points"], r["action"]) for r in plan["references"]) == [(2, "compute"), (2, "compute")]
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress",
                 "--reference"]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in (cache / "references").iterdir()) == sorted(r["key"] for r in plan["references"])
    status, said, _ = _dry(capsys, str(path), "--out", str(out), "--reference", "--json")
    again = json.loads(said)
    assert (again["done"], again["to_run"], again["references"]) == (4, 0, [])
    # a rcast sweep: the sweep's own line, no reference
    status, said, err = _dry(capsys, str(_sweep(tmp_path)), "--out", str(tmp_path / "r"), "--reference")
    assert status == 0 and "no point of this sweep runs the photon-map pass" in err
