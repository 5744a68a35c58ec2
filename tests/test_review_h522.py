"""Review of h519 - h521 (h522): ``tlm --version`` and ``--help`` to a stdout that cannot be written (``> /dev/full``)
exited 0 with nothing written: argparse's ``_print_message`` swallows the OSError of its write, then exits 0, and
the failure :class:`tlm.cli_streams._Guarded` kept was never raised on that path. Now they say
``tlm: error: cannot write stdout: no space left on device``, exit 1, as every other command that prints does."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FULL = "/dev/full"
NO_SPACE = "tlm: error: cannot write stdout: no space left on device"


@pytest.mark.skipif(not os.path.exists(FULL), reason="no /dev/full")
@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["params", "--help"]])
def test_version_and_help_to_a_full_disk_fail(argv, tmp_path):
    with open(FULL, "w") as full:
        done = subprocess.run([sys.executable, "-m", "tlm", *argv], cwd=REPO, stdout=full, stderr=subprocess.PIPE,
                              text=True, env={**os.environ, "TLM_CACHE": str(tmp_path / "cache")}, timeout=120)
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip().splitlines()[-1] == NO_SPACE, done.stderr


def test_version_and_help_still_exit_0(tmp_path):
    for argv in (["--version"], ["--help"]):
        done = subprocess.run([sys.executable, "-m", "tlm", *argv], cwd=REPO, capture_output=True, text=True,
                              env={**os.environ, "TLM_CACHE": str(tmp_path / "cache")}, timeout=120)
        assert done.returncode == 0 and done.stdout and not done.stderr, done


def test_a_long_names_folder_is_replaced_and_its_files_written_where_no_exchange_is(tmp_path, monkeypatch):
    """A name of 245-255 bytes, which mkdir takes: its folder written twice on a file system without the exchange
    (the old folder moved aside first, storage_swap: '.NAME.old-...' was past NAME_MAX), and a file of such a name
    written whole (storage_files.write_files: '.NAME.new...'), each sibling's name shortened as the others' are."""
    from tlm import storage, storage_lock

    monkeypatch.setattr(storage_lock, "_renameat2", lambda: None)
    monkeypatch.setattr(storage_lock, "_EXCHANGES", {})
    out = tmp_path / ("x" * 250)
    for text in ("first", "second"):
        with storage.atomic_folder(out, "results.json") as tmp:
            (tmp / "results.json").write_text(text)
    assert (out / "results.json").read_text() == "second"
    path = tmp_path / ("y" * 245 + ".yaml")
    storage.write_files([(path, "a: 1\n")])
    storage.write_files([(path, "a: 2\n")])
    assert path.read_text() == "a: 2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, path.name])
