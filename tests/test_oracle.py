"""Mitsuba 3 as an oracle (tlm/oracle): the scene mapping, our ray cast against Mitsuba's
direct light, the ground-truth cache and the error metrics.

Skipped as a whole where the optional ``mitsuba`` package is not installed.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage

pytest.importorskip("mitsuba")

from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.kernels.traverse import build_accel
from tlm.oracle import mitsuba as om
from tlm.oracle.masks import ray_cast_pixels, smooth_pixels
from tlm.render.frame import Frame, cast
from tlm.render.passes import rcast_pass
from tlm.scenes.builders import cornell
from tlm.scenes.loader import load_scene, transform_scene
from tlm.scenes.model import Camera, Light, Material, Scene

from .scenes import sphere_scene

# Our ray cast against Mitsuba's `direct` on the Lambertian box at 48x48: the mean-normalised
# relative RMSE over the smooth pixels (tlm.oracle.masks: away from silhouettes, creases and
# the light, where one pixel holds two surfaces). Ours at 3x3 the resolution averaged down
# (contact shadows at the blocks' feet are sharp: a pixel's centre alone is not its mean)
# with light_samples 16; Mitsuba at 256 spp. Measured noise of each (RMSE between two seeds
# / sqrt 2): ours 0.005 with render.spp 4 (0.010 with spp 1), Mitsuba 0.005, so unbiased
# renderers differ by ~0.007 (0.011); measured 0.006-0.007 (0.011-0.012). The bar leaves
# about 2x for seeds and platforms; a radiometric slip (a lost 1/pi, a cosine, the light's
# side, a mirrored camera) gives 0.05 to 1.
RCAST_RMSE_BAR = 0.02


def _ours(scene: Scene, supersample: int = 1, **render) -> tuple[np.ndarray, np.ndarray]:
    """Our ray-cast frame (height, width, 3) and which pixels see a light, rendered at
    ``supersample`` times the resolution and averaged down (a box filter, like Mitsuba's film)."""
    s = supersample
    w, h = scene.camera.width, scene.camera.height
    big = replace(scene, camera=replace(scene.camera, width=w * s, height=h * s))
    cfg = config_from_dict({"scene": "cornell", "render": render})
    frame = Frame.create(big, build_accel(big.triangles), cfg)
    g = cast(frame, np.arange(w * h * s * s))
    radiance, _ = rcast_pass(frame, g)
    light = g.sees_light.reshape(w * h * s * s, -1).any(axis=1)  # any of a pixel's eye rays
    return radiance.reshape(h, s, w, s, 3).mean(axis=(1, 3)), light.reshape(h, s, w, s).any(axis=(1, 3))


def box_scene(width: int, height: int) -> Scene:
    """The Cornell box without its spheres: white, red and green Lambertian walls and
    blocks, the published ceiling light; 60 triangles."""
    geo = cornell(wall_div=2, block_div=1)
    names = geo.part_names
    keep = ~np.isin(geo.part, [names.index("mirror_object"), names.index("glass_object")])
    materials = (
        Material("white", "lambertian", albedo=(0.73, 0.73, 0.73)),
        Material("red", "lambertian", albedo=(0.63, 0.065, 0.05)),
        Material("green", "lambertian", albedo=(0.14, 0.45, 0.09)),
    )
    part_material = np.array([{"left_wall": 1, "right_wall": 2}.get(n, 0) for n in names], dtype=np.int32)
    light = Light("quad", power=(1.1e6, 0.95e6, 0.75e6), corner=(343.0, 548.8, 227.0),
                  edge_u=(0.0, 0.0, 105.0), edge_v=(-130.0, 0.0, 0.0))
    camera = Camera((278.0, 273.0, -800.0), (278.0, 273.0, 0.0), (0.0, 1.0, 0.0), 39.3, width, height)
    part = geo.part[keep]
    return Scene("box", geo.triangles[keep], part_material[part], materials, part, names, (light,), camera, 0)


def _blocks(image: np.ndarray, n: int) -> np.ndarray:
    h, w, _ = image.shape
    return image.reshape(n, h // n, n, w // n, 3).mean(axis=(1, 3))


def test_camera_mapping_is_ours_on_the_cornell_box():
    scene = load_scene("cornell", None, [32, 32])
    theirs = om.render(scene, integrator="direct", spp=16)
    ours, light = _ours(scene)
    assert theirs.shape == ours.shape == (32, 32, 3) and theirs.dtype == np.float64
    for image in (theirs, ours):
        left, right = image[8:24, :5].mean(axis=(0, 1)), image[8:24, -5:].mean(axis=(0, 1))
        assert left[0] > 2 * left[1], left  # the red wall on the left
        assert right[1] > 2 * right[0], right  # the green wall on the right
        lum = image.mean(axis=2)
        row, _ = np.unravel_index(np.argmax(lum), lum.shape)
        assert row < 8  # the light, seen directly, in the top quarter
    # the light is seen where we see it, and the coarse picture correlates with ours, much
    # better than with a mirrored or upside-down copy. Mitsuba's film sees part of the light
    # in the pixels around it, and Mitsuba's `direct` shows the light in the spheres (our
    # ray-cast frame leaves them to the reflect and refract passes): both are left out.
    assert light.any() and theirs[light].mean() > 0.5 * ours[light].mean()
    near_light = ndimage.binary_dilation(light)
    cap = np.percentile(ours[~near_light], 99)

    def coarse(image):
        return _blocks(np.where(near_light[..., None], 0.0, np.minimum(image, cap)), 8).ravel()

    corr = float(np.corrcoef(coarse(theirs), coarse(ours))[0, 1])
    assert corr > 0.95, corr
    for flipped in (ours[:, ::-1], ours[::-1]):
        assert float(np.corrcoef(coarse(theirs), coarse(flipped))[0, 1]) < corr - 0.2


def test_quad_light_emits_on_the_side_of_edge_u_cross_edge_v():
    scene = box_scene(16, 16)
    (light,) = scene.lights
    up = replace(light, edge_u=light.edge_v, edge_v=light.edge_u)  # emits up, into the ceiling
    lit = om.render(scene, integrator="direct", spp=4)
    dark = om.render(replace(scene, lights=(up,)), integrator="direct", spp=4)
    assert lit.mean() > 0.05 and dark.max() == 0.0


def test_lambertian_and_mirror_surfaces_are_two_sided():
    """Reversing every triangle's winding (its geometric normal) changes nothing."""
    scene = box_scene(16, 16)
    flipped = replace(scene, triangles=scene.triangles[:, ::-1].copy())
    a = om.render(scene, integrator="direct", spp=16)
    b = om.render(flipped, integrator="direct", spp=16)
    np.testing.assert_allclose(b, a, atol=1e-4 * a.max())
    mirror = replace(scene, materials=(*scene.materials[:1],
                                       Material("chrome", "mirror", reflectance=(0.9, 0.9, 0.9)), scene.materials[2]))
    # paths differ once a diffuse bounce samples a direction in the flipped frame: compare means
    c = om.render(mirror, integrator="path", spp=64, max_depth=3)
    d = om.render(replace(mirror, triangles=flipped.triangles), integrator="path", spp=64, max_depth=3)
    wall_c, wall_d = c[4:12, :3].mean(), d[4:12, :3].mean()  # the mirror wall (black if one-sided)
    assert wall_c > 0.02 and abs(wall_d / wall_c - 1) < 0.05, (wall_c, wall_d)
    assert abs(d.mean() / c.mean() - 1) < 0.03


def test_scaled_and_moved_scenes_render_alike():
    """Mitsuba renders in a frame of its own (eye at the origin, a fixed size), so a scene
    scaled by 1e-6 or moved 1e6 away is not lost to float32 and ray offsets."""
    scene = box_scene(16, 16)
    a = om.render(scene, integrator="direct", spp=4)
    for scale, move in ((1e-6, 0.0), (1.0, 1e6), (1e6, -1e3)):
        b = om.render(transform_scene(scene, scale, np.full(3, move)), integrator="direct", spp=4)
        np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-6 * a.max())


def test_point_light_units_in_the_furnace(tmp_path):
    """A point light of intensity pi at the centre of a unit diffuse sphere of albedo 0.5
    gives direct radiance 0.5 / pi * pi / 1 = 0.5 everywhere (tessellation: ~1 %)."""
    scene = load_scene(str(sphere_scene(tmp_path)))
    image = om.render(scene, integrator="direct", spp=4)
    np.testing.assert_allclose(image, 0.5, rtol=0.01)
    # per-corner shading normals reach Mitsuba: radial ones shade unlike the facets' own
    tri = scene.triangles
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flat = np.repeat((face / np.linalg.norm(face, axis=1, keepdims=True))[:, None], 3, axis=1)
    radial = tri / np.linalg.norm(tri, axis=2, keepdims=True)
    a = om.render(scene, integrator="direct", spp=4, normals=flat)
    b = om.render(scene, integrator="direct", spp=4, normals=radial)
    np.testing.assert_allclose(b, 0.5, rtol=0.01)
    assert np.abs(a - b).max() > 1e-3


def test_ray_cast_matches_mitsuba_direct_on_a_lambertian_box():
    scene = box_scene(48, 48)
    ours, _ = _ours(scene, supersample=3, light_samples=16)
    theirs = om.render(scene, integrator="direct", spp=256)
    smooth = smooth_pixels(scene)
    assert smooth.mean() > 0.35  # most of the walls and the blocks' faces
    err = om.mean_normalised_rel_rmse(ours, theirs, smooth)
    assert err < RCAST_RMSE_BAR, err
    # the light's radiance, seen directly: power / (pi area) in both
    (light,) = scene.lights
    le = np.asarray(light.power) / (math.pi * light.area)
    inside = np.abs(theirs - le).max(axis=2) < 1e-3 * le.max()  # pixels wholly inside the light
    assert inside.sum() >= 4 and np.allclose(ours[inside], le)


def test_ground_truth_cache_round_trips_and_keys_on_the_scene(cache, monkeypatch):
    scene = box_scene(8, 8)
    image, meta = om.ground_truth(scene, integrator="direct", spp=4)
    (folder,) = (cache / "oracle").iterdir()
    assert folder.name == meta["key"] == om.oracle_key(scene, integrator="direct", spp=4)
    assert sorted(p.name for p in folder.iterdir()) == ["image.npy", "meta.json"]
    assert json.loads((folder / "meta.json").read_text()) == meta
    assert meta["integrator"] == "direct" and meta["spp"] == 4 and meta["max_depth"] == -1 and meta["seed"] == 0
    assert meta["mitsuba_version"] == om.mitsuba_version() and meta["seconds"] >= 0
    assert image.shape == (8, 8, 3) and image.dtype == np.float64 and image.max() > 0

    def no_render(*args, **kwargs):
        raise AssertionError("rendered again")

    monkeypatch.setattr(om, "render", no_render)
    again, meta2 = om.ground_truth(scene, integrator="direct", spp=4)
    np.testing.assert_array_equal(again, image)
    assert meta2 == meta
    # every part of the scene and of the settings is in the key
    greener = replace(scene, materials=(*scene.materials[:2], Material("green", "lambertian", albedo=(0.1, 0.5, 0.1))))
    moved = replace(scene, camera=replace(scene.camera, eye=(278.0, 273.0, -801.0)))
    keys = {om.oracle_key(s, integrator=i, spp=n, seed=sd)
            for s, i, n, sd in ((scene, "direct", 4, 0), (greener, "direct", 4, 0), (moved, "direct", 4, 0),
                                (scene, "path", 4, 0), (scene, "direct", 16, 0), (scene, "direct", 4, 1))}
    assert len(keys) == 6
    normals = np.repeat(np.array([0.0, 1.0, 0.0])[None, None], scene.n_triangles * 3, axis=0).reshape(-1, 3, 3)
    assert om.oracle_key(scene, integrator="direct", spp=4, normals=normals) != meta["key"]
    assert om.ground_truth(greener, integrator="direct", spp=4, compute=False) is None


def test_missing_mitsuba_is_one_line_with_the_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # `import mitsuba` now raises ImportError
    with pytest.raises(InputError) as e:
        om.render(box_scene(8, 8), integrator="direct", spp=1)
    message = str(e.value)
    assert "\n" not in message and "pip install -e" in message and "[oracle]" in message


def test_bad_settings_are_one_line_errors():
    scene = box_scene(8, 8)
    with pytest.raises(InputError, match="integrator"):
        om.scene_dict(scene, integrator="bdpt", spp=4)
    with pytest.raises(InputError, match="spp"):
        om.scene_dict(scene, integrator="path", spp=0)


def test_error_metrics():
    rng = np.random.default_rng(1)
    ref = rng.random((16, 16, 3)) + 0.1
    assert om.rel_mse(ref, ref) == 0.0 and om.mean_normalised_rel_rmse(ref, ref) == 0.0
    np.testing.assert_allclose(om.mean_normalised_rel_rmse(1.1 * ref, ref),
                               0.1 * np.sqrt(np.mean(ref**2)) / ref.mean())
    # rel_mse: a black reference pixel is measured against 1e-2 mean(ref)^2
    dark = ref.copy()
    dark[0, 0] = 0.0
    test = dark.copy()
    test[0, 0] = 0.1
    expected = 0.1**2 / (1e-2 * dark.mean() ** 2) / dark.size * 3
    np.testing.assert_allclose(om.rel_mse(test, dark), expected)
    mask = np.ones((16, 16), dtype=bool)
    mask[0, 0] = False
    assert om.mean_normalised_rel_rmse(test, dark, mask) == 0.0
    pytest.importorskip("flip_evaluator")
    assert om.flip(ref, ref) == 0.0
    assert 0.0 < om.flip(1.5 * ref, ref) < 1.0
    assert 0.0 < om.flip(1.5 * ref, ref, exposure=0.5) < 1.0


# The bar for the whole Cornell box (spheres included): our RCast composite against
# Mitsuba's `direct` at matched sample counts (ours 64 eye rays x 16 light samples per pixel,
# Mitsuba 1024 spp), the lights masked and the pixels whose eye rays meet a mirror or glass
# (the ray-cast frame leaves them black by the thesis's pass structure; Mitsuba's direct
# shows the light reflected there). Measured with the code below at 64x64: 0.0153 (87% of
# the pixels kept), at 48x48 (this test) 0.0156; with 256 samples each instead, 0.0446 at
# 64x64, the two renderers' noise
# (Mitsuba's own, between two seeds / sqrt 2, is 0.014 there).
CORNELL_DIRECT_BAR = 0.03


@pytest.mark.slow
def test_cornell_ray_cast_matches_mitsuba_direct_at_matched_samples():
    from tlm.experiments.run import render

    w = 48
    scene = load_scene("cornell", resolution=[w, w])
    res = render(config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [w, w],
                                   "render": {"spp": 64, "light_samples": 16}}))
    ours = res.radiance["rcast"]
    theirs = om.render(scene, integrator="direct", spp=1024, seed=3)
    keep = ray_cast_pixels(res.frame, res.gbuffer)
    assert 0.8 < keep.mean() < 0.95
    err = om.mean_normalised_rel_rmse(ours, theirs, keep)
    assert err <= CORNELL_DIRECT_BAR, err
    # the figure can fail: 10% too much light, or the image mirrored, is far above the bar
    assert om.mean_normalised_rel_rmse(1.1 * ours, theirs, keep) > 2 * CORNELL_DIRECT_BAR
    assert om.mean_normalised_rel_rmse(ours[:, ::-1], theirs, keep & keep[:, ::-1]) > 5 * CORNELL_DIRECT_BAR


