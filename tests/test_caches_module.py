"""tlm's caches are a module of their own (tlm.caches), apart from the atomic writes (tlm.storage).

storage knows nothing of caches (caches imports storage, never the reverse: no import cycle); a
write of storage's that fails reaches caches through :func:`tlm.storage.on_failed_write`, which
is how a full disk under a cache's folder is said once."""

from __future__ import annotations

import pytest

from tlm import caches, storage
from tlm.errors import InputError

MOVED = ("cache_home", "cache_root", "cache_problem", "cache_failed", "say_cache_warning", "cache_warnings",
         "cache_warnings_held", "_note_cache_write", "file_digest", "cached_image", "digest_problem", "CACHES",
         "CACHE_WARNING", "_CACHE_LOCK", "_CACHE_CHECKED", "_CACHE_LINES", "_CACHE_SAID")


@pytest.mark.parametrize("name", MOVED)
def test_a_cache_name_lives_in_tlm_caches_alone(name):
    """No copy left behind in storage: a monkeypatch of ``storage.<name>`` would patch nothing."""
    assert hasattr(caches, name) and not hasattr(storage, name)


def test_a_failed_write_is_told_to_each_hearer_once(tmp_path, monkeypatch):
    heard: list[tuple[str, type]] = []

    def hear(path, e):
        heard.append((path.name, type(e)))

    monkeypatch.setattr(storage, "_HEARERS", list(storage._HEARERS))
    storage.on_failed_write(hear)
    storage.on_failed_write(hear)  # (asked twice: told once)
    assert caches._note_cache_write in storage._HEARERS  # (caches hears, once imported)

    storage.write_file(tmp_path / "fine.json", "{}")
    with pytest.raises(FileNotFoundError):
        storage.write_file(tmp_path / "no" / "such" / "k.json", "{}")
    (tmp_path / "afile").write_text("mine")
    with pytest.raises(InputError), storage.atomic_folder(tmp_path / "afile", "m"):
        pass
    assert heard == [("k.json", FileNotFoundError), ("afile", InputError)]
