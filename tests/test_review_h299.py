"""Review of 3f82752 (a config read once, parsed from memory; --out checked before anything is said) (h299).

A scene file given as a deleted file, what a shell's large here-document is (``tlm run /dev/stdin <<EOF``: bash
writes it to ``/tmp/sh-thd.XXXX`` and removes the name before tlm reads it), passed the check that refuses a scene
file given as a pipe (it is a regular file), and the render's second read, by its resolved name, stopped with
``/tmp/sh-thd.XXXX (deleted): file not found``: a path the user never typed. It is now refused as a pipe's is,
naming the path as given.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tlm import api
from tlm.cli import main
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]

needs_dev_fd = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")


@pytest.fixture
def deleted(tmp_path):
    """``deleted(text)``: ``/dev/fd/N`` of a file holding ``text`` whose name is removed (a here-document's)."""
    fds = []

    def make(text: str) -> str:
        path = tmp_path / f"sh-thd.{len(fds)}"
        path.write_text(text)
        fds.append(os.open(path, os.O_RDONLY))
        path.unlink()
        return f"/dev/fd/{fds[-1]}"

    yield make
    for fd in fds:
        os.close(fd)


@needs_dev_fd
def test_a_scene_file_given_as_a_deleted_file_is_named_as_given(tmp_path, deleted, capsys):
    given = deleted((ROOT / "scenes" / "cornell.yaml").read_text())
    assert Path(given).is_file()  # (a regular file, read again through /dev/fd: not a pipe)
    assert main(["run", given, "--out", str(tmp_path / "r")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1, err  # (was: tlm: error: .../sh-thd.0 (deleted): file not found)
    assert err.startswith(f"tlm: error: {given}: is a scene file given as a pipe, a device or a deleted file"), err
    assert "(deleted)" not in err and not (tmp_path / "r").exists()
    with pytest.raises(InputError) as e:
        api.load_config(deleted((ROOT / "scenes" / "cornell.yaml").read_text()))
    assert e.value.source.startswith("/dev/fd/") and "deleted file" in str(e.value)

