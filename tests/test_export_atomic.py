"""An export writes its files together, all or none (:func:`tlm.scenes.export.write_files`,
:func:`tlm.builtin.export_experiment`): a full disk or a signal while ``tlm scene export`` writes
the MTL, the OBJ and the scene file, or while ``tlm config export`` writes a sweep and its base,
leaves an earlier export of the same name as it was, no new file beside it and no hidden one."""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import numpy as np
import pytest

import tlm.builtin
import tlm.scenes.export
import tlm.storage
from tlm.errors import EnvironmentFailure
from tlm.scenes.export import export_triangles
from tlm.scenes.model import Camera, Material, Scene


def _scene(name: str, shift: float) -> Scene:
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    [[2.0, 2.0, 2.0], [3.0, 2.0, 2.0], [2.0, 3.0, 2.0]]]) + shift
    materials = (Material("white", "lambertian", albedo=(0.7, 0.7, 0.7)), Material("mirror", "mirror"))
    camera = Camera((0.0, 0.0, -5.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0, 8, 8)
    return Scene(name, tri, np.array([1, 0], dtype=np.int32), materials, np.zeros(2, dtype=np.int32),
                 ("all",), (), camera, 0)


def _contents(folder: Path) -> dict[str, bytes]:
    """Every entry of ``folder`` (hidden ones too) and its bytes."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _full_on(n: int, calls: list[Path]):
    """A ``write_file`` whose ``n``-th call finds the disk full partway through (as the real
    one does: the error comes out of :func:`tlm.storage.write_atomic`)."""
    real = tlm.storage.write_file

    def write_file(path, data):
        calls.append(Path(path))
        if len(calls) != n:
            return real(path, data)
        with tlm.storage.write_atomic(Path(path), "wb" if isinstance(data, bytes) else "w") as fh:
            fh.write(data[:8])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    return write_file


@pytest.mark.parametrize("earlier", [True, False], ids=["over-an-earlier-export", "fresh"])
@pytest.mark.parametrize("target", ["x.yaml", "x.obj"])
def test_a_full_disk_on_the_second_file_leaves_the_folder_as_it_was(tmp_path, monkeypatch, earlier, target):
    if earlier:
        export_triangles(_scene("before", 0.0), tmp_path / target)
    before = _contents(tmp_path)
    calls: list[Path] = []
    monkeypatch.setattr(tlm.storage, "write_file", _full_on(2, calls))
    with pytest.raises(EnvironmentFailure) as e:
        export_triangles(_scene("after", 0.5), tmp_path / target)
    assert len(calls) == 2
    assert str(e.value) == f"{tmp_path / 'x.obj'}: cannot write: no space left on device"  # (the file, not a temporary)
    assert _contents(tmp_path) == before  # (the old code left the new MTL beside the old OBJ, or alone)


@pytest.mark.parametrize("earlier", [True, False], ids=["over-an-earlier-export", "fresh"])
@pytest.mark.parametrize("when", ["before", "after"])
@pytest.mark.parametrize("onto", ["x.obj", "x.yaml"])
def test_a_signal_while_the_files_are_renamed_into_place_leaves_the_folder_as_it_was(tmp_path, monkeypatch,
                                                                                     earlier, when, onto):
    """The MTL is in place already when the signal comes, just before or just after the rename
    onto ``onto``: every file goes back to what it was, the new ones are removed."""
    if earlier:
        export_triangles(_scene("before", 0.0), tmp_path / "x.yaml")
    before = _contents(tmp_path)
    real, signalled = os.replace, []

    def replace(src, dst, *a, **k):  # (the signal comes once: the rollback's renames go through)
        hit = Path(dst).name == onto and not signalled
        if hit:
            signalled.append(hit)
        if hit and when == "before":
            raise KeyboardInterrupt
        real(src, dst, *a, **k)
        if hit:
            raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        export_triangles(_scene("after", 0.5), tmp_path / "x.yaml")
    monkeypatch.undo()
    assert signalled == [True]
    assert _contents(tmp_path) == before


def test_the_files_replace_an_earlier_export_whole_and_leave_nothing_hidden(tmp_path):
    export_triangles(_scene("before", 0.0), tmp_path / "x.yaml")
    export_triangles(_scene("after", 0.5), tmp_path / "x.yaml")
    files = _contents(tmp_path)
    assert sorted(files) == ["x.mtl", "x.obj", "x.yaml"]
    assert all(data.startswith(b"# tlm scene after") for data in files.values())


def test_write_files_writes_bytes_and_text_and_names_the_file_that_did_not_fit(tmp_path, monkeypatch):
    (tmp_path / "a.bin").write_bytes(b"old")
    tlm.scenes.export.write_files([(tmp_path / "a.bin", b"\x00\x01"), (tmp_path / "b.txt", "text\n")])
    assert _contents(tmp_path) == {"a.bin": b"\x00\x01", "b.txt": b"text\n"}
    monkeypatch.setattr(tlm.storage, "write_file", _full_on(1, []))
    with pytest.raises(EnvironmentFailure, match=r"c\.txt: cannot write: no space left on device$"):
        tlm.scenes.export.write_files([(tmp_path / "c.txt", "c"), (tmp_path / "a.bin", b"new")])
    assert _contents(tmp_path) == {"a.bin": b"\x00\x01", "b.txt": b"text\n"}


@pytest.mark.parametrize("fail", ["full-disk", "signal"])
def test_config_export_writes_a_sweep_and_its_base_or_neither(tmp_path, monkeypatch, fail):
    calls: list[Path] = []
    if fail == "full-disk":
        monkeypatch.setattr(tlm.storage, "write_file", _full_on(2, calls))
    else:
        real = tlm.storage.write_file

        def write_file(path, data):
            calls.append(Path(path))
            real(path, data)
            if len(calls) == 2:
                raise KeyboardInterrupt

        monkeypatch.setattr(tlm.storage, "write_file", write_file)
    with pytest.raises(EnvironmentFailure if fail == "full-disk" else KeyboardInterrupt):
        tlm.builtin.export_experiment("sweep_fifo", tmp_path / "fifo.yaml")
    # (each written to its hidden file beside it first: tlm.storage.write_files)
    assert [re.sub(r"^\.(.*)\.new.*$", r"\1", p.name) for p in calls] == ["fifo.yaml", "cornell.yaml"]
    assert _contents(tmp_path) == {}  # (the old code left fifo.yaml, whose base: cornell.yaml is not there)
    monkeypatch.undo()
    assert tlm.builtin.export_experiment("sweep_fifo", tmp_path / "fifo.yaml") == [tmp_path / "fifo.yaml",
                                                                                   tmp_path / "cornell.yaml"]
