"""Damaged cache entries: each file of a functional entry (``.npz``, its ``.json`` sidecar)
and of a reference (``reference.npy``, ``meta.json``) cut short, zeroed or overwritten with
garbage is reported once as a warning naming the file, removed, and computed again; the
result equals the clean cache's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments import frames
from tlm.experiments.frames import cache_dir, cached_render
from tlm.experiments.reference_cache import load_reference, save_reference

REPO = Path(__file__).resolve().parents[1]
CFG = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
       "arch": {"frames": 2, "trace": False}}
WAYS = ("truncated", "zeroed", "garbage")


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def damage(path: Path, way: str) -> None:
    data = path.read_bytes()
    if way == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif way == "zeroed":
        path.write_bytes(bytes(len(data)))
    else:
        path.write_bytes(np.random.default_rng(1).bytes(len(data)))


def same_functional(a, b) -> None:
    assert a.passes == b.passes and a.pixels == b.pixels
    for p in a.work:
        for k, v in a.work[p].items():
            np.testing.assert_array_equal(v, b.work[p][k])


def without_seconds(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k != "host_seconds"}


@pytest.mark.slow
@pytest.mark.parametrize("way", WAYS)
@pytest.mark.parametrize("file", ["npz", "json"])
def test_a_damaged_functional_entry_is_rendered_again(file, way, capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    assert not clean.cached
    path = cache_dir() / f"{clean.key}.{file}"
    damage(path, way)
    capsys.readouterr()
    again = cached_render(cfg)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"tlm: warning: damaged functional cache entry {path} (")
    assert err[0].endswith("removed, rendering it again")
    assert not again.cached  # rendered again, and cached again
    same_functional(again.functional, clean.functional)
    assert without_seconds(again.summary) == without_seconds(clean.summary)
    third = cached_render(cfg)  # the entry is whole again: read, no warning
    assert third.cached and capsys.readouterr().err == ""
    same_functional(third.functional, clean.functional)


def test_an_entry_of_an_older_format_is_replaced_quietly(capsys):
    cfg = config_from_dict(CFG, "test")
    clean = cached_render(cfg)
    side = cache_dir() / f"{clean.key}.json"
    side.write_text(json.dumps({**json.loads(side.read_text()), "format": "functional-summary/1"}))
    capsys.readouterr()
    again = cached_render(cfg)
    assert not again.cached and capsys.readouterr().err == ""
    assert frames.is_cached(clean.key)


def a_reference(key: str = "k" * 20) -> tuple[str, np.ndarray]:
    image = np.random.default_rng(0).random((16, 24, 3)).astype(np.float32)
    save_reference(key, image, {"rounds": 4, "converged": True, "relative_standard_error": 0.01})
    return key, image


@pytest.mark.parametrize("way", WAYS)
@pytest.mark.parametrize("file", ["reference.npy", "meta.json"])
def test_a_damaged_reference_is_removed(file, way, cache, capsys):
    key, image = a_reference()
    got = load_reference(key)
    np.testing.assert_array_equal(got[0], image)
    path = cache / "references" / key / file
    damage(path, way)
    capsys.readouterr()
    assert load_reference(key) is None
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"tlm: warning: damaged reference cache entry {path} (")
    assert not (cache / "references" / key).exists()
    assert load_reference(key) is None and capsys.readouterr().err == ""  # said once
    a_reference(key)  # computed again: equal to the clean one
    np.testing.assert_array_equal(load_reference(key)[0], image)


@pytest.mark.slow
def test_a_pmap_run_with_a_damaged_reference_warns_and_goes_on(tmp_path, cache, capsys):
    """The run measures no error (the reference is gone, its hint says how to compute it)."""
    args = ["run", str(REPO / "configs" / "cornell.yaml"), "--mode", "pmap", "--set", "resolution=[16,12]",
            "--set", "photons.count=2000", "--no-report", "--no-progress", "--outputs", "images",
            "--no-reference"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    key = json.loads((tmp_path / "a" / "results.json").read_text())["error"]["reference"]
    folder = cache / "references" / key
    a_reference(key)  # (a stand-in of the right key; its content does not matter here)
    damage(folder / "meta.json", "zeroed")
    capsys.readouterr()
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert f"tlm: warning: damaged reference cache entry {folder / 'meta.json'}" in err and "Traceback" not in err
    assert json.loads((tmp_path / "b" / "results.json").read_text())["error"]["available"] is False


def test_a_reference_the_cache_cannot_keep_still_measures_the_run(tmp_path, cache, monkeypatch, capsys):
    """A read-only (or full) cache: the reference computed for the run is used by it and
    said not to be cached; the run does not fail after computing it."""
    import tlm.experiments.reference_cache as reference_cache
    from tlm.errors import EnvironmentFailure

    def refused(key, image, meta):
        raise EnvironmentFailure("cannot write into the cache (read-only or not permitted)", source=str(cache))

    monkeypatch.setattr(reference_cache, "save_reference", refused)
    out = tmp_path / "r"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--mode", "pmap", "--set", "resolution=[12,8]",
                 "--set", "photons.count=1500", "--set", "reference.photons=1500", "--set", "reference.max_rounds=4",
                 "--set", "reference.min_rounds=2", "--set", "reference.spp=1", "--no-report", "--no-progress",
                 "--outputs", "images", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "not cached (" in err and "read-only" in err and "used by this run only" in err and "Traceback" not in err
    assert json.loads((out / "results.json").read_text())["error"]["available"] is True
    assert not (cache / "references").exists() or not any((cache / "references").iterdir())
