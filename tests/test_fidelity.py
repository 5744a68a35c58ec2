"""The rendering a researcher can trust (issue 17): Fresnel, shadows through
index-matched glass, shading normals, jittered eye samples, caustic and indirect maps.

The comparison against an independent renderer (Mitsuba 3) is in tests/test_oracle*.py;
the analytic glass cases in tests/extreme/test_shading.py.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tests.extreme.util import WHITE, make_scene, point_light_radiance, render_scene
from tlm.kernels.camera import primary_rays, subpixel_offsets
from tlm.kernels.photons import trace_photons
from tlm.kernels.shade import direct_light, fresnel_dielectric, scatter_specular
from tlm.kernels.traverse import build_accel
from tlm.scenes.loader import load_scene
from tlm.scenes.model import KIND, Light, Material
from tlm.scenes.normals import crease_normals, interpolate
from tlm.scenes.shapes import aabox, quad, uv_sphere

# ---------------------------------------------------------------- Fresnel


def test_fresnel_limits():
    cos = np.array([1.0, 1.0, 0.5, 0.0])
    f, cos_t = fresnel_dielectric(cos, np.array([1.0, 1 / 1.5, 1.0, 1 / 1.5]))
    assert f[0] == 0.0 and f[2] == 0.0  # index matched: nothing reflects, exactly
    assert f[1] == pytest.approx(0.04)  # ((n - 1) / (n + 1))**2 at normal incidence
    assert f[3] == pytest.approx(1.0)  # grazing
    f, cos_t = fresnel_dielectric(np.array([0.1, 0.9]), np.array([1.5, 1.5]))  # leaving glass
    assert f[0] == 1.0 and cos_t[0] == 0.0  # beyond the critical angle: total reflection
    assert 0.0 < f[1] < 0.1


def test_fresnel_is_reciprocal_and_bounded():
    """F is the same entering at theta_i as leaving at the matching theta_t (Stokes)."""
    rng = np.random.default_rng(0)
    cos_i = rng.uniform(0.0, 1.0, 1000)
    n = rng.uniform(1.01, 3.0, 1000)
    f_in, cos_t = fresnel_dielectric(cos_i, 1.0 / n)
    f_out, back = fresnel_dielectric(cos_t, n)
    np.testing.assert_allclose(f_in, f_out, atol=1e-12)
    np.testing.assert_allclose(back, cos_i, atol=1e-9)
    assert np.all((f_in >= 0) & (f_in <= 1))


def test_scatter_uses_the_shading_normal_but_never_crosses_the_surface():
    d = np.array([[0.0, -1.0, 0.0], [0.999, -0.0447, 0.0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    geo = np.array([[0.0, 1.0, 0.0]] * 2)
    tilt = np.array([[0.3, 1.0, 0.0], [-0.5, 1.0, 0.0]])
    tilt /= np.linalg.norm(tilt, axis=1, keepdims=True)
    refl, refr, _ = scatter_specular(d, tilt, geo, np.array([1.5, 1.5]))
    assert np.all(np.sum(refl * geo, axis=1) > 0)  # reflections leave on the arriving side
    assert np.all(np.sum(refr * geo, axis=1) < 0)  # refractions cross
    # the first ray is bent by the tilted shading normal, not mirrored straight back
    assert abs(refl[0, 0]) > 0.1


# ---------------------------------------------------------------- index-matched glass


def test_shadow_rays_pass_index_matched_glass_and_not_real_glass():
    """A lit floor under a glass slab: IOR 1 lets the light through times its
    transmittance; IOR 1.5 blocks the shadow ray (that light is a caustic, the photon map's)."""
    floor = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0], 2, 2)  # normal +y
    slab = aabox([-1.0, 1.0, -1.0], [1.0, 1.2, 1.0], n=1)
    light = Light("point", (30.0,) * 3, position=(0.0, 3.0, 0.0))
    out = {}
    for name, ior in (("none", None), ("matched", 1.0), ("glass", 1.5)):
        parts = [(floor, WHITE)]
        if ior is not None:
            parts.append((slab, Material("g", "dielectric", ior=ior, transmittance=(0.5, 0.25, 1.0))))
        scene = make_scene(parts, [light], [0.0, 4.0, -0.01], [0.0, 0.0, 0.0])
        accel = build_accel(scene.triangles)
        table = scene.material_table()
        matched = (table["kind"] == KIND["dielectric"]) & (table["ior"] == 1.0)
        transparent = np.where(matched[:, None], table["transmittance"], 0.0) if matched.any() else None
        pts = np.array([[0.1, 0.0, 0.2], [-0.3, 0.0, 0.1]])
        nrm = np.array([[0.0, 1.0, 0.0]] * 2)
        tri = np.zeros(2, dtype=np.int64)
        rad, work, _ = direct_light(accel, scene.lights, pts, nrm, tri, np.full((2, 3), 0.8), np.arange(2), 0, 1,
                                    1e-6, transparent=transparent)
        out[name] = (rad, work)
    expect = point_light_radiance(pts, nrm, 0.8, [0.0, 3.0, 0.0], 30.0)
    np.testing.assert_allclose(out["none"][0][:, 0], expect, rtol=1e-12)
    np.testing.assert_allclose(out["matched"][0], expect[:, None] * [[0.5, 0.25, 1.0]] ** np.array(2), rtol=1e-12)
    assert np.all(out["glass"][0] == 0.0)
    # the matched slab's shadow rays are traced segment by segment: 3 per point (two faces crossed)
    assert np.all(out["matched"][1]["shadow_rays"] == 3) and np.all(out["glass"][1]["shadow_rays"] == 1)


