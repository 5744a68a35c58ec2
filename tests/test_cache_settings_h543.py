"""The cache model's settings in one place (h543, from probe h525).

A key added to the run config's ``cache`` section (the probe's ``cache.prefetch``) reached the
frame's passes but not the photon tracer, which, like four other places, took the section
field by field; and :meth:`Deferred.like` copied only ``page_words`` and ``pairs``, so a new
setting of :class:`Streams` was dropped on the threads' cold pairs (the same misses either way,
no test said so). Now :meth:`Streams.of` turns the section into pairs, every key by
``CACHE_KEYS`` (a key it lacks is refused), every caller goes through it, and ``Deferred.like``
copies :meth:`Streams.settings`, which holds every setting a Streams has.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
from pathlib import Path

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.config_sections import CacheConfig
from tlm.kernels import memory
from tlm.kernels.memory import Accesses, Streams
from tlm.kernels.recording import Deferred
from tlm.kernels.traverse import build_accel
from tlm.render import frame as render_frame
from tlm.render import pmap, walk
from tlm.render.frame import Frame, cast
from tlm.scenes.loader import load_scene

ROOT = Path(__file__).resolve().parents[1]


def test_streams_of_takes_every_key_of_the_cache_section():
    assert set(memory.CACHE_KEYS) == {f.name for f in dataclasses.fields(CacheConfig)}
    streams = Streams.of(CacheConfig(pairs=2, block_words=64))
    assert streams.settings() == {"page_words": 64, "pairs": 2}
    assert (streams.page_words, streams.pairs, streams.states) == (64, 2, {})


def test_a_cache_key_the_model_lacks_is_refused_not_dropped():
    probe = dataclasses.make_dataclass("Cache", [("pairs", int, 4), ("block_words", int, 1024),
                                                 ("prefetch", bool, False)], frozen=True)
    with pytest.raises(ValueError, match=r"cache\.prefetch is no setting of the cache model.*CACHE_KEYS"):
        Streams.of(probe())


def test_settings_are_every_attribute_but_the_state():
    """A setting added to Streams.__init__ but not to SETTINGS would be dropped by a copy."""
    fresh = Streams(64, 2)
    assert set(vars(fresh)) - {"states"} == set(Streams.SETTINGS)
    assert list(inspect.signature(Streams.__init__).parameters)[1:] == list(Streams.SETTINGS)


def test_deferred_like_keeps_every_setting():
    carried = Streams.of(CacheConfig(pairs=1, block_words=48))
    carried.charge("nodes", Accesses(np.array([0, 40, 47]), np.array([0, 0, 1]), 48), 2)
    cold = Deferred.like(carried)
    assert cold.settings() == carried.settings()
    for name in vars(carried):  # every field: a new one cannot be left behind
        if name != "states":
            assert getattr(cold, name) == getattr(carried, name), name
    assert cold.states == {} and cold.heads == {}  # (cold: no state copied)
    assert repr(cold) == "Deferred(page_words=48, pairs=1, states={})"
    carried.settle(cold)  # (settled on pairs like its own: no error)
    with pytest.raises(ValueError, match="is not charged on pairs like"):
        Streams(64, 1).settle(cold)


def _reads(path: Path) -> list[int]:
    """Lines of ``path`` that read ``<x>.cache.block_words`` (the section taken field by field)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "block_words"
            and isinstance(n.value, ast.Attribute) and n.value.attr == "cache"]


def test_no_module_takes_the_cache_section_field_by_field():
    found = {str(p.relative_to(ROOT)): lines for p in sorted((ROOT / "tlm").rglob("*.py"))
             if (lines := _reads(p))}
    assert found == {}, f"build the pairs with Streams.of(cfg.cache), not field by field: {found}"


@pytest.fixture(scope="module")
def small():
    scene = load_scene("cornell", resolution=[8, 6])
    cfg = config_from_dict({"resolution": [8, 6], "mode": "pmap", "photons": {"count": 300},
                            "cache": {"block_words": 64, "pairs": 1}})
    return Frame.create(scene, build_accel(scene.triangles), cfg)


def test_the_passes_and_the_photon_tracer_get_the_whole_section(small, monkeypatch):
    given = []
    made = Streams.of.__func__

    def spy(cls, cache):
        given.append(cache)
        return made(cls, cache)

    monkeypatch.setattr(Streams, "of", classmethod(spy))
    assert render_frame.new_streams(small).settings() == {"page_words": 64, "pairs": 1}
    traced = pmap.trace_photon_map(small)
    assert traced.work["trav_misses"].sum() > 0
    work = {k: np.zeros(48, dtype=np.int64) for k in walk.WALK_WORK}
    list(walk.walk_pieces(small, cast(small, np.arange(48)), "dielectric", 2, work))
    assert len(given) >= 3 and all(c is small.cfg.cache for c in given)
