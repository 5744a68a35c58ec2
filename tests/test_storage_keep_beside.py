"""A finished output that cannot take its destination's place (tlm.storage): kept beside it under
a name of its own (``OUT.unsaved-<pid>``, then ``-2``, ``-3``, ...), never over an earlier kept
output, and named in the line that says so; a write_atomic within a write_atomic of one path,
in one thread, has a temporary file of its own."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import threading
from contextlib import contextmanager
from pathlib import Path

import pytest

import tlm
from tests.helpers_storage import refuse_to_carry
from tlm import storage
from tlm.errors import EnvironmentFailure, InputError
from tlm.storage import atomic_folder, write_atomic


def _take_over(out: Path) -> None:
    """Something else arrives at ``out`` while the run works: a folder of the user's own."""
    out.mkdir()
    (out / "notes.txt").write_text("the user's")


def _kept_in(message: str) -> Path:
    """The folder a message says the output is kept in."""
    m = re.search(r"kept in '([^']+)'", message)
    assert m, message
    return Path(m[1])


def _two_runs_taken_over(out: Path) -> list[str]:
    """Two writes of ``out`` in a row, each finding it taken over at the end: their messages."""
    said = []
    for text in ("first", "second"):
        shutil.rmtree(out, ignore_errors=True)  # (the user moves their folder away between runs)
        with pytest.raises(InputError, match=r"refusing to replace it; this run's output is kept in") as e, \
                atomic_folder(out, "m") as tmp:
            (tmp / "m").write_text(text)
            _take_over(out)
        said.append(str(e.value))
    return said


def test_two_runs_in_a_row_meeting_a_taken_destination_keep_both_outputs(tmp_path):
    out = tmp_path / "r"
    said = _two_runs_taken_over(out)
    first, second = map(_kept_in, said)
    assert first != second
    assert (first / "m").read_text() == "first" and (second / "m").read_text() == "second"
    assert sorted(p.name for p in tmp_path.iterdir() if "unsaved" in p.name) == sorted([first.name, second.name])
    assert (out / "notes.txt").read_text() == "the user's"


def test_two_runs_in_a_row_in_another_thread_keep_both_outputs(tmp_path):
    """The same from one thread other than the main one (whose kept names carry its tag)."""
    out = tmp_path / "r"
    result: list = []

    def work():
        try:
            result.append(_two_runs_taken_over(out))
        except BaseException as e:  # (re-raised in the main thread)
            result.append(e)

    t = threading.Thread(target=work)
    t.start()
    t.join(60)
    if isinstance(result[0], BaseException):
        raise result[0]
    first, second = map(_kept_in, result[0])
    assert first != second and "-t" in first.name
    assert (first / "m").read_text() == "first" and (second / "m").read_text() == "second"


def test_two_tlm_runs_in_a_row_whose_folder_is_taken_keep_both_runs(tmp_path, monkeypatch):
    """tlm.run twice into one folder that something else takes over just before each run ends:
    both finished runs are kept, each in the folder its error names."""
    out = tmp_path / "run"
    real = storage.folder_lock

    @contextmanager
    def taken(folder):
        if Path(folder) == out and not out.exists():
            _take_over(out)
        with real(folder):
            yield

    monkeypatch.setattr(storage, "folder_lock", taken)
    small = {"mode": "rcast", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1,
             "arch.packet_size": 16}
    kept = []
    for seed in (1, 2):
        shutil.rmtree(out, ignore_errors=True)
        with pytest.raises(InputError, match=r"this run's output is kept in") as e:
            tlm.run(tlm.load_config("cornell", {**small, "seed": seed}), out, outputs="images")
        kept.append(_kept_in(str(e.value)))
    assert kept[0] != kept[1]
    assert [json.loads((k / "results.json").read_text())["seed"] for k in kept] == [1, 2]


def test_a_kept_name_already_taken_by_a_file_is_passed_over(tmp_path):
    """A file of the user's at ``OUT.unsaved-<pid>`` is left as it is; the output takes the next name."""
    out = tmp_path / "r"
    (tmp_path / f"r.unsaved-{os.getpid()}").write_text("mine")
    kept = list(map(_kept_in, _two_runs_taken_over(out)))
    assert [k.name for k in kept] == [f"r.unsaved-{os.getpid()}-2", f"r.unsaved-{os.getpid()}-3"]
    assert [(k / "m").read_text() for k in kept] == ["first", "second"]
    assert (tmp_path / f"r.unsaved-{os.getpid()}").read_text() == "mine"


