"""Stiff shading: self-intersection of shadow and secondary rays, shadow acne under
grazing light, total internal reflection, IOR 1 and IOR 10, grazing mirrors.

Scenes are built in memory and rendered through ``tlm.experiments.run.render`` (the
loader is bypassed, every pass is the real one). Where the answer is analytic (point
lights, flat surfaces, an independent Snell tracer written here) we ask for 1e-6
relative per pixel: the library computes hit points and directions in float64, so
anything above rounding is a wrong hit or a wrong bounce, not noise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tlm.kernels.shade import refract
from tlm.scenes.model import Light, Material
from tlm.scenes.shapes import aabox, quad, uv_sphere
from tlm.scenes.shapes import grid as triangulate

from .util import WHITE, assert_clean, make_scene, point_light_radiance, render_scene, rotation

ALBEDO = 0.8
PLACEMENTS = {
    # (size scale, offset, rotation axis, angle)
    "unit-axis-aligned": (1.0, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.0),
    "unit-tilted": (1.0, (0.0, 0.0, 0.0), (1.0, 2.0, 0.5), 31.0),
    "tiny-far": (1e-4, (1e3, -2e3, 5e2), (0.3, -1.0, 2.0), 57.0),
    "huge-far": (1e4, (-1e5, 3e4, 2e5), (-2.0, 1.0, 1.0), 13.0),
}


def place(points: np.ndarray, placement: str) -> np.ndarray:
    s, off, axis, ang = PLACEMENTS[placement]
    return (np.asarray(points) * s) @ rotation(axis, ang).T + np.asarray(off)


def unplace(points: np.ndarray, placement: str) -> np.ndarray:
    s, off, axis, ang = PLACEMENTS[placement]
    return ((np.asarray(points) - np.asarray(off)) @ rotation(axis, ang)) / s


def lit_floor(placement: str, light_local, power_local: float, jitter: bool = False, cells: int = 16):
    """A tessellated floor y = 0 over [-2, 2]^2 seen from above, a point light at
    ``light_local``; everything placed by ``placement`` (power scales with size**2)."""
    pts = np.stack(np.meshgrid(np.linspace(-2, 2, cells + 1), np.linspace(-2, 2, cells + 1), indexing="ij"), -1)
    if jitter:  # irregular triangles, still exactly in the plane y = 0
        rng = np.random.default_rng(0)
        pts[1:-1, 1:-1] += rng.uniform(-0.3, 0.3, pts[1:-1, 1:-1].shape) * (4.0 / cells)
    floor = triangulate(np.stack([pts[..., 0], np.zeros(pts.shape[:2]), pts[..., 1]], axis=-1))
    s = PLACEMENTS[placement][0]
    light = Light("point", (power_local * s * s,) * 3, position=tuple(place(np.asarray(light_local), placement)))
    eye = place(np.array([0.3, 3.0, 0.2]), placement)
    target = place(np.array([0.0, 0.0, 0.0]), placement)
    up = place(np.array([0.0, 0.0, 1.0]), placement) - place(np.zeros(3), placement)
    return floor, light, eye, target, up


@pytest.mark.parametrize("placement", list(PLACEMENTS))
def test_plane_lit_from_above_has_exact_direct_light(placement):
    """One tessellated plane lit by a point light above it: every pixel sees the plane
    and has exactly the analytic direct radiance (albedo/pi * P/(4 pi) * cos/d^2, to
    1e-6), no shadow ray finds an occluder (no self-intersection with the triangle it
    leaves or its coplanar neighbours: no black speckles), whatever the size (1e-4 to
    1e4), the tilt and the distance from the origin (up to 2e5)."""
    floor, light, eye, target, up = lit_floor(placement, [0.5, 2.0, -0.3], 100.0)
    scene = make_scene([(place(floor, placement), Material("white", "lambertian", albedo=(ALBEDO,) * 3))],
                       [light], eye, target, up, vfov=50.0, resolution=(24, 24))
    res = render_scene(scene, mode="rcast")
    assert_clean(res)
    g = res.gbuffer
    assert np.all(g.triangle >= 0)
    assert int(res.work["rcast"]["shadow_hits"].sum()) == 0
    assert np.all(res.work["rcast"]["shadow_rays"] == 1)
    pts = unplace(g.origin + g.t[:, None] * g.direction, placement)
    expect = point_light_radiance(pts, np.tile([0.0, 1.0, 0.0], (pts.shape[0], 1)), ALBEDO, [0.5, 2.0, -0.3], 100.0)
    np.testing.assert_allclose(res.radiance["rcast"].reshape(-1, 3), np.repeat(expect[:, None], 3, 1), rtol=1e-6)


def quad_irradiance(points: np.ndarray, normal: np.ndarray, corners: np.ndarray, radiance: float) -> np.ndarray:
    """Lambert's formula: irradiance at ``points`` from a uniform polygon ``corners`` of
    constant ``radiance`` (the polygon entirely above every point's tangent plane)."""
    e = np.zeros(points.shape[0])
    k = corners.shape[0]
    for i in range(k):
        a = corners[i] - points
        b = corners[(i + 1) % k] - points
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        c = np.cross(a, b)
        theta = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
        e += theta * (c @ normal) / np.linalg.norm(c, axis=1)
    return radiance / 2.0 * np.abs(e)


@pytest.mark.parametrize("placement", ["unit-tilted", "tiny-far"])
def test_plane_under_a_quad_light_no_speckles(placement):
    """The same plane under a quad light (8 x 8 stratified shadow rays a point): no
    shadow ray is ever blocked, and each pixel is within 3% of Lambert's analytic
    irradiance (the stratified estimate's own noise), the image mean within 0.5%."""
    s = PLACEMENTS[placement][0]
    corner, eu, ev = np.array([-0.4, 1.5, -0.3]), np.array([0.8, 0.0, 0.0]), np.array([0.0, 0.0, 0.6])
    floor, _, eye, target, up = lit_floor(placement, [0.0, 1.0, 0.0], 1.0)
    c_w = place(corner, placement)
    eu_w, ev_w = (place(corner + e, placement) - c_w for e in (eu, ev))
    power = 50.0
    light = Light("quad", (power * s * s,) * 3, corner=tuple(c_w), edge_u=tuple(eu_w), edge_v=tuple(ev_w))
    assert light.normal @ (rotation(*PLACEMENTS[placement][2:]) @ [0.0, -1.0, 0.0]) > 0.999  # facing down
    scene = make_scene([(place(floor, placement), Material("white", "lambertian", albedo=(ALBEDO,) * 3))],
                       [light], eye, target, up, vfov=50.0, resolution=(20, 20))
    res = render_scene(scene, mode="rcast", render={"light_samples": 64})
    assert_clean(res)
    assert int(res.work["rcast"]["shadow_hits"].sum()) == 0
    assert np.all(res.work["rcast"]["shadow_rays"] == 64)
    g = res.gbuffer
    pts = unplace(g.origin + g.t[:, None] * g.direction, placement)
    le = power / (math.pi * 0.48)
    quad_corners = np.array([corner, corner + eu, corner + eu + ev, corner + ev])
    expect = ALBEDO / math.pi * quad_irradiance(pts, np.array([0.0, 1.0, 0.0]), quad_corners, le)
    got = res.radiance["rcast"].reshape(-1, 3)[:, 0]
    np.testing.assert_allclose(got, expect, rtol=0.03)
    assert abs(got.mean() / expect.mean() - 1.0) < 0.005


@pytest.mark.parametrize("placement", ["unit-tilted", "tiny-far", "huge-far"])
@pytest.mark.parametrize("elevation_deg", [1.0, 0.1, 0.01])
def test_grazing_point_light_no_shadow_acne(placement, elevation_deg):
    """Shadow acne: a point light far off to the side and nearly in the plane of an
    irregularly tessellated floor (1 to 0.01 degrees above it, seen from the floor's
    centre). Every shadow ray runs just above dozens of coplanar triangles; none may
    report them as occluders (the float32 test's noise exceeds the ray's height over
    the plane near its origin; the float64 check must reject it). Radiance equals the
    analytic value to 1e-6 plus the conditioning of the grazing cosine: a facet's normal
    built from vertices rounded at the placement's magnitude is off by
    ulp(|offset|) / facet size radians, a relative error of that over sin(elevation)
    (4e-5 for the 1e-4 scene 2e3 away at 0.01 degrees)."""
    dist = 40.0
    h = dist * math.tan(math.radians(elevation_deg))
    light_local = np.array([dist, h, 5.0])
    floor, light, eye, target, up = lit_floor(placement, light_local, 1e5, jitter=True, cells=24)
    scene = make_scene([(place(floor, placement), Material("white", "lambertian", albedo=(ALBEDO,) * 3))],
                       [light], eye, target, up, vfov=50.0, resolution=(24, 24))
    res = render_scene(scene, mode="rcast")
    assert_clean(res)
    g = res.gbuffer
    assert np.all(g.triangle >= 0)
    hits = int(res.work["rcast"]["shadow_hits"].sum())
    assert hits == 0, f"{hits} pixels in spurious shadow"
    pts = unplace(g.origin + g.t[:, None] * g.direction, placement)
    expect = point_light_radiance(pts, np.tile([0.0, 1.0, 0.0], (pts.shape[0], 1)), ALBEDO, light_local, 1e5)
    assert np.all(expect > 0)
    s = PLACEMENTS[placement][0]
    facet = s * 4.0 / 24.0
    kappa = np.spacing(np.abs(scene.triangles).max()) / facet / math.sin(math.radians(elevation_deg))
    np.testing.assert_allclose(res.radiance["rcast"].reshape(-1, 3)[:, 0], expect, rtol=1e-6 + 4.0 * kappa)


@pytest.mark.parametrize("elevation_deg", [1.0, 0.01, 0.0001])
def test_grazing_light_over_the_edge_of_a_closed_box(elevation_deg):
    """Grazing light over the top face of a closed, tessellated box, seen close to the
    edge the light is behind (3e-4 to 0.03 from it): a shadow ray from the top face
    passes above the edge (by as little as 6e-10); the side faces lie below the top's
    plane and cannot occlude, even though the edge tolerance of the triangle test
    widens them by ~2**-20 of their size. No top-face pixel is in shadow, and the
    radiance is the analytic one to 1e-6."""
    box = aabox([-2.0, -1.0, -2.0], [2.0, 0.0, 2.0], n=12)
    dist = 40.0
    light_local = np.array([dist, dist * math.tan(math.radians(elevation_deg)), 0.0])
    light = Light("point", (1e5,) * 3, position=tuple(light_local))
    scene = make_scene([(box, WHITE)], [light], [1.99, 0.05, 0.0], [1.99, 0.0, 0.0], [0.0, 0.0, 1.0],
                       vfov=40.0, resolution=(32, 32))
    res = render_scene(scene, mode="rcast")
    assert_clean(res)
    g = res.gbuffer
    p = g.origin + g.t[:, None] * g.direction
    top = (g.triangle >= 0) & (np.abs(p[:, 1]) < 1e-12)
    assert top.sum() > 700 and (2.0 - p[top, 0]).min() < 1e-3
    shadowed = res.work["rcast"]["shadow_hits"].reshape(-1)[top]
    assert int(shadowed.sum()) == 0, f"{int(shadowed.sum())} top-face pixels in spurious shadow"
    expect = point_light_radiance(p[top], np.tile([0.0, 1.0, 0.0], (int(top.sum()), 1)), ALBEDO, light_local, 1e5)
    np.testing.assert_allclose(res.radiance["rcast"].reshape(-1, 3)[top, 0], expect, rtol=1e-6)


# ---------------------------------------------------------------- total internal reflection


def snell(d: np.ndarray, n_out: np.ndarray, ior: float) -> tuple[np.ndarray, np.ndarray]:
    """Independent Snell refraction (unit d, outward unit normal): the direction, or the
    mirror direction where the ray is totally reflected; and the TIR mask."""
    cos = np.sum(d * n_out, axis=1)
    entering = cos < 0
    eta = np.where(entering, 1.0 / ior, ior)
    n = np.where(entering[:, None], n_out, -n_out)
    ci = -np.sum(d * n, axis=1)
    sin_t2 = eta**2 * (1.0 - ci**2)
    tir = sin_t2 > 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin_t2))
    t = eta[:, None] * d + (eta * ci - ct)[:, None] * n
    r = d + 2.0 * ci[:, None] * n
    out = np.where(tir[:, None], r, t)
    return out / np.linalg.norm(out, axis=1, keepdims=True), tir