def _without_part(scene, part_name):
    keep = scene.part != scene.part_names.index(part_name)
    return replace(scene, triangles=scene.triangles[keep], material_index=scene.material_index[keep],
                   part=scene.part[keep], normals=scene.normals[keep])


def _with_material(scene, name, material):
    mats = tuple(material if m.name == name else m for m in scene.materials)
    return replace(scene, materials=mats)


@pytest.mark.slow
def test_index_matched_glass_is_indistinguishable_from_no_object():
    """Cornell with its glass sphere at IOR 1 and transmittance 1 against Cornell without
    the sphere, whole composite with the photon map: their difference is the two images'
    noise (the glass changes which random numbers a path draws, nothing else). The
    difference's RMS is compared with the noise of the empty box rendered with two seeds;
    the old opaque shadow rays made it 26 sigma (302 pixels)."""
    base = load_scene("cornell", resolution=[40, 40])
    empty = _without_part(base, "glass_object")
    matched = _with_material(base, "glass", Material("glass", "dielectric", ior=1.0, transmittance=(1.0, 1.0, 1.0)))
    settings = {"mode": "pmap", "photons": {"count": 20000}, "render": {"spp": 4, "light_samples": 4}}
    a = render_scene(empty, seed=1, **settings).composite
    b = render_scene(empty, seed=2, **settings).composite
    m = render_scene(matched, seed=3, **settings).composite
    noise = np.sqrt(np.mean((a - b) ** 2))
    diff = np.sqrt(np.mean((m - a) ** 2))
    assert diff < 1.3 * noise, (diff, noise)
    # and the means agree: no darkening where the opaque sphere's shadow was
    assert abs(m.mean() / a.mean() - 1.0) < 0.02
    opaque = _with_material(base, "glass", Material("glass", "lambertian", albedo=(0.0, 0.0, 0.0)))
    o = render_scene(opaque, seed=3, **settings).composite
    assert np.sqrt(np.mean((o - a) ** 2)) > 1.5 * noise  # the test sees an object that is there
    assert o.mean() / a.mean() < 0.95


@pytest.mark.slow
def test_photons_crossing_index_matched_glass_stay_direct():
    """Only index-matched glass between the light and the walls: no caustic is stored (a
    photon that crossed it is still direct light, the ray-cast frame's)."""
    base = load_scene("cornell", resolution=[8, 8])
    scene = _with_material(base, "glass", Material("glass", "dielectric", ior=1.0, transmittance=(1.0, 1.0, 1.0)))
    scene = _with_material(scene, "chrome", Material("chrome", "lambertian", albedo=(0.5, 0.5, 0.5)))
    traced = trace_photons(scene, build_accel(scene.triangles), 4000, seed=3)
    assert traced.photons.caustic_map.n == 0 and traced.photons.indirect_map.n > 0


@pytest.mark.slow
def test_aimed_caustic_photons_carry_the_unaimed_caustic_power():
    """The caustic group of a quad light is aimed at the specular objects with weight
    cos * solid angle / pi: the caustic map's power is the one photons emitted over the
    whole hemisphere deposit as caustics (caustic_fraction 0: no aiming), within noise,
    and it holds many more photons."""
    scene = load_scene("cornell", resolution=[8, 8])
    accel = build_accel(scene.triangles)
    aimed = [trace_photons(scene, accel, 40000, seed=s, caustic_fraction=0.5).photons.caustic_map for s in (1, 2)]
    plain = [trace_photons(scene, accel, 40000, seed=s, caustic_fraction=0.0).photons.caustic_map for s in (1, 2)]
    pa = np.array([m.power.sum() for m in aimed])
    pp = np.array([m.power.sum() for m in plain])
    spread = abs(pa[0] - pa[1]) + abs(pp[0] - pp[1])
    assert abs(pa.mean() - pp.mean()) < 2.0 * spread + 0.03 * pp.mean(), (pa, pp)
    assert min(m.n for m in aimed) > max(m.n for m in plain)  # half the photons in the group, more caustics


