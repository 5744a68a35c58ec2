"""A full disk under the output folder: every write that fails there names its file (one line, exit 1), and the
folder is one a rerun recovers from. A write to a descriptor (``os.pwrite``), a buffered file's flush and its
flush at close raise an OSError that names no file: :func:`tlm.storage.naming` and :func:`tlm.storage.appending`
name it (the sweep's ``.tlm-running-*`` record, its ``sweep.jsonl``, the marker of a folder being made)."""

from __future__ import annotations

import builtins
import errno
import os
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
from tlm import claims, storage
from tlm.cli import main
from tlm.errors import EnvironmentFailure

REAL_OPEN = builtins.open
FULL = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # (as os.pwrite and a flush raise it: no filename)
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 32}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _full(*_args, **_kw):
    raise OSError(FULL.errno, FULL.strerror)


def test_a_sweep_folder_s_running_record_that_does_not_fit_names_its_file(tmp_path, monkeypatch):
    """claims.sharing: os.pwrite of the holder's record on a full disk (it named no file: a bare 'no space
    left on device'); its file is removed again, and the folder is shared once the disk has room."""
    monkeypatch.setattr(os, "pwrite", _full)
    with pytest.raises(EnvironmentFailure) as got, claims.sharing(tmp_path, "abc", "sweep"):
        pytest.fail("held on a full disk")
    assert str(got.value) == f"{tmp_path / '.tlm-running-abc'}: cannot write: no space left on device"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".tlm-lock"]
    monkeypatch.undo()
    with claims.sharing(tmp_path, "abc", "sweep"):
        assert (tmp_path / ".tlm-running-abc").is_file()


@pytest.mark.parametrize("code", [errno.EIO, errno.EDQUOT])
def test_naming_names_the_path_of_a_write_that_names_no_file(tmp_path, code):
    with pytest.raises(EnvironmentFailure) as got, storage.naming(tmp_path / "f"):
        raise OSError(code, os.strerror(code))
    assert str(got.value) == f"{tmp_path / 'f'}: cannot write: {os.strerror(code).lower()}"
    with pytest.raises(OSError) as other, storage.naming(tmp_path / "f"):  # (not the machine's: its filename)
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))
    assert not isinstance(other.value, EnvironmentFailure) and other.value.filename == str(tmp_path / "f")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_an_appended_file_s_flush_at_close_names_the_file():
    """/dev/full: every write is ENOSPC, raised by the flush at close (Python's names no file)."""
    with pytest.raises(EnvironmentFailure) as got, storage.appending(Path("/dev/full")) as f:
        f.write("a row\n")
    assert str(got.value) == "/dev/full: cannot write: no space left on device"
    with pytest.raises(EnvironmentFailure) as got, storage.appending("/dev/full") as f:
        f.write("a row\n")
        f.flush()
        pytest.fail("flushed to /dev/full")
    assert str(got.value) == "/dev/full: cannot write: no space left on device"


def test_a_new_folder_s_marker_that_does_not_fit_names_the_folder_s_marker(tmp_path, monkeypatch):
    """storage.claim_folder: the marker written into the prepared sibling (``.out.claim<host>-<pid>``, removed
    at once) was named by that sibling's path; now by the folder's own."""
    out = tmp_path / "out"
    monkeypatch.setattr(os, "replace", _full)
    with pytest.raises(EnvironmentFailure) as got:
        storage.claim_folder(out, "sweep.yaml", "x: 1\n", existing=False)
    assert str(got.value) == f"{out / 'sweep.yaml'}: cannot write: no space left on device"
    assert list(tmp_path.iterdir()) == []


def _dev_full_for(name: str):
    """``open``, but ``name`` opened to append to is /dev/full: its rows' flush raises ENOSPC naming no file."""
    def fake(file, mode="r", *args, **kw):
        if isinstance(file, (str, os.PathLike)) and Path(file).name == name and mode.startswith("a"):
            return REAL_OPEN("/dev/full", "w", *args, **kw)
        return REAL_OPEN(file, mode, *args, **kw)
    return fake


def _failing_point(task):
    raise RuntimeError("this point fails (no render)")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_sweep_whose_rows_do_not_fit_names_sweep_jsonl_and_a_rerun_recovers(tmp_path, monkeypatch, capsys):
    """tlm sweep: the rows appended to sweep.jsonl as points finish, on a full disk: the flush raised
    ENOSPC with no filename (``tlm: error: no space left on device``); now one line naming the file, exit 1.
    The rerun, with room, writes every row (its points fail: the point code is a stub here)."""
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}, sort_keys=False))
    out = tmp_path / "o"
    monkeypatch.setattr(sweep_mod, "run_point", _failing_point)
    monkeypatch.setattr(builtins, "open", _dev_full_for("sweep.jsonl"))
    code = main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and err[-1] == f"tlm: error: {out / 'sweep.jsonl'}: cannot write: no space left on device", err
    assert not list(out.glob(".tlm-running-*"))
    monkeypatch.setattr(builtins, "open", REAL_OPEN)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 1
    assert "2 points: 0 ok, 2 failed" in capsys.readouterr().out
    assert len(storage.read_jsonl(out / "sweep.jsonl")) == 2 and not list(out.glob(".tlm-running-*"))
