"""Damaged cache entries that never healed or were trusted (a faults probe's findings).

* The functional cache: a folder in place of an entry's ``.npz`` or ``.json`` sidecar was said
  "removed" but stayed (every point failed with IsADirectoryError); a sidecar of the right format
  without a key a result row reads (``host_seconds``, ``work``, ...) or with one of another type
  was trusted (every point failed with KeyError); a write that failed after the ``.npz`` (a full
  disk) left the ``.npz`` without its sidecar.
* The reference cache (and the Mitsuba ground truths', the same code): a ``meta.json`` without
  ``rounds`` or ``relative_standard_error``, with ``"rounds": "eight"``, or without the checksum
  of ``reference.npy`` (so a garbled image was used) was trusted; a ``meta.json`` that is a folder
  was said with a broken quote.
* The scene cache: a folder in place of an entry was not removed, and then said as a cache that
  cannot be written.
* The words: a functional cache that cannot be written said every frame is rendered again (what
  it holds is read); ``tlm run`` with a reference cache it cannot write said the reference is
  cached for every run, then that it is used by this run only.
"""

from __future__ import annotations

import errno
import json
from pathlib import Path

import numpy as np
import pytest

from tlm import api, caches
from tlm.config import config_from_dict
from tlm.experiments import frames
from tlm.experiments.frames import cache_dir, cached_render
from tlm.experiments.reference_cache import load_reference, save_reference
from tlm.scenes import cache as scene_cache

CFG = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
       "arch": {"frames": 2, "trace": False}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("tlm: warning: ")]


# ---------------------------------------------------------------- the functional cache


