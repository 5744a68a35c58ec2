"""The traceback file of an unexpected error is made new: never written through a link.

When tlm's cache cannot take it, ``tlm.cli_signals.save_traceback`` writes the traceback into the
shared temporary folder under a name anyone can guess (the time and the process id); it
followed a link planted at that name, overwriting whatever the link pointed at.
"""

from __future__ import annotations

import os
import tempfile
import time

import tlm.caches
from tlm import storage
from tlm.cli_signals import save_traceback


def _where(monkeypatch, tmp_path):
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    monkeypatch.setattr(tlm.caches, "cache_root", lambda *parts: blocked.joinpath("tlm", *parts))  # (unwritable)
    shared = tmp_path / "tmp"
    shared.mkdir()
    monkeypatch.setattr(tempfile, "gettempdir", lambda: str(shared))
    monkeypatch.setattr(time, "strftime", lambda fmt, *a: "20260101-000000")
    return shared


def test_a_link_planted_at_the_traceback_files_name_is_not_written_through(tmp_path, monkeypatch):
    shared = _where(monkeypatch, tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (shared / f"tlm-traceback-20260101-000000-{storage._host()}-{os.getpid()}.txt").symlink_to(victim)
    assert save_traceback(RuntimeError("boom")) is None
    assert victim.read_text() == "keep"


def test_the_traceback_file_is_this_users_alone(tmp_path, monkeypatch):
    shared = _where(monkeypatch, tmp_path)
    path = save_traceback(RuntimeError("boom"))
    assert path is not None and path.parent == shared
    assert "RuntimeError: boom" in path.read_text()
    assert path.stat().st_mode & 0o777 == 0o600


def test_the_traceback_files_name_carries_the_host_as_well_as_the_pid(tmp_path, monkeypatch):
    """The cache folder may be shared between machines: a pid alone names no process there."""
    _where(monkeypatch, tmp_path)
    monkeypatch.setattr(storage.socket, "gethostname", lambda: "node-7.cluster")
    path = save_traceback(RuntimeError("boom"))
    assert path is not None and path.name == f"tlm-traceback-20260101-000000-hnode7cluster-{os.getpid()}.txt"