def test_refract_kernel_total_internal_reflection_and_snell():
    """``refract``: leaving glass (IOR 1.5 and 10) beyond the critical angle is total
    internal reflection (the mirror direction, flagged), below it Snell's law holds
    (n1 sin1 = n2 sin2 to 1e-12); at grazing incidence (89.999 deg) nothing is NaN;
    every direction is unit."""
    ang = np.radians(np.r_[np.linspace(0.0, 89.0, 90), 89.9, 89.999])
    for ior in (1.5, 10.0):
        crit = math.degrees(math.asin(1.0 / ior))
        d = np.c_[np.sin(ang), np.cos(ang), np.zeros_like(ang)]  # inside, towards the face y = top
        n_out = np.tile([0.0, 1.0, 0.0], (ang.shape[0], 1))
        out, tir = refract(d, n_out, np.full(ang.shape[0], ior))
        assert np.all(np.isfinite(out))
        np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, rtol=1e-12)
        np.testing.assert_array_equal(tir, np.degrees(ang) > crit)
        np.testing.assert_allclose(out[tir], d[tir] * [1.0, -1.0, 1.0], atol=1e-12)
        ok = ~tir
        np.testing.assert_allclose(ior * d[ok, 0], out[ok, 0], atol=1e-12)  # tangential: n1 sin1 = n2 sin2
        # entering from air: never TIR, bends towards the normal
        out_in, tir_in = refract(-d, n_out, np.full(ang.shape[0], ior))
        assert not tir_in.any() and np.all(np.isfinite(out_in))
        np.testing.assert_allclose(out_in[:, 0] * ior, -d[:, 0], atol=1e-12)
        ref, ref_tir = snell(d, n_out, ior)
        np.testing.assert_array_equal(ref_tir, tir)
        np.testing.assert_allclose(out, ref, atol=1e-12)


