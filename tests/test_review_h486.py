"""h486: review of 97d786d (h477: the report reads a run's files only where its ``.tlm-written`` lists them).

* A thesis cell or an extreme case that a rerun of its study kept (the study's listing does not name it) was left
  out of ``tlm report T`` alone: ``tlm report T/cornell`` (or ``tlm report X/cases``, the way the report points to an
  extreme study's cases) searched the folder, found the kept run folder and drew it, put it in Table III too, with no
  sign of it. A run folder a search finds where a study puts its runs is now read by the study's listing, as
  ``tlm report T`` reads its cells (tlm.report.written.own_runs); one given itself is read as ever.
* The report said "the run folder has no radiance/ (radiance is there, ...)": where the file is there but not the
  run's, it says "the run wrote no ...", and a folder is named as one (``radiance/``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.report.collect import read
from tlm.report.images import cell_panel, images_section, run_panels
from tlm.storage_carry import LISTING

CORNELL = str(Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml")


def _run(out: Path, *args: str) -> None:
    assert main(["run", CORNELL, "--no-report", "--no-progress", "--out", str(out), "--set", "resolution=[8,8]",
                 *args]) == 0


def _relisted(out: Path, drop) -> None:
    """``out``'s listing less the lines whose path ``drop(path)`` is true (as though the run had not written them)."""
    lines = (out / LISTING).read_bytes().splitlines(keepends=True)
    (out / LISTING).write_bytes(b"".join(x for x in lines if not drop(x.split(b"\t")[0].strip().decode())))


def test_a_search_under_a_thesis_study_leaves_out_a_cell_its_listing_does_not_name(tmp_path, cache):
    study = tmp_path / "T"
    _run(study / "cornell" / "rcast", "--set", "mode=rcast")
    shutil.copytree(study / "cornell" / "rcast", study / "cornell" / "reflect")  # (an earlier study's, kept)
    shutil.copytree(study / "cornell" / "rcast", study / "cornell" / "mine")  # (not a cell's name: the user's run)
    (study / "thesis_comparison.csv").write_text("scene,mode\n")
    (study / LISTING).write_text("cornell\ncornell/rcast\ncornell/rcast/results.json\t1\t1\n")
    inputs = read([study / "cornell"])
    assert sorted(r.path.name for r in inputs.runs) == ["mine", "rcast"]
    (note,) = [n for n in inputs.notes if "reflect" in n]
    assert note == (f"{study / 'cornell' / 'reflect'}: a thesis cell that the study {study} did not write (not in "
                    f"its {LISTING}: an earlier study's, kept by a rerun, or the user's), left out of this report")
    assert [r.path.name for r in read([study / "cornell" / "reflect"]).runs] == ["reflect"]  # (given itself: read)
    (study / LISTING).unlink()  # (a study with no listing: every cell read, as tlm report T reads them)
    assert sorted(r.path.name for r in read([study / "cornell"]).runs) == ["mine", "rcast", "reflect"]


def test_what_the_report_says_of_a_file_there_that_the_run_did_not_write(tmp_path, cache):
    out = tmp_path / "R"
    _run(out, "--set", "mode=reflect")
    _relisted(out, lambda p: p == "radiance/rcast.npy" or p == "images/composite.png")
    run = read([out]).runs[0]
    remark = run_panels(run)[0].remark
    assert remark.startswith("the run wrote no radiance/rcast.npy (radiance/rcast.npy is there, but not in the run's "
                             f"{LISTING}: an earlier output's, kept by a rerun, or the user's)"), remark
    assert cell_panel(run, "reflect").remark.startswith(f"no image: {run.label} wrote no images/composite.png "
                                                        "(images/composite.png is there, but not")
    _relisted(out, lambda p: p.startswith(("images", "radiance")))
    run = read([out]).runs[0]
    assert run_panels(run)[1].remark.startswith("cannot rebuild: the run wrote no radiance/ (radiance/ is there, but")
    (note,) = [n for n in images_section(read([out]), tmp_path).notes if "left out" in n]
    assert ": the run wrote no images/ or radiance/ (images/ is there, but not in the run's" in note
    assert note.endswith("(radiance/ is there, but not in the run's .tlm-written: an earlier output's, kept by a "
                         "rerun, or the user's), left out")
    shutil.rmtree(out / "radiance")  # (none there: the folder has none, as it said)
    assert run_panels(read([out]).runs[0])[0].remark == "cannot rebuild: the run folder has no radiance/"


@pytest.mark.slow
def test_tlm_report_of_an_extreme_study_s_cases_leaves_out_a_case_a_rerun_kept(tmp_path, cache, capsys):
    file, out = tmp_path / "cases.yaml", tmp_path / "X"
    cases = [{"name": name, "category": "c", "expect": "runs", "config": {"scene": "cornell", "mode": "rcast"},
              "checks": ["finite"]} for name in ("a", "b")]
    for n in (2, 1):
        file.write_text(yaml.safe_dump({"base": {"resolution": [8, 8], "arch": {"frames": 1, "trace": False}},
                                        "cases": cases[:n]}))
        assert main(["extreme", str(file), "--out", str(out), "--no-report", "--no-progress"]) == 0
        if n == 2:
            (out / LISTING).unlink()  # (then the rerun keeps the case it does not write: cases/b)
    assert (out / "cases" / "b" / "results.json").is_file()
    capsys.readouterr()
    assert main(["report", str(out / "cases"), "--out", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")
    err = capsys.readouterr().err
    assert (f"tlm: note: {out / 'cases' / 'b'}: an extreme case that the study {out} did not write (not in its "
            f"{LISTING}: an earlier study's, kept by a rerun, or the user's), left out of this report") in err
    assert "a: cornell/rcast" in page and "b: cornell/rcast" not in page
    shutil.rmtree(out / "cases" / "a")  # (nothing of the study's own left: the line says why)
    assert main(["report", str(out / "cases"), "--out", str(tmp_path / "rep2")]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"tlm: error: {out / 'cases'}: holds no tlm output") and "an extreme case that" in line
