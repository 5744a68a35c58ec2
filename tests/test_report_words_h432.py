"""The report's words on what it names (h432): the "holds no tlm output" line counts the folders
passed over past the three it names, not the search's note lines (a line "and 12 more hidden
folders ..." is 12 folders); the search's notes never say "and 1 more" (nor "1 more ... folders");
and the first screen tells apart two inputs that share a name: two scene files of one frame rate
("from 126 FPS (room.yaml Refract) to 126 FPS (room.yaml Refract)" named one of them twice), and
two input folders of one name in the page's headline."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.report.collect import Inputs, Run, read
from tlm.report.folders import NOTES_SHOWN, find
from tlm.report.names import name_scenes
from tlm.report.summary import _fps


def _hidden(root: Path, n: int) -> None:
    for i in range(n):
        (root / f".hidden{i:02d}").mkdir(parents=True)


@pytest.mark.parametrize("n", [12, 25])
def test_no_tlm_output_counts_the_folders_passed_over_not_the_lines(tmp_path, n):
    root = tmp_path / "root"
    _hidden(root, n)
    with pytest.raises(InputError) as e:
        read([root])
    said = str(e.value)
    assert said.count("a hidden folder, not searched") == 3, said
    assert said.endswith(f"; and {n - 3} more passed over"), said  # (the old count: 8, the 11 lines less 3)


def test_one_more_hidden_folder_than_the_notes_show_is_named_not_counted(tmp_path):
    root = tmp_path / "root"
    _hidden(root, NOTES_SHOWN + 1)
    notes: list[str] = []
    named: list[int] = []
    assert find(root, None, notes, named) == []
    assert notes == [f"{root / f'.hidden{i:02d}'}: a hidden folder, not searched" for i in range(NOTES_SHOWN + 1)]
    assert named == [1] * (NOTES_SHOWN + 1)
    assert not any("1 more" in n for n in notes)


def test_two_more_hidden_folders_are_counted_in_the_plural(tmp_path):
    root = tmp_path / "root"
    _hidden(root, NOTES_SHOWN + 2)
    notes: list[str] = []
    named: list[int] = []
    find(root, None, notes, named)
    assert notes[NOTES_SHOWN:] == ["and 2 more hidden folders not searched"]
    assert named == [*[1] * NOTES_SHOWN, 2] and len(notes) == NOTES_SHOWN + 1


def _run(source: Path, fps: float) -> Run:
    return Run(source.parent, "", "run", {"scene": {"name": "room", "source": str(source)}, "mode": "refract",
                                          "fps": fps, "timing": {}}, {"scene": str(source)})


def test_how_fast_names_each_scene_file_of_one_frame_rate(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # (the scene files under the current folder: named relative to it)
    runs = [_run(tmp_path / "room.yaml", 126.0), _run(tmp_path / "u2" / "room.yaml", 126.0)]
    inputs = Inputs([], runs=runs)
    name_scenes(inputs.runs)
    assert [r.scene_label for r in runs] == ["room.yaml", "u2/room.yaml"]
    text, fig = _fps(inputs, tmp_path)
    assert fig is not None
    assert "<b>How fast:</b> 126 FPS (room.yaml Refract and u2/room.yaml Refract) at one pipeline." in text, text
    runs[1].results["fps"] = 348.0  # (two rates: the range, as before)
    text, _ = _fps(inputs, tmp_path)
    assert "from 126 FPS (room.yaml Refract) to 348 FPS (u2/room.yaml Refract) at one pipeline." in text, text


def test_the_headline_tells_apart_two_input_folders_of_one_name(tmp_path):
    for sub, fps in (("a", 126.0), ("b", 348.0)):
        folder = tmp_path / sub / "runs" / "room"  # (tlm run room.yaml's folder, from ./room.yaml and u2/room.yaml)
        folder.mkdir(parents=True)
        (folder / "results.json").write_text(json.dumps(
            {"scene": {"name": "room", "source": str(tmp_path / sub / "room.yaml")}, "mode": "refract", "fps": fps,
             "timing": {}}))
    assert main(["report", str(tmp_path / "a" / "runs" / "room"), str(tmp_path / "b" / "runs" / "room"),
                 "--out", str(tmp_path / "rep")]) == 0
    text = (tmp_path / "rep" / "report.html").read_text()
    assert "<h1>tlm report: a/runs/room, b/runs/room</h1>" in text, text[:400]
