"""tlm.storage_files: several files written all or none, with the writer it is given (tlm.storage's
write_files passes its own write_file, which a test may patch)."""

from __future__ import annotations

import errno

import pytest

from tlm import storage
from tlm.errors import EnvironmentFailure
from tlm.storage_files import write_files


def test_a_full_disk_at_the_second_file_leaves_both_paths_as_they_were(tmp_path):
    (tmp_path / "a.txt").write_text("old a")
    calls = []

    def write_file(path, data):
        calls.append(path.name)
        if len(calls) == 2:
            raise EnvironmentFailure("cannot write", source=str(path)) from OSError(errno.ENOSPC, "No space")
        storage.write_file(path, data)

    with pytest.raises(EnvironmentFailure) as got:
        write_files([(tmp_path / "a.txt", "new a"), (tmp_path / "b.txt", "new b")], write_file, lambda: "h-1")
    assert str(tmp_path / "b.txt") in str(got.value) and ".new" not in str(got.value)
    assert calls == [".a.txt.newh-1-" + calls[0].rsplit("-", 1)[1], calls[1]]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]  # (no hidden file left, no b.txt)
    assert (tmp_path / "a.txt").read_text() == "old a"


def test_storage_write_files_writes_through_its_own_write_file(tmp_path, monkeypatch):
    seen = []
    real = storage.write_file
    monkeypatch.setattr(storage, "write_file", lambda path, data: (seen.append(path.name), real(path, data)))
    storage.write_files([(tmp_path / "x.yaml", "x: 1\n"), (tmp_path / "y.yaml", "y: 2\n")])
    assert len(seen) == 2 and all(n.startswith((".x.yaml.new", ".y.yaml.new")) for n in seen)
    assert (tmp_path / "x.yaml").read_text() == "x: 1\n" and (tmp_path / "y.yaml").read_text() == "y: 2\n"