@pytest.mark.slow
def test_point_light_caustics_come_from_the_particle_tracer(cache):
    """The ring's cardioid is a point light's caustic through a mirror: no eye path reaches
    it, so Mitsuba's path tracer leaves the floor inside the ring dark; the composite truth
    takes the particle tracer at the diffuse pixels and has it. Cornell's light is an area
    light: the path tracer alone."""
    from tlm.experiments.run import render
    from tlm.render.passes import diffuse_pixels

    assert om.needs_light_tracing(load_scene("ring")) and not om.needs_light_tracing(load_scene("cornell"))
    w, h = 64, 48
    res = render(config_from_dict({"scene": "ring", "mode": "rcast", "resolution": [w, h], "render": {"spp": 1}}))
    scene = res.scene
    diffuse = diffuse_pixels(res.frame, res.gbuffer).reshape(h, w)
    assert 0.5 < diffuse.mean() < 1.0
    path, _ = om.ground_truth(scene, "path", spp=64, seed=1)
    truth, meta = om.composite_truth(scene, diffuse, spp=64, seed=1)
    assert meta["integrator"] == "path + ptracer" and meta["ptracer"]["spp"] == om.PTRACER_FACTOR * 64
    np.testing.assert_array_equal(truth[~diffuse], path[~diffuse])
    # the floor inside the ring: the ray-cast frame (direct light) is dark there, the truth is not
    g = res.gbuffer
    p = g.origin + np.where(np.isfinite(g.t), g.t, 0.0)[:, None] * g.direction
    inside = ((np.hypot(p[:, 0], p[:, 2]) < 4.0) & (p[:, 1] < 0.01) & (g.triangle >= 0)).reshape(h, w) & diffuse
    assert inside.sum() > 20
    assert truth[inside].mean() > 2.0 * path[inside].mean() + 1e-3
