"""``tlm report``'s folders and words: a folder of tlm folders is searched at any depth (a folder
in it with none is named, not passed over), one scene file reached by two paths is one scene,
and the report says a count of one and a single value as English does."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.report.collect import Inputs, Run, Study, read
from tlm.report.names import name_scenes
from tlm.report.provenance import provenance_section
from tlm.report.summary import PMS, summary_section


def _run_folder(folder: Path, fps: float = 0.772) -> Path:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(
        {"scene": {"name": "Box", "source": "/x/Box.yaml"}, "mode": "refract", "fps": fps, "timing": {}}))
    return folder


def _intro(report: Path) -> str:
    text = report.read_text()
    start = text.index("Inputs:")
    return text[start:text.index("<section", start)]


def test_runs_are_found_at_any_depth_and_an_empty_folder_is_named(tmp_path):
    nest = tmp_path / "nest"
    _run_folder(nest / "run2")
    _run_folder(nest / "deep" / "run1")
    _run_folder(nest / "deep" / "run1" / "inner")  # (a run's own folders are its own: not read)
    _run_folder(nest / ".hidden" / "run3")  # (hidden: not meant)
    (nest / "junk" / "sub").mkdir(parents=True)
    (nest / "junk" / "sub" / "notes.txt").write_text("x")
    (nest / "old_report").mkdir()
    (nest / "old_report" / "report.html").write_text("<html></html>")  # (a report: not an input)
    os.symlink(nest / "deep", nest / "link")  # (a link inside the tree: its folder is read where it lies)
    outside = _run_folder(tmp_path / "elsewhere" / "run9")
    os.symlink(outside.parent, nest / "away")

    inputs = read([nest])
    assert [r.path for r in inputs.runs] == [nest / "deep" / "run1", nest / "run2"]
    assert inputs.notes == [f"{nest / 'away'}: a link to {outside.parent}, a folder outside {nest} and no run, sweep "
                            "or study itself: not followed (give it to tlm report as a folder of its own)",
                            f"{nest / 'junk'}: no run, sweep or study in it"]
    assert [r.label for r in inputs.runs] == ["run1: /x/Box.yaml/refract", "run2: /x/Box.yaml/refract"]

    assert main(["report", str(nest), "--out", str(nest / "rep")]) == 0
    intro = _intro(nest / "rep" / "report.html")
    assert ": 2 runs, 0 sweeps, 0 studies (none)." in intro
    assert f'<p class="note">{nest / "junk"}: no run, sweep or study in it.</p>' in intro
    assert main(["report", str(nest), "--out", str(nest / "rep")]) == 0  # again: its own folder is not read
    assert f"{nest / 'rep'}:" not in _intro(nest / "rep" / "report.html")


def test_a_link_to_a_run_kept_elsewhere_is_read_and_a_link_not_followed_is_said(tmp_path, capsys):
    links = tmp_path / "rep" / "links"
    links.mkdir(parents=True)
    run = _run_folder(tmp_path / "disk" / "r1")
    os.symlink(run, links / "r1link")  # (a run folder out of the tree: read, as the one-level scan did)
    (tmp_path / "other" / "sub").mkdir(parents=True)
    os.symlink(tmp_path / "other", links / "olink")  # (no tlm folder itself: not followed, and said so)
    (run / "back").symlink_to(links)  # (a tlm folder is never searched: no loop)

    assert main(["report", str(links), "--out", str(tmp_path / "out")]) == 0
    note = (f"{links / 'olink'}: a link to {tmp_path / 'other'}, a folder outside {links} and no run, sweep or "
            "study itself: not followed (give it to tlm report as a folder of its own)")
    assert capsys.readouterr().err.splitlines() == [f"tlm: note: {note}"]
    intro = _intro(tmp_path / "out" / "report.html")
    assert ": 1 run, 0 sweeps, 0 studies (none)." in intro and f'<p class="note">{note}.</p>' in intro
    assert [r.path for r in read([links]).runs] == [links / "r1link"]


def test_no_tlm_output_names_what_was_passed_over(tmp_path, capsys):
    links = tmp_path / "links"
    (tmp_path / "other").mkdir()
    (links / ".runs" / "run").mkdir(parents=True)
    (links / "old" / "report.html").parent.mkdir()
    (links / "old" / "report.html").write_text("<html></html>")
    links.joinpath("olink").symlink_to(tmp_path / "other")
    assert main(["report", str(links), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "holds no tlm output" in err
    assert (f"{links / 'olink'}: a link to {tmp_path / 'other'}, a folder outside {links}" in err
            and f"; {links / '.runs'}: a hidden folder, not searched; {links / 'old'}: a report's folder, not searched"
            in err), err
    assert not (tmp_path / "out").exists()


def test_the_notes_of_folders_with_no_run_are_bounded(tmp_path, capsys):
    runs = tmp_path / "runs"
    _run_folder(runs / "m" / "run")
    for i in range(25):
        (runs / f"e{i:02d}" / "deeper").mkdir(parents=True)  # (one line for e00, none for e00/deeper)
    inputs = read([runs])
    assert inputs.notes == [*(f"{runs / f'e{i:02d}'}: no run, sweep or study in it" for i in range(10)),
                            "and 15 more folders with no run, sweep or study in them"]
    assert main(["report", str(runs), "--out", str(tmp_path / "out")]) == 0
    assert len(capsys.readouterr().err.splitlines()) == 11
    assert _intro(tmp_path / "out" / "report.html").count('<p class="note">') == 11


def test_two_runs_of_one_name_in_two_folders_are_told_apart(tmp_path):
    _run_folder(tmp_path / "a" / "run")
    _run_folder(tmp_path / "b" / "run")
    assert [r.label for r in read([tmp_path]).runs] == ["a/run: /x/Box.yaml/refract", "b/run: /x/Box.yaml/refract"]


def test_a_single_run_is_one_run_and_its_frame_rate_is_said_once(tmp_path):
    run = _run_folder(tmp_path / "run")
    assert main(["report", str(run), "--out", str(tmp_path / "rep")]) == 0
    text = (tmp_path / "rep" / "report.html").read_text()
    assert f"Inputs: {run}: 1 run, 0 sweeps, 0 studies (none)." in text
    assert "<b>How fast:</b> 0.772 FPS (/x/Box.yaml Refract) at one pipeline." in text
    assert " to 0.772 FPS" not in text and "(s)" not in text.replace("(s)</", "")


def test_one_scene_mode_is_the_only_one(tmp_path):
    busy = dict(zip(PMS, (0.1, 0.68, 0.5, 0.2), strict=True))
    units = {f"pipe0.{pm}": {"fractions": {"busy": b}} for pm, b in busy.items()}
    run = Run(Path("runs/a"), "a", "run", {"scene": {"name": "cornell"}, "mode": "pmap", "fps": 3.22,
                                          "timing": {"units": units}}, {})
    lead = summary_section(Inputs([], runs=[run]), tmp_path).lead
    assert "the TTrav PM is the bottleneck in the only scene-mode, busy 68% of the time." in lead
    assert "1 of 1" not in lead and "68–68" not in lead


def test_host_seconds_per_scene_in_words(tmp_path):
    study = Study("thesis", Path("th"), [], {"host_seconds": {"thesis/ring": 14.73, "thesis/room": 3.314,
                                                              "cornell": 3.5}})
    html = provenance_section(Inputs([], studies=[study]), tmp_path).html
    assert "; host seconds per scene: thesis/ring 14.7, thesis/room 3.31, cornell 3.50</p>" in html
    assert "{" not in html


def test_one_scene_file_reached_by_two_paths_is_one_scene(tmp_path, monkeypatch):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "exp").mkdir()
    (tmp_path / "scenes" / "Mirror.yaml").write_text("name: Mirror\n")
    monkeypatch.chdir(tmp_path / "exp")  # (the file is not under the current folder: named by its whole path)

    def run(ref: str, source: str, kind: str) -> Run:
        return Run(Path(kind), kind, kind, {"scene": {"name": "Mirror", "source": source}, "timing": {}},
                   {"scene": ref})

    point = run("../scenes/Mirror.yaml", f"{tmp_path}/exp/../scenes/Mirror.yaml", "sweep-point")
    single = run(f"{tmp_path}/scenes/Mirror.yaml", f"{tmp_path}/scenes/Mirror.yaml", "run")
    inputs = Inputs([], runs=[point, single])
    name_scenes(inputs.runs)
    assert point.scene_label == single.scene_label == f"{tmp_path}/scenes/Mirror.yaml"
    assert inputs.shared_names() == []
    monkeypatch.chdir(tmp_path)  # (under the current folder: relative to it)
    name_scenes(inputs.runs)
    assert point.scene_label == single.scene_label == "scenes/Mirror.yaml"


def test_a_link_inside_the_folder_to_a_run_there_does_not_rename_it(tmp_path):
    """``root/alink -> root/z/run``: the run is read where it lies, named ``run`` (the link, sorting
    first, named it ``alink``)."""
    from tlm.report.folders import find

    root = tmp_path / "root"
    run = root / "z" / "run"
    run.mkdir(parents=True)
    (run / "results.json").write_text("{}")
    (root / "alink").symlink_to(run, target_is_directory=True)
    assert [p for p, _ in find(root)] == [run]


def test_no_tlm_output_says_at_most_three_passed_over_folders_on_its_line(tmp_path):
    """The "holds no tlm output" error is one line: three of what the search passed over, then how
    many more (44 notes made a line of a few KB)."""
    from tlm.errors import InputError

    root = tmp_path / "root"
    for i in range(12):
        (root / f".hidden{i:02d}").mkdir(parents=True)
    with pytest.raises(InputError) as e:
        read([root])
    said = str(e.value)
    assert said.count("a hidden folder, not searched") == 3 and said.endswith("; and 9 more passed over"), said
    # (the search's notes: 10 of the 12 hidden folders and a line for the 2 more; three shown, the other 9 folders
    # counted: h432, it counted the 8 lines)