def light_guide(transmittance: float, ior: float = 1.5):
    """A glass bar x in [0, 10], |y|, |z| <= 0.5, the eye inside it near x = 0.5 looking
    along +x (vfov 40): every eye ray is totally reflected by the long faces 0 to 8
    times and leaves through the end face x = 10 onto a white wall x = 12 lit by a
    point light that the bar cannot shadow."""
    bar = aabox([0.0, -0.5, -0.5], [10.0, 0.5, 0.5], n=3)
    wall = quad([12.0, -30.0, -30.0], [0.0, 0.0, 60.0], [0.0, 60.0, 0.0], 2, 2)  # normal -x
    glass = Material("glass", "dielectric", ior=ior, transmittance=(transmittance,) * 3)
    light = Light("point", (400.0,) * 3, position=(11.0, 3.0, 1.0))
    return make_scene([(bar, glass), (wall, WHITE)], [light], [0.5, 0.01, 0.02], [1.5, 0.01, 0.02],
                      vfov=40.0, resolution=(20, 20))


def guide_paths(o: np.ndarray, d: np.ndarray, ior: float):
    """Per ray: TIR bounces in the bar, the wall point and the final direction."""
    lo, hi = np.array([0.0, -0.5, -0.5]), np.array([10.0, 0.5, 0.5])
    n = o.shape[0]
    bounces = np.zeros(n, dtype=int)
    wall_point = np.zeros((n, 3))
    out_dir = np.zeros((n, 3))
    for i in range(n):
        p, v = o[i].copy(), d[i].copy()
        while True:
            with np.errstate(divide="ignore"):
                t = np.where(v > 0, (hi - p) / v, np.where(v < 0, (lo - p) / v, np.inf))
            k = int(np.argmin(t))
            p = p + t[k] * v
            if k == 0 and v[0] > 0:  # the end face x = 10
                w, tir = snell(v[None], np.array([[1.0, 0.0, 0.0]]), ior)
                assert not tir[0]
                v = w[0]
                break
            assert abs(v[k]) < math.sqrt(1.0 - 1.0 / ior**2), "expected total internal reflection"
            v[k] = -v[k]
            bounces[i] += 1
        wall_point[i] = p + (12.0 - p[0]) / v[0] * v
        out_dir[i] = v
    return bounces, wall_point, out_dir


