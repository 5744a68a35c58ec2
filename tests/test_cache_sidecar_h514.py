"""A functional frame's sidecar is checked whole and names the code that wrote it; a dry run is not a use (h514).

From the cache probe h513: a value changed in a frame's ``<key>.json`` (``"tri_tests": 89398`` made ``12345``) was read
as it was, beside the ``tri_tests_per_ray`` the frame's real count gives; the sidecar did not say which code wrote it
(``tlm cache`` could not tell an entry of older code, never read again, from a live one); and ``tlm sweep --dry-run``
read every cached frame whole, which made it used now for ``tlm cache prune --older-than``.
"""

from __future__ import annotations

import json
import os
import time

import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments import frame_keys, frames
from tlm.experiments.frames import cache_dir, cached_render
from tlm.fingerprint import code_fingerprint

CFG = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
       "arch": {"frames": 2, "trace": False}}
DAY = 86400


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("tlm: warning")]


def test_a_value_changed_in_a_sidecar_is_a_damaged_entry(capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    side = cache_dir() / f"{clean.key}.json"
    held = json.loads(side.read_text())
    real = held["work"]["rcast"]["tri_tests"]
    held["work"]["rcast"]["tri_tests"] = real + 1  # (its keys and types as they were, the npz's checksum too)
    side.write_text(json.dumps(held, indent=1) + "\n")
    assert not frames.is_cached(clean.key)  # (was: counted cached, by a dry run too)
    capsys.readouterr()
    again = cached_render(cfg)  # (was: read, its tri_tests real + 1 beside the real tri_tests_per_ray)
    assert _warnings(capsys.readouterr().err) == [
        f"tlm: warning: damaged functional cache entry {side} (its content differs from its 'sidecar_sha256'): "
        "removed, rendering it again"]
    assert not again.cached and again.summary["work"]["rcast"]["tri_tests"] == real
    third = cached_render(cfg)  # (written again whole: read, nothing said)
    assert third.cached and capsys.readouterr().err == "" and third.summary == again.summary


def test_the_sidecar_names_its_code_and_is_sealed_and_a_read_frame_is_as_a_rendered_one():
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    held = json.loads((cache_dir() / f"{clean.key}.json").read_text())
    assert held["code_fingerprint"] == code_fingerprint()  # (tlm cache, h515: an entry of other code is stale)
    assert held["format"] == frames.SUMMARY_FORMAT and frames.seal_problem(held) is None
    assert frames.sealed(held) == held  # (the digest of the rest, canonical: the same written and read back)
    got = cached_render(cfg)
    assert got.cached and set(got.summary) == set(clean.summary)  # (neither the digest nor the code in a summary)


def test_a_sidecar_of_other_code_or_without_its_digest_is_damaged(capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    side = cache_dir() / f"{clean.key}.json"
    whole = json.loads(side.read_text())
    for text, why in (
            (json.dumps(frames.sealed({**whole, "code_fingerprint": "0" * 16})),
             "its 'code_fingerprint' \"0000000000000000\" is not this code's"),
            (json.dumps({k: v for k, v in whole.items() if k != frames.SEAL}), "it has no 'sidecar_sha256'")):
        side.write_text(text)
        assert not frames.is_cached(clean.key)
        capsys.readouterr()
        again = cached_render(cfg)
        assert _warnings(capsys.readouterr().err) == [
            f"tlm: warning: damaged functional cache entry {side} ({why}): removed, rendering it again"]
        assert not again.cached and frames.is_cached(clean.key)


def test_an_entry_of_the_format_before_the_digest_is_rendered_again_quietly(capsys):
    """A sidecar of ``functional-summary/6`` (no digest, no code): an older tlm's, as any older format (its key holds
    that tlm's code too, so this code finds none under its keys but by a copy)."""
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    side = cache_dir() / f"{clean.key}.json"
    old = {k: v for k, v in json.loads(side.read_text()).items() if k not in ("sidecar_sha256", "code_fingerprint")}
    side.write_text(json.dumps({**old, "format": "functional-summary/6"}))
    assert not frames.is_cached(clean.key)
    capsys.readouterr()
    again = cached_render(cfg)
    assert not again.cached and capsys.readouterr().err == ""
    assert json.loads(side.read_text())["format"] == frames.SUMMARY_FORMAT and frames.is_cached(clean.key)


def _sweep(tmp_path):
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": CFG, "grid": {"arch.packet_size": [1, 16]}}))
    return path


@pytest.mark.parametrize("noatime", [True, False], ids=["O_NOATIME", "times-set-back"])
def test_a_dry_run_leaves_the_frames_last_use_as_it_was(tmp_path, cache, monkeypatch, capsys, noatime):
    path = _sweep(tmp_path)
    assert main(["sweep", str(path), "--out", str(tmp_path / "out"), "--jobs", "1", "--no-progress"]) == 0
    files = sorted(cache_dir().iterdir())
    assert {f.suffix for f in files} == {".npz", ".json"}
    old = time.time() - 40 * DAY
    for f in files:
        os.utime(f, (old, old))
    before = {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files}
    if not noatime:  # (a file not the process's own: read, its access time set back)
        monkeypatch.delattr(os, "O_NOATIME", raising=False)
    capsys.readouterr()
    assert main(["sweep", str(path), "--out", str(tmp_path / "again"), "--dry-run"]) == 0
    assert "1 cached, 0 to render" in capsys.readouterr().out
    assert {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files} == before  # (was: read now)
    assert main(["cache", "prune", "--older-than", "30d"]) == 0  # (was: kept, "last used" now)
    assert not any(cache_dir().iterdir())


def test_a_dry_run_leaves_a_remembered_scene_key_unused(tmp_path, cache, monkeypatch, capsys):
    """A mesh scene's remembered fingerprint (``scenes/key-<hash>.json``), read by a dry run's frame keys."""
    (tmp_path / "tri.obj").write_text("v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 2 3\n")
    (tmp_path / "s.yaml").write_text(
        "geometry: {mesh: tri.obj}\ndefault_material: m\n"
        "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
        "lights: [{type: point, position: [0, 3, 0], power: [50, 50, 50]}]\n"
        "camera: {eye: [0, 3, -3], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": {**CFG, "scene": str(tmp_path / "s.yaml"), "resolution": [8, 8]},
                                    "grid": {"arch.packet_size": [1, 16]}}))
    assert main(["sweep", str(path), "--out", str(tmp_path / "out"), "--jobs", "1", "--no-progress"]) == 0
    keys = sorted((cache / "scenes").glob("key-*.json"))
    assert keys
    old = time.time() - 40 * DAY
    for f in keys:
        os.utime(f, (old, old))
    before = {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in keys}
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", type(frame_keys._SCENE_KEYS)())  # (another process: read from disk)
    assert main(["sweep", str(path), "--out", str(tmp_path / "again"), "--dry-run"]) == 0
    assert {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in keys} == before  # (was: read now)