# ---------------------------------------------------------------- shading normals


def test_crease_normals_smooth_a_sphere_and_keep_a_box_sharp():
    sphere = uv_sphere((1.0, 2.0, 3.0), 2.0, 36, 18)
    n = crease_normals(sphere, None, 30.0)
    exact = (sphere - np.array([1.0, 2.0, 3.0])) / 2.0
    err = np.degrees(np.arccos(np.clip(np.sum(n * exact, axis=2), -1, 1)))
    face = np.cross(sphere[:, 1] - sphere[:, 0], sphere[:, 2] - sphere[:, 0])
    ok = np.linalg.norm(face, axis=1) > 0
    face = face[ok] / np.linalg.norm(face[ok], axis=1, keepdims=True)
    facet_err = np.degrees(np.arccos(np.clip(np.einsum("ncj,nj->nc", exact[ok], face), -1, 1)))
    assert err[ok].max() < 1.0 < facet_err.max()  # the corner normals are the sphere's, the facets' are not
    box = aabox([0, 0, 0], [1, 1, 1], n=2)
    nb = crease_normals(box, None, 30.0)
    fb = np.cross(box[:, 1] - box[:, 0], box[:, 2] - box[:, 0])
    fb /= np.linalg.norm(fb, axis=1, keepdims=True)
    np.testing.assert_allclose(nb, np.repeat(fb[:, None], 3, axis=1), atol=1e-12)  # 90 degrees: sharp
    flat = crease_normals(sphere, None, 0.0)
    np.testing.assert_allclose(flat[ok][:, 0], face, atol=1e-12)


def test_parts_never_smooth_into_each_other():
    a = quad([0, 0, 0], [1, 0, 0], [0, 0, 1], 1, 1)  # the plane y = 0
    b = quad([0, 0, 0], [0, 0, 1], [-1, -0.2, 0], 1, 1)  # shares the edge x = y = 0 at 11 degrees
    na = np.cross(a[0, 1] - a[0, 0], a[0, 2] - a[0, 0])
    nb = np.cross(b[0, 1] - b[0, 0], b[0, 2] - b[0, 0])
    if na @ nb < 0:  # wind b like a
        b = b[:, ::-1]
    tri = np.concatenate([a, b])
    one = crease_normals(tri, np.zeros(4, dtype=np.int64), 60.0)
    two = crease_normals(tri, np.array([0, 0, 1, 1]), 60.0)
    assert not np.allclose(one, two)
    for p in range(4):
        face = np.cross(tri[p, 1] - tri[p, 0], tri[p, 2] - tri[p, 0])
        np.testing.assert_allclose(two[p], np.repeat((face / np.linalg.norm(face))[None], 3, 0), atol=1e-12)


def test_interpolated_normals_vary_across_a_facet_and_face_its_side():
    sphere = uv_sphere((0.0, 0.0, 0.0), 1.0, 12, 6)
    n = crease_normals(sphere, None, 40.0)
    geo = np.cross(sphere[:, 1] - sphere[:, 0], sphere[:, 2] - sphere[:, 0])
    tri = np.flatnonzero(np.linalg.norm(geo, axis=1) > 0)[:20]
    geo = geo[tri] / np.linalg.norm(geo[tri], axis=1, keepdims=True)
    a = interpolate(n, tri, np.full(20, 0.1), np.full(20, 0.1), geo)
    b = interpolate(n, tri, np.full(20, 0.6), np.full(20, 0.3), geo)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    assert np.all(np.sum(a * geo, axis=1) > 0) and np.all(np.sum(b * geo, axis=1) > 0)
    assert np.all(np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1, 1))) > 1.0)


def test_scene_normals_from_an_obj_file_and_the_crease_angle_key(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0.6 0 0.8\nvn 0 0.6 0.8\n"
                                      "f 1//1 2//2 3//3\n")
    light = "lights: [{type: point, position: [0, 0, 3], power: [1, 1, 1]}]\n"
    cam = "camera: {eye: [0.2, 0.2, 3], target: [0.2, 0.2, 0], up: [0, 1, 0], vfov: 40}\nresolution: [4, 4]\n"
    mats = "materials: {w: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: w\n"
    (tmp_path / "s.yaml").write_text("geometry: {mesh: tri.obj}\n" + mats + light + cam)
    scene = load_scene(str(tmp_path / "s.yaml"))
    np.testing.assert_allclose(scene.normals[0], [[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]])
    assert scene.extra["normals"] == "file"
    (tmp_path / "flat.yaml").write_text("geometry: {mesh: tri.obj}\ncrease_angle: 0\n" + mats + light + cam)
    flat = load_scene(str(tmp_path / "flat.yaml"))
    np.testing.assert_allclose(flat.normals[0], [[0, 0, 1]] * 3)
    assert flat.extra["normals"] == "crease"


