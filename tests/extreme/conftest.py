"""The extreme-case suite never reads or writes the user's reference cache."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _private_cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path_factory.getbasetemp() / "tlm-cache"))
