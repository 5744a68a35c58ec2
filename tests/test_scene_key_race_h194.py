"""A file saved while a scene loads (h194, a review of h182): what remembers a load (a scene's fingerprint, in the
process and on disk as ``scenes/key-<hash>.json``; a parsed mesh's entry, ``scenes/mesh-<hash>.npz``) checks a
mesh's side files (an OBJ's material libraries, a glTF's buffers) by the bytes the parse read, not by what they
hold after it: an edit saved meanwhile left the old parse remembered under the new file's sha256, given to every
later process (a rerun rendered the old material for ever). And ``tlm cache prune`` cut short by Ctrl-C or SIGTERM
says what it had removed by then."""

from __future__ import annotations

import json
import os
import signal
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest
import yaml

import tlm.experiments.frame_keys as frame_keys
import tlm.experiments.frames as frames
import tlm.scenes.materials as materials
from tlm import cache_admin
from tlm.cli import main
from tlm.experiments.frames import scene_fingerprint
from tlm.scenes import cache as scene_cache
from tlm.scenes import meshes
from tlm.scenes.loader import load_scene

from .helpers_scene_loads import another_process
from .helpers_scene_loads import box as copied_box

SCENES = Path(__file__).resolve().parent.parent / "scenes"
OLD, NEW = "Kd 0.725 0.71 0.68", "Kd 0.1 0.71 0.68"  # (the first such line of the MTL: its floor)


@pytest.fixture(autouse=True)
def _own_cache(cache, monkeypatch):  # (tests/conftest.py; nothing this process remembered from another test)
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", OrderedDict())
    return cache


def box(folder: Path) -> Path:
    """A copy of the Cornell box scene file with its OBJ mesh and material library (its floor's line OLD)."""
    path = copied_box(folder)
    assert OLD in (folder / "meshes" / "CornellBox-Original.mtl").read_text()
    return path


def edit(path: Path) -> None:
    """The user's edit of the MTL, saved."""
    path.write_text(path.read_text().replace(OLD, NEW, 1))


def remembered(cache: Path) -> list[Path]:
    return sorted((cache / "scenes").glob("key-*.json"))


def fresh(path: Path) -> str:
    """The fingerprint of the scene as its files are now (no memo)."""
    return scene_fingerprint(load_scene(path))


def racing(monkeypatch, module, name: str, then) -> list:
    """``module.name`` calling ``then()`` once, after its first call returned (the edit saved meanwhile)."""
    real, done = getattr(module, name), []

    def raced(*args, **kw):
        out = real(*args, **kw)
        if not done:
            done.append(1)
            then()
        return out

    monkeypatch.setattr(module, name, raced)
    return done


def test_an_mtl_saved_while_the_scene_loads_leaves_no_fingerprint_remembered(tmp_path, monkeypatch, cache):
    """The MTL edited after its parse read it, before the load ended: the fingerprint (of the old material) is
    neither remembered in the process nor on disk under the new MTL's sha256 (was: every later process gave
    it: a rerun rendered the old material for ever)."""
    path = box(tmp_path)
    mtl = tmp_path / "meshes" / "CornellBox-Original.mtl"
    before = fresh(path)
    done = racing(monkeypatch, materials, "parse_mtl", lambda: edit(mtl))
    assert frames.scene_key(path) == before and done  # (the bytes it read: the old material)
    assert remembered(cache) == [] and not frame_keys._SCENE_KEYS
    after = fresh(path)
    assert after != before
    assert frames.scene_key(path) == after  # (this process: loaded again)
    another_process(monkeypatch)
    assert frames.scene_key(path) == after  # (another: so too)
    assert len(remembered(cache)) == 1  # (a load no edit raced: remembered, and given again)
    another_process(monkeypatch)
    monkeypatch.setattr(frame_keys, "load_scene", lambda *a, **k: pytest.fail("loaded: not remembered"))
    assert frames.scene_key(path) == after