def test_smooth_normals_shade_a_tessellated_sphere_smoothly():
    """A coarse Lambertian sphere under a point light: with crease normals the shading
    across the facet edges has far smaller jumps than flat shading's."""
    ball = uv_sphere((0.0, 0.0, 0.0), 1.0, 16, 8)
    light = Light("point", (40.0,) * 3, position=(2.0, 3.0, -4.0))
    jumps = {}
    for crease in (0.0, 45.0):
        scene = make_scene([(ball, WHITE)], [light], [0.0, 0.0, -4.0], [0.0, 0.0, 0.0], vfov=35.0,
                           resolution=(48, 48), crease_angle=crease)
        img = render_scene(scene, mode="rcast").radiance["rcast"][..., 0]
        inside = img[12:36, 12:36]
        jumps[crease] = np.abs(np.diff(inside, axis=1)).max()
    assert jumps[45.0] < 0.5 * jumps[0.0]


# ---------------------------------------------------------------- eye samples


def test_subpixel_samples_are_stratified_and_packet_invariant():
    fx, fy = subpixel_offsets(np.array([5, 9]), 16, 0x5EED)
    assert fx.shape == (32,) and np.all((fx >= 0) & (fx < 1) & (fy >= 0) & (fy < 1))
    cells = (np.floor(fx[:16] * 4) + 4 * np.floor(fy[:16] * 4)).astype(int)
    assert sorted(cells) == list(range(16))  # one sample per stratum
    gx, _ = subpixel_offsets(np.array([9]), 16, 0x5EED)
    np.testing.assert_array_equal(gx, fx[16:])
    cx, cy = subpixel_offsets(np.array([3]), 1, 0x5EED)
    assert cx[0] == cy[0] == 0.5  # one sample: the pixel's centre


def test_more_samples_per_pixel_antialias_an_edge():
    """A white quad's vertical edge across a pixel column: one central ray gives 0 or 1,
    16 jittered samples give the covered fraction."""
    wall = quad([-1.0, -10.0, 0.0], [0.0, 20.0, 0.0], [10.0, 0.0, 0.0], 1, 1)
    light = Light("point", (100.0,) * 3, position=(0.0, 0.0, -3.0))
    scene = make_scene([(wall, WHITE)], [light], [-0.95, 0.0, -5.0], [-0.95, 0.0, 0.0], vfov=20.0,
                       resolution=(33, 9))
    one = render_scene(scene, mode="rcast").radiance["rcast"][4, :, 0]
    many = render_scene(scene, mode="rcast", render={"spp": 16}).radiance["rcast"][4, :, 0]
    lit = np.flatnonzero(one > 0)
    assert lit.shape[0] and lit.max() < 32
    e = lit.max() + 1  # the first dark column of the single central rays
    assert one[e] == 0.0 and abs(one[e - 1] / one[e - 2] - 1) < 0.1  # 0 or the smooth falloff: no edge inside
    # 16 samples: the edge column holds the covered fraction, strictly between its neighbours
    edge = [j for j in (e - 1, e) if 0.05 * many[e - 2] < many[j] < 0.9 * many[e - 2]]
    assert edge, many[e - 3 : e + 2]
    o, d = primary_rays(scene.camera, np.arange(33 * 9), spp=16)
    assert o.shape == d.shape == (33 * 9 * 16, 3)


def test_point_light_radiance_helper_matches_the_renderer():
    """A sanity anchor for the helpers above (flat floor, one point light, spp 1)."""
    floor = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0], 2, 2)
    light = Light("point", (20.0,) * 3, position=(0.3, 2.0, 0.1))
    scene = make_scene([(floor, WHITE)], [light], [0.0, 3.0, -0.01], [0.0, 0.0, 0.0], resolution=(8, 8))
    res = render_scene(scene, mode="rcast")
    g = res.gbuffer
    p = g.origin + g.t[:, None] * g.direction
    expect = point_light_radiance(p, np.tile([0.0, 1.0, 0.0], (64, 1)), 0.8, [0.3, 2.0, 0.1], 20.0)
    np.testing.assert_allclose(res.radiance["rcast"].reshape(-1, 3)[:, 0], expect, rtol=1e-9)
    assert math.isfinite(float(expect.sum()))
