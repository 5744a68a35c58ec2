"""Fixtures shared by the test modules."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

COLLECTED = pytest.StashKey[list]()  # every test the session collected, before -m / -k deselect any


def pytest_configure(config):
    """Ctrl-C as at a terminal, whoever started the suite: a shell's background job (``.ci/run &``,
    a script's ``cmd &``) starts with SIGINT ignored (POSIX), which tlm keeps, as Python does
    (tests/test_faults_h121.py), so the tests of what tlm does on Ctrl-C, in this process
    (``main([...])``) and in the children that inherit its dispositions, would test an ignored
    signal instead. (In each xdist worker too: it runs this hook.)"""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):
    """Keep the whole collection (tests/test_fast_tier.py reads the tier from it, marks applied)."""
    session.stash[COLLECTED] = list(items)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache folder of the test's own (``$TLM_CACHE``): references, frames, truths, tracebacks."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("TLM_CACHE", str(folder))
    return folder


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    """An empty folder of the user's own, away from configs/, as the working folder too."""
    folder = tmp_path / "work"
    folder.mkdir()
    monkeypatch.chdir(folder)
    return folder


@pytest.fixture
def piped():
    """``piped(text)``: ``/dev/fd/N`` of a pipe holding ``text`` (str, or bytes as they are) whose writer closed,
    as ``<(...)`` gives; its reader is closed after the test."""
    fds = []

    def make(text: str | bytes) -> str:
        r, w = os.pipe()
        fds.append(r)
        os.write(w, text if isinstance(text, bytes) else text.encode())
        os.close(w)
        return f"/dev/fd/{r}"

    yield make
    for fd in fds:
        os.close(fd)


@pytest.fixture
def pipes(piped):
    """:func:`piped`, its path a :class:`~pathlib.Path`."""
    return lambda text: Path(piped(text))


@pytest.fixture
def nothing_known(monkeypatch):
    """Each test finds out afresh which file systems exchange folders, and which a probe could not write
    (tlm.storage_lock's memory of them: tests/test_storage_leftovers_h256.py, test_lock_probe_h527.py)."""
    from tlm import storage_lock

    monkeypatch.setattr(storage_lock, "_EXCHANGES", {})
    monkeypatch.setattr(storage_lock, "_EXCHANGED_AT", {})
    monkeypatch.setattr(storage_lock, "_UNWRITABLE", {})
