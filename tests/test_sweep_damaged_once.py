"""A damaged functional-cache entry is rendered again once in a sweep, by the point its group
sends first, as a frame not cached is: :func:`tlm.experiments.frames.is_cached` said an entry
whose files were there was cached, so every point of its group went at once, and with
``--jobs 2`` both workers found the damage, said so and rendered the frame."""

from __future__ import annotations

import json

import pytest
import yaml

from tlm import fingerprint
from tlm.config import config_from_dict
from tlm.experiments import frames
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}
SAID = "damaged functional cache entry"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def damage(key: str) -> None:
    """The entry's npz zeroed from its middle on, its size kept (its sidecar as it was)."""
    npz = frames.cache_dir() / f"{key}.npz"
    data = npz.read_bytes()
    npz.write_bytes(data[: len(data) // 2] + bytes(len(data) - len(data) // 2))


def damaged_sweep(tmp_path, capfd) -> tuple[str, list[str]]:
    """A sweep of two points of one frame, its entry damaged, run again with ``--jobs 2``: the frame's
    key (as this process computes it) and the functional keys the points' results hold."""
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}))
    first = run_sweep(path, tmp_path / "a", jobs=1)
    assert (first.ok, first.renders) == (2, 1)
    key = frames.render_key(config_from_dict(BASE), tmp_path)
    assert frames.is_cached(key)
    damage(key)
    assert not frames.is_cached(key)  # (was: both files there)
    capfd.readouterr()
    again = run_sweep(path, tmp_path / "b", jobs=2)
    err = capfd.readouterr().err
    assert (again.ok, again.failed, again.renders) == (2, 0, 1), err  # (was 2 rendered)
    assert sorted(r["functional_cached"] for r in again.rows) == [False, True]
    assert err.count(SAID) <= 1, err  # (a worker's stderr may come later: at most once)
    held = [json.loads((tmp_path / "b" / "points" / r["hash"] / "results.json").read_text())["functional"]["key"]
            for r in again.rows]
    assert frames.is_cached(key), held  # (the entry whole again)
    return key, held


def test_a_damaged_entry_is_rendered_by_one_worker(tmp_path, capfd):
    key, held = damaged_sweep(tmp_path, capfd)
    assert held == [key, key]


def test_a_worker_keys_its_frame_with_the_sweeps_code_fingerprint(tmp_path, capfd, monkeypatch):
    """The package edited since this process took its code fingerprint (a checkout worked on while the
    suite, or a sweep, runs): a local worker keys the frame by the sweep's fingerprint, which the points'
    hashes hold and its fork server's code was loaded under, not by the one the disk gives at its first
    point. It took the disk's: the damaged entry under the sweep's key was never read (nor said, nor
    rendered again: the test above failed once so in a full run), and the frame was cached under another
    code's key, rendered by the fork server's code (read by a later run of that code as its own)."""
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (not the disk's: as after an edit)
    key, held = damaged_sweep(tmp_path, capfd)
    assert held == [key, key]


def test_an_entry_of_an_older_format_is_not_cached(tmp_path):
    d = frames.cache_dir()
    d.mkdir(parents=True)
    (d / "k.npz").write_bytes(b"x")
    (d / "k.json").write_text('{"format": "functional-summary/2"}')
    assert not frames.is_cached("k")
    (d / "k.json").write_text("{not json")
    assert not frames.is_cached("k")
