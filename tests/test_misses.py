"""Page misses of the render passes, from the kernels' real address streams.

* brute force: the passes' ``*_misses`` equal :func:`page_misses` of the full word
  streams (every node, index word and vertex word of every ray, every shading record),
  put together here from the kernels' own calls in pixel-major program order;
* packets of pixels run in order with one carried :class:`Streams` give exactly the
  whole image's misses (and cold pairs per packet do not, so the test can fail);
* both for the thesis's 4 pairs per PM and for 1 (the node heap and the leaf indices
  on one pair, merged owner-major), and for other block sizes; on a real frame 1 pair
  misses more than 4, 2 and 3 miss as 4 does, smaller blocks miss more (``cache``);
* the recorded leaf lists agree with the counts, also for rays that fell back to the
  float64 traversal.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.kernels import shade, traverse, traverse_numpy
from tlm.kernels.memory import REGION_PAGES, Streams, page_misses, span_addresses
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.kernels.work import MISS_KEYS, WORK_KEYS
from tlm.render import frame as render_frame
from tlm.render import pmap
from tlm.render.frame import Frame, cast
from tlm.render.passes import rcast_pass, reflect_pass, refract_pass
from tlm.scenes.loader import load_scene

W, H = 24, 20
PASSES = (rcast_pass, reflect_pass, refract_pass)


@pytest.fixture(scope="module")
def frame():
    scene = load_scene("cornell", resolution=[W, H])
    accel = build_accel(scene.triangles)
    # one eye ray per pixel and Snell alone (no Fresnel split): one ray per pixel and bounce,
    # the order the brute force below rebuilds
    return Frame.create(scene, accel, config_from_dict({"resolution": [W, H], "mode": "refract",
                                                        "render": {"spp": 1, "fresnel": False}}))


@pytest.fixture
def gbuffer(frame):  # a fresh one per test: a G-buffer remembers its specular walks
    return cast(frame, np.arange(W * H))


# ---------------------------------------------------------------- brute force


def ray_words(accel, touched, i: int) -> dict[str, np.ndarray]:
    """Every word ray ``i`` read, stream by stream, in order (nothing compressed)."""
    nodes = touched.node_ids[touched.node_ptr[i] : touched.node_ptr[i + 1]]
    leaves = touched.leaf_ids[touched.leaf_ptr[i] : touched.leaf_ptr[i + 1]]
    lf, ll = accel.leaf_first[leaves], accel.leaf_last[leaves]
    full = ll > lf
    lf, ll = lf[full], ll[full]
    return {
        "nodes": nodes.astype(np.int64),
        "indices": span_addresses(lf // 4, (ll - 1) // 4 + 1),
        "vertices": span_addresses(lf, ll, 3),
    }


class Capture:
    """The kernels' calls during one pass: secondary rays, shadow rays and fragments."""

    def __init__(self, monkeypatch):
        self.rays = []  # touched of each closest_hit call (bounces in order)
        self.shade = []  # (keys, triangles, touched of its shadow rays, shadow rays per point)
        real_closest, real_direct, real_any = render_frame.closest_hit, render_frame.direct_light, shade.any_hit

        def closest(*args, **kw):
            h = real_closest(*args, **kw)
            self.rays.append(h.touched)
            return h

        def direct(accel, lights, points, normals, triangles, albedo, keys, *args, **kw):
            self._shadow = []
            out = real_direct(accel, lights, points, normals, triangles, albedo, keys, *args, **kw)
            assert len(self._shadow) <= 1  # one light: its rays are point-major
            touched = self._shadow[0] if self._shadow else None
            self.shade.append((keys.copy(), triangles.copy(), touched, out[1]["shadow_rays"].copy()))
            return out

        def anyhit(*args, **kw):
            occ = real_any(*args, **kw)
            self._shadow.append(occ.touched)
            return occ

        monkeypatch.setattr(render_frame, "closest_hit", closest)
        monkeypatch.setattr(render_frame, "direct_light", direct)
        monkeypatch.setattr(shade, "any_hit", anyhit)