def _swap_fails_and_a_user_file_is_stuck(monkeypatch):
    """The new folder cannot take ``out``'s place (the swap fails), and the user's file carried
    into it cannot be moved back: returns the real Path.rename, to restore."""
    rename = Path.rename

    def swap(tmp, out, writer=None):
        raise OSError(errno.EIO, "Input/output error", str(out))

    def stuck(self, target):
        if self.name == "notes.md" and ".tmp-" in str(self.parent):
            raise OSError(errno.EACCES, "Permission denied", str(self))
        return rename(self, target)

    monkeypatch.setattr(storage, "_swap_in", swap)
    monkeypatch.setattr(Path, "rename", stuck)
    return rename


def _earlier_output_with_notes(out: Path) -> None:
    with atomic_folder(out, "m", owned=("m",)) as tmp:
        (tmp / "m").write_text("old")
    (out / "notes.md").write_text("mine")


def test_a_failed_swap_that_keeps_the_user_s_file_beside_names_the_folder(tmp_path, monkeypatch, capsys):
    out = tmp_path / "r"
    _earlier_output_with_notes(out)
    rename = _swap_fails_and_a_user_file_is_stuck(monkeypatch)
    with pytest.raises(OSError), atomic_folder(out, "m", owned=("m",)) as tmp:
        (tmp / "m").write_text("new")
    monkeypatch.setattr(Path, "rename", rename)
    lines = [x for x in capsys.readouterr().err.splitlines() if "could not be moved back" in x]
    assert len(lines) == 1 and "'notes.md'" in lines[0], lines
    kept = _kept_in(lines[0])
    assert kept.parent == tmp_path and kept.name.startswith("r.unsaved-")
    assert (kept / "notes.md").read_text() == "mine" and (kept / "m").read_text() == "new"
    assert (out / "m").read_text() == "old"


def test_a_failed_swap_that_cannot_keep_the_user_s_file_beside_leaves_it_and_says_where(tmp_path, monkeypatch,
                                                                                      capsys):
    """No kept folder can be made either (the folder above refuses new names): the temporary
    folder holding the user's file is not removed, and the warning names it."""
    out = tmp_path / "r"
    _earlier_output_with_notes(out)
    rename = _swap_fails_and_a_user_file_is_stuck(monkeypatch)
    mkdir = Path.mkdir

    def refused(self, *a, **kw):
        if ".unsaved-" in self.name:
            raise OSError(errno.EROFS, "Read-only file system", str(self))
        return mkdir(self, *a, **kw)

    monkeypatch.setattr(Path, "mkdir", refused)
    with pytest.raises(OSError), atomic_folder(out, "m", owned=("m",)) as tmp:
        (tmp / "m").write_text("new")
    monkeypatch.setattr(Path, "rename", rename)
    lines = [x for x in capsys.readouterr().err.splitlines() if "could not be moved back" in x]
    assert len(lines) == 1 and f"left in {str(tmp)!r}" in lines[0], lines
    assert (tmp / "notes.md").read_text() == "mine"
    shutil.rmtree(tmp)


def test_a_write_atomic_within_one_of_the_same_path_has_its_own_temporary_file(tmp_path):
    """One thread writing a path inside a block writing the same path: each block has its own
    temporary file; both succeed, and the last to finish is the file."""
    path = tmp_path / "f.txt"
    with write_atomic(path) as outer:
        outer.write("outer")
        with write_atomic(path) as inner:
            inner.write("inner")
        assert path.read_text() == "inner"
    assert path.read_text() == "outer"
    assert [p.name for p in tmp_path.iterdir()] == ["f.txt"]


def test_two_generators_of_one_thread_writing_one_path_both_succeed(tmp_path):
    path = tmp_path / "f.txt"

    def write(text):
        with write_atomic(path) as fh:
            fh.write(text)
            yield

    a, b = write("a"), write("b")
    next(a)
    next(b)
    for g in (a, b):
        with pytest.raises(StopIteration):
            next(g)
    assert path.read_text() == "b" and [p.name for p in tmp_path.iterdir()] == ["f.txt"]


def test_an_environment_failure_carrying_a_file_names_a_kept_folder_of_its_own(tmp_path, monkeypatch):
    """The carry-over refusal (a user's entry that cannot be moved) twice in a row: both outputs kept."""
    out = tmp_path / "r"
    _earlier_output_with_notes(out)
    rename = refuse_to_carry(monkeypatch, "notes.md")
    kept = []
    for text in ("one", "two"):
        with pytest.raises(EnvironmentFailure, match=r"cannot carry .*notes\.md.* kept in") as e, \
                atomic_folder(out, "m", owned=("m",)) as tmp:
            (tmp / "m").write_text(text)
        kept.append(_kept_in(str(e.value)))
    monkeypatch.setattr(Path, "rename", rename)
    assert kept[0] != kept[1]
    assert [(k / "m").read_text() for k in kept] == ["one", "two"]
    assert (out / "m").read_text() == "old" and (out / "notes.md").read_text() == "mine"
