"""Scene loads counted, a process's memory of scene fingerprints forgotten, and a Cornell box scene of OBJ and MTL
files copied for a test (shared by the scene-load and scene-fingerprint tests)."""

from __future__ import annotations

import shutil
from collections import OrderedDict
from pathlib import Path

import tlm.experiments.frame_keys as frame_keys
import tlm.experiments.frames as frames
import tlm.experiments.loading as loading

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def counted_loads(monkeypatch) -> list[str]:
    """Each scene load from now on, by where the code looked the loader up: ``"key"`` (a frame key's,
    :mod:`tlm.experiments.frames`) or ``"render"`` (:mod:`tlm.experiments.loading`)."""
    got: list[str] = []

    def counting(where, load):
        def counted(*args, **kw):
            got.append(where)
            return load(*args, **kw)
        return counted

    monkeypatch.setattr(frame_keys, "load_scene", counting("key", frame_keys.load_scene))  # (h487: out of frames)
    monkeypatch.setattr(frames, "load_scene", counting("key", frames.load_scene))
    monkeypatch.setattr(loading, "load_scene", counting("render", loading.load_scene))
    return got


def another_process(monkeypatch) -> None:
    """What this process remembers of scene fingerprints forgotten, as in a new one (the disk's caches kept)."""
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", OrderedDict())


def box(folder: Path) -> Path:
    """A copy of the Cornell box scene file with its OBJ mesh and material library in ``folder``; the scene file."""
    (folder / "meshes").mkdir(parents=True)
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl"):
        shutil.copy(SCENES / "meshes" / name, folder / "meshes" / name)
    shutil.copy(SCENES / "cornell-box.yaml", folder / "box.yaml")
    return folder / "box.yaml"
