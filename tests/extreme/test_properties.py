"""Property-based cases (hypothesis, bounded and derandomized so the suite stays fast
and repeatable): random triangle soups and packets of rays through ``closest_hit``,
and random configurations within the schema through the renderer.

Agreement with brute force is up to *explained* disagreements, the same rule as
``tests/test_intersect.py``: both answers must be legitimate readings of a near-tie
(two hits within 1e-5 relative distance, or a hit within 1e-5 of an edge, judged by an
independent float64 Möller–Trumbore), since the float32 test and the BSP's clipping
to its boxes may decide those either way.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tlm.config import FILTERS, MODES
from tlm.kernels.intersect import brute_force
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.scenes.model import Light, Material
from tlm.scenes.shapes import aabox, quad, uv_sphere

from ..test_intersect import explained, mt_reference
from .util import WHITE, assert_clean, make_scene, no_nan_hits, render_scene

# lattice values make shared edges, shared vertices, coplanar and degenerate
# triangles and axis-parallel rays common; floats make everything else
lattice = st.integers(-4, 4).map(lambda i: i / 2.0)
real = st.floats(-3.0, 3.0, allow_nan=False, allow_infinity=False)
coord = st.one_of(lattice, real)
vec3 = st.tuples(coord, coord, coord)
direction = st.tuples(*[st.one_of(st.sampled_from([-1.0, -0.0, 0.0, 1.0, 0.5]), real)] * 3)
LEVELS = st.sampled_from([0, 1, 2, 3, None])
FAST = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def soup_and_rays(draw):
    tris = draw(st.lists(st.tuples(vec3, vec3, vec3), min_size=1, max_size=12))
    tri = np.asarray(tris, dtype=np.float64)
    n = draw(st.integers(1, 24))
    o = np.asarray(draw(st.lists(vec3, min_size=n, max_size=n)), dtype=np.float64)
    # half of the rays aim at a vertex or an edge point of the soup: shared edges,
    # silhouettes, grazing hits
    aim = draw(st.lists(st.tuples(st.integers(0, tri.shape[0] - 1), st.sampled_from([0.0, 0.5, 1.0, 0.25]),
                                  st.integers(0, 2), st.booleans()), min_size=n, max_size=n))
    d = np.asarray(draw(st.lists(direction, min_size=n, max_size=n)), dtype=np.float64)
    for i, (k, f, e, use) in enumerate(aim):
        if use:
            a, b = tri[k, e], tri[k, (e + 1) % 3]
            target = a + f * (b - a)
            if np.any(target != o[i]):
                d[i] = target - o[i]
    return tri, o, d


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@FAST
@given(case=soup_and_rays(), levels=LEVELS)
def test_closest_hit_agrees_with_brute_force(case, levels):
    """Random small soups (1-12 triangles) and packets (1-24 rays, half aimed at
    vertices and edges): closest_hit never returns NaN, its counts are non-negative,
    it finds a hit exactly where brute force does or the difference is an explained
    near-tie, the same triangle gives bitwise the same t, and any_hit says "occluded"
    where closest_hit found a hit (or the hit is an explained near-edge case)."""
    tri, o, d = case
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    assert np.all((h.triangle >= 0) == np.isfinite(h.t))
    t, k, u, v = brute_force(o, d, tri)
    assert not (np.isnan(t).any() or np.isnan(u).any() or np.isnan(v).any())
    differ = h.triangle != k
    if differ.any():
        ref = mt_reference(o, d, tri)
        # each side either agrees with the float64 reference or is an explained near-tie
        ok = ((h.triangle == ref.tri) | explained(ref, h.triangle)) & ((k == ref.tri) | explained(ref, k))
        assert ok[differ].all(), (h.triangle[differ], k[differ], ref.tri[differ], ref.t[differ], ref.edge[differ])
    same = ~differ & (k >= 0)
    np.testing.assert_allclose(h.t[same], t[same], rtol=1e-12)
    occ = any_hit(accel, o, d).occluded
    mismatch = occ != (h.triangle >= 0)
    if mismatch.any():
        ref = mt_reference(o, d, tri)
        assert explained(ref, h.triangle)[mismatch].all()


@pytest.mark.slow
@FAST
@given(case=soup_and_rays(), keep=st.lists(st.booleans(), min_size=24, max_size=24), batch=st.integers(1, 6))
def test_one_leaf_packets_are_invariant(case, keep, batch):
    """With every triangle in one leaf (levels=0), any sub-packet of at least two rays
    (in any order) gives bitwise the same t, triangle, u, v and work counts per ray as
    the whole packet, whatever the batch size."""
    tri, o, d = case
    accel = build_accel(tri, levels=0)
    whole = closest_hit(accel, o, d)
    idx = np.flatnonzero(np.asarray(keep[: o.shape[0]]))[::-1]
    if idx.shape[0] < 2:
        idx = np.arange(o.shape[0])[::-1]
    if idx.shape[0] < 2:
        return
    part = closest_hit(accel, o[idx], d[idx], batch=batch)
    for f in ("t", "triangle", "u", "v"):
        np.testing.assert_array_equal(getattr(part, f), getattr(whole, f)[idx], err_msg=f)
    for f in ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests"):
        np.testing.assert_array_equal(getattr(part.counts, f), getattr(whole.counts, f)[idx], err_msg=f)


@st.composite
def closed_shape_and_rays(draw):
    """A jittered octahedron or box (closed) and rays from outside aimed at its vertices
    and edge points: many graze its silhouette."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if draw(st.booleans()):
        v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
        v += rng.uniform(-0.2, 0.2, v.shape)
        faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
        tri = v[np.array(faces)]
    else:
        tri = aabox([-1.0, -0.7, -0.9], [0.8, 1.1, 1.0], n=draw(st.integers(1, 2)))
        tri = tri + rng.uniform(-1e-3, 1e-3, (1, 1, 3))
    f = rng.choice([0.0, 0.5, 0.3], size=(40, 1))
    e = rng.integers(0, 3, 40)
    k = rng.integers(0, tri.shape[0], 40)
    target = tri[k, e] + f * (tri[k, (e + 1) % 3] - tri[k, e])
    o = rng.normal(size=(40, 3))
    o *= 3.0 / np.linalg.norm(o, axis=1, keepdims=True)
    return tri, o, target - o


