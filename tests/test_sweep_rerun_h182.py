"""A rerun of a sweep whose every point is done loads no scene (h182): a point's hash holds its frame's
functional key, which holds the parsed scene's fingerprint, and a new process had to load (parse) the
scene to compute it, a rerun with nothing to do too (and a mesh entry that ``tlm cache prune`` removed was
written back). The fingerprint a load gave is remembered on disk by the files it read
(:func:`tlm.experiments.frames.scene_key`), and given again while they are as they were: the keys stay
what they were."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.experiments.frames as frames
from tlm import cache_admin
from tlm.experiments.sweep import run_sweep

from .helpers_scene_loads import another_process, box, counted_loads


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.fixture
def loads(monkeypatch):
    """Each scene load (the key's, the render's), in this process."""
    return counted_loads(monkeypatch)


def sweep(folder: Path) -> Path:
    base = {"scene": str(box(folder / "scene")), "mode": "rcast", "resolution": [16, 16],
            "render": {"light_samples": 1, "spp": 1}, "arch": {"frames": 1, "trace": False}}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.fifo_depth": [1, 16, 256, 4096]}}))
    return path


def test_a_rerun_of_a_finished_sweep_loads_no_scene(tmp_path, monkeypatch, loads):
    path = sweep(tmp_path)
    first = run_sweep(path, tmp_path / "o", jobs=1)
    assert (first.ok, first.renders) == (4, 1) and loads == ["key", "render"]
    another_process(monkeypatch)
    again = run_sweep(path, tmp_path / "o", jobs=1)
    assert (again.ok, again.skipped, again.renders) == (0, 4, 0)
    assert loads == ["key", "render"]  # (a "key" more before: the rerun parsed the scene for the points' keys)
    assert [r["hash"] for r in again.rows] == [r["hash"] for r in first.rows]
    scenes = cache_admin.scan("scenes")  # (tlm cache lists it, and prunes it, as an entry of the scenes cache)
    assert [e.name for e in scenes.entries if e.name.startswith("key-")] and not scenes.other
    # a file the load read changed (the mesh's material library): loaded again, other keys
    mtl = tmp_path / "scene" / "meshes" / "CornellBox-Original.mtl"
    text = mtl.read_text()
    assert "Kd 0.725 0.71 0.68" in text
    mtl.write_text(text.replace("Kd 0.725 0.71 0.68", "Kd 0.5 0.71 0.68", 1))
    another_process(monkeypatch)
    edited = run_sweep(path, tmp_path / "o", jobs=1)
    assert (edited.ok, edited.skipped, edited.renders) == (4, 0, 1)
    assert loads == ["key", "render", "key", "render"]
    assert not {r["hash"] for r in edited.rows} & {r["hash"] for r in first.rows}


def test_a_damaged_remembered_fingerprint_is_a_load_said_nowhere(tmp_path, monkeypatch, loads, capfd):
    path = sweep(tmp_path)
    run_sweep(path, tmp_path / "o", jobs=1)
    kept = sorted((frames.cache_root("scenes")).glob("key-*.json"))
    assert len(kept) == 1
    kept[0].write_text('{"tlm": "tlm-scene-key/1", "key": [], "fin')
    another_process(monkeypatch)
    capfd.readouterr()
    again = run_sweep(path, tmp_path / "o", jobs=1)
    assert (again.ok, again.skipped) == (0, 4) and loads == ["key", "render", "key"]
    assert capfd.readouterr().err == ""
    another_process(monkeypatch)
    again = run_sweep(path, tmp_path / "o", jobs=1)
    assert again.skipped == 4 and loads == ["key", "render", "key"]  # (kept again, whole)


def test_an_mtl_saved_while_the_first_run_loads_the_scene_is_not_given_to_the_rerun(tmp_path, monkeypatch, loads):
    """The user saves an edit of the MTL while the sweep loads the scene (after the parse read it): no
    fingerprint of the material read is remembered under the new MTL's sha256, so the rerun runs every point
    again of the new one (h194; was: every rerun skipped them all, of the old material, for ever)."""
    import tlm.scenes.materials as materials

    path = sweep(tmp_path)
    mtl = tmp_path / "scene" / "meshes" / "CornellBox-Original.mtl"
    real, done = materials.parse_mtl, []

    def raced(*args, **kw):
        out = real(*args, **kw)
        if not done:
            done.append(1)
            mtl.write_text(mtl.read_text().replace("Kd 0.725 0.71 0.68", "Kd 0.1 0.71 0.68", 1))
        return out

    monkeypatch.setattr(materials, "parse_mtl", raced)
    first = run_sweep(path, tmp_path / "o", jobs=1)
    assert done and first.ok == 4
    another_process(monkeypatch)
    again = run_sweep(path, tmp_path / "o", jobs=1)
    assert (again.ok, again.skipped) == (4, 0)  # (was: (0, 4))
    assert not {r["hash"] for r in again.rows} & {r["hash"] for r in first.rows}
    another_process(monkeypatch)
    loaded = len(loads)
    last = run_sweep(path, tmp_path / "o", jobs=1)  # (the new material's fingerprint: remembered)
    assert (last.ok, last.skipped) == (0, 4) and len(loads) == loaded
