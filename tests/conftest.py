"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache folder of the test's own (``$TLM_CACHE``): references, frames, truths, tracebacks."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("TLM_CACHE", str(folder))
    return folder
