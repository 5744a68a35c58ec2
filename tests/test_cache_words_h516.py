"""The caches' lines say what happens (h516, of h513's probe).

* A cache that can be read but not written (a shared, filled cache mounted read-only) said "photon-map references
  are computed again by every run" and "ground truths are rendered again by every run", then read both from it:
  its line now says that what it holds is read and none is added, as the functional cache's did.
* A sweep of a scene of no mesh file (cornell) on an unwritable cache was told "large meshes are parsed again on
  every load": the scene cache's line now waits for a mesh file's load (:func:`tlm.caches.cache_needed`).
* A folder in place of a cached file was "(4096 bytes, its sidecar says 3200)"; a reference's rounds too large
  for the free space "has 0.0 MB free, a save takes 0.0 MB" (the save is a few KB).
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections import OrderedDict, namedtuple
from pathlib import Path

import pytest
import yaml

import tlm.experiments.reference as reference
from tlm import api, caches
from tlm.config import config_from_dict
from tlm.experiments import frame_keys
from tlm.experiments.loading import load_frame
from tlm.scenes import meshes

PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 6], "render": {"spp": 1}, "photons": {"count": 500},
        "reference": {"photons": 500, "max_rounds": 2, "min_rounds": 2, "spp": 1, "tolerance": 0.9}}


def _read_only(monkeypatch, folder: Path) -> None:
    """``folder`` as a cache mounted read-only: readable, nothing under it writable by the look tlm takes
    (``os.access``, which a root user's read-only mount fails too; root's writes are not stopped)."""
    real = os.access

    def access(path, mode, *args, **kwargs):
        p = Path(path)
        if mode & os.W_OK and (p == folder or folder in p.parents):
            return False
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(caches.os, "access", access)


def _said(err: str, start: str) -> list[str]:
    return [line.removeprefix("tlm: warning: ") for line in err.splitlines()
            if line.startswith(f"tlm: warning: cannot write tlm's {start}")]


# ---------------------------------------------------------------- what a read-only cache holds is read


def test_a_read_only_cache_s_reference_is_read_and_its_line_says_so(tmp_path, monkeypatch, capsys):
    filled = tmp_path / "filled"
    monkeypatch.setenv("TLM_CACHE", str(filled))
    first = api.run(PMAP, tmp_path / "r0", outputs=())
    shared = tmp_path / "shared"
    shutil.copytree(filled, shared)
    _read_only(monkeypatch, shared)
    monkeypatch.setenv("TLM_CACHE", str(shared))
    capsys.readouterr()
    again = api.run(PMAP, tmp_path / "r1", outputs=())
    folder = shared / "references"
    line = (f"cannot write tlm's reference cache {folder} ({folder} is not writable (permission denied)): the "
            "references it holds are read, but none is added: a photon-map reference not in it is computed again "
            "by every run; set TLM_CACHE to a writable folder")
    assert _said(capsys.readouterr().err, "reference") == [line]
    assert line in again["warnings"]
    assert again["error"]["reference_sha256"] == first["error"]["reference_sha256"]  # (read from the cache)


@pytest.mark.parametrize("kind, held", [
    ("oracle", "the ground truths it holds are read, but none is added: a ground truth not in it is rendered "
               "again by every run"),
    ("references", "the references it holds are read, but none is added: a photon-map reference not in it is "
                   "computed again by every run"),
])
def test_a_read_only_cache_says_what_it_holds_is_read_where_it_holds_a_folder(tmp_path, monkeypatch, capsys, kind,
                                                                              held):
    shared = tmp_path / "shared"
    (shared / kind).mkdir(parents=True)
    _read_only(monkeypatch, shared)
    monkeypatch.setenv("TLM_CACHE", str(shared))
    caches.cache_root(kind)
    (line,) = _said(capsys.readouterr().err, "")
    assert line.endswith(f"): {held}; set TLM_CACHE to a writable folder"), line
    assert caches.cache_warnings() == [line]

    bare = tmp_path / "bare"  # (a read-only cache without the folder: nothing is read, all is computed again)
    bare.mkdir()
    _read_only(monkeypatch, bare)
    monkeypatch.setenv("TLM_CACHE", str(bare))
    caches.cache_root(kind)
    (line,) = _said(capsys.readouterr().err, "")
    assert "it holds" not in line and " again by every run; set TLM_CACHE" in line, line


# ---------------------------------------------------------------- the scene cache: said where a mesh is loaded


SWEEP = {"description": "two points of one frame", "base": {"scene": "cornell", "mode": "rcast",
                                                           "resolution": [8, 8], "render": {"spp": 1}},
         "grid": {"arch.pipelines": [1, 2]}}


@pytest.fixture
def blocked(tmp_path, monkeypatch):
    """A cache folder that cannot be made (under a regular file), as ``$TLM_CACHE``; no scene remembered in this
    process (each scene's key looked up in the scene cache)."""
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    monkeypatch.setenv("TLM_CACHE", str(afile / "cache"))
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", OrderedDict())
    return afile / "cache"


def _mesh(tmp_path) -> Path:
    mesh = tmp_path / "box.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    return mesh


def test_a_sweep_of_a_scene_of_no_mesh_file_says_nothing_of_the_scene_cache(tmp_path, blocked, capsys):
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump(SWEEP))
    done = api.run_sweep(path, tmp_path / "out", jobs=1)
    assert done.ok == 2
    err = capsys.readouterr().err
    assert _said(err, "scene cache") == [], err
    assert len(_said(err, "functional cache")) == 1  # (the frames' cache: said as before)
    records = [done.warnings] + [json.loads(res.read_text())["warnings"]
                                 for res in (tmp_path / "out" / "points").glob("*/results.json")]
    assert len(records) == 3 and not [w for ws in records for w in ws if "scene cache" in w], records

    meshes.load_mesh(_mesh(tmp_path))  # (a mesh file's load needs it: said now, once)
    meshes.load_mesh(_mesh(tmp_path))
    (line,) = _said(capsys.readouterr().err, "scene cache")
    assert line.startswith(f"cannot write tlm's scene cache {blocked / 'scenes'} ({blocked.parent} is a file, "
                           "not a folder): large meshes are parsed again on every load"), line
    assert line in caches.cache_warnings()


