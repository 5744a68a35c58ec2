"""A long --out name's folder probe (h527): ``tlm.storage_lock.exchanges_in`` makes two folders beside the
destination to ask whether its file system exchanges folders in one call; their names carried the whole
name, so that a name near NAME_MAX (255 bytes) made them too long, mkdir failed (ENAMETOOLONG) and the probe
said no: each new folder then cost folder_lock's 10 ms wait, and the exchange was never used. They are shortened
now as tlm's other siblings are (a prefix, ``~`` and a hash: ``sibling_stem``), which clean_stale still finds."""

from __future__ import annotations

import os
import re

import pytest

from tlm import storage, storage_lock

LONG = "r" * 250  # (an --out name of 250 bytes: within NAME_MAX, past it with the probe's suffix)


def _exchanges_at_all(folder) -> bool:
    """Whether ``folder``'s file system exchanges, asked with a short name, nothing remembered."""
    storage_lock._EXCHANGES.clear()
    storage_lock._EXCHANGED_AT.clear()
    return storage_lock.exchanges_in(folder, "short")


def test_a_long_name_s_probe_says_yes_and_leaves_nothing(tmp_path, nothing_known):
    if storage_lock._renameat2() is None:
        pytest.skip("no renameat2 here")
    made = []
    real_mkdir = os.mkdir

    def mkdir(path, *args, **kwargs):
        made.append(os.fspath(path))
        return real_mkdir(path, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os, "mkdir", mkdir)
        said = storage_lock.exchanges_in(tmp_path, LONG)
    if not said and not _exchanges_at_all(tmp_path):
        pytest.skip("this file system does not exchange folders (an overlay, NFS)")
    assert said is True, "a 250-byte name's probe said no where a short name's says yes"
    assert len(made) == 2 and all(len(os.fsencode(os.path.basename(p))) <= 255 for p in made), made
    assert list(tmp_path.iterdir()) == []  # (the probe's two folders removed)


def test_a_killed_long_probe_s_leftovers_are_cleaned(tmp_path, nothing_known, monkeypatch):
    """A probe killed between its mkdir and its rmdir (its rmdir left out here) leaves two folders of a long
    name, each within NAME_MAX, which clean_stale, asked for that name's leftovers, removes; a short name's
    are named as before (``.<name>.old-<host>-<pid>-<thread>-<n>-0``)."""
    if storage_lock._renameat2() is None:
        pytest.skip("no renameat2 here")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os, "rmdir", lambda path: None)
        storage_lock.exchanges_in(tmp_path, LONG)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert len(left) == 2, left  # (before h527: none, the names too long to make)
    assert all(len(os.fsencode(n)) <= storage.name_max(tmp_path) for n in left), left
    stem = storage.sibling_stem(tmp_path / LONG, strict=False)
    assert all(n.startswith(f".{stem}.old-") for n in left), left
    storage.clean_stale(tmp_path, re.escape(stem))  # (what atomic_folder asks for beside its --out)
    assert list(tmp_path.iterdir()) == []
    storage_lock._EXCHANGES.clear()  # (asked afresh: probed again)
    with pytest.MonkeyPatch.context() as mp:  # (a short name: carried whole, as before)
        mp.setattr(os, "rmdir", lambda path: None)
        storage_lock.exchanges_in(tmp_path, "out")
    names = sorted(p.name for p in tmp_path.iterdir())
    pattern = re.compile(rf"\.out\.old-{storage_lock._host()}-{os.getpid()}-\d+-\d+-[01]")
    assert len(names) == 2 and all(pattern.fullmatch(n) for n in names), names

