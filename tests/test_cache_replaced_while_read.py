"""A cache entry another process writes while this one reads it (tlm.caches.cached_image): its
folder is replaced whole, so the files read across the replacement are of two entries, not
one damaged entry."""

from __future__ import annotations

import numpy as np

import tlm.caches as caches
from tlm.experiments.reference_cache import load_reference, save_reference

KEY = "0123456789abcdef"
META = {"rounds": 4, "relative_standard_error": 0.1}


def test_a_reference_rewritten_while_it_is_read_is_read_whole_not_said_damaged(cache, monkeypatch, capsys):
    """Another process stores the same reference (more rounds) between this one's read of
    meta.json and of reference.npy: the image is read again from the new entry, where it was
    said damaged ("its checksum differs from its sidecar's") and the new entry was removed
    (a sweep's points computing one reference at once; ~1 read in 400 with 2 writers)."""
    save_reference(KEY, np.zeros((4, 4, 3)), META)
    real = caches.digest_problem
    rewritten = []

    def another_writer_meanwhile(path, digest):  # (after meta.json was read, before the image)
        if not rewritten:
            rewritten.append(save_reference(KEY, np.ones((4, 4, 3)), {**META, "rounds": 8}))
        return real(path, digest)

    monkeypatch.setattr(caches, "digest_problem", another_writer_meanwhile)
    got = load_reference(KEY)
    assert capsys.readouterr().err == ""
    assert got is not None and rewritten
    image, meta = got
    assert meta["rounds"] == 8 and (image == 1).all()
    assert load_reference(KEY)[1]["rounds"] == 8  # (kept, not removed)


def test_a_reference_removed_while_it_is_read_is_none_not_said_damaged(cache, monkeypatch, capsys):
    """The folder renamed aside by another writer (its own not yet in place) as the image is
    read: no entry, said nothing, where it said "cannot read it (No such file or directory)"."""
    folder = save_reference(KEY, np.zeros((4, 4, 3)), META)
    real = caches.digest_problem

    def moved_aside_meanwhile(path, digest):
        if folder.exists():
            folder.rename(folder.with_name(f".{folder.name}.old-other"))
        return real(path, digest)

    monkeypatch.setattr(caches, "digest_problem", moved_aside_meanwhile)
    assert load_reference(KEY) is None
    assert capsys.readouterr().err == ""