def test_a_scene_cache_fixed_before_a_mesh_is_loaded_is_never_said(tmp_path, blocked, capsys):
    assert frame_keys.scene_key("cornell")  # (its key looked up in the scene cache: it cannot be written)
    blocked.parent.unlink()  # (fixed: the cache can be made)
    meshes.load_mesh(_mesh(tmp_path))
    assert _said(capsys.readouterr().err, "") == []
    assert caches.cache_warnings() == []


# ---------------------------------------------------------------- the words


def test_a_folder_in_place_of_a_cached_file_is_said_a_folder(tmp_path, capsys):
    entry = tmp_path / "references" / "k1"
    (entry / "reference.npy").mkdir(parents=True)
    (entry / "meta.json").write_text(json.dumps({"key": "k1", "npy": {"size": 3200, "sha256": "0" * 64}}))
    assert caches.cached_image(entry, "reference.npy", "k1", "reference", "it is computed again") is None
    err = capsys.readouterr().err
    assert f"damaged reference cache entry {entry / 'reference.npy'} (a folder, not a file): removed" in err, err
    assert "bytes" not in err
    assert caches.digest_problem(tmp_path, {"size": 4096, "sha256": "0" * 64}) == "a folder, not a file"


def test_a_save_too_large_for_the_free_space_gives_sizes_that_show(cache, monkeypatch):
    cfg = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4],
           "reference": {"photons": 500, "k_nearest": 8, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4,
                         "spp": 2}}
    frame = load_frame(config_from_dict(cfg))
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9 - 1000, 1000))
    said: list[str] = []
    found = reference.ensure_reference(frame, compute=True, say=said.append)
    (line,) = [line for line in said if "not saved for a resume" in line]
    assert re.search(r" has 1000B free, a save takes \d+\.\dK \(looked at again", line), line
    assert "MB" not in line
    assert found.meta["rounds"] == 4 and (cache / "references" / found.key / "reference.npy").is_file()
