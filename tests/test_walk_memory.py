"""Memory bounded by the batch, whatever the specular depth (issue 25, item 3).

* the specular walk goes in pieces of whole pixels of at most ``render.batch_rays`` rays
  (:func:`~tlm.render.walk.walk_pieces`), and shaded points in runs of at most that many
  shadow rays: a render with a small budget (many pieces and runs) gives the radiance,
  work and page misses of one piece, bit for bit, with 4 pairs and with 1 (the node heap
  and the leaf indices on one pair, where a pixel's order of reads matters most), and the
  photon-map frame gathers at the same points;
* each piece traces at most the budget, unless it is a single pixel;
* the photon tracer goes in chunks of photons of at most ``batch_rays`` rays, all
  bounces (but at least ``PHOTON_MIN_BATCH`` photons): the maps (order included), work
  and misses are those of one chunk;
* ``benchmarks/bench_memory.py --quick``: a deep walk (8x the rays of a shallow one)
  peaks at about the shallow one's memory, each measured in a fresh interpreter.
"""

from __future__ import annotations

import dataclasses
import itertools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.render import frame as render_frame
from tlm.render import passes, pmap, walk
from tlm.render.frame import Frame, cast
from tlm.scenes.loader import load_scene

ROOT = Path(__file__).resolve().parents[1]
W, H = 20, 16


def frame_with(scene, budget: int, **cache) -> Frame:
    cfg = config_from_dict({"resolution": [W, H], "mode": "pmap", "photons": {"count": 2000},
                            "render": {"batch_rays": budget}, "cache": cache})
    return Frame.create(scene, build_accel(scene.triangles), cfg)


@pytest.fixture(scope="module")
def scene():
    return load_scene("cornell", resolution=[W, H])


@pytest.mark.slow
@pytest.mark.parametrize(("page_words", "pairs"), [(1024, 4), (32, 1)])
def test_small_budget_is_bit_identical(scene, page_words, pairs):
    big = frame_with(scene, 1 << 20, block_words=page_words, pairs=pairs)
    small = dataclasses.replace(big, cfg=dataclasses.replace(
        big.cfg, render=dataclasses.replace(big.cfg.render, batch_rays=23)))
    photons = pmap.trace_photon_map(big).photons
    pixels = np.arange(W * H)
    # the small budget does cut the walk and the shading (else the test shows nothing)
    work = {k: np.zeros(W * H, dtype=np.int64) for k in walk.WALK_WORK}
    pieces = list(walk.walk_pieces(small, cast(small, pixels), "dielectric", small.cfg.render.refract_depth, work))
    assert len(pieces) > 5
    assert len(render_frame._pixel_runs(np.repeat(np.arange(W * H), 3), 23 // 4)) > 5
    out = {}
    for label, fr in (("big", big), ("small", small)):
        g = cast(fr, pixels)
        res = {f.__name__: f(fr, g, render_frame.new_streams(fr))
               for f in (passes.rcast_pass, passes.reflect_pass, passes.refract_pass)}
        res["pmap"] = pmap.pmap_pass(fr, g, photons, streams=render_frame.new_streams(fr))
        res["gather"] = passes.gather_points(fr, g)
        out[label] = res
    assert out["big"]["refract_pass"][1]["secondary_rays"].max() > 2  # paths split at the glass
    for name, (rad, wk) in ((n, out["big"][n]) for n in ("rcast_pass", "reflect_pass", "refract_pass", "pmap")):
        np.testing.assert_array_equal(out["small"][name][0], rad, err_msg=name)
        for k, v in wk.items():
            np.testing.assert_array_equal(out["small"][name][1][k], v, err_msg=(name, k))
    for a, b in zip(out["small"]["gather"], out["big"]["gather"], strict=True):
        np.testing.assert_array_equal(a, b)


def test_pieces_hold_at_most_the_budget(scene):
    budget = 40
    fr = frame_with(scene, budget)
    fr = dataclasses.replace(fr, cfg=dataclasses.replace(
        fr.cfg, render=dataclasses.replace(fr.cfg.render, refract_depth=12, min_weight=0.0)))
    g = cast(fr, np.arange(W * H))
    work = {k: np.zeros(W * H, dtype=np.int64) for k in walk.WALK_WORK}
    traced, seen = 0, []
    for piece in walk.walk_pieces(fr, g, "dielectric", 12, work):
        rays = int(work["secondary_rays"].sum()) - traced
        traced += rays
        owners = np.unique(np.concatenate([acc.owner for _, acc in piece.reads]))
        assert rays <= budget or owners.shape[0] == 1, (rays, owners)
        seen.append(owners)
    assert traced > 5 * budget
    order = np.concatenate(seen)
    assert np.all(np.diff(order) > 0)  # pieces in pixel order, no pixel in two pieces
    # and the whole walk, in one piece, traced the same rays
    whole = dataclasses.replace(fr, cfg=dataclasses.replace(
        fr.cfg, render=dataclasses.replace(fr.cfg.render, batch_rays=1 << 20)))
    again = {k: np.zeros(W * H, dtype=np.int64) for k in walk.WALK_WORK}
    assert len(list(walk.walk_pieces(whole, cast(whole, np.arange(W * H)), "dielectric", 12, again))) == 1
    for k in walk.WALK_WORK:
        np.testing.assert_array_equal(again[k], work[k], err_msg=k)


@pytest.mark.slow
@pytest.mark.parametrize(("pairs", "global_map"), [(4, False), (1, True)])
def test_photon_chunks_are_bit_identical(scene, pairs, global_map, monkeypatch):
    from tlm.kernels import photons

    monkeypatch.setattr(photons, "PHOTON_MIN_BATCH", 1)  # (chunks of 100 photons, not the floor's one)
    assert len(photons.photon_spans(3000, 8, 800)) == 30
    accel = build_accel(scene.triangles)
    one = trace_photons(scene, accel, 3000, pairs=pairs, global_map=global_map, page_words=64)
    chunked = trace_photons(scene, accel, 3000, pairs=pairs, global_map=global_map, page_words=64, batch_rays=800)
    assert one.work["trav_misses"].sum() > 0
    for k, v in one.work.items():
        np.testing.assert_array_equal(chunked.work[k], v, err_msg=k)
    for which in ("caustic_map", "indirect_map", "global_map"):
        a, b = getattr(one.photons, which), getattr(chunked.photons, which)
        if which == "global_map" and not global_map:
            assert a is None and b is None
            continue
        assert a.n > 0, which
        for f in ("position", "normal", "incoming", "power", "caustic"):
            np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)


@pytest.mark.slow
def test_deep_walk_memory_does_not_grow_with_depth():
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_memory.py"), "--quick"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.count("PASS:") == 2, run.stdout


def test_photon_chunks_hold_the_budget_but_at_least_the_floor():
    from tlm.kernels.photons import PHOTON_MIN_BATCH, photon_spans

    def sizes(n, bounces, budget):
        spans = photon_spans(n, bounces, budget)
        assert spans[0][0] == 0 and spans[-1][1] == n and all(a[1] == b[0] for a, b in itertools.pairwise(spans))
        return [b - a for a, b in spans]

    assert max(sizes(100_000, 8, 1 << 17)) == (1 << 17) // 8  # the budget's photons, all bounces
    assert max(sizes(100_000, 8, 2731)) == PHOTON_MIN_BATCH  # a small budget: the floor
    assert max(sizes(100_000, 0, 10_000)) == 10_000  # (no bounces: the rays of one)
    assert sizes(100_000, 8, None) == [100_000]
    assert sizes(10, 8, 16) == [10]
