"""h456: review of 7468c3b (h449: a rerun keeps the user's files inside an output's subfolders).

* A folder the carry made to hold the user's files (``aov/mine.txt`` kept by a run that wrote no ``aov``), or one
  the user made under an output's name, was the output's to the next rerun (not in its listing): removed whole,
  the user's files with it, unsaid. Only ``report`` (``tlm report``'s) is replaced whole now.
* A path of the user's that the new output writes itself (the same name, a folder where the user's file was, a
  file where the user's folder was) went unsaid: a warning names it now; a folder of the user's of a name the
  new output also writes (a study's new scene) is merged, not dropped.
* A signal while the user's files went back (after a carry or swap that failed) removed those still in the
  new output's temporary folder with it: that folder is kept, and said.
* A thesis study's scene named ``.tlm-written`` took the listing's name (its folder where the listing goes).
"""

from __future__ import annotations

import errno
import shutil
from pathlib import Path

import pytest

from tlm import storage
from tlm.experiments.thesis_setting import scene_keys
from tlm.storage import atomic_folder
from tlm.storage_carry import LISTING


def _output(out: Path, files: dict[str, str], owned=("m", "images", "aov", "report")) -> None:
    """An output of ``files`` (``m``, the marker, among them) written into ``out`` by :func:`atomic_folder`."""
    with atomic_folder(out, "m", owned=owned) as tmp:
        for rel, text in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_text(text)


def _files(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (its listing left out) and its text, by its path relative to it."""
    return {p.relative_to(folder).as_posix(): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != LISTING}


def _mine(out: Path, *paths: str) -> None:
    for rel in paths:
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_text("mine")


def test_a_folder_the_carry_made_keeps_the_user_s_files_at_every_rerun_after(tmp_path):
    """A run writing aov, the user's aov/mine.txt, then two runs writing no aov: kept by both (the third run
    removed it: the folder the second run's carry made was in no listing)."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a": "1", "aov/w": "1"})
    _mine(out, "aov/mine.txt", "images/d/deep/mine")
    for n in "23":
        _output(out, {"m": n, "images/a": n})
        assert _files(out) == {"m": n, "images/a": n, "aov/mine.txt": "mine", "images/d/deep/mine": "mine"}
    _output(out, {"m": "4", "images/a": "4", "aov/w": "4"})  # (aov written again: the user's beside it)
    assert _files(out) == {"m": "4", "images/a": "4", "aov/w": "4", "aov/mine.txt": "mine",
                           "images/d/deep/mine": "mine"}


def test_a_folder_of_an_output_s_name_made_by_the_user_is_kept_and_report_is_replaced_whole(tmp_path):
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a": "1"})
    _mine(out, "aov/notes.md", "report/report.html", "report/mine.png")  # (report/: tlm report's, after the run)
    _output(out, {"m": "2", "images/a": "2"})
    assert _files(out) == {"m": "2", "images/a": "2", "aov/notes.md": "mine"}


def test_a_user_s_path_the_new_output_writes_itself_is_said(tmp_path, capsys):
    """Its file where the new output writes a folder, its folder where it writes a file, its file of a name the
    earlier output did not write: the new output's, each named in one warning; the rest of the user's kept."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a": "1"})
    _mine(out, "images/x", "images/y/z", "images/pmap.png", "images/keep.png")
    capsys.readouterr()
    _output(out, {"m": "2", "images/a": "2", "images/x/f": "2", "images/y": "2", "images/pmap.png": "2"})
    assert _files(out) == {"m": "2", "images/a": "2", "images/x/f": "2", "images/y": "2", "images/pmap.png": "2",
                           "images/keep.png": "mine"}
    (line,) = [x for x in capsys.readouterr().err.splitlines() if "yours" in x]
    assert "'images/pmap.png', 'images/x' and 'images/y'" in line and "replaced by this output's own" in line
    assert str(out) in line
    _output(out, {"m": "3", "images/a": "3"})  # (nothing of the user's taken: nothing said)
    assert "yours" not in capsys.readouterr().err


def test_a_user_s_folder_of_a_name_the_new_output_also_writes_is_merged(tmp_path, capsys):
    """A study's folder of a new scene key (not an owned name) that the user had made: its files kept beside the
    new output's (it was dropped whole, unsaid)."""
    out = tmp_path / "o"
    _output(out, {"m": "1"}, owned=("m",))
    _mine(out, "bunny/notes.md", "bunny/cycles.csv")
    _output(out, {"m": "2", "bunny/cycles.csv": "2", "bunny/run/results.json": "2"}, owned=("m",))
    assert _files(out) == {"m": "2", "bunny/notes.md": "mine", "bunny/cycles.csv": "2",
                           "bunny/run/results.json": "2"}
    assert ("'bunny/cycles.csv' (yours: not written by the earlier output, or changed since) was replaced"
            in capsys.readouterr().err)


def test_a_signal_as_the_user_s_files_go_back_keeps_them(tmp_path, monkeypatch, capsys):
    """The carry fails (a folder of the user's that cannot be moved), and Ctrl-C comes as the user's file carried
    before it goes back: the new output's folder, that file in it, is kept beside, named (it was removed)."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a": "1"})
    _mine(out, "images/b_mine.png", "images/c_locked/x")
    rename = Path.rename

    def refused(self, target):
        if self.name == "c_locked" and ".tmp-" in str(target):
            raise OSError(errno.EACCES, "Permission denied", str(self))
        if self.name == "b_mine.png" and ".tmp-" in str(self):
            raise KeyboardInterrupt
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", refused)
    with pytest.raises(KeyboardInterrupt):
        _output(out, {"m": "2", "images/a": "2"})
    monkeypatch.setattr(Path, "rename", rename)
    (kept,) = tmp_path.glob("o.unsaved-*")
    assert (kept / "images" / "b_mine.png").read_text() == "mine" and (kept / "m").read_text() == "2"
    assert _files(out) == {"m": "1", "images/a": "1", "images/c_locked/x": "mine"}
    err = capsys.readouterr().err
    assert "'images/b_mine.png' could not be moved back" in err and str(kept) in err


def test_a_signal_after_a_failed_swap_as_the_user_s_files_go_back_keeps_them(tmp_path, monkeypatch):
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a": "1"})
    _mine(out, "images/mine.png")
    rename = Path.rename

    def swap(tmp, dest, writer=None):
        raise OSError(errno.EIO, "Input/output error", str(dest))

    def interrupted(self, target):
        if self.name == "mine.png" and ".tmp-" in str(self):
            raise KeyboardInterrupt
        return rename(self, target)

    monkeypatch.setattr(storage, "_swap_in", swap)
    monkeypatch.setattr(Path, "rename", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _output(out, {"m": "2", "images/a": "2"})
    monkeypatch.setattr(Path, "rename", rename)
    (kept,) = tmp_path.glob("o.unsaved-*")
    assert (kept / "images" / "mine.png").read_text() == "mine"
    shutil.rmtree(kept)


def test_a_thesis_scene_named_as_the_listing_takes_another_key(tmp_path):
    scene = tmp_path / f"{LISTING}.yaml"
    cornell = Path(__file__).resolve().parents[1] / "scenes" / "cornell.yaml"
    scene.write_text(cornell.read_text() + "\n# a copy of mine\n")
    assert scene_keys([scene.name], tmp_path, str(tmp_path / "thesis.yaml")) == {
        scene.name: (f"{LISTING}-2", None)}
