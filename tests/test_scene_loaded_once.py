"""A render through the functional cache loads its scene once: on a miss, the frame is
rendered from the scene its key loaded (:func:`tlm.experiments.frames.cached_render`), not
loaded again by :func:`tlm.experiments.loading.load_frame`; on a hit nothing renders. The
work, the summary and the host stages are those of a render that loaded the scene itself."""

from __future__ import annotations

import numpy as np
import pytest

import tlm
import tlm.experiments.frame_keys as frame_keys
import tlm.experiments.frames as frames
from tlm.config import config_from_dict
from tlm.experiments import run as runs

from .helpers_scene_loads import counted_loads

CONFIG = {"scene": "cornell", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
          "photons": {"count": 2000}}


@pytest.fixture(autouse=True)
def _own_cache(cache, monkeypatch):  # (tests/conftest.py; and no fingerprint remembered from another test)
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", type(frame_keys._SCENE_KEYS)())
    return cache


@pytest.fixture
def loads(monkeypatch):
    """Each scene load, by where the code looked the loader up (the key's, the render's)."""
    return counted_loads(monkeypatch)


@pytest.fixture
def renders(monkeypatch):
    """The renders :func:`cached_render` ran."""
    got: list[str] = []
    render = runs.render

    def counted(cfg, *args, **kw):
        got.append(cfg.mode)
        return render(cfg, *args, **kw)

    monkeypatch.setattr(runs, "render", counted)
    return got


def arrays(fn, path) -> dict:
    """Every array the cache keeps of ``fn`` (its ``.npz``): name -> (dtype, shape, bytes)."""
    fn.save(path)
    with np.load(path, allow_pickle=False) as z:
        return {k: (z[k].dtype.str, z[k].shape, z[k].tobytes()) for k in z.files}


def settings(mode: str, **more):
    return config_from_dict({**CONFIG, "mode": mode, **more})


@pytest.mark.parametrize("mode", ["rcast", "pmap"])
def test_a_miss_loads_the_scene_once_and_a_hit_renders_nothing(mode, loads, renders):
    cold = frames.cached_render(settings(mode))
    assert not cold.cached and renders == [mode]
    assert loads == ["key"]  # (before: ["key", "render"], the render loading it again)
    assert "load_scene" in cold.summary["host_seconds"]  # (the key's load, booked to the render)
    warm = frames.cached_render(settings(mode))  # (the fingerprint remembered: no load at all)
    assert warm.cached and renders == [mode] and loads == ["key"]
    frame_keys._SCENE_KEYS.clear()  # (another process: the key loads the scene, the cache holds the frame)
    again = frames.cached_render(settings(mode))
    assert again.cached and renders == [mode] and loads == ["key", "key"]
    # another frame of a remembered scene: the key loads nothing, the render loads it once
    other = frames.cached_render(settings(mode, seed=7))
    assert not other.cached and renders == [mode, mode] and loads == ["key", "key", "render"]
    assert "load_scene" in other.summary["host_seconds"]


@pytest.mark.parametrize("mode", ["rcast", "pmap"])
def test_the_frame_rendered_from_the_keys_scene_is_the_one_a_render_loads(mode, tmp_path, loads):
    """The work and the summary of a miss, bit for bit, and the host stages, as the render's
    own load gives them (tlm.render_image: the scene loaded by the render)."""
    got = frames.cached_render(settings(mode))
    assert loads == ["key"]
    res = runs.render(settings(mode))
    assert loads == ["key", "render"]
    assert arrays(got.functional, tmp_path / "a.npz") == arrays(res.functional(), tmp_path / "b.npz")
    full = runs.results_dict(res, exposure=0.0, config_path=None)
    for key in frames.SUMMARY_KEYS[:-1]:  # (warnings: the cache's own, without unused settings)
        assert got.summary[key] == full[key], key
    assert sorted(got.summary["host_seconds"]) == sorted(res.timer.seconds)


@pytest.mark.parametrize("mode", ["rcast", "pmap"])
def test_run_and_render_image_load_the_scene_once(mode, tmp_path, loads):
    tlm.run({**CONFIG, "mode": mode}, tmp_path / "out", outputs="images", reference=False)
    assert loads == ["render"]
    tlm.render_image({**CONFIG, "mode": mode})
    assert loads == ["render", "render"]