@pytest.mark.parametrize("ior", [1.5, 1.33])
def test_total_internal_reflection_keeps_energy(ior):
    """Light guide: eye rays inside a glass bar are totally reflected 0 to ~8 times and
    leave through the end face. The Refract frame is T (one refraction out) times the
    analytic direct radiance where an independent Snell tracer lands on the wall, to
    1e-6, whatever the number of reflections: TIR is lossless. T = 0.5 gives exactly
    half of T = 1. The specular bounces counted are the reflections plus one."""
    # Snell alone (render.fresnel false): the exact Fresnel split is tested on its own below
    full = render_scene(light_guide(1.0, ior), mode="refract", render={"refract_depth": 24, "fresnel": False})
    half = render_scene(light_guide(0.5, ior), mode="refract", render={"refract_depth": 24, "fresnel": False})
    for res in (full, half):
        assert_clean(res)
        assert res.plan.run_names == ["rcast", "refract"]
    g = full.gbuffer
    bounces, wall_point, _ = guide_paths(g.origin, g.direction, ior)
    assert bounces.max() >= 4 and (bounces == 0).any()
    expect = point_light_radiance(wall_point, np.tile([-1.0, 0.0, 0.0], (wall_point.shape[0], 1)), ALBEDO,
                                  [11.0, 3.0, 1.0], 400.0)
    got = full.radiance["refract"].reshape(-1, 3)[:, 0]
    np.testing.assert_allclose(got, expect, rtol=1e-6)
    np.testing.assert_allclose(half.radiance["refract"], 0.5 * full.radiance["refract"], rtol=1e-12)
    np.testing.assert_array_equal(full.work["refract"]["specular_bounces"].reshape(-1), bounces + 1)
    assert np.all(full.radiance["rcast"] == 0.0)


