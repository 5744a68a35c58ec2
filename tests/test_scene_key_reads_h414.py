"""h414: a frame key's hit (:func:`tlm.experiments.frames._scene_key` giving the remembered fingerprint) read the
scene's YAML file twice: once for its checks (its text) and once for its bytes' sha256 (what the remembered digest is
of). It reads it once now, and gives the same fingerprint and digest."""

from __future__ import annotations

import builtins
import io
import os

import pytest

from tlm.experiments import frame_keys, frames
from tlm.experiments.provenance import scene_identity


@pytest.fixture(autouse=True)
def _own_cache(cache, monkeypatch):  # (tests/conftest.py; this process's memo of scene keys, emptied)
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", type(frame_keys._SCENE_KEYS)())
    return cache


def _counting(monkeypatch, path) -> list:
    """The opens of ``path`` from now on (builtins.open, and io.open: pathlib's), one item each."""
    opened, real = [], io.open
    target = os.path.realpath(path)

    def counted(file, *args, **kwargs):
        if isinstance(file, (str, bytes, os.PathLike)) and os.path.realpath(file) == target:
            opened.append(args[0] if args else kwargs.get("mode", "r"))
        return real(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", counted)
    monkeypatch.setattr(io, "open", counted)
    return opened


@pytest.mark.parametrize("where", ["memo", "disk"])
def test_a_key_hit_reads_the_scene_file_once(where, tmp_path, monkeypatch):
    path = tmp_path / "s.yaml"
    path.write_text("extends: cornell\nresolution: [8, 8]\n", encoding="utf-8")
    first = frames._scene_key(str(path), None, None, None)
    assert first[1] is not None  # (loaded: the key remembered)
    if where == "disk":  # (another process: the key file on disk; a scene without meshes keeps none, so keep it)
        checks = frame_keys._SCENE_KEYS[next(iter(frame_keys._SCENE_KEYS))]
        frames._keep_key(next(iter(frame_keys._SCENE_KEYS)), *checks)
        frame_keys._SCENE_KEYS.clear()
    assert first[2] == scene_identity(path)
    opened = _counting(monkeypatch, path)
    fingerprint, scene, digest = frames._scene_key(str(path), None, None, None)
    assert scene is None  # (a hit)
    assert (fingerprint, digest) == (first[0], first[2])
    assert len(opened) == 1, opened  # (was 2: the checks' read of its text and _yaml_bytes's of its bytes)


def test_a_hit_whose_file_changed_bytes_not_text_digests_it_again(tmp_path, monkeypatch):
    path = tmp_path / "s.yaml"
    path.write_text("extends: cornell\nresolution: [8, 8]\n", encoding="utf-8")
    first = frames._scene_key(str(path), None, None, None)
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))  # (the same text, other bytes)
    opened = _counting(monkeypatch, path)
    expected = scene_identity(path)
    digest_reads = len(opened)  # (provenance.scene_identity's own)
    opened.clear()
    fingerprint, scene, digest = frames._scene_key(str(path), None, None, None)
    assert scene is None and fingerprint == first[0]
    assert digest == expected != first[2]
    assert len(opened) == 1 + digest_reads, opened  # (the checks' read, then the digest's: was one more)
    opened.clear()
    assert frames._scene_key(str(path), None, None, None)[1:] == (None, digest)
    assert len(opened) == 1, opened


def test_a_hit_whose_file_changed_text_loads_it_again(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("extends: cornell\nresolution: [8, 8]\n", encoding="utf-8")
    frames._scene_key(str(path), None, None, None)
    path.write_text("extends: cornell\nresolution: [8, 9]\n", encoding="utf-8")
    _, scene, digest = frames._scene_key(str(path), None, None, None)
    assert scene is not None and digest == scene_identity(path)