@pytest.mark.slow
@settings(max_examples=40, deadline=None, derandomize=True)
@given(case=closed_shape_and_rays(), levels=LEVELS)
def test_a_ray_alone_equals_the_ray_in_its_packet(case, levels):
    """Packet invariance, the kernels' promise, for single rays: each ray traced alone
    gives bitwise the same triangle and t as inside the whole packet (here rays grazing
    the silhouette of a closed shape, where rounding decides)."""
    tri, o, d = case
    accel = build_accel(tri, levels=levels)
    whole = closest_hit(accel, o, d)
    for i in range(o.shape[0]):
        one = closest_hit(accel, o[i : i + 1], d[i : i + 1])
        assert one.triangle[0] == whole.triangle[i] and one.t[0] == whole.t[i], i


# ---------------------------------------------------------------- random configurations


def tiny_scene(width: int, height: int, photons: int):
    """A small closed room: white walls, a mirror block, a glass ball, a quad light in
    the ceiling and a point light; 150 triangles."""
    room = aabox([-2.0, -2.0, -2.0], [2.0, 2.0, 2.0], n=2)
    block = aabox([0.3, -2.0, 0.2], [1.2, -0.8, 1.1], n=1)
    ball = uv_sphere((-0.7, -1.3, 0.4), 0.6, 10, 5)
    floor_patch = quad([-1.5, -1.99, -1.5], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 2, 2)
    lights = [
        Light("quad", (20.0, 18.0, 15.0), corner=(-0.5, 1.99, -0.5), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, 0.0, 1.0)),
        Light("point", (8.0, 8.0, 8.0), position=(1.0, 1.0, -1.0)),
    ]
    parts = [
        (room, WHITE),
        (block, Material("chrome", "mirror", reflectance=(0.9, 0.9, 0.9))),
        (ball, Material("glass", "dielectric", ior=1.5, transmittance=(0.95, 0.95, 0.95))),
        (floor_patch, Material("red", "lambertian", albedo=(0.6, 0.1, 0.1))),
    ]
    return make_scene(parts, lights, [0.0, 0.0, -1.9], [0.0, -0.5, 0.0], vfov=70.0, resolution=(width, height),
                      photons=photons)


configs = st.fixed_dictionaries({
    "mode": st.sampled_from(MODES),
    "seed": st.integers(0, 1000),
    "resolution": st.tuples(st.integers(4, 16), st.integers(4, 16)).map(list),
    "bsp": st.fixed_dictionaries({"levels": st.sampled_from([None, 0, 1, 3, 6])}),
    "render": st.fixed_dictionaries({
        "light_samples": st.sampled_from([1, 4, 9]),
        "reflect_depth": st.integers(0, 3),
        "refract_depth": st.integers(0, 3),
        "batch": st.integers(1, 6),
    }),
    "photons": st.fixed_dictionaries({
        "count": st.sampled_from([None, 0, 1, 3, 50, 400]),
        "max_bounces": st.integers(0, 4),
        "russian_roulette": st.booleans(),
        "caustic_fraction": st.sampled_from([0.0, 0.5, 0.95]),
        "levels": st.sampled_from([None, 0, 2, 5]),
    }),
    "estimate": st.fixed_dictionaries({
        "filter": st.sampled_from(FILTERS.names()),
        "radius_fraction": st.sampled_from([0.005, 0.02, 0.1, 0.5]),
        "k": st.integers(1, 8),
        "k_nearest": st.integers(1, 20),
        "cone_k": st.sampled_from([1.0, 1.1, 3.0]),
    }),
})


@pytest.mark.slow
@settings(max_examples=50, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(cfg=configs)
def test_random_configs_render_clean(cfg):
    """Any configuration within the schema (modes, 1/4/9 light samples, depths 0-3,
    4-16 pixels a side, BSP depths, photon counts 0-400 with any bounce limit, roulette
    and caustic share, every filter, k and k_nearest from 1) renders the tiny scene
    without an exception: every planned frame is finite and non-negative, of the
    requested size, passes with depth 0 are left out, and the composite is their sum."""
    w, h = cfg["resolution"]
    scene = tiny_scene(w, h, photons=300)
    res = render_scene(scene, **cfg)
    assert_clean(res)
    for name, rad in res.radiance.items():
        assert rad.shape == (h, w, 3), name
    if cfg["render"]["reflect_depth"] == 0:
        assert "reflect" not in res.plan.run_names
    if cfg["render"]["refract_depth"] == 0:
        assert "refract" not in res.plan.run_names
    if cfg["mode"] == "pmap" and cfg["photons"]["count"] == 0:
        assert "pmap" not in res.plan.run_names
    total = sum(res.radiance[n] for n in res.plan.run_names if n in res.radiance)  # (fgather: work only)
    np.testing.assert_array_equal(res.composite, total)