def test_trapped_rays_stay_black():
    """Eye rays inside a glass slab heading at 60-80 degrees to its faces are totally
    reflected at every face and never leave: the Refract frame is black (no light
    seen, no NaN), each such path stops after exactly ``refract_depth`` bounces, and each
    bounce traced a secondary ray that hit the slab again."""
    slab = aabox([-50.0, -0.5, -50.0], [50.0, 0.5, 50.0], n=2)
    glass = Material("glass", "dielectric", ior=1.5, transmittance=(1.0, 1.0, 1.0))
    light = Light("point", (100.0,) * 3, position=(0.0, 5.0, 0.0))
    floor = quad([-60.0, -3.0, -60.0], [0.0, 0.0, 120.0], [120.0, 0.0, 0.0], 1, 1)
    # looking along +z and 20 degrees up: incidence on the faces y = +-0.5 is 70 degrees,
    # on the far face z = 50 (from 10 units away) below critical only for no pixel
    dz = np.array([0.0, math.sin(math.radians(20.0)), math.cos(math.radians(20.0))])
    scene = make_scene([(slab, glass), (floor, WHITE)], [light], [0.0, 0.0, 0.0], dz, vfov=10.0,
                       resolution=(8, 8))
    res = render_scene(scene, mode="refract", render={"refract_depth": 7, "fresnel": False})
    assert_clean(res)
    w = res.work["refract"]
    assert np.all(w["specular_bounces"] == 7)
    assert np.all(w["secondary_rays"] == 7)
    assert np.all(res.radiance["refract"] == 0.0)


# ---------------------------------------------------------------- IOR 1 and IOR 10


def slab_scene(ior: float | None, transmittance: float = 1.0, shape: str = "slab"):
    """A white wall z = 2 lit by a point light at (0.3, 0.2, 1.2), seen from (0, 0, -3)
    through a glass slab z in [0, 0.2] (or a glass sphere), or through nothing."""
    wall = quad([-10.0, -10.0, 2.0], [0.0, 20.0, 0.0], [20.0, 0.0, 0.0], 4, 4)  # normal -z
    parts = [(wall, WHITE)]
    if ior is not None:
        glass = Material("glass", "dielectric", ior=ior, transmittance=(transmittance,) * 3)
        obj = aabox([-4.0, -4.0, 0.0], [4.0, 4.0, 0.2], n=3) if shape == "slab" else \
            uv_sphere((0.05, -0.03, 0.0), 0.6, 24, 12)
        parts.append((obj, glass))
    light = Light("point", (50.0,) * 3, position=(0.3, 0.2, 1.2))
    return make_scene(parts, [light], [0.0, 0.0, -3.0], [0.0, 0.0, 0.0], vfov=30.0, resolution=(24, 24))


