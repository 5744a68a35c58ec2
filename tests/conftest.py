"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest

COLLECTED = pytest.StashKey[list]()  # every test the session collected, before -m / -k deselect any


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