@pytest.mark.parametrize("file", ["npz", "json"])
def test_a_folder_in_place_of_a_functional_entry_s_file_is_removed_and_rendered_again(file, capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    path = cache_dir() / f"{clean.key}.{file}"
    path.unlink()
    path.mkdir()
    (path / "inside").write_text("x")
    capsys.readouterr()
    again = cached_render(cfg)  # (was: IsADirectoryError, the folder left there)
    said = _warnings(capsys.readouterr().err)
    assert said == [f"tlm: warning: damaged functional cache entry {path} (a folder, not a file): removed, "
                    "rendering it again"], said
    assert not again.cached and path.is_file()
    assert frames.is_cached(clean.key)
    third = cached_render(cfg)  # healed: read back, nothing said
    assert third.cached and capsys.readouterr().err == ""


@pytest.mark.parametrize("change, why", [
    (lambda s: s.pop("host_seconds"), "it has no 'host_seconds'"),
    (lambda s: s.pop("work"), "it has no 'work'"),
    (lambda s: s.update(work="lots"), "its 'work' is \"lots\", not an object"),
    (lambda s: s.update(warnings=[1]), "its 'warnings' are not all lines"),
])
def test_a_sidecar_without_what_a_result_row_reads_is_damaged(change, why, capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    side = cache_dir() / f"{clean.key}.json"
    summary = json.loads(side.read_text())
    change(summary)
    side.write_text(json.dumps(summary))  # (the format tag and the npz's checksum as they were)
    assert not frames.is_cached(clean.key)  # (a sweep lets one point render it first)
    capsys.readouterr()
    again = cached_render(cfg)  # (was: trusted, and every point failed with KeyError 'host_seconds')
    said = _warnings(capsys.readouterr().err)
    assert said == [f"tlm: warning: damaged functional cache entry {side} ({why}): removed, rendering it again"]
    assert not again.cached and set(again.summary) >= {*frames.SUMMARY_KEYS, "host_seconds"}
    assert cached_render(cfg).cached and capsys.readouterr().err == ""


def test_a_sidecar_that_cannot_be_written_leaves_no_npz_behind(monkeypatch):
    """A full disk after the ``.npz``: the ``.npz`` without its sidecar, which nothing reads, is removed."""
    def full(path, data):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(frames, "write_file", full)
    got = cached_render(config_from_dict(CFG, "test"))
    assert not got.cached
    assert not (cache_dir() / f"{got.key}.npz").exists() and not (cache_dir() / f"{got.key}.json").exists()
    assert [p.name for p in cache_dir().iterdir()] == []  # (no temporary file either)


# ---------------------------------------------------------------- the reference cache


def _reference(key: str = "k" * 20) -> Path:
    image = np.random.default_rng(0).random((16, 24, 3)).astype(np.float32)
    return save_reference(key, image, {"rounds": 8, "converged": True, "relative_standard_error": 0.01,
                                       "tolerance": 0.5})


@pytest.mark.parametrize("change, why", [
    (lambda m: m.pop("rounds"), "it has no 'rounds'"),
    (lambda m: m.pop("relative_standard_error"), "it has no 'relative_standard_error'"),
    (lambda m: m.update(rounds="eight"), "its 'rounds' is \"eight\", not a whole number"),
    (lambda m: m.update(rounds=True), "its 'rounds' is true, not a whole number"),
    (lambda m: m.update(relative_standard_error="small"),
     "its 'relative_standard_error' is \"small\", not a whole number or a number or null"),
    (lambda m: m.update(tolerance=[0.5]), "its 'tolerance' is [0.5], not a whole number or a number"),
    (lambda m: m.update(converged="yes"), "its 'converged' is \"yes\", not true or false"),
])
def test_a_reference_meta_json_without_its_keys_or_of_other_types_is_damaged(change, why, capsys):
    folder = _reference()
    meta = json.loads((folder / "meta.json").read_text())
    change(meta)
    (folder / "meta.json").write_text(json.dumps(meta))
    capsys.readouterr()
    assert load_reference(folder.name) is None  # (was: trusted; tlm reference then failed with KeyError 'rounds')
    said = _warnings(capsys.readouterr().err)
    assert said == [f"tlm: warning: damaged reference cache entry {folder / 'meta.json'} ({why}): removed; "
                    "'tlm reference' computes it again"], said
    assert not folder.exists()
    _reference()  # computed again: read back whole
    assert load_reference(folder.name)[1]["rounds"] == 8


def test_a_reference_without_the_checksum_of_its_image_is_not_trusted(capsys):
    """Without ``npy`` a garbled ``reference.npy`` (still an image) was used as it is."""
    folder = _reference()
    meta = json.loads((folder / "meta.json").read_text())
    del meta["npy"]
    (folder / "meta.json").write_text(json.dumps(meta))
    np.save(folder / "reference.npy", np.full((16, 24, 3), 7.0, dtype=np.float32))
    capsys.readouterr()
    assert load_reference(folder.name) is None
    said = _warnings(capsys.readouterr().err)
    assert said == [f"tlm: warning: damaged reference cache entry {folder / 'meta.json'} (it has no size and "
                    "checksum of reference.npy (an entry of an older tlm, or a damaged one)): removed; 'tlm "
                    "reference' computes it again"], said
    assert not folder.exists()


def test_a_ground_truth_without_the_checksum_of_its_image_is_not_trusted(cache, capsys):
    """The Mitsuba ground truths' cache reads its entries with the same code."""
    folder = cache / "oracle" / "k0"
    folder.mkdir(parents=True)
    np.save(folder / "image.npy", np.zeros((4, 6, 3), dtype=np.float32))
    (folder / "meta.json").write_text(json.dumps({"key": "k0", "width": 6, "height": 4}))
    assert caches.cached_image(folder, "image.npy", "k0", "Mitsuba ground-truth", "it is rendered again") is None
    assert "it has no size and checksum of image.npy" in capsys.readouterr().err and not folder.exists()


def test_a_folder_in_place_of_meta_json_is_said_without_a_broken_quote(capsys):
    folder = _reference()
    (folder / "meta.json").unlink()
    (folder / "meta.json").mkdir()
    capsys.readouterr()
    assert load_reference(folder.name) is None
    said = _warnings(capsys.readouterr().err)
    # (was: "... (unreadable (IsADirectoryError: [Errno 21] Is a directory: '/.../meta)): ...", its path cut mid-quote)
    assert said == [f"tlm: warning: damaged reference cache entry {folder / 'meta.json'} (unreadable "
                    "(IsADirectoryError: Is a directory)): removed; 'tlm reference' computes it again"], said
    assert not folder.exists()


# ---------------------------------------------------------------- the scene cache


def test_a_folder_in_place_of_a_scene_cache_entry_is_removed_and_written_again(cache, capsys):
    tri = np.random.default_rng(2).random((scene_cache.MIN_TRIANGLES, 3, 3))
    part = np.zeros(len(tri), dtype=np.int64)
    calls = []

    def compute(t, p, angle):
        calls.append(angle)
        return np.ones_like(t)

    scene_cache.crease_normals(tri, part, 30.0, compute)
    (entry,) = scene_cache.cache_dir().iterdir()
    entry.unlink()
    entry.mkdir()
    (entry / "inside").write_text("x")
    capsys.readouterr()
    np.testing.assert_array_equal(scene_cache.crease_normals(tri, part, 30.0, compute), np.ones_like(tri))
    said = _warnings(capsys.readouterr().err)
    # (was: "... computing it again (it could not be removed)", then "cannot write tlm's scene cache ... (is a
    # directory)": a cache said unwritable that is writable)
    assert said == [f"tlm: warning: damaged scene cache entry {entry} (a folder, not a file): removed, computing it "
                    "again"], said
    assert entry.is_file() and len(calls) == 2
    scene_cache.crease_normals(tri, part, 30.0, compute)  # healed: read back
    assert len(calls) == 2 and capsys.readouterr().err == ""


# ---------------------------------------------------------------- the words


def test_a_functional_cache_that_cannot_be_written_says_what_it_holds_is_read(tmp_path, monkeypatch, capsys):
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    monkeypatch.setenv("TLM_CACHE", str(afile))
    caches.cache_failed(afile / "functional", "read-only")
    (line,) = _warnings(capsys.readouterr().err)
    assert "every frame is rendered again" not in line  # (a sweep of cached frames renders none of them)
    assert ("the frames it holds are read, but none is added: a frame not in it is rendered again by every run and "
            "sweep point, even points that differ only in arch.*") in line


def test_a_run_s_reference_the_cache_cannot_take_is_said_so_before_and_after(tmp_path, monkeypatch, capsys):
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    monkeypatch.setenv("TLM_CACHE", str(afile / "cache"))
    cfg = {"scene": "cornell", "mode": "pmap", "resolution": [8, 6], "render": {"spp": 1}, "photons": {"count": 500},
           "reference": {"photons": 500, "max_rounds": 2, "min_rounds": 2, "spp": 1, "tolerance": 0.9}}
    lines = []
    api.run(cfg, tmp_path / "run", outputs=(), reference=True, say=lines.append)
    before = next(line for line in lines if line.startswith("computing the photon-map reference"))
    assert "it is cached for" not in before  # (was: "it is cached for every run of this scene", then not cached)
    assert before.endswith(f"the cache cannot take it ({afile} is a file, not a folder): used by this run only, "
                           "and computed again by the next ('reference=False' or reference.auto: false skips it)")
    assert any(line.endswith("used by this run only") and "not cached (" in line for line in lines), lines
