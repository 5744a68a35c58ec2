"""h489: a sweep folder's stale report, and what a rerun with another grid says.

h484 ran ``tlm sweep r1.yaml --out X`` (its report in X/report), then ``tlm sweep r4.yaml --out X --no-report``:
X/report/report.html still said "sweep file .../r1.yaml" beside r4's rows, and so after a sweep interrupted into a
folder whose report was of another ``--set``; nothing said so (``tlm run --no-report`` removes a run folder's earlier
report). A sweep that claims its folder now removes the report there, as a run does (but one of the very rows it
leaves: the same sweep.yaml, no point to run, the report newer than sweep.jsonl); its own is written after its
points. And a rerun whose factor's values changed said only "left by an earlier run into the folder of other tlm
code, another config or a different --set": it now names what changed since the folder's earlier sweep
(its sweep.yaml), or that only tlm's code did.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
import tlm.fingerprint as fingerprint
from tlm.cli import main
from tlm.experiments.sweep_folder import changes

SET = {"mode": "rcast", "render.spp": 1, "render.light_samples": 1, "resolution": [8, 8]}


def _sweep(tmp_path: Path, name: str, depths: list[int]) -> str:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"base": "cornell", "set": SET, "grid": {"arch.fifo_depth": depths}}))
    return str(path)


def _run(path: str, out: Path, *args: str) -> int:
    return main(["sweep", path, "--out", str(out), "--jobs", "1", "--no-progress", *args])


@pytest.mark.slow
def test_a_sweep_without_its_report_removes_the_earlier_sweeps_report(tmp_path, cache):
    out = tmp_path / "X"
    assert _run(_sweep(tmp_path, "r1.yaml", [16, 256]), out) == 0
    page = (out / "report" / "report.html").stat().st_ino
    assert _run(_sweep(tmp_path, "r1.yaml", [16, 256]), out, "--no-report") == 0  # (the same rows: of them, kept)
    assert (out / "report" / "report.html").stat().st_ino == page
    assert _run(_sweep(tmp_path, "r4.yaml", [16, 1024]), out, "--no-report") == 0
    assert not (out / "report").exists()  # (the old code: r1's report beside r4's rows)
    assert not [p.name for p in out.iterdir() if p.name.startswith(".report")]  # (nothing left aside)
    mine = tmp_path / "mine"  # (a `report` of the user's, a link to a report's folder: not the sweep's, kept)
    mine.mkdir()
    (mine / "report.html").write_text("my notes")
    (out / "report").symlink_to(mine)
    assert _run(_sweep(tmp_path, "r1.yaml", [16, 256]), out, "--no-report") == 0
    assert (out / "report").is_symlink() and (mine / "report.html").read_text() == "my notes"


@pytest.mark.slow
def test_a_sweep_cut_short_removes_the_earlier_sweeps_report(tmp_path, cache, monkeypatch, capsys):
    out = tmp_path / "S"
    path = _sweep(tmp_path, "int.yaml", [16, 256])
    assert _run(path, out, "--set", "resolution=[6,6]") == 0
    assert (out / "report" / "report.html").is_file()

    def cut(task):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_mod, "run_point", cut)
    assert _run(path, out) != 0  # (the h484 probe's: interrupted, of another --set than its report's)
    assert "interrupted" in capsys.readouterr().err
    assert (out / "sweep.yaml").is_file() and not (out / "report").exists()  # (the old code: the 6x6 report)


@pytest.mark.slow
def test_a_rerun_with_other_factor_values_says_what_changed(tmp_path, cache, capsys):
    out = tmp_path / "F"
    assert _run(_sweep(tmp_path, "fifo.yaml", [16, 256]), out, "--no-report") == 0
    capsys.readouterr()
    assert _run(_sweep(tmp_path, "fifo.yaml", [16, 1024]), out, "--no-report") == 0
    err = " ".join(capsys.readouterr().err.split())
    assert (f"1 point folder in {out / 'points'} is not this sweep's: a point of the folder's earlier sweep (its "
            "sweep.yaml before this one's): grid's arch.fifo_depth was [16, 256], now [16, 1024]; nothing reads it"
            ) in err
    assert "another config" not in err  # (the old code: three possible causes)
    assert main(["sweep", _sweep(tmp_path, "other.yaml", [16, 256]), "--out", str(out), "--dry-run",
                 "--set", "resolution=[6,6]"]) == 0  # (the dry run says it too, of the folder's sweep.yaml now)
    err = " ".join(capsys.readouterr().err.split())
    assert (f"3 point folders in {out / 'points'} are not this sweep's: 2 of them are points of the folder's "
            f"earlier sweep ({tmp_path / 'fifo.yaml'}, its sweep.yaml before this one's): grid's arch.fifo_depth was "
            "[16, 1024], now [16, 256] and its --set was none, now resolution=[6,6]; 1 more left by a sweep into the "
            "folder before it, of other tlm code, another config or a different --set; nothing reads them") in err


@pytest.mark.slow
def test_a_rerun_after_a_code_change_says_only_that(tmp_path, cache, capsys, monkeypatch):
    out = tmp_path / "C"
    path = _sweep(tmp_path, "c.yaml", [16, 256])
    code = fingerprint.code_fingerprint()
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (not the disk's: as before an edit)
    assert _run(path, out, "--no-report") == 0
    monkeypatch.setattr(fingerprint, "_CODE", code)
    capsys.readouterr()
    assert _run(path, out, "--no-report") == 0
    err = " ".join(capsys.readouterr().err.split())
    assert (f"2 point folders in {out / 'points'} are not this sweep's: points of the folder's earlier sweep (its "
            "sweep.yaml before this one's), of the same settings and factors, run by other tlm code (code_fingerprint "
            f"0123456789abcdef in their results.json, this tlm's {code}); nothing reads them") in err
    assert "another config" not in err and "input file" not in err


def test_the_changes_between_two_sweeps_are_named():
    then = {"base": {"render": {"spp": 4}, "mode": "pmap"}, "set": {"mode": "rcast"}, "overrides": ["seed=1"],
            "grid": {"arch.fifo_depth": [16, 256], "render.exposure": [0.5, 1.0]}, "zip": {}}
    now = {"base": {"render": {"spp": 8}, "mode": "pmap"}, "set": {"mode": "rcast"},
           "grid": {"arch.fifo_depth": [16, 1024], "render.batch": [1, 4]}, "zip": {}}
    assert changes(then, now) == [
        "base's render.spp was 4, now 8", "grid's arch.fifo_depth was [16, 256], now [16, 1024]",
        "grid's render.exposure was [0.5, 1.0], now none", "grid's render.batch was none, now [1, 4]",
        "its --set was seed=1, now none"]
    assert changes(now, now) == []