def test_an_mtl_saved_after_its_mesh_entry_was_checked_leaves_no_fingerprint_remembered(tmp_path, monkeypatch,
                                                                                        cache):
    """A mesh read back from the scene cache (its MTL checked against the entry's digest), the MTL saved after
    that check, before the load ended: nothing remembered under the new MTL's sha256."""
    monkeypatch.setattr(scene_cache, "MIN_TRIANGLES", 0)  # (the box's 36 triangles kept)
    path = box(tmp_path)
    mtl = tmp_path / "meshes" / "CornellBox-Original.mtl"
    before = frames.scene_key(path)
    assert len(list((cache / "scenes").glob("mesh-*.npz"))) == 1
    for f in remembered(cache):
        f.unlink()
    another_process(monkeypatch)
    done = racing(monkeypatch, scene_cache, "_geometry", lambda: edit(mtl))
    assert frames.scene_key(path) == before and done  # (read back from the entry: the old material)
    assert remembered(cache) == [] and not frame_keys._SCENE_KEYS
    another_process(monkeypatch)  # (the race is over: what it patched reads as ever)
    after = frames.scene_key(path)
    assert after == fresh(path) != before
    for f in remembered(cache):  # (a load from the entry that no edit raced: remembered)
        f.unlink()
    another_process(monkeypatch)
    monkeypatch.setattr(scene_cache, "_kept", lambda *a: pytest.fail("parsed: the entry not read"))
    assert frames.scene_key(path) == after and len(remembered(cache)) == 1


def test_the_mesh_cache_keeps_no_entry_of_an_mtl_saved_while_it_was_parsed(tmp_path, monkeypatch, cache):
    """:func:`tlm.scenes.cache.mesh`'s entry checks the MTL by the bytes the parse read (was: its digest
    after the parse, so the entry held the old material under the new MTL's digest, read back by every
    load after)."""
    monkeypatch.setattr(scene_cache, "MIN_TRIANGLES", 0)
    box(tmp_path)
    obj, mtl = tmp_path / "meshes" / "CornellBox-Original.obj", tmp_path / "meshes" / "CornellBox-Original.mtl"

    def floor(geom) -> float:
        return {m.name: m.albedo for m in geom.materials}["floor"][0]

    done = racing(monkeypatch, materials, "parse_mtl", lambda: edit(mtl))
    assert floor(meshes.load_mesh(obj)) == pytest.approx(0.725) and done  # (as it read it)
    assert not list((cache / "scenes").glob("mesh-*.npz"))
    assert floor(meshes.load_mesh(obj)) == pytest.approx(0.1)  # (was: 0.725, the entry's)
    assert len(list((cache / "scenes").glob("mesh-*.npz"))) == 1  # (no edit raced this one: kept)
    assert floor(meshes.load_mesh(obj)) == pytest.approx(0.1)


def test_a_gltf_buffer_saved_while_the_scene_loads_leaves_no_fingerprint_remembered(tmp_path, monkeypatch, cache):
    """A ``.gltf``'s buffer file edited after trimesh read it (through tlm's resolver, which notes the bytes it
    returned), before the load ended."""
    import trimesh

    path = box(tmp_path)
    trimesh.creation.box().export(tmp_path / "cube.gltf")  # (gltf_buffer_1.bin: the 8 corners, float32)
    scene = yaml.safe_load(path.read_text())
    scene["geometry"] = [scene["geometry"], {"mesh": "cube.gltf", "name": "cube",
                                             "transform": {"scale": 0.2, "translate": [0.0, 0.5, 0.0]}}]
    scene["default_material"] = "floor"
    path.write_text(yaml.safe_dump(scene))
    corners = tmp_path / "gltf_buffer_1.bin"
    assert json.loads((tmp_path / "cube.gltf").read_text())["accessors"][1]["type"] == "VEC3"

    def halved() -> None:
        corners.write_bytes((np.frombuffer(corners.read_bytes(), dtype="<f4") * 0.5).astype("<f4").tobytes())

    before = fresh(path)
    done = racing(monkeypatch, trimesh, "load", halved)  # (its first call: the cube's; the OBJ is tlm's own reader)
    assert frames.scene_key(path) == before and done
    assert remembered(cache) == [] and not frame_keys._SCENE_KEYS
    another_process(monkeypatch)
    after = frames.scene_key(path)
    assert after == fresh(path) != before
    assert len(remembered(cache)) == 1  # (no edit raced it: remembered)


