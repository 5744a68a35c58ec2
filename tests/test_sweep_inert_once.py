"""A sweep factor the run's mode never reads renders its frame once: the functional cache key
(:func:`tlm.experiments.frames.functional_key`) leaves out the settings
:func:`tlm.render.planner.inert_settings` names for the mode, the list its warnings use. It held
``photons.count`` in mode rcast, so each point of such a sweep rendered the same frame again; a
pmap sweep of it still renders each point's frame."""

from __future__ import annotations

import pytest
import yaml

from tlm.config import config_from_dict, to_dict
from tlm.experiments.frames import functional_key
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def sweep(tmp_path, mode: str):
    path = tmp_path / f"{mode}.yaml"
    path.write_text(yaml.safe_dump({"base": {**BASE, "mode": mode}, "grid": {"photons.count": [500, 1000]}}))
    return run_sweep(path, tmp_path / mode, jobs=1)


def test_a_photon_count_sweep_in_rcast_renders_once(tmp_path):
    done = sweep(tmp_path, "rcast")
    assert (done.ok, done.failed, done.renders) == (2, 0, 1)  # (was 2 rendered: the count in the key)
    assert sorted(r["functional_cached"] for r in done.rows) == [False, True]
    assert any("photons.count changes nothing" in w for w in done.warnings)


def test_a_photon_count_sweep_in_pmap_renders_each_point(tmp_path):
    done = sweep(tmp_path, "pmap")
    assert (done.ok, done.failed, done.renders) == (2, 0, 2)
    assert [r["functional_cached"] for r in done.rows] == [False, False]


def key(**raw) -> str:
    return functional_key(config_from_dict(raw), "scene", "code")


def test_the_key_keeps_what_the_mode_reads():
    assert key(mode="rcast", photons={"count": 5}) == key(mode="rcast")
    assert key(mode="rcast", estimate={"k": 3}) == key(mode="rcast")
    assert key(mode="pmap", photons={"count": 5}) != key(mode="pmap")
    assert key(mode="pmap", estimate={"filter": "disk", "k": 3}) == key(mode="pmap", estimate={"filter": "disk"})
    assert key(mode="pmap", estimate={"filter": "kvoxel", "k": 3}) != key(mode="pmap", estimate={"filter": "kvoxel"})
    assert key(mode="rcast", render={"spp": 2}) != key(mode="rcast")
    assert key(mode="rcast", cache={"pairs": 1}) != key(mode="rcast")
    assert key(mode="rcast") != key(mode="reflect")
    assert key(mode="rcast", arch={"fifo_depth": 4}) == key(mode="rcast")  # (the timing model's)
    assert key(mode="rcast") == functional_key(to_dict(config_from_dict({"mode": "rcast"})), "scene", "code")
