"""Photon emission and tracing: power bookkeeping, storage rules, Russian roulette, seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tlm.kernels import photons as photons_module
from tlm.kernels.emission import bounding_cone, emit, photon_key, split_photons
from tlm.kernels.memory import page_misses, span_addresses
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.scenes.loader import load_scene
from tlm.scenes.model import Light

from .scenes import sphere_scene


def test_split_photons_by_power():
    lights = (Light("point", (1.0, 1.0, 1.0)), Light("point", (3.0, 3.0, 3.0)), Light("point", (0.0, 0.0, 0.0)))
    assert split_photons(lights, 100).tolist() == [25, 75, 0]
    assert split_photons(lights, 7).sum() == 7
    assert split_photons(lights, 0).tolist() == [0, 0, 0]
    assert split_photons((Light("point", (0.0, 0.0, 0.0)),), 10).tolist() == [0]


def test_quad_emission_is_cosine_weighted_and_carries_the_light_power():
    light = Light("quad", (2.0, 4.0, 6.0), corner=(0.0, 1.0, 0.0), edge_u=(0.0, 0.0, 1.0), edge_v=(1.0, 0.0, 0.0))
    o, d, power, group = emit((light,), 40000, photon_key(3))
    assert o.shape == d.shape == power.shape == (40000, 3) and not group.any()
    np.testing.assert_allclose(power.sum(axis=0), light.power)
    cos = d @ light.normal
    assert cos.min() >= 0.0
    assert abs(cos.mean() - 2.0 / 3.0) < 0.01  # E[cos] under a cosine-weighted hemisphere
    assert np.all((o[:, 0] >= 0) & (o[:, 0] <= 1) & (o[:, 2] >= 0) & (o[:, 2] <= 1) & (o[:, 1] == 1.0))


def test_point_light_aims_at_the_scene_and_scales_power_by_the_cone():
    pos = np.array([0.0, 10.0, 0.0])
    lo, hi = np.array([-1.0, 0.0, -1.0]), np.array([1.0, 1.0, 1.0])
    axis, cos_max = bounding_cone(pos, lo, hi)
    light = Light("point", (1.0, 1.0, 1.0), position=tuple(pos))
    _o, d, power, _ = emit((light,), 20000, photon_key(0), (lo, hi))
    assert np.all(d @ axis >= cos_max - 1e-12)
    np.testing.assert_allclose(power.sum(axis=0), np.ones(3) * (1.0 - cos_max) / 2.0)
    # inside the box: the whole sphere, all the power
    _, cos_all = bounding_cone(np.zeros(3), -np.ones(3), np.ones(3))
    assert cos_all == -1.0


def test_first_hits_are_not_stored_and_bounce_limit(tmp_path):
    scene = load_scene(str(sphere_scene(tmp_path)))
    accel = build_accel(scene.triangles)
    one = trace_photons(scene, accel, 2000, max_bounces=1)
    assert one.photons.n == 0  # the only hit is straight from the light: the ray-cast frame's
    assert one.totals()["bounces"] == 2000
    three = trace_photons(scene, accel, 2000, max_bounces=3)
    assert 0 < three.photons.n <= 2 * 2000
    assert not three.photons.caustic.any()  # no specular surface: every stored photon is indirect
    np.testing.assert_allclose(np.linalg.norm(three.photons.incoming, axis=1), 1.0)
    # stored normals face the arriving photon
    assert np.all(np.sum(three.photons.normal * three.photons.incoming, axis=1) <= 0)


@pytest.mark.slow
def test_same_seed_same_map_other_seed_other_map(tmp_path):
    scene = load_scene(str(sphere_scene(tmp_path)))
    accel = build_accel(scene.triangles)
    a = trace_photons(scene, accel, 3000, seed=7)
    b = trace_photons(scene, accel, 3000, seed=7)
    c = trace_photons(scene, accel, 3000, seed=8)
    for name in ("position", "power", "incoming", "normal"):
        np.testing.assert_array_equal(getattr(a.photons, name), getattr(b.photons, name))
    for ma, mb in zip(a.photons.maps, b.photons.maps, strict=True):  # the caustic and the indirect map
        np.testing.assert_array_equal(ma.tree.items, mb.tree.items)
    assert a.photons.n != c.photons.n or not np.array_equal(a.photons.position, c.photons.position)


@pytest.mark.slow
def test_russian_roulette_is_unbiased(tmp_path):
    """Mean stored power with and without Russian roulette agree within 3 sigma."""
    scene = load_scene(str(sphere_scene(tmp_path, n_seg=24, n_rings=12)))
    accel = build_accel(scene.triangles)
    totals = {True: [], False: []}
    for rr in (True, False):
        for seed in range(8):
            tr = trace_photons(scene, accel, 4000, seed=seed, max_bounces=6, russian_roulette=rr)
            totals[rr].append(tr.photons.power.sum())
    m_rr, m_no = np.mean(totals[True]), np.mean(totals[False])
    sigma = math.sqrt(np.var(totals[True], ddof=1) / 8 + np.var(totals[False], ddof=1) / 8)
    assert abs(m_rr - m_no) <= 3.0 * sigma + 1e-12 * m_no, (m_rr, m_no, sigma)
    # and the expectation is the geometric series of the albedo: bounces 1..5 stored
    expected = 3.0 * 4.0 * math.pi**2 * sum(0.5**b for b in range(1, 6))
    assert abs(m_no - expected) / expected < 0.02


@pytest.mark.slow
def test_caustic_group_stores_only_caustics():
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    tr = trace_photons(scene, accel, 20000, seed=1, caustic_fraction=0.5)
    ph = tr.photons
    assert ph.caustic.any() and (~ph.caustic).any()
    none = trace_photons(scene, accel, 20000, seed=1, caustic_fraction=0.0)
    # without a caustic group the global photons store caustics too
    assert none.photons.caustic.any()


@pytest.mark.slow
def test_photon_misses_are_those_of_the_photon_major_streams(monkeypatch):
    """Each photon's page misses, all its bounces: the full word streams of its rays (node
    heap and leaf indices for the Traversal PM, vertices for the Intersection PM), photon
    after photon in emission order, each photon's bounces in order."""
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    calls = []
    real = photons_module.closest_hit

    def spy(*args, **kw):
        h = real(*args, **kw)
        calls.append(h.touched)
        return h

    monkeypatch.setattr(photons_module, "closest_hit", spy)
    tr = trace_photons(scene, accel, 1500, seed=2)
    n = 1500
    assert len(calls) >= 3 and tr.work["rays"].max() == len(calls)
    rows = {"nodes": [], "indices": [], "vertices": []}  # (photon, bounce, words)
    for b, t in enumerate(calls):
        pid = np.flatnonzero(tr.work["rays"] > b)  # the photons still travelling, in order
        for i, p in enumerate(pid.tolist()):
            leaves = t.leaf_ids[t.leaf_ptr[i] : t.leaf_ptr[i + 1]]
            lf, ll = accel.leaf_first[leaves], accel.leaf_last[leaves]
            lf, ll = lf[ll > lf], ll[ll > lf]
            rows["nodes"].append((p, b, t.node_ids[t.node_ptr[i] : t.node_ptr[i + 1]]))
            rows["indices"].append((p, b, span_addresses(lf // 4, (ll - 1) // 4 + 1)))
            rows["vertices"].append((p, b, span_addresses(lf, ll, 3)))
    want = {"trav_misses": np.zeros(n, np.int64), "isect_misses": np.zeros(n, np.int64)}
    for name, r in rows.items():
        r.sort(key=lambda x: x[:2])
        words = np.concatenate([x[2] for x in r])
        owner = np.concatenate([np.full(x[2].shape[0], x[0]) for x in r])
        miss, _ = page_misses(words)
        want["isect_misses" if name == "vertices" else "trav_misses"] += np.bincount(owner[miss], minlength=n)
    for k, v in want.items():
        np.testing.assert_array_equal(tr.work[k], v, err_msg=k)
        assert v.sum() > 0
    assert tr.work["isect_misses"].sum() > tr.work["trav_misses"].sum()  # 16 vertex pages, 2 index pages


@pytest.mark.parametrize("bad", [{"n": -1}, {"max_bounces": -1}, {"caustic_fraction": 1.0}])
def test_bad_arguments(bad):
    scene = load_scene("ring")
    accel = build_accel(scene.triangles)
    args = {"n": 10} | bad
    with pytest.raises(ValueError, match=next(iter(bad))):
        trace_photons(scene, accel, **args)


def test_a_frames_tables_give_the_trace_made_from_the_scene():
    """trace_photons takes a render's face normals, shading normals and material table
    (made once per frame) and traces what it traces when it makes them itself."""
    from tlm.config import config_from_dict
    from tlm.render.frame import Frame
    from tlm.render.pmap import trace_photon_map

    scene = load_scene("ring")
    accel = build_accel(scene.triangles)
    frame = Frame.create(scene, accel, config_from_dict({"scene": "ring", "mode": "pmap",
                                                         "photons": {"count": 3000, "max_bounces": 4}}))
    given = trace_photon_map(frame)
    made = trace_photons(scene, accel, 3000, seed=frame.cfg.seed, max_bounces=4,
                         **{k: v for k, v in vars(frame.cfg.photons).items()
                            if k in ("russian_roulette", "levels", "leaf_photons", "caustic_fraction",
                                     "caustic_count", "aim", "aim_triangles")},
                         global_map=frame.cfg.estimate.final_gather > 0, batch=frame.cfg.render.batch,
                         page_words=frame.cfg.cache.block_words, pairs=frame.cfg.cache.pairs,
                         fresnel=frame.cfg.render.fresnel)
    assert given.totals() == made.totals() and given.photons.n == made.photons.n > 0
    for a, b in zip(given.photons.gathered, made.photons.gathered, strict=True):
        for f in ("position", "normal", "incoming", "power", "caustic"):
            assert getattr(a, f).tobytes() == getattr(b, f).tobytes(), f


@pytest.mark.parametrize("radii, global_map", [((("glass", 8),), False), ((("global", 8),), False)])
def test_radii_of_a_map_the_trace_does_not_make_are_refused(radii, global_map):
    """``trace_photons(radii=...)`` names maps the trace makes ("caustic", "indirect", and
    "global" with ``global_map``): another name is an error before anything is traced."""
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    with pytest.raises(ValueError, match=r"radii: no '(glass|global)' map"):
        trace_photons(scene, accel, 100, radii=radii, global_map=global_map)
    made = trace_photons(scene, accel, 500, radii=(("indirect", 8), ("indirect", 8)), prepare=True)
    assert 8 in made.photons.indirect_map._memo and "leaf_order" in made.photons.caustic_map._memo
