"""``tlm.write_report`` (the library call) prints nothing itself: the notes on a folder of
folders (one with no run in it, a link not followed, ...) go to its ``note`` callback, as
``tlm.error_vs_cost``'s do, and the page says them; ``tlm report`` prints them on stderr as
before (tests/test_report_folders_words.py)."""

from __future__ import annotations

import json
from pathlib import Path

from tlm import api


def _run_folder(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(
        {"scene": {"name": "Box", "source": "/x/Box.yaml"}, "mode": "refract", "fps": 0.772, "timing": {}}))
    return folder


def _nest(tmp_path: Path) -> tuple[Path, str]:
    """A folder of one run and a folder with none: one note."""
    nest = tmp_path / "nest"
    _run_folder(nest / "run1")
    (nest / "junk").mkdir()
    return nest, f"{nest / 'junk'}: no run, sweep or study in it"


def test_the_library_call_prints_nothing_and_the_page_keeps_the_note(tmp_path, capsys):
    nest, note = _nest(tmp_path)
    page = api.write_report([nest], tmp_path / "rep")
    assert capsys.readouterr().err == ""  # (it said "tlm: note: .../junk: ..." on stderr)
    assert f'<p class="note">{note}.</p>' in page.read_text()


def test_the_notes_go_to_the_callers_note_as_soon_as_the_folders_are_searched(tmp_path, capsys):
    nest, note = _nest(tmp_path)
    heard: list[tuple[str, bool]] = []
    page = api.write_report([nest], tmp_path / "rep", note=lambda line: heard.append(
        (line, (tmp_path / "rep" / "report.html").exists())))
    assert heard == [(note, False)]  # (once, before the page is written: before the figures are drawn)
    assert page.is_file() and capsys.readouterr().err == ""


def test_a_locked_report_hears_its_notes_too(tmp_path, capsys):
    nest, note = _nest(tmp_path)
    heard: list[str] = []
    api.write_report([nest], tmp_path / "rep", lock=True, note=heard.append)
    assert heard == [note] and capsys.readouterr().err == ""
