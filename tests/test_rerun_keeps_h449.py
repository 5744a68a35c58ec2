"""h449: a rerun into an output's folder keeps the user's files inside the output's own subfolders.

A run's ``images``, ``radiance`` and ``aov`` (a study's folders the same) were replaced whole by a rerun, so a
user's ``images/my_annotated.png`` went without a word. The output now lists what it wrote (``.tlm-written``,
:func:`tlm.storage_carry.write_listing`); a rerun carries what the old listing does not name to the same path in the
new folder, unless the new output writes that path (then it is the new output's). A rerun that fails leaves
the old folder, the user's files in it, as it was.
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pytest

from tlm import storage
from tlm.cli import main
from tlm.errors import EnvironmentFailure
from tlm.experiments.study import run_study
from tlm.storage import atomic_folder

LISTING = ".tlm-written"  # (tlm.storage.LISTING: what an output wrote in its folder)
CORNELL = str(Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml")
RUN = ["run", CORNELL, "--set", "resolution=[8,8]", "--no-report", "--no-progress"]


def _files(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (its listing left out) and its text, by its path relative to it."""
    return {str(p.relative_to(folder)): p.read_bytes().decode("latin-1") for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != LISTING}


def _listed(out: Path) -> set[str]:
    """The paths ``out``'s listing names (a file's line: its path, then its size and time, a tab before each)."""
    return {line.split("\t")[0] for line in (out / LISTING).read_text().splitlines()}


def _output(out: Path, files: dict[str, str], owned=("m", "images", "aov")) -> None:
    """An output of ``files`` (``m``, the marker, among them) written into ``out`` by :func:`atomic_folder`."""
    with atomic_folder(out, "m", owned=owned) as tmp:
        for rel, text in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_text(text)


def test_a_rerun_of_tlm_run_keeps_the_user_s_files_in_its_subfolders(tmp_path, cache):
    out = tmp_path / "r"
    assert main([*RUN, "--out", str(out)]) == 0
    assert (out / "aov" / "work.npz").is_file() and (out / "radiance" / "rcast.npy").is_file()
    (out / "images" / "my_annotated.png").write_text("mine")
    (out / "images" / "analysis").mkdir()
    (out / "images" / "analysis" / "fit.py").write_text("mine")
    (out / "aov" / "mine.txt").write_text("mine")
    (out / "radiance" / "notes.md").write_text("mine")
    shutil.copy2(out / "images" / "rcast.png", out / "images" / "rcast_copy.png")  # (cp -p: tlm's mtime)
    (out / "images" / "composite.png").write_text("mine")  # (a path the run writes: the run's, said)
    assert main([*RUN, "--out", str(out), "--outputs", "images"]) == 0
    assert (out / "images" / "my_annotated.png").read_text() == "mine"
    assert (out / "images" / "analysis" / "fit.py").read_text() == "mine"
    assert (out / "aov" / "mine.txt").read_text() == "mine" and (out / "radiance" / "notes.md").read_text() == "mine"
    assert (out / "images" / "rcast_copy.png").is_file()
    assert (out / "images" / "composite.png").read_bytes().startswith(b"\x89PNG")
    # what the first run wrote and the second does not write goes (--outputs images: no AOVs, no radiance)
    assert sorted(os.listdir(out / "aov")) == ["mine.txt"] and sorted(os.listdir(out / "radiance")) == ["notes.md"]


def test_the_listing_not_the_file_s_dates_tells_the_user_s_files(tmp_path):
    """A file the old output wrote that the new one does not write goes, one the user put there stays, in a
    folder of the old output's that the new one does not write too; a file the user put where the new output
    writes one is the new output's, and a folder of the user's where the new output writes a file goes too."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a.png": "1", "images/old.png": "1", "aov/w.npz": "1", "images/d/x": "1"})
    assert _listed(out) == {"m", "images", "images/a.png", "images/old.png", "aov", "aov/w.npz", "images/d",
                            "images/d/x"}
    for rel in ("images/mine.png", "images/a.png", "aov/mine.txt", "images/d/mine", "images/sub/deep/y"):
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_text("mine")
    (out / "images" / "b").mkdir()
    (out / "images" / "b" / "z").write_text("mine")
    shutil.copy2(out / "images" / "old.png", out / "images" / "old_copy.png")
    _output(out, {"m": "2", "images/a.png": "2", "images/b": "2"})
    assert _files(out) == {"m": "2", "images/a.png": "2", "images/b": "2", "images/mine.png": "mine",
                           "images/old_copy.png": "1", "aov/mine.txt": "mine", "images/d/mine": "mine",
                           "images/sub/deep/y": "mine"}
    assert _listed(out) == {"m", "images", "images/a.png", "images/b"}
    # an output with no listing (deleted, an older tlm's): what the new output writes is its, the rest is kept
    # (h464: it was replaced whole, the user's files with it), and said
    (out / LISTING).unlink()
    _output(out, {"m": "3", "images/a.png": "3"})
    assert _files(out) == {"m": "3", "images/a.png": "3", "images/b": "2", "images/mine.png": "mine",
                           "images/old_copy.png": "1", "aov/mine.txt": "mine", "images/d/mine": "mine",
                           "images/sub/deep/y": "mine"}


def test_a_rerun_that_fails_leaves_the_user_s_files_where_they_were(tmp_path, monkeypatch):
    """At the swap (the user's files moved into the new folder by then: they go back), and while they are
    moved (one of them cannot be: the others go back, the new output is kept beside, said)."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a.png": "1"})
    for rel in ("images/mine.png", "images/sub/y"):
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_text("mine")
    before = _files(out)

    def swap(tmp, dest, writer=None):
        raise OSError(errno.EIO, "Input/output error", str(dest))

    with monkeypatch.context() as m:
        m.setattr(storage, "_swap_in", swap)
        with pytest.raises(OSError):
            _output(out, {"m": "2", "images/a.png": "2"})
    assert _files(out) == before
    rename = Path.rename

    def stuck(self, target):
        if self.name == "sub" and ".tmp-" not in str(self):  # (after images/mine.png: that goes back)
            raise OSError(errno.EACCES, "Permission denied", str(self))
        return rename(self, target)

    with monkeypatch.context() as m:
        m.setattr(Path, "rename", stuck)
        with pytest.raises(EnvironmentFailure, match=r"cannot carry .*sub.* left as it was"):
            _output(out, {"m": "2", "images/a.png": "2"})
    assert _files(out) == before
    assert [p.name for p in tmp_path.iterdir() if ".unsaved-" in p.name]
    _output(out, {"m": "3", "images/a.png": "3"})
    assert _files(out) == {**before, "m": "3", "images/a.png": "3"}


def test_a_study_rerun_keeps_the_user_s_files_in_the_study_s_subfolders(tmp_path):
    """A study's folders (a thesis study's runs) as a run's: through :func:`tlm.experiments.study.run_study`."""
    out = tmp_path / "s"

    def point(p, folder):
        (folder / "runs" / p).mkdir(parents=True)
        (folder / "runs" / p / "results.json").write_text("{}")
        return {"p": p}

    run_study("test", out, "s", ["a", "b"], point)
    (out / "runs" / "a" / "notes.md").write_text("mine")
    (out / "notes.md").write_text("mine")
    run_study("test", out, "s", ["a"], point)
    assert (out / "runs" / "a" / "notes.md").read_text() == "mine" and (out / "notes.md").read_text() == "mine"
    assert sorted(os.listdir(out / "runs")) == ["a"]  # (runs/b: the old study's, not written again)
    assert sorted(os.listdir(out / "runs" / "a")) == ["notes.md", "results.json"]