def test_a_load_that_read_one_library_twice_different_remembers_nothing(tmp_path, monkeypatch, cache):
    """One MTL read by two loads of one scene (one mesh placed twice), saved between them: the scene holds
    both materials, so no fingerprint is the file's."""
    path = box(tmp_path)
    scene = yaml.safe_load(path.read_text())
    scene["geometry"] = [scene["geometry"], {**scene["geometry"], "name": "again",
                                             "transform": {"translate": [0.0, 3.0, 0.0]}}]
    path.write_text(yaml.safe_dump(scene))
    mtl = tmp_path / "meshes" / "CornellBox-Original.mtl"
    done = racing(monkeypatch, materials, "parse_mtl", lambda: edit(mtl))
    frames.scene_key(path)
    assert done and remembered(cache) == [] and not frame_keys._SCENE_KEYS


# ------------------------------------------------------------------ tlm cache prune, interrupted


def aged_keys(cache: Path, n: int, size: int = 100) -> list[Path]:
    """``n`` remembered scene fingerprints (entries of the scenes cache), ``size`` bytes each, a week unused."""
    folder = cache / "scenes"
    folder.mkdir(parents=True, exist_ok=True)
    t = time.time() - 7 * 86400
    out = []
    for i in range(n):
        f = folder / f"key-{i:024x}.json"
        f.write_text("x" * size)
        os.utime(f, (t - i, t - i))
        out.append(f)
    return out


@pytest.mark.parametrize(("signum", "status", "said"), [(signal.SIGINT, 130, "interrupted"),
                                                         (signal.SIGTERM, 143, "terminated (SIGTERM)")])
@pytest.mark.parametrize("command", ["prune", "clear"])
def test_an_interrupted_prune_says_what_it_had_removed(signum, status, said, command, cache, monkeypatch, capsys):
    keys = aged_keys(cache, 4)
    real, calls = cache_admin._remove_one, []

    def signalled_at_the_third(*args, **kw):
        calls.append(1)
        if len(calls) == 3:
            signal.raise_signal(signum)
        return real(*args, **kw)

    monkeypatch.setattr(cache_admin, "_remove_one", signalled_at_the_third)
    argv = ["cache", "prune", "--older-than", "1d"] if command == "prune" else ["cache", "clear"]
    capsys.readouterr()
    assert main(argv) == status
    out, err = capsys.readouterr()
    doing = "pruning" if command == "prune" else "clearing"
    assert err.strip().splitlines()[-1] == f"tlm: {said} while {doing} the cache: removed 2 entries (200B) before " \
                                           "the interrupt", err
    assert out == ""
    assert sum(f.exists() for f in keys) == 2


def test_a_prune_interrupted_before_its_removal_says_none_removed(cache, monkeypatch, capsys):
    keys = aged_keys(cache, 2)

    def interrupted_survey(*args, **kw):
        signal.raise_signal(signal.SIGINT)
        return []

    monkeypatch.setattr(cache_admin, "survey", interrupted_survey)
    capsys.readouterr()
    assert main(["cache", "prune", "--max-size", "0"]) == 130
    err = capsys.readouterr().err
    assert err.strip().splitlines()[-1] == ("tlm: interrupted while pruning the cache: removed 0 entries (0B) before "
                                            "the interrupt"), err
    assert all(f.exists() for f in keys)
    # (a dry run removes nothing: its interrupt is the plain line)
    assert main(["cache", "prune", "--max-size", "0", "--dry-run"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "tlm: interrupted"