@pytest.mark.parametrize("shape", ["slab", "sphere"])
def test_ior_one_object_vanishes(shape):
    """A dielectric of IOR 1.0 and transmittance 1 (a slab, a tessellated sphere) does
    not bend or dim anything: the composite through it equals the ray-cast frame of the
    scene without it, pixel by pixel, to 1e-6 (the light sits behind the object, so no
    shadow ray crosses it)."""
    without = render_scene(slab_scene(None), mode="refract")
    with_obj = render_scene(slab_scene(1.0, shape=shape), mode="refract")
    assert_clean(with_obj)
    seen = with_obj.gbuffer.triangle >= 0
    sees_glass = with_obj.frame.kind[np.maximum(with_obj.gbuffer.triangle, 0)] == 2
    assert sees_glass.sum() >= (0.95 * seen.size if shape == "slab" else 100)
    assert int(with_obj.work["refract"]["shadow_hits"].sum()) == 0
    np.testing.assert_allclose(with_obj.composite, without.radiance["rcast"], rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("ior", [1.0, 1.5, 10.0])
def test_slab_shifts_rays_by_snell(ior):
    """Through a parallel glass slab (T = 0.9) rays leave parallel to how they came in,
    shifted sideways by Snell's law (a lot at IOR 10). The Refract frame equals
    T**2 times the analytic direct radiance at the point an independent tracer reaches,
    to 1e-6; exactly two refractions per pixel."""
    res = render_scene(slab_scene(ior, 0.9), mode="refract", render={"fresnel": False})  # Snell alone
    assert_clean(res)
    g = res.gbuffer
    assert np.all(res.frame.kind[g.triangle] == 2)
    o, d = g.origin, g.direction
    p1 = o + (-o[:, 2] / d[:, 2])[:, None] * d
    d2, tir = snell(d, np.tile([0.0, 0.0, -1.0], (d.shape[0], 1)), ior)
    assert not tir.any()
    p2 = p1 + ((0.2 - p1[:, 2]) / d2[:, 2])[:, None] * d2
    d3, tir = snell(d2, np.tile([0.0, 0.0, 1.0], (d.shape[0], 1)), ior)
    assert not tir.any()
    np.testing.assert_allclose(d3, d, atol=1e-12)
    p3 = p2 + ((2.0 - p2[:, 2]) / d3[:, 2])[:, None] * d3
    expect = 0.81 * point_light_radiance(p3, np.tile([0.0, 0.0, -1.0], (p3.shape[0], 1)), ALBEDO,
                                         [0.3, 0.2, 1.2], 50.0)
    np.testing.assert_allclose(res.radiance["refract"].reshape(-1, 3)[:, 0], expect, rtol=1e-6)
    assert np.all(res.work["refract"]["specular_bounces"] == 2)


@pytest.mark.parametrize("ior", [1.5, 2.4])
def test_slab_with_fresnel(ior):
    """The same slab with the exact Fresnel split (the default): each pixel's light is
    T**2 (1 - F)**2 times the analytic radiance at the wall point, F the unpolarised
    Fresnel reflectance at the pixel's angle (the same on both faces of a parallel slab),
    plus what the internal reflections carry (weights F**2 and below: within
    1e-3 + 2 F**2 of it, relative; Snell alone would be (1 - F)**-2 ~ 8% above).
    Every pixel splits: a front reflection and a refraction."""
    res = render_scene(slab_scene(ior, 0.9), mode="refract")
    assert_clean(res)
    g = res.gbuffer
    o, d = g.origin, g.direction
    cos_i = np.abs(d[:, 2])
    eta = 1.0 / ior
    cos_t = np.sqrt(1.0 - eta * eta * (1.0 - cos_i * cos_i))
    rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    f = 0.5 * (rs * rs + rp * rp)
    assert np.all((f > 0.03) & (f < 0.2))
    p1 = o + (-o[:, 2] / d[:, 2])[:, None] * d
    d2, _ = snell(d, np.tile([0.0, 0.0, -1.0], (d.shape[0], 1)), ior)
    p2 = p1 + ((0.2 - p1[:, 2]) / d2[:, 2])[:, None] * d2
    d3, _ = snell(d2, np.tile([0.0, 0.0, 1.0], (d.shape[0], 1)), ior)
    p3 = p2 + ((2.0 - p2[:, 2]) / d3[:, 2])[:, None] * d3
    direct = point_light_radiance(p3, np.tile([0.0, 0.0, -1.0], (p3.shape[0], 1)), ALBEDO, [0.3, 0.2, 1.2], 50.0)
    first = 0.81 * (1.0 - f) ** 2 * direct
    got = res.radiance["refract"].reshape(-1, 3)[:, 0]
    assert np.all(got >= first * (1 - 1e-9))  # the internal reflections only add
    np.testing.assert_allclose(got, first, rtol=1e-3 + 2.0 * float(f.max()) ** 2)
    snell_only = render_scene(slab_scene(ior, 0.9), mode="refract", render={"fresnel": False})
    assert np.all(res.work["refract"]["secondary_rays"] > snell_only.work["refract"]["secondary_rays"])


def test_ior_ten_sphere_renders_finite():
    """A tessellated glass sphere of IOR 10 (critical angle 5.7 degrees: most internal
    paths are totally reflected many times between facets) renders without NaN, never
    brighter than the brightest directly lit point (TIR lossless, refraction T <= 1),
    and every eye path that enters it ends within ``refract_depth`` bounces."""
    res = render_scene(slab_scene(10.0, 1.0, shape="sphere"), mode="refract",
                       render={"refract_depth": 12, "fresnel": False})
    assert_clean(res)
    w = res.work["refract"]
    assert w["specular_bounces"].max() <= 12
    assert (w["specular_bounces"] > 2).any()
    wall = slab_scene(None)
    direct = render_scene(wall, mode="rcast").radiance["rcast"]
    assert res.radiance["refract"].max() <= direct.max() * (1 + 1e-9) + 1e-12


# ---------------------------------------------------------------- grazing mirror


@pytest.mark.parametrize("placement", ["unit-axis-aligned", "unit-tilted", "huge-far"])
def test_grazing_incidence_on_a_mirror(placement):
    """A tessellated mirror floor seen at grazing incidence (0.02 to 2 degrees): each eye
    ray that meets it reflects once (never re-hits the mirror's coplanar triangles) and
    shows reflectance times the analytic direct radiance at the point of the lit back
    wall that the mirrored ray reaches, to 1e-6. No mirror pixel is black."""
    h = 0.02
    mirror = quad([-5.0, 0.0, 0.0], [0.0, 0.0, 50.0], [10.0, 0.0, 0.0], 8, 40)
    wall = quad([-20.0, -1.0, 50.0], [0.0, 20.0, 0.0], [40.0, 0.0, 0.0], 2, 2)  # normal -z
    light_local = np.array([0.5, 4.0, 40.0])
    s = PLACEMENTS[placement][0]
    chrome = Material("chrome", "mirror", reflectance=(0.9, 0.9, 0.9))
    up = place(np.array([0.0, 1.0, 0.0]), placement) - place(np.zeros(3), placement)
    scene = make_scene(
        [(place(mirror, placement), chrome), (place(wall, placement), WHITE)],
        [Light("point", (1e4 * s * s,) * 3, position=tuple(place(light_local, placement)))],
        place(np.array([0.0, h, 0.0]), placement), place(np.array([0.0, h - 0.6, 50.0]), placement), up,
        vfov=2.0, resolution=(16, 32),
    )
    res = render_scene(scene, mode="reflect")
    assert_clean(res)
    g = res.gbuffer
    on_mirror = res.frame.kind[np.maximum(g.triangle, 0)] == 1
    assert on_mirror.sum() > 200
    w = res.work["reflect"]
    assert np.all(w["specular_bounces"].reshape(-1)[on_mirror] == 1)
    o, d = unplace(g.origin[on_mirror], placement), unplace(g.origin[on_mirror] + g.direction[on_mirror],
                                                            placement)
    d = d - o
    assert np.all(d[:, 1] < 0)
    grazing = np.degrees(np.arcsin(-d[:, 1] / np.linalg.norm(d, axis=1)))
    assert grazing.min() < 0.1
    p = o + (-o[:, 1] / d[:, 1])[:, None] * d
    r = d * [1.0, -1.0, 1.0]
    q = p + ((50.0 - p[:, 2]) / r[:, 2])[:, None] * r
    expect = 0.9 * point_light_radiance(q, np.tile([0.0, 0.0, -1.0], (q.shape[0], 1)), ALBEDO, light_local, 1e4)
    got = res.radiance["reflect"].reshape(-1, 3)[on_mirror, 0]
    assert np.all(got > 0), f"{(got == 0).sum()} black mirror pixels"
    np.testing.assert_allclose(got, expect, rtol=1e-6)
