"""Stiff photon maps: coincident photons, photons on one plane or one line, 0 to 3
photons, photons exactly on split planes, zero-power lights, radius 0 (and radii whose
square underflows), k = 1 — through ``tlm.kernels.estimate`` and through the renderer's
pmap pass.

Where the estimate has a closed form (a handful of photons at known distances, a
regular grid of known density) we ask for 1e-12 relative (the sums are a few float64
additions); for the stochastic k-voxel filter we average over many queries (distinct
random keys) and ask for the expectation to a stated statistical tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tlm.kernels import estimate as est
from tlm.kernels import kvoxel
from tlm.kernels.bsp import build_point_tree
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.render.frame import Frame, cast
from tlm.render.pmap import pmap_pass
from tlm.scenes.model import Light, Material
from tlm.scenes.shapes import aabox, uv_sphere

from .util import WHITE, assert_clean, make_scene, render_scene

CONE = 1.1
CONE_NORM = 1.0 - 2.0 / (3.0 * CONE)  # the cone filter's area factor
DOWN = np.array([0.0, 0.0, -1.0])  # photons arrive travelling down onto surfaces facing +z
UP = np.array([0.0, 0.0, 1.0])


def estimates(pos, power, inc, pts, nrm, r, levels=None, k=8, k_nearest=50, keys=None):
    tree = build_point_tree(pos, levels)
    out = {
        "disk": est.disk_estimate(pos, power, inc, tree, pts, nrm, r),
        "mvoxel": est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, r, cone_k=CONE),
        "kvoxel": kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, r, k=k, cone_k=CONE, keys=keys),
        "knn": est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=k_nearest, cone_k=CONE),
    }
    for name, e in out.items():
        assert np.isfinite(e.density).all() and (e.density >= 0).all(), name
        for f in ("node_visits", "leaves_visited", "photons_tested", "photons_accepted", "probe_tests"):
            c = getattr(e, f)
            assert c.dtype == np.int64 and (c >= 0).all(), (name, f)
    return out


def tiles(v, n: int) -> np.ndarray:
    return np.tile(np.asarray(v, dtype=np.float64), (n, 1))


# ---------------------------------------------------------------- coincident photons


@pytest.mark.parametrize("where", [(0.0, 0.0, 0.0), (0.25, -0.5, 3.0), (1e6, -2e6, 5e5)])
def test_coincident_photons_analytic(where):
    """64 photons at exactly one point (at the origin, where the k-voxel filter's
    coplanarity tolerance is 0, and 1e6 away): every split of the tree lies on that
    point and leaves an empty child. Queries at distance d in {0, r/2, r} (d as the
    coordinates give it) get 64 p / (pi r^2) from the disk filter (the test is <=) and
    64 p (1 - d/(cone_k r)) / ((1 - 2/(3 cone_k)) pi r^2) from the m-voxel filter, to
    1e-12, with all 64 photons accepted once. k-NN: all neighbours at distance 0 gives
    0, never NaN. k-voxel: the voxel holding the photons is searched or not, so 0 or 64
    photons are accepted, and the query at the point itself (its own first sample)
    always finds them."""
    x0 = np.asarray(where)
    n, p, r = 64, 0.01, 0.2
    pos, power, inc = tiles(x0, n), tiles([p, 2 * p, 3 * p], n), tiles(DOWN, n)
    q = np.array([x0, x0 + [0.5 * r, 0.0, 0.0], x0 + [0.0, r, 0.0]])
    e = estimates(pos, power, inc, q, tiles(UP, 3), r)
    d2 = ((q - x0) ** 2).sum(axis=1)
    assert np.all(d2 <= r * r)
    d = np.sqrt(d2)
    area = math.pi * r * r
    disk = n * power[0] / area
    np.testing.assert_allclose(e["disk"].density, np.stack([disk] * 3), rtol=1e-12)
    w = 1.0 - d / (CONE * r)
    np.testing.assert_allclose(e["mvoxel"].density, w[:, None] * disk / CONE_NORM, rtol=1e-12)
    for name in ("disk", "mvoxel"):
        np.testing.assert_array_equal(e[name].photons_accepted, n)
    assert np.all(e["knn"].density[0] == 0.0)
    many = kvoxel.kvoxel_estimate(pos, power, inc, build_point_tree(pos), np.concatenate([q, tiles(x0, 100)]),
                               tiles(UP, 103), r, k=8, cone_k=CONE, keys=np.arange(103))
    assert np.isfinite(many.density).all()
    assert set(np.unique(many.photons_accepted).tolist()) <= {0, n}
    assert np.all(many.photons_accepted[3:] == n) and np.all(many.density[3:] > 0)


# ---------------------------------------------------------------- one plane, one line


@pytest.mark.slow
@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_photons_on_one_plane_give_the_grid_density(offset):
    """A regular 200 x 200 grid of photons (spacing h = 0.01, power p each) lying exactly
    on the plane z = 0.5 (optionally 1e6 from the origin in x and y): every split along
    z lands on the plane and leaves an empty child. Queries on the plane away from the
    border (r = 8h, ~200 photons in the disk; k-NN with 200 neighbours) give the grid's
    density p / h^2 to 3% with every filter (the lattice-counting error of a disk of
    radius 8h is ~1%), and the disk filter equals the exact count within r."""
    h, p, m = 0.01, 1e-4, 200
    g = (np.arange(m) + 0.5) * h
    xx, yy = np.meshgrid(g, g, indexing="ij")
    pos = np.c_[xx.ravel() + offset, yy.ravel() + offset, np.full(m * m, 0.5)]
    power, inc = tiles([p, p, p], m * m), tiles(DOWN, m * m)
    rng = np.random.default_rng(1)
    q = np.c_[rng.uniform(0.6, 1.4, (60, 2)) + offset, np.full(60, 0.5)]
    r = 8 * h
    e = estimates(pos, power, inc, q, tiles(UP, 60), r, k_nearest=200, keys=np.arange(60))
    truth = p / h**2
    for name, x in e.items():
        np.testing.assert_allclose(x.density[:, 0].mean(), truth, rtol=0.03, err_msg=name)
    d2 = ((pos[None, :, :] - q[:, None, :]) ** 2).sum(axis=2)
    count = (d2 <= r * r).sum(axis=1)
    np.testing.assert_array_equal(e["disk"].photons_accepted, count)
    np.testing.assert_allclose(e["disk"].density[:, 0], count * p / (math.pi * r * r), rtol=1e-12)


@pytest.mark.parametrize("line", ["x-axis", "diagonal"])
def test_photons_on_one_line(line):
    """3000 photons on one line (along x, or along (1, 1, 1)), so the tree splits a
    one-dimensional set in three dimensions (two of every three splits separate
    nothing): queries on and near the line give finite, non-negative estimates; the
    disk and m-voxel filters count exactly the photons within r (brute force) and the
    disk value is that count times p / (pi r^2)."""
    rng = np.random.default_rng(2)
    t = rng.uniform(0.0, 1.0, 3000)
    pos = np.c_[t, np.full(3000, 0.3), np.full(3000, 0.6)] if line == "x-axis" else np.c_[t, t, t]
    p = 1e-3
    power, inc = tiles([p, p, p], 3000), tiles(DOWN, 3000)
    q = np.concatenate([pos[:30], pos[30:60] + rng.normal(0, 0.01, (30, 3))])
    r = 0.02
    e = estimates(pos, power, inc, q, tiles(UP, 60), r, keys=np.arange(60))
    count = (((pos[None, :, :] - q[:, None, :]) ** 2).sum(axis=2) <= r * r).sum(axis=1)
    for name in ("disk", "mvoxel"):
        np.testing.assert_array_equal(e[name].photons_accepted, count, err_msg=name)
    np.testing.assert_allclose(e["disk"].density[:, 0], count * p / (math.pi * r * r), rtol=1e-12)


# ---------------------------------------------------------------- 0, 1, 2, 3 photons


@pytest.mark.parametrize("levels", [None, 0, 4])
def test_zero_photons(levels):
    """An empty map (with the default depth, no split, or 4 forced levels over nothing):
    every filter gives density 0 and tests no photon; nothing is NaN."""
    z = np.zeros((0, 3))
    q = np.random.default_rng(3).uniform(0, 1, (10, 3))
    for name, e in estimates(z, z, z, q, tiles(UP, 10), 0.1, levels=levels).items():
        assert np.all(e.density == 0.0), name
        assert np.all(e.photons_tested == 0) and np.all(e.photons_accepted == 0), name


@pytest.mark.parametrize("levels", [None, 4])
def test_one_photon_analytic(levels):
    """One photon of power p at x0, queries at distance d in {0, r/2, r, 2r}: disk
    p / (pi r^2) within r; m-voxel and k-voxel (one photon: the k-voxel's voxels hold it
    or nothing, and with no split every sample's voxel is the whole disk) the cone value
    p (1 - d/(cone_k r)) / ((1 - 2/(3 cone_k)) pi r^2); k-NN with k = 1: r_k = d, so
    p (1 - 1/cone_k) / ((1 - 2/(3 cone_k)) pi d^2), and 0 at d = 0 (r_k = 0)."""
    x0, p, r = np.array([0.3, 0.4, 0.5]), 0.02, 0.1
    pos, power, inc = x0[None], np.array([[p, p, p]]), DOWN[None]
    d = np.array([0.0, 0.5 * r, r, 2 * r])
    q = x0 + d[:, None] * np.array([0.6, 0.8, 0.0])
    e = estimates(pos, power, inc, q, tiles(UP, 4), r, levels=levels, k_nearest=1)
    inside = d <= r
    np.testing.assert_allclose(e["disk"].density[:, 0], np.where(inside, p / (math.pi * r * r), 0.0), rtol=1e-12)
    cone = np.where(inside, p * (1.0 - d / (CONE * r)) / (CONE_NORM * math.pi * r * r), 0.0)
    np.testing.assert_allclose(e["mvoxel"].density[:, 0], cone, rtol=1e-12)
    if levels is None:  # no split: one voxel covers every disk, k-voxel is m-voxel
        np.testing.assert_allclose(e["kvoxel"].density[:, 0], cone, rtol=1e-12)
    with np.errstate(divide="ignore"):
        knn = np.where(d > 0, p * (1.0 - 1.0 / CONE) / (CONE_NORM * math.pi * d * d), 0.0)
    np.testing.assert_allclose(e["knn"].density[:, 0], knn, rtol=1e-12)


@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("levels", [None, 1, 4])
def test_two_and_three_photons_analytic(n, levels):
    """Two or three photons at known distances 0.02, 0.05, 0.09 from a query, powers
    1, 2, 4 (times 1e-3); 4 forced levels leave most leaves empty. Disk and m-voxel give
    the closed-form sums within r = 0.06 (photons beyond are excluded); k-NN with
    k_nearest = 1, 2 and n uses the k nearest with r_k the k-th distance. A photon
    arriving from behind (the last one, for n = 3 with normal flipped) never counts."""
    dist = np.array([0.02, 0.05, 0.09])[:n]
    pw = np.array([1.0, 2.0, 4.0])[:n] * 1e-3
    x = np.array([0.5, 0.5, 0.5])
    dirs = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.6, 0.0, 0.8]])[:n]
    pos = x + dist[:, None] * dirs
    power, inc = np.repeat(pw[:, None], 3, axis=1), tiles(DOWN, n)
    r = 0.06
    e = estimates(pos, power, inc, x[None], UP[None], r, levels=levels)
    inside = dist <= r
    np.testing.assert_allclose(e["disk"].density[0, 0], pw[inside].sum() / (math.pi * r * r), rtol=1e-12)
    cone = (pw * (1 - dist / (CONE * r)))[inside].sum() / (CONE_NORM * math.pi * r * r)
    np.testing.assert_allclose(e["mvoxel"].density[0, 0], cone, rtol=1e-12)
    for k in sorted({1, 2, n}):
        rk = dist[k - 1]
        want = (pw[:k] * (1 - dist[:k] / (CONE * rk))).sum() / (CONE_NORM * math.pi * rk * rk)
        got = est.knn_estimate(pos, power, inc, x[None], UP[None], k_nearest=k, cone_k=CONE).density[0, 0]
        np.testing.assert_allclose(got, want, rtol=1e-12, err_msg=f"k={k}")
    if n == 3:
        inc_b = inc.copy()
        inc_b[2] = -DOWN  # arrives from below: excluded
        e_b = estimates(pos, power, inc_b, x[None], UP[None], 0.1, levels=levels)
        np.testing.assert_array_equal(e_b["disk"].photons_accepted, 2)


# ---------------------------------------------------------------- split planes


@pytest.mark.parametrize("levels", [1, 3, 6])
def test_photons_exactly_on_split_planes_counted_once(levels):
    """Photons stacked in exactly representable layers x in {0, 0.25, 0.5, 0.75, 1}
    (symmetric, so the centre-of-mass splits fall exactly on layers), queries on the
    split planes and exactly r away from them (r = 0.25, d^2 = r^2 exactly): every
    photon within r is accepted exactly once by the disk and m-voxel filters (the counts
    equal brute force), and the disk density is count * p / (pi r^2)."""
    rng = np.random.default_rng(4)
    layers = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    yz = np.round(rng.uniform(0, 1, (400, 2)) * 8) / 8
    pos = np.c_[np.repeat(layers, 80), yz]
    tree = build_point_tree(pos, levels)
    assert tree.split[0] == 0.5  # the root split lies exactly on the middle layer
    p = 1e-3
    power, inc = tiles([p, p, p], 400), tiles(DOWN, 400)
    q = np.c_[np.repeat([0.25, 0.5, 0.75], 20), np.round(rng.uniform(0, 1, (60, 2)) * 8) / 8]
    r = 0.25
    e = estimates(pos, power, inc, q, tiles(UP, 60), r, levels=levels, keys=np.arange(60))
    count = (((pos[None, :, :] - q[:, None, :]) ** 2).sum(axis=2) <= r * r).sum(axis=1)
    for name in ("disk", "mvoxel"):
        np.testing.assert_array_equal(e[name].photons_accepted, count, err_msg=name)
    np.testing.assert_allclose(e["disk"].density[:, 0], count * p / (math.pi * r * r), rtol=1e-12)


# ---------------------------------------------------------------- radius 0, tiny radii, k = 1


def uniform_plane(n: int, seed: int):
    rng = np.random.default_rng(seed)
    pos = np.c_[rng.uniform(0, 1, (n, 2)), np.full(n, 0.5)]
    return pos, tiles([1.0 / n] * 3, n), tiles(DOWN, n)


def test_radius_zero_gives_zero():
    """Radius exactly 0: every fixed-radius filter returns 0 (no photon is within a
    zero-area disk that counts), never NaN, even for a query exactly on a photon."""
    pos, power, inc = uniform_plane(500, 5)
    q = np.vstack([pos[:5], [[0.5, 0.5, 0.5]]])
    e = estimates(pos, power, inc, q, tiles(UP, 6), 0.0)
    for name in ("disk", "mvoxel", "kvoxel"):
        assert np.all(e[name].density == 0.0), name


@pytest.mark.parametrize(
    "filt", ["disk", "mvoxel", "kvoxel"]
)
@pytest.mark.parametrize("radius", [1e-170, 5e-324])
def test_tiny_radius_never_nan(filt, radius):
    """A positive radius whose square underflows (1e-170, the smallest subnormal) is a
    radius 0 in all but name: no photon lies within it (the query is not on one), so
    the density is 0, finite, never NaN."""
    pos, power, inc = uniform_plane(500, 6)
    q, n = np.array([[0.5, 0.5, 0.5], [0.1234, 0.5678, 0.5]]), tiles(UP, 2)
    tree = build_point_tree(pos)
    with np.errstate(all="ignore"):
        if filt == "disk":
            e = est.disk_estimate(pos, power, inc, tree, q, n, radius)
        elif filt == "mvoxel":
            e = est.mvoxel_estimate(pos, power, inc, tree, q, n, radius)
        else:
            e = kvoxel.kvoxel_estimate(pos, power, inc, tree, q, n, radius)
    assert np.all(e.density == 0.0), e.density


@pytest.mark.slow
def test_k_equals_one():
    """k = 1: the k-voxel filter samples only the voxel holding x; per query it is
    noisy, but unbiased: over 2000 queries of a uniform plane map (density 1) its mean
    is 1 to 3% (the m-voxel mean too). k-NN with one neighbour: finite everywhere and
    the analytic value p (1 - 1/cone_k) / ((1 - 2/(3 cone_k)) pi d^2) of the nearest."""
    pos, power, inc = uniform_plane(20000, 7)
    rng = np.random.default_rng(8)
    q = np.c_[rng.uniform(0.2, 0.8, (2000, 2)), np.full(2000, 0.5)]
    e = estimates(pos, power, inc, q, tiles(UP, 2000), 0.03, k=1, k_nearest=1, keys=np.arange(2000))
    np.testing.assert_allclose(e["kvoxel"].density[:, 0].mean(), 1.0, rtol=0.03)
    np.testing.assert_allclose(e["mvoxel"].density[:, 0].mean(), 1.0, rtol=0.03)
    d = np.sqrt(((pos[None, :, :] - q[:200, None, :]) ** 2).sum(axis=2)).min(axis=1)
    want = power[0, 0] * (1 - 1 / CONE) / (CONE_NORM * math.pi * d * d)
    np.testing.assert_allclose(e["knn"].density[:200, 0], want, rtol=1e-9)


# ---------------------------------------------------------------- through the renderer


def room(lights: list[Light], glass: bool = True, resolution=(12, 12), photons: int = 2000):
    """A closed white room with a glass ball (caustics) and the eye inside."""
    walls = aabox([-2.0, -2.0, -2.0], [2.0, 2.0, 2.0], n=2)
    parts = [(walls, WHITE)]
    if glass:
        parts.append((uv_sphere((0.4, -1.2, 0.5), 0.6, 12, 6),
                      Material("glass", "dielectric", ior=1.5, transmittance=(1.0, 1.0, 1.0))))
    return make_scene(parts, lights, [0.0, 0.0, -1.9], [0.0, -0.5, 0.0], vfov=70.0, resolution=resolution,
                      photons=photons)


POINT = Light("point", (30.0, 30.0, 30.0), position=(0.0, 1.5, 0.0))


@pytest.mark.parametrize("kind", ["point", "quad", "both"])
def test_zero_power_lights_leave_the_pass_out(kind):
    """Every light has zero power (a point light, a quad light, or both): the planner
    leaves the pmap pass out and says why, every frame is black, nothing is NaN."""
    dark = {
        "point": [Light("point", (0.0, 0.0, 0.0), position=(0.0, 1.5, 0.0))],
        "quad": [Light("quad", (0.0, 0.0, 0.0), corner=(-0.5, 1.99, -0.5), edge_u=(1.0, 0.0, 0.0),
                       edge_v=(0.0, 0.0, 1.0))],
    }
    dark["both"] = dark["point"] + dark["quad"]
    res = render_scene(room(dark[kind]), mode="pmap")
    assert_clean(res)
    assert "pmap" not in res.plan.run_names
    assert "no light with power" in res.plan.to_dict()["left_out"]["pmap"]
    assert np.all(res.composite == 0.0)


def test_zero_power_light_next_to_a_real_one():
    """A zero-power quad light next to a real point light: every photon comes from the
    real one (a zero-power light gets none), the map and every frame are finite, and
    the map and the photon frame are exactly those of the scene without the dark light."""
    # behind the eye (a quad light is seen by eye rays, and a dark one shows black)
    dark = Light("quad", (0.0, 0.0, 0.0), corner=(-0.5, -0.5, -1.95), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, 1.0, 0.0))
    both = render_scene(room([POINT, dark]), mode="pmap", photons={"count": 3000})
    alone = render_scene(room([POINT]), mode="pmap", photons={"count": 3000})
    for res in (both, alone):
        assert_clean(res)
        assert res.plan.runs("pmap")
    assert both.photons.photons.emitted == 3000
    np.testing.assert_array_equal(both.photons.photons.position, alone.photons.photons.position)
    np.testing.assert_array_equal(both.radiance["pmap"], alone.radiance["pmap"])


def test_one_channel_light():
    """A light with power in the red channel only: photons carry no green or blue, the
    pmap and ray-cast frames are exactly 0 in green and blue and positive in red."""
    res = render_scene(room([Light("point", (30.0, 0.0, 0.0), position=(0.0, 1.5, 0.0))]), mode="pmap",
                       photons={"count": 3000})
    assert_clean(res)
    for name in ("rcast", "pmap"):
        assert np.all(res.radiance[name][..., 1:] == 0.0), name
        assert res.radiance[name][..., 0].max() > 0.0, name


@pytest.mark.slow
@pytest.mark.parametrize("count", [1, 2, 3, 7])
@pytest.mark.parametrize("filt", ["disk", "mvoxel", "kvoxel", "knn"])
def test_tiny_photon_counts_render(count, filt):
    """1, 2, 3 or 7 photons emitted (0 to a handful stored, photon tree of default depth
    or 4 forced levels): the pmap pass runs and its frame is finite and non-negative."""
    for levels in (None, 4):
        res = render_scene(room([POINT]), mode="pmap", photons={"count": count, "levels": levels},
                           estimate={"filter": filt, "k": 1, "k_nearest": 1})
        assert_clean(res)
        assert res.plan.runs("pmap")
        assert res.photons.photons.emitted == count


def test_zero_power_map_through_the_pmap_pass():
    """``trace_photons`` on a scene whose only light is dark emits nothing; the empty
    map builds, and the pmap pass on it returns a black frame and no gather work."""
    scene = room([Light("point", (0.0, 0.0, 0.0), position=(0.0, 1.5, 0.0))])
    from tlm.config import config_from_dict

    accel = build_accel(scene.triangles)
    trace = trace_photons(scene, accel, 1000)
    assert trace.photons.n == 0 and trace.photons.emitted == 0
    frame = Frame.create(scene, accel, config_from_dict({"mode": "pmap"}))
    g = cast(frame, np.arange(scene.camera.width * scene.camera.height))
    rad, work = pmap_pass(frame, g, trace.photons)
    assert np.all(rad == 0.0) and all(int(v.sum()) == 0 for v in work.values())


@pytest.mark.slow
@pytest.mark.parametrize(
    ("filt", "est_cfg"),
    [
        ("disk", {"radius": 1e-170, "caustic_radius": 1e-170}),
        ("mvoxel", {"radius_fraction": 1e-300, "caustic_radius_fraction": 1e-300}),
        ("kvoxel", {"radius": 1e-170, "caustic_radius": 1e-170}),
        ("knn", {"radius": 1e-170, "caustic_radius": 1e-170}),
    ],
)
def test_tiny_radius_renders_black_not_nan(filt, est_cfg):
    """The smallest radii the config accepts (it requires > 0; both maps'): the photon frame is
    black (no photon within), never NaN, whatever the filter (k-NN ignores the radius
    and stays finite)."""
    with np.errstate(all="ignore"):
        res = render_scene(room([POINT]), mode="pmap", photons={"count": 2000},
                           estimate={"filter": filt, **est_cfg})
    assert np.isfinite(res.radiance["pmap"]).all()
    if filt != "knn":
        assert np.all(res.radiance["pmap"] == 0.0)
