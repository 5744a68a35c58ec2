"""Review of 9c07933 (h274): a full disk is told from an error's own words, not from a path that holds them (an
output folder named ``no space left on device``: its points' ``file too large`` stopped the sweep as a full disk,
with no error.json); a report refuses an ``--out`` that is, or holds, one of its inputs (``tlm report runs/a
--out runs`` removed ``runs/a`` with the folder the report replaced; ``tlm plots --out X --runs X/runs`` alike),
before anything is read or run."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
from tlm import api
from tlm.cli import main
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments.sweep_point import error_record
from tlm.report import check_out
from tlm.report.regenerate import regenerate
from tlm.storage_errors import says_disk_full

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}
NAMED = "/data/No space left on device (old disk)"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.mark.parametrize(("kind", "message", "full"), [
    ("EnvironmentFailure", f"{NAMED}/points/ab: cannot write: file too large", False),
    ("EnvironmentFailure", f"{NAMED}/points/ab: cannot write: read-only file system (on the Dask worker w)", False),
    ("EnvironmentFailure", "/o/disk quota exceeded/points/ab: cannot write: input/output error", False),
    ("OSError", f"[Errno 5] Input/output error: '{NAMED}/x'", False),
    ("EnvironmentFailure", f"{NAMED}/points/ab: cannot write: no space left on device", True),
    ("EnvironmentFailure", f"{NAMED}/points/ab: cannot write: disk quota exceeded (on the Dask worker h)", True),
    ("EnvironmentFailure", f"{NAMED}: cannot create the output folder (No space left on device)", True),
    ("EnvironmentFailure", "/o/t: cannot write: a write was cut short (8 requested and 0 written): no space left on "
                           "device?", True),
    ("OSError", f"[Errno 28] No space left on device: '{NAMED}/x'", True),
])
def test_a_full_disk_is_told_from_its_words_not_from_a_path(kind, message, full):
    assert says_disk_full(kind, message) is full


def test_a_sweep_into_a_folder_named_so_is_not_stopped_as_a_full_disk(tmp_path, monkeypatch, capsys):
    """Every point fails with ``file too large`` (ulimit -f) into a folder whose name holds the words: each is a
    failed point with its error.json, the sweep runs them all (it stopped at the first, 'with room, run it again')."""
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16, 256]}}, sort_keys=False))
    out = tmp_path / "No space left on device (old disk)"
    calls = []

    def point(task):
        calls.append(task.hash)
        error = error_record(EnvironmentFailure("cannot write: file too large", source=task.out), "write", "")
        sweep_mod.write_error(task, error)
        return {"status": "failed", "error": error, "worker": None}

    monkeypatch.setattr(sweep_mod, "run_point", point)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 1
    err = capsys.readouterr().err
    assert len(calls) == 3 and "the sweep stopped" not in err, err
    assert len(list((out / "points").glob("*/error.json"))) == 3


def _report(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "report.html").write_text("<html></html>\n")
    return folder


@pytest.mark.parametrize("where", ["holds", "is"])
def test_a_report_refuses_an_out_that_is_or_holds_an_input(tmp_path, where):
    """(The report replaced its folder whole: the input inside it went with the old report.)"""
    rep = _report(tmp_path / "rep")
    run = rep / "a"
    run.mkdir()
    (run / "mine.txt").write_text("kept\n")
    given = run if where == "holds" else rep
    with pytest.raises(InputError) as got:
        api.write_report([given], rep)
    assert str(got.value) == (f"out: {str(rep)!r} {where} {str(given)!r}, an input of the report: writing the "
                              "report there would remove it (the report replaces its folder whole); name another "
                              "folder")
    assert (run / "mine.txt").read_text() == "kept\n" and (rep / "report.html").is_file()


def test_tlm_plots_refuses_an_out_that_holds_its_runs_before_its_first_step(tmp_path):
    rep = _report(tmp_path / "plots")
    configs = tmp_path / "configs"
    configs.mkdir()
    ran = []
    with pytest.raises(InputError, match="holds") as got:
        regenerate(configs, rep / "runs", rep, ["sweep_fifo"], run_command=lambda argv: ran.append(argv) or 0)
    assert ran == [] and str(rep / "runs") in str(got.value)


def test_an_out_beside_or_inside_its_inputs_is_accepted(tmp_path):
    """An earlier report as --out, DIR/report, plots/ beside runs/: as before."""
    runs, rep = tmp_path / "runs", _report(tmp_path / "earlier")
    (runs / "a").mkdir(parents=True)
    assert check_out(rep, [runs / "a"]) == rep.resolve()
    assert check_out(None, [runs]) == (runs / "report").resolve()
    assert check_out(runs / "a" / "report", [runs / "a"], [runs]) == (runs / "a" / "report").resolve()
    assert check_out(tmp_path / "plots", [], [runs, tmp_path / "configs"]) == (tmp_path / "plots").resolve()