def brute_force(frame, g, cap: Capture, work, eye: bool, page_words: int, pairs: int) -> dict[str, np.ndarray]:
    """Each miss key per pixel from the full streams, ordered (pixel, bounce, ray); the
    streams sharing a pair merged, ordered (pixel, bounce, stream, ray), each stream in
    its own address region."""
    p = g.pixels.shape[0]
    local = {int(px): i for i, px in enumerate(g.pixels.tolist())}
    items: dict[str, list] = {}  # stream -> [(pixel, bounce, seq, words)]

    def add(prefix, touched, owners, bounce):
        for i, owner in enumerate(owners):
            for name, words in ray_words(frame.accel, touched, i).items():
                items.setdefault(prefix + name, []).append((int(owner), bounce, i, words))

    if eye:
        add("", g.hits.touched, np.arange(p), 0)
    else:  # bounce b traces the pixels whose path is still alive, in pixel order
        for b, touched in enumerate(cap.rays, start=1):
            add("", touched, np.flatnonzero(work["secondary_rays"] >= b), b)
    for keys, tri, touched, per_point in cap.shade:
        pix = np.array([local[int(k)] for k in keys // 64])
        bounce = keys % 64  # the shaded points of all bounces, each its own
        if touched is not None:
            owners = np.repeat(pix, per_point)
            rays_bounce = np.repeat(bounce, per_point)
            for i, owner in enumerate(owners):
                for name, words in ray_words(frame.accel, touched, i).items():
                    items.setdefault("shadow_" + name, []).append((int(owner), int(rays_bounce[i]), i, words))
        for i, (px, t) in enumerate(zip(pix.tolist(), tri.tolist(), strict=True)):
            items.setdefault("shading", []).append((px, int(bounce[i]), i, np.array([t], np.int64)))
    probe = Streams(page_words, pairs)
    merged: dict[str, list] = {}  # pair -> [(pixel, bounce, region, seq, words, stream)]
    for name, rows in items.items():
        pair, region = probe.pair_of(name)
        merged.setdefault(pair, []).extend(
            (px, b, region, i, words + region * REGION_PAGES * page_words, name) for px, b, i, words in rows)
    out = {k: np.zeros(p, np.int64) for k in MISS_KEYS if k != "gather_misses"}
    for rows in merged.values():
        rows.sort(key=lambda r: r[:4])
        words = np.concatenate([r[4] for r in rows])
        owner = np.concatenate([np.full(r[4].shape[0], r[0]) for r in rows])
        key = np.concatenate([np.full(r[4].shape[0], r[5]) for r in rows])
        miss, _ = page_misses(words, page_words=page_words)
        for name in np.unique(key).tolist():
            out[render_frame.STREAM_KEYS[name]] += np.bincount(owner[miss & (key == name)], minlength=p)
    return out


@pytest.mark.slow
@pytest.mark.parametrize(("page_words", "pairs"), [(1024, 4), (16, 4), (1024, 1), (16, 1)])
@pytest.mark.parametrize("f", PASSES, ids=lambda f: f.__name__)
def test_misses_are_those_of_the_full_streams(frame, gbuffer, monkeypatch, f, page_words, pairs):
    cap = Capture(monkeypatch)
    _, work = f(frame, gbuffer, Streams(page_words, pairs))
    want = brute_force(frame, gbuffer, cap, work, f is rcast_pass, page_words, pairs)
    for k, v in want.items():
        np.testing.assert_array_equal(work[k], v, err_msg=k)
    if f is rcast_pass:
        assert work["trav_misses"].sum() > 0 and work["isect_misses"].sum() > 0
        assert work["shadow_isect_misses"].sum() > 0
    if page_words == 16:  # small pages: every stream misses somewhere
        for k in want:
            assert work[k].sum() > 0, k
    assert work["shadow_rays"].sum() > 0 and work["fragments"].sum() > 0


def test_eye_rays_must_be_recorded(frame):
    g = cast(frame, np.arange(10), record=False)
    assert g.hits.touched is None
    with pytest.raises(ValueError, match="record=True"):
        rcast_pass(frame, g)
    # the other passes trace their own rays
    reflect_pass(frame, g)


# ---------------------------------------------------------------- packets in order


@pytest.mark.slow
@pytest.mark.parametrize(("page_words", "pairs", "sizes"), [(1024, 4, (1, 7, 64)), (32, 4, (1, 7, 64)),
                                                          (1024, 1, (5, 64)), (64, 1, (5, 64))])
def test_packets_in_pixel_order_give_the_whole_image(frame, gbuffer, page_words, pairs, sizes):
    whole = {f.__name__: f(frame, gbuffer, Streams(page_words, pairs)) for f in PASSES}
    for size in sizes:
        starts = range(0, W * H, size)
        for f in PASSES:
            rad_w, work_w = whole[f.__name__]
            streams = Streams(page_words, pairs)
            got = {k: [] for k in WORK_KEYS}
            cold = {k: [] for k in MISS_KEYS if k in WORK_KEYS}
            for s0 in starts:
                g = cast(frame, np.arange(s0, min(s0 + size, W * H)))
                rad, work = f(frame, g, streams)
                np.testing.assert_array_equal(rad, rad_w[s0 : s0 + size])
                for k in WORK_KEYS:
                    got[k].append(work[k])
                if size == 64:
                    _, work = f(frame, g, Streams(page_words, pairs))  # cold pairs per packet
                    for k in cold:
                        cold[k].append(work[k])
            for k in WORK_KEYS:
                np.testing.assert_array_equal(np.concatenate(got[k]), work_w[k], err_msg=(f.__name__, size, k))
            if size == 64:  # packets with cold pairs miss more: the carried state matters
                assert sum(np.concatenate(v).sum() for v in cold.values()) > sum(work_w[k].sum() for k in cold)


# ---------------------------------------------------------------- the cache section


def with_cache(frame, **cache):
    """The frame with other ``cache`` settings (the passes' default Streams follow them)."""
    return dataclasses.replace(frame, cfg=config_from_dict({"resolution": [W, H], "mode": "refract",
                                                            "render": {"spp": 1, "fresnel": False},
                                                            "cache": cache}))


@pytest.mark.slow
def test_one_pair_misses_more_and_two_are_as_many_as_four(frame, gbuffer):
    runs = {pairs: {f.__name__: f(with_cache(frame, pairs=pairs), gbuffer)[1] for f in PASSES}
            for pairs in (1, 2, 3, 4)}
    for f in PASSES:  # the passes' default Streams are the config's
        np.testing.assert_array_equal(f(frame, gbuffer, Streams(1024, 1))[1]["trav_misses"],
                                      runs[1][f.__name__]["trav_misses"])
    for name, four in runs[4].items():
        for k in WORK_KEYS:
            for pairs in (2, 3):  # at most two cached streams per PM phase: two pairs are enough
                np.testing.assert_array_equal(runs[pairs][name][k], four[k], err_msg=(pairs, name, k))
            one = runs[1][name][k]
            if k in ("trav_misses", "shadow_trav_misses"):  # node heap and leaf indices on one pair
                assert np.all(one >= four[k]), (name, k)
            else:  # the vertex streams have no pairs knob; the shading records are alone
                np.testing.assert_array_equal(one, four[k], err_msg=(name, k))
    for k in ("trav_misses", "shadow_trav_misses"):
        assert runs[1]["rcast_pass"][k].sum() > runs[4]["rcast_pass"][k].sum(), k


def test_smaller_blocks_miss_more(frame, gbuffer):
    runs = {bw: {f.__name__: f(with_cache(frame, block_words=bw), gbuffer)[1] for f in PASSES}
            for bw in (64, 1024)}
    total = dict.fromkeys(runs, 0)
    for name, big in runs[1024].items():
        for k in WORK_KEYS:
            small = runs[64][name][k]
            if k in MISS_KEYS:
                assert small.sum() >= big[k].sum(), (name, k)
                total[64] += small.sum()
                total[1024] += big[k].sum()
            else:  # the block size changes the misses only
                np.testing.assert_array_equal(small, big[k], err_msg=(name, k))
    assert total[64] > total[1024]


@pytest.mark.slow
def test_the_photon_tracer_and_the_gather_follow_the_cache_section(frame, gbuffer):
    settings = {"thesis": {}, "one_pair": {"pairs": 1}, "small": {"block_words": 64},
                "both": {"pairs": 1, "block_words": 64}}
    frames = {name: with_cache(frame, **c) for name, c in settings.items()}
    traced = {name: pmap.trace_photon_map(fr, n=3000) for name, fr in frames.items()}
    thesis = traced["thesis"]
    for t in traced.values():  # the same photons, whatever the cache
        np.testing.assert_array_equal(t.photons.position, thesis.photons.position)
    w, w1 = thesis.work, traced["one_pair"].work
    np.testing.assert_array_equal(w1["isect_misses"], w["isect_misses"])
    assert np.all(w1["trav_misses"] >= w["trav_misses"]) and w1["trav_misses"].sum() > w["trav_misses"].sum()
    ws = traced["small"].work
    assert ws["trav_misses"].sum() > w["trav_misses"].sum() and ws["isect_misses"].sum() > w["isect_misses"].sum()
    gather = {name: pmap.pmap_pass(fr, gbuffer, thesis.photons)[1]["gather_misses"] for name, fr in frames.items()}
    assert gather["thesis"].sum() > 0
    # the Fragment PM's photon-leaf stream is the only one of its pass: pairs do not matter
    np.testing.assert_array_equal(gather["one_pair"], gather["thesis"])
    np.testing.assert_array_equal(gather["both"], gather["small"])
    assert gather["small"].sum() > gather["thesis"].sum()
    # packets in pixel order with one carried Streams of the section: the whole frame's
    streams, parts = render_frame.new_streams(frames["both"]), []
    for s0 in range(0, W * H, 97):
        g = cast(frame, np.arange(s0, min(s0 + 97, W * H)))
        parts.append(pmap.pmap_pass(frames["both"], g, thesis.photons, streams=streams)[1]["gather_misses"])
    np.testing.assert_array_equal(np.concatenate(parts), gather["both"])


# ---------------------------------------------------------------- recorded leaves


def assert_touched_matches_counts(accel, res) -> None:
    t, c = res.touched, res.counts
    np.testing.assert_array_equal(np.diff(t.leaf_ptr), c.leaf_visits)
    np.testing.assert_array_equal(np.diff(t.node_ptr), c.node_visits)
    r = c.leaf_visits.shape[0]
    owner = np.repeat(np.arange(r), c.leaf_visits)
    size = accel.leaf_size[t.leaf_ids]
    np.testing.assert_array_equal(np.bincount(owner, weights=size, minlength=r).astype(np.int64), c.tri_tests)


@pytest.mark.slow
@pytest.mark.parametrize("first_only", [False, True])
def test_touched_follows_the_float64_fallback(frame, monkeypatch, first_only):
    """Rays whose float32 answer fails its check are traversed again in float64; their
    recorded leaves must be the float64 traversal's, which here (its tests made to find
    nothing) are all the leaves the ray crosses, not the float32 run's. The numpy engine:
    its check and fallback are the functions patched here (the compiled one is compared
    with it in tests/test_engines.py)."""
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    accel = frame.accel
    rng = np.random.default_rng(3)
    o = rng.uniform(100, 450, (300, 3))
    d = rng.normal(size=(300, 3))
    fn = any_hit if first_only else closest_hit
    plain = fn(accel, o, d, record=True)
    real_check, real64 = traverse.check, traverse_numpy.closest_slots64

    def flaky(o_, d_, tmin, tmax, soa64, slot):
        t, u, v, ok = real_check(o_, d_, tmin, tmax, soa64, slot)
        ok = ok.copy()
        ok[::2] = False  # every other hit fails its check
        return t, u, v, ok

    def blind(*args):
        slot, t = real64(*args)
        return np.full_like(slot, -1), np.full_like(t, np.inf)

    monkeypatch.setattr(traverse, "check", flaky)
    monkeypatch.setattr(traverse_numpy, "closest_slots64", blind)
    res = fn(accel, o, d, record=True)
    assert_touched_matches_counts(accel, res)
    assert_touched_matches_counts(accel, plain)
    hit = np.flatnonzero(plain.occluded if first_only else plain.triangle >= 0)
    bad = hit[::2]
    assert bad.shape[0] > 20
    c = res.counts
    np.testing.assert_array_equal(c.leaf_visits[bad], c.leaves_crossed[bad])  # float64 found nothing
    assert np.any(c.leaf_visits[bad] > plain.counts.leaf_visits[bad])
    again = traverse._traverse(accel, o[bad], d[bad], 0.0, np.inf, None, True, first_only, 4, exact64=True)
    for j, i in enumerate(bad.tolist()):
        got = res.touched.leaf_ids[res.touched.leaf_ptr[i] : res.touched.leaf_ptr[i + 1]]
        want = again.touched.leaf_ids[again.touched.leaf_ptr[j] : again.touched.leaf_ptr[j + 1]]
        np.testing.assert_array_equal(got, want)


def test_touched_matches_counts_in_the_passes(frame, gbuffer, monkeypatch):
    """Every ray a pass traces (eye, secondary, shadow) records as many leaves as it visited."""
    seen = []
    real_closest, real_any = render_frame.closest_hit, shade.any_hit

    def closest(*args, **kw):
        h = real_closest(*args, **kw)
        seen.append(h)
        return h

    def anyhit(*args, **kw):
        h = real_any(*args, **kw)
        seen.append(h)
        return h

    monkeypatch.setattr(render_frame, "closest_hit", closest)
    monkeypatch.setattr(shade, "any_hit", anyhit)
    for f in PASSES:
        f(frame, gbuffer)
    assert len(seen) > 5
    for res in [gbuffer.hits, *seen]:
        assert_touched_matches_counts(frame.accel, res)


@pytest.mark.slow
@pytest.mark.parametrize(("page_words", "pairs"), [(1024, 4), (32, 1)])
def test_packets_in_order_with_samples_and_fresnel_branches(page_words, pairs):
    """The default rendering (4 jittered samples per pixel, glass split by Fresnel, the
    photon term gathered at the walks' ends from two maps): packets of 7 pixels in order
    with one carried Streams give the whole image's radiance, work and misses, bit for bit."""
    scene = load_scene("cornell", resolution=[W, H])
    fr = Frame.create(scene, build_accel(scene.triangles),
                      config_from_dict({"resolution": [W, H], "mode": "pmap", "photons": {"count": 3000},
                                        "cache": {"block_words": page_words, "pairs": pairs}}))
    assert fr.spp == 4 and fr.cfg.render.fresnel
    photons = pmap.trace_photon_map(fr).photons
    assert photons.caustic_map.n > 0 and photons.indirect_map.n > 0

    def run(g, streams):
        out = {f.__name__: f(fr, g, streams[f.__name__]) for f in PASSES}
        out["pmap"] = pmap.pmap_pass(fr, g, photons, streams=streams["pmap"])
        return out

    names = [f.__name__ for f in PASSES] + ["pmap"]
    whole = run(cast(fr, np.arange(W * H)), {n: render_frame.new_streams(fr) for n in names})
    assert whole["refract_pass"][1]["secondary_rays"].max() > 2  # some pixel's path split at the glass
    streams = {n: render_frame.new_streams(fr) for n in names}
    parts = [run(cast(fr, np.arange(s0, min(s0 + 7, W * H))), streams) for s0 in range(0, W * H, 7)]
    for n in names:
        np.testing.assert_array_equal(np.concatenate([p[n][0] for p in parts]), whole[n][0], err_msg=n)
        for k, v in whole[n][1].items():
            np.testing.assert_array_equal(np.concatenate([p[n][1][k] for p in parts]), v, err_msg=(n, k))
