"""Spot and directional lights end to end: scene-file keys and their one-line errors, the
direct-light kernel (shadow rays, the cone's falloff, irradiance x cosine), the photons they
emit (irradiance on a floor against the analytic value, for the global and the aimed caustic
groups), glTF's KHR_lights_punctual spot and directional lights (placed and turned by their
nodes and the item's transform, kept by the scene cache), the scene export, the light
warnings, Mitsuba 3's direct light, and bit-identical photon-map runs on 1, 2 and 3 threads.
Also: a light's, the camera's and the resolution's missing keys are named as required."""

from __future__ import annotations

import base64
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import ndimage

from tlm.cli import main
from tlm.errors import InputError
from tlm.kernels.emission import emit, photon_key
from tlm.kernels.shade import direct_light
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.render import checks
from tlm.scenes import cache as scache
from tlm.scenes import meshes
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import write_glb
from tlm.scenes.model import Light, bounding_sphere, spot_falloff

from .test_threads import _render, _same_render, small_chunks  # noqa: F401 (small_chunks: a fixture)

FLOOR = {"shape": "plane", "name": "floor", "params": {"size": [4.0, 4.0], "divisions": [4, 4]}}
# (its bottom a millimetre over the floor: no face of it in the floor's plane)
BLOCK = {"shape": "box", "name": "block", "params": {"min": [-0.4, 0.001, -0.4], "max": [0.4, 0.8, 0.4]}}
SPOT = {"type": "spot", "position": [1.0, 3.0, 0.5], "direction": [-1.0, -3.0, -0.5], "power": [40.0, 40.0, 40.0],
        "inner_cone_angle": 15.0, "outer_cone_angle": 25.0}
SUN = {"type": "directional", "direction": [0.4, -1.0, 0.3], "irradiance": [1.0, 0.9, 0.8]}
STAGE = {
    "geometry": [FLOOR, BLOCK],
    "materials": {"floor": {"type": "lambertian", "albedo": [0.7, 0.7, 0.7]},
                  "block": {"type": "lambertian", "albedo": [0.6, 0.3, 0.2]}},
    "parts": {"floor": "floor", "block": "block"},
    "lights": [SPOT, SUN],
    "camera": {"eye": [0.5, 3.5, -3.5], "target": [0.0, 0.0, 0.0], "vfov": 50.0},
    "resolution": [16, 16],
}


def _scene_file(folder: Path, name: str = "s.yaml", **over) -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({**STAGE, **over}))  # (NaN as YAML's .nan)
    return path


def _stage(folder: Path, **over):
    return load_scene(str(_scene_file(folder, **over)))


# ---------------------------------------------------------------- scene files


def test_spot_and_directional_lights_from_a_scene_file(tmp_path):
    scene = _stage(tmp_path)
    spot, sun = scene.lights
    assert spot.kind == "spot" and spot.position == (1.0, 3.0, 0.5) and spot.power == (40.0, 40.0, 40.0)
    assert spot.direction == (-1.0, -3.0, -0.5)  # (as written: any length)
    np.testing.assert_allclose(spot.axis, np.array([-1.0, -3.0, -0.5]) / math.sqrt(10.25), rtol=1e-15)
    assert (spot.inner_angle, spot.outer_angle) == (15.0, 25.0)
    # the flux it emits: power / (4 pi) x 2 pi (1 - cos_i + (cos_i - cos_o) / 3)
    ci, co = math.cos(math.radians(15.0)), math.cos(math.radians(25.0))
    np.testing.assert_allclose(spot.flux, 40.0 * 0.5 * (1.0 - ci + (ci - co) / 3.0), rtol=1e-14)
    # a directional light's power: its irradiance over the disc covering the triangles' bounding sphere
    lo, hi = scene.bounds()
    radius = 0.5 * np.linalg.norm(hi - lo)
    assert sun.kind == "directional" and sun.irradiance == (1.0, 0.9, 0.8)
    np.testing.assert_allclose(sun.power, np.array([1.0, 0.9, 0.8]) * math.pi * radius**2, rtol=1e-14)
    # intensity (W/sr) instead of power; glTF's default cone angles (0 and 45 degrees)
    bare = {"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": [1.0, 2.0, 3.0]}
    (light,) = _stage(tmp_path, lights=[bare]).lights
    np.testing.assert_allclose(light.power, 4.0 * math.pi * np.array([1.0, 2.0, 3.0]), rtol=1e-15)
    assert (light.inner_angle, light.outer_angle) == (0.0, 45.0)
    # the scene's transform: a spot moves and its power scales by scale^2; the irradiance stays
    moved = _stage(tmp_path, transform={"scale": 2.0, "translate": [1.0, 0.0, 0.0]})
    assert moved.lights[0].position == (3.0, 6.0, 1.0) and moved.lights[0].power == (160.0, 160.0, 160.0)
    assert moved.lights[1].irradiance == sun.irradiance
    np.testing.assert_allclose(moved.lights[1].power, np.multiply(sun.power, 4.0), rtol=1e-14)


def _error(tmp_path, capsys, **over) -> str:
    path = _scene_file(tmp_path, **over)
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1  # one line, and nothing half-written on stdout
    return err.strip().removeprefix(f"tlm: error: {path}: ")


BAD_LIGHTS = {
    "spot NaN position": ({**SPOT, "position": [float("nan"), 1.0, 0.0]}, "lights[0].position: [nan, 1.0, 0.0] is "
                          "not finite"),
    "spot zero direction": ({**SPOT, "direction": [0.0, 0.0, 0.0]},
                            "lights[0].direction: [0.0, 0.0, 0.0] is no direction (it has no length)"),
    "spot inner over outer": ({**SPOT, "inner_cone_angle": 30.0},
                              "lights[0].inner_cone_angle: 30 must be less than outer_cone_angle (25 degrees)"),
    "spot inner is outer": ({**SPOT, "inner_cone_angle": 25.0},
                            "lights[0].inner_cone_angle: 25 must be less than outer_cone_angle (25 degrees)"),
    "spot inner over the default outer": ({**{k: v for k, v in SPOT.items() if k != "outer_cone_angle"},
                                           "inner_cone_angle": 50}, "lights[0].inner_cone_angle: 50 must be less "
                                          "than outer_cone_angle (45 degrees, the default)"),
    "spot outer over 90": ({**SPOT, "outer_cone_angle": 91.0}, "lights[0].outer_cone_angle: 91.0 must be <= 90.0"),
    "spot outer 0": ({**SPOT, "inner_cone_angle": 0.0, "outer_cone_angle": 0.0},
                     "lights[0].outer_cone_angle: 0.0 must be > 0.0"),
    "spot inner negative": ({**SPOT, "inner_cone_angle": -1.0}, "lights[0].inner_cone_angle: -1.0 must be >= 0.0"),
    "spot NaN angle": ({**SPOT, "outer_cone_angle": float("nan")},
                       "lights[0].outer_cone_angle: nan is not a finite number"),
    "spot negative power": ({**SPOT, "power": [-1.0, 1.0, 1.0]}, "lights[0].power: [-1.0, 1.0, 1.0] must be >= 0.0"),
    "spot negative intensity": ({**{k: v for k, v in SPOT.items() if k != "power"}, "intensity": [1.0, -2.0, 1.0]},
                                "lights[0].intensity: [1.0, -2.0, 1.0] must be >= 0.0"),
    "spot power and intensity": ({**SPOT, "intensity": [1.0, 1.0, 1.0]},
                                 "lights[0]: give power or intensity, not both (power = 4 pi x intensity)"),
    "spot unknown key": ({**SPOT, "cone": 30}, "lights[0].cone: unknown key"),
    "directional zero direction": ({**SUN, "direction": [0, 0, 0]},
                                   "lights[0].direction: [0.0, 0.0, 0.0] is no direction (it has no length)"),
    "directional NaN direction": ({**SUN, "direction": [0.0, float("nan"), 0.0]},
                                  "lights[0].direction: [0.0, nan, 0.0] is not finite"),
    "directional negative irradiance": ({**SUN, "irradiance": [1.0, 1.0, -0.5]},
                                        "lights[0].irradiance: [1.0, 1.0, -0.5] must be >= 0.0"),
    "directional power": ({**SUN, "power": [1.0, 1.0, 1.0]}, "lights[0].power: unknown key"),
}


@pytest.mark.parametrize("case", BAD_LIGHTS)
def test_bad_spot_and_directional_values_are_one_line_errors(tmp_path, capsys, case):
    light, said = BAD_LIGHTS[case]
    assert _error(tmp_path, capsys, lights=[light]).startswith(said)


REQUIRED = {
    "point": ({"type": "point", "position": [0, 1, 0]}, "lights[0].power: required for type point: [r, g, b] in W, "
              "each >= 0"),
    "point position": ({"type": "point", "power": [1, 1, 1]}, "lights[0].position: required for type point: "
                       "[x, y, z]"),
    "quad corner": ({"type": "quad", "edge_u": [1, 0, 0], "edge_v": [0, 0, 1], "power": [1, 1, 1]},
                    "lights[0].corner: required for type quad: [x, y, z]"),
    "quad edge_v": ({"type": "quad", "corner": [0, 2, 0], "edge_u": [1, 0, 0], "power": [1, 1, 1]},
                    "lights[0].edge_v: required for type quad: [x, y, z]"),
    "quad power": ({"type": "quad", "corner": [0, 2, 0], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1]},
                   "lights[0].power: required for type quad: [r, g, b] in W, each >= 0"),
    "spot position": ({k: v for k, v in SPOT.items() if k != "position"},
                      "lights[0].position: required for type spot: [x, y, z]"),
    "spot direction": ({k: v for k, v in SPOT.items() if k != "direction"},
                       "lights[0].direction: required for type spot: [x, y, z], not zero (the way it shines)"),
    "spot power": ({k: v for k, v in SPOT.items() if k != "power"},
                   "lights[0].power: required for type spot: [r, g, b] in W, each >= 0 (4 pi x its intensity), or "
                   "intensity: [r, g, b] in W/sr"),
    "directional direction": ({"type": "directional", "irradiance": [1, 1, 1]}, "lights[0].direction: required for "
                              "type directional: [x, y, z], not zero (the way its light travels)"),
    "directional irradiance": ({"type": "directional", "direction": [0, -1, 0]}, "lights[0].irradiance: required "
                               "for type directional: [r, g, b] in W per unit area, each >= 0"),
}


@pytest.mark.parametrize("case", REQUIRED)
def test_a_light_without_a_required_key_says_it_is_required_for_its_type(tmp_path, capsys, case):
    light, said = REQUIRED[case]
    assert _error(tmp_path, capsys, lights=[light]) == said


@pytest.mark.parametrize("key, said", [
    ("eye", "camera.eye: required: [x, y, z], where the camera is"),
    ("target", "camera.target: required: [x, y, z], the point seen at the image's centre"),
    ("vfov", "camera.vfov: required: the vertical field of view in degrees, in (0, 179]"),
])
def test_a_camera_without_a_required_key_says_it_is_required(tmp_path, capsys, key, said):
    camera = {k: v for k, v in STAGE["camera"].items() if k != key}
    assert _error(tmp_path, capsys, camera=camera) == said


def test_a_scene_without_a_resolution_says_it_is_required(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(json.dumps({k: v for k, v in STAGE.items() if k != "resolution"}))
    assert main(["scene", "show", str(path)]) == 2
    assert capsys.readouterr().err.strip() == (f"tlm: error: {path}: resolution: required: [width, height] in whole "
                                               "pixels (or the config's resolution)")
    assert load_scene(str(path), resolution=[8, 8]).camera.width == 8  # (the config's)


# ---------------------------------------------------------------- direct light


def _floor_points(scene, n: int = 24):
    """Points of the floor (y = 0) on a grid, found by rays straight down: positions, triangles."""
    accel = build_accel(scene.triangles)
    g = (np.arange(n) + 0.5) / n * 3.6 - 1.8
    x, z = np.meshgrid(g, g)
    o = np.stack([x.ravel(), np.full(x.size, 5.0), z.ravel()], axis=1)
    h = closest_hit(accel, o, np.tile([0.0, -1.0, 0.0], (o.shape[0], 1)), tmin=0.0)
    keep = (h.triangle >= 0) & (np.abs(o[:, 1] - h.t) < 1e-9)  # (on the floor, not on the block)
    return accel, (o + h.t[:, None] * [0.0, -1.0, 0.0])[keep], h.triangle[keep]


def _direct(scene, accel, light, p, tri):
    k = p.shape[0]
    up = np.tile([0.0, 1.0, 0.0], (k, 1))
    return direct_light(accel, (light,), p, up, tri, np.full((k, 3), 0.5), np.arange(k, dtype=np.int64), 0, 4,
                        1e-5 * accel.scale)


def test_a_spot_lights_as_the_point_light_of_its_power_times_its_falloff(tmp_path):
    scene = _stage(tmp_path)
    spot = scene.lights[0]
    accel, p, tri = _floor_points(scene)
    point = Light("point", spot.power, position=spot.position)
    lit, work, _ = _direct(scene, accel, spot, p, tri)
    full, pwork, _ = _direct(scene, accel, point, p, tri)
    to = p - np.asarray(spot.position)
    f = spot_falloff(to @ spot.axis / np.linalg.norm(to, axis=1), *spot.cone_cosines)
    assert (f == 1.0).sum() > 20 and (f == 0.0).sum() > 20 and ((f > 0) & (f < 1)).sum() > 20
    np.testing.assert_allclose(lit, full * f[:, None], rtol=1e-12, atol=0.0)
    assert (lit[f == 1.0] == full[f == 1.0]).all()  # (inside the inner cone: the point light's bits)
    # a shadow ray where the cone reaches (as a point light's), none outside it
    assert (work["shadow_rays"] == np.where(f > 0, pwork["shadow_rays"], 0)).all()
    # the block shadows the floor behind it: some points in the cone are dark
    assert ((f > 0) & (lit.max(axis=1) == 0.0)).sum() > 5


def test_a_directional_light_gives_irradiance_times_cosine_and_shadows(tmp_path):
    scene = _stage(tmp_path)
    sun = scene.lights[1]
    accel, p, tri = _floor_points(scene)
    lit, work, _ = _direct(scene, accel, sun, p, tri)
    cos = -sun.axis[1]
    shadow = any_hit(accel, p, np.broadcast_to(-sun.axis * 20.0, p.shape), tmin=1e-6, tmax=1.0, ignore=tri).occluded
    assert 5 < shadow.sum() < p.shape[0] // 2
    expect = 0.5 / math.pi * np.asarray(sun.irradiance) * cos
    np.testing.assert_allclose(lit[~shadow], np.broadcast_to(expect, lit[~shadow].shape), rtol=1e-12)
    assert (lit[shadow] == 0.0).all() and (work["shadow_rays"] == 1).all()


# ---------------------------------------------------------------- photons


def _floor_irradiance(o, d, power, cells: int = 8, half: float = 2.0):
    """Irradiance on the floor (y = 0, x and z in [-half, half]) of the photons' first crossing,
    per cell; and the photon count per cell."""
    down = d[:, 1] < 0
    t = -o[down, 1] / d[down, 1]
    x = o[down, 0] + t * d[down, 0]
    z = o[down, 2] + t * d[down, 2]
    h = np.histogram2d(x, z, bins=cells, range=[[-half, half], [-half, half]], weights=power[down].sum(axis=1))[0]
    c = np.histogram2d(x, z, bins=cells, range=[[-half, half], [-half, half]])[0]
    return h / (2 * half / cells) ** 2, c


def _exact(f, cells: int = 8, half: float = 2.0, sub: int = 16):
    """The cell means of f(x, z) on the grid of :func:`_floor_irradiance` (sub x sub points a cell)."""
    g = (np.arange(cells * sub) + 0.5) / (cells * sub) * 2 * half - half
    x, z = np.meshgrid(g, g, indexing="ij")
    return f(x, z).reshape(cells, sub, cells, sub).mean(axis=(1, 3))


def _spot_irradiance(light: Light):
    def f(x, z):
        p = np.stack([x, np.zeros_like(x), z], axis=-1) - np.asarray(light.position)
        dist = np.linalg.norm(p, axis=-1)
        cos_l = p @ light.axis / dist
        falloff = spot_falloff(cos_l, *light.cone_cosines)
        return sum(light.power) / (4 * math.pi) * falloff * (-p[..., 1] / dist) / dist**2
    return f


BOX = (np.array([-2.0, 0.0, -2.0]), np.array([2.0, 0.8, 2.0]))


def _agrees(est, count, exact, least: int = 400) -> int:
    """Cells with at least ``least`` photons where the estimate is within 5 standard deviations
    (its relative deviation is 1 / sqrt(count) at most) of the exact value; how many."""
    sure = count >= least
    assert (np.abs(est[sure] - exact[sure]) <= 5.0 * exact[sure] / np.sqrt(count[sure]) + 1e-12).all(), (
        est[sure] / exact[sure])
    return int(sure.sum())


def test_spot_photons_carry_its_flux_in_proportion_to_its_falloff():
    spot = Light("spot", (30.0, 20.0, 10.0), position=(0.3, 1.5, -0.2), direction=(0.2, -1.0, 0.1),
                 inner_angle=20.0, outer_angle=45.0)
    n = 200_000
    o, d, power, caustic = emit((spot,), n, photon_key(7), BOX)
    assert o.shape == (n, 3) and not caustic.any() and (o == np.asarray(spot.position)).all()
    np.testing.assert_allclose(power.sum(axis=0), spot.flux, rtol=1e-10)
    assert np.ptp(power, axis=0).max() == 0.0  # equal parts: directions drawn in proportion to the falloff
    assert (d @ spot.axis >= spot.cone_cosines[1] - 1e-12).all()  # within the outer cone
    est, count = _floor_irradiance(o, d, power)
    assert _agrees(est, count, _exact(_spot_irradiance(spot))) >= 20


@pytest.mark.parametrize("aim", ["box", "parts"])
def test_a_spots_caustic_photons_are_weighted_by_its_falloff(aim):
    """Aimed at a box that straddles the edge of the cone: the caustic group's irradiance under
    the box is the spot's, and none of its photons is aimed outside the outer cone (a photon
    drawn there draws again)."""
    spot = Light("spot", (30.0, 30.0, 30.0), position=(0.0, 1.5, 0.0), direction=(0.0, -1.0, 0.0),
                 inner_angle=10.0, outer_angle=30.0)
    target = np.array([[0.25, 0.0, -0.5], [1.25, 0.5, 0.5]])  # the outer cone meets the floor at r = 0.87
    box = {"specular_box": (target[0], target[1])} if aim == "box" else {"caustic_boxes": target[None]}
    o, d, power, caustic = emit((spot,), 100_000, photon_key(3), BOX, caustic_fraction=0.5, **box)
    est, count = _floor_irradiance(o[caustic], d[caustic], power[caustic], cells=16)
    g = (np.arange(16) + 0.5) / 16 * 4.0 - 2.0
    under = ((g[:, None] > 0.25) & (g[:, None] < 1.25)) & ((g[None, :] > -0.5) & (g[None, :] < 0.5))
    exact = _exact(_spot_irradiance(spot), cells=16)
    assert (exact[under] == 0).any() and (exact[under] > 0).any()  # (the cone's edge crosses the box)
    assert (d[caustic] @ spot.axis > spot.cone_cosines[1]).all() and (power[caustic] > 0).all()
    lit = under & (exact > 0)
    assert _agrees(np.where(lit, est, 0), np.where(lit, count, 0), exact, least=300) >= 4
    assert (est[under & (exact == 0)] == 0).all()


@pytest.mark.parametrize("aim", ["box", "parts"])
def test_a_spots_caustic_photons_at_objects_wholly_inside_its_cone(aim):
    """A glass block wholly inside a spot's outer cone (the usual way to light one): every
    draw falls inside the cone (the chance P is 1, or a rounding above), so none is drawn
    again and every caustic photon carries a finite, positive power (this raised a math
    domain error: log1p(-1))."""
    spot = Light("spot", (40.0, 40.0, 40.0), position=(0.0, 3.0, 0.0), direction=(0.0, -1.0, 0.0),
                 inner_angle=15.0, outer_angle=40.0)
    lo, hi = np.array([-0.3, 0.001, -0.3]), np.array([0.3, 0.6, 0.3])
    kw = {"specular_box": (lo, hi)} if aim == "box" else {"caustic_boxes": np.array([[lo, hi]])}
    _, d, power, caustic = emit((spot,), 20_000, photon_key(5), BOX, caustic_fraction=0.5, **kw)
    assert caustic.any() and (d[caustic] @ spot.axis > spot.cone_cosines[1]).all()
    assert np.isfinite(power).all() and (power[caustic] > 0).all()


def _down_cone_grid(outer: float, n: int = 1000):
    """Directions on a fine (theta, phi) grid of the cone of half-angle ``outer`` degrees about
    -y, and each one's solid angle."""
    th = (np.arange(n) + 0.5) / n * math.radians(outer)
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * math.pi
    t, p = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), -np.cos(t), np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    return d, (np.sin(t) * (th[1] - th[0]) * (ph[1] - ph[0])).ravel()


@pytest.mark.parametrize("aim", ["box", "parts"])
@pytest.mark.parametrize("outer", [30.0, 4.0])
def test_a_spots_caustic_photons_fall_inside_its_outer_cone_with_unbiased_power(aim, outer):
    """A spot straight down, aimed at two boxes whose cones its outer cone cuts (30 degrees:
    38% (aim: box) and 58% (parts) of the boxes' cones lie inside it; 4 degrees: 0.7% and
    1.9%): its caustic photons are drawn where the two cones overlap (emission.spot_aimed), so
    none is left outside the outer cone, however narrow (at 4 degrees most were, when the draws
    were made in the boxes' cones and redrawn up to emission.SPOT_DRAWS times), and the caustic
    group's power is the spot's power over 4 pi times its falloff integrated over the
    directions inside the boxes' cones (on the grid), within 5 standard errors."""
    from tlm.kernels.emission import bounding_cone, box_cones

    spot = Light("spot", (30.0, 30.0, 30.0), position=(0.0, 1.5, 0.0), direction=(0.0, -1.0, 0.0),
                 inner_angle=outer / 3.0, outer_angle=outer)
    pos, co = np.asarray(spot.position), spot.cone_cosines[1]
    boxes = np.array([[[0.02, 0.0, -0.5], [1.02, 0.5, 0.5]], [[-0.6, 0.0, 0.02], [0.2, 0.3, 0.8]]])
    if aim == "box":
        kw = {"specular_box": (boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0))}
        a, c = bounding_cone(pos, *kw["specular_box"])
        axes, coss = a[None, :], np.array([c])
    else:
        kw = {"caustic_boxes": boxes}
        axes, coss = (x[0] for x in box_cones(pos[None, :], boxes[:, 0], boxes[:, 1]))
    grid, dw = _down_cone_grid(outer)
    holds = grid @ axes.T >= coss[None, :]  # (directions x cones)
    exact = 30.0 / (4.0 * np.pi) * (spot_falloff(grid @ spot.axis, *spot.cone_cosines) * holds.any(axis=1) * dw).sum()
    _, d, power, caustic = emit((spot,), 40_000, photon_key(11), BOX, caustic_fraction=0.5, **kw)
    m = int(caustic.sum())
    outside = (d[caustic] @ spot.axis <= co).sum()
    assert outside == 0  # (drawn inside the overlap: none outside, even in the narrow cone)
    assert (power[caustic][d[caustic] @ spot.axis <= co] == 0).all()
    total = power[caustic, 0].sum()
    error = power[caustic, 0].std() * math.sqrt(m)
    assert abs(total - exact) <= 5.0 * error, (total, exact, error)
    assert error < 0.05 * exact


def test_cap_overlap_is_the_solid_angle_two_caps_share():
    """emission.cap_overlap against the share of 400,000 points spread evenly on the sphere (a
    Fibonacci lattice) in both caps: caps apart, one in the other, overlapping, wider than a
    hemisphere, and the whole sphere (cosine -1: a spot inside the box it aims at)."""
    from tlm.kernels.emission import cap_overlap

    n = 400_000
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    pts = np.stack([np.sqrt(1.0 - z * z) * np.cos(phi), np.sqrt(1.0 - z * z) * np.sin(phi), z], axis=1)
    cases = [(20.0, 30.0, 60.0), (20.0, 30.0, 5.0), (40.0, 30.0, 50.0), (120.0, 30.0, 100.0),
             (150.0, 80.0, 170.0), (180.0, 45.0, 90.0), (60.0, 89.0, 100.0), (10.0, 10.0, 0.0)]
    for a, b, g in cases:
        axis_b = np.array([math.sin(math.radians(g)), 0.0, math.cos(math.radians(g))])
        ca, cb = math.cos(math.radians(a)), math.cos(math.radians(b))
        counted = 4.0 * math.pi * ((pts[:, 2] >= ca) & (pts @ axis_b >= cb)).mean()
        got = cap_overlap(np.array([ca]), cb, np.array([math.cos(math.radians(g))]))[0]
        assert got == pytest.approx(counted, abs=1e-3), (a, b, g)  # (the lattice counts within 5e-4 here)


def test_directional_photons_start_outside_the_scene_and_give_its_irradiance():
    sun = Light("directional", (0.0, 0.0, 0.0), direction=(0.4, -1.0, 0.3), irradiance=(1.0, 0.9, 0.8))
    n = 100_000
    o, d, power, _ = emit((sun,), n, photon_key(5), BOX)
    centre, radius = bounding_sphere(*BOX)
    assert (d == sun.axis).all()
    assert (np.linalg.norm(o - centre, axis=1) > radius).all()  # outside the sphere: outside the scene
    np.testing.assert_allclose((o - centre) @ sun.axis, -1.01 * radius, rtol=1e-12)  # on one plane
    side = o - centre - ((o - centre) @ sun.axis)[:, None] * sun.axis
    assert np.linalg.norm(side, axis=1).max() <= radius * (1 + 1e-12)  # on the disc covering the sphere
    np.testing.assert_allclose(power.sum(axis=0), np.asarray(sun.irradiance) * math.pi * radius**2, rtol=1e-10)
    est, count = _floor_irradiance(o, d, power)
    cos = -sun.axis[1]
    assert _agrees(est, count, _exact(lambda x, z: sum(sun.irradiance) * cos + 0 * x)) == 64


@pytest.mark.parametrize("aim", ["box", "parts"])
def test_directional_caustic_photons_start_on_the_discs_of_the_specular_objects(aim):
    sun = Light("directional", (0.0, 0.0, 0.0), direction=(-0.3, -1.0, 0.2), irradiance=(2.0, 2.0, 2.0))
    boxes = np.array([[[-1.5, 0.0, -1.5], [-0.75, 0.3, -0.75]], [[0.5, 0.0, 0.5], [1.5, 0.6, 1.5]]])
    box = ({"specular_box": (boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0))} if aim == "box"
           else {"caustic_boxes": boxes})
    o, d, power, caustic = emit((sun,), 300_000, photon_key(9), BOX, caustic_fraction=0.5, **box)
    est, count = _floor_irradiance(o[caustic], d[caustic], power[caustic], cells=16)
    g = (np.arange(16) + 0.5) / 16 * 4.0 - 2.0
    under = np.zeros((16, 16), dtype=bool)
    for lo, hi in boxes:
        under |= ((g[:, None] > lo[0]) & (g[:, None] < hi[0])) & ((g[None, :] > lo[2]) & (g[None, :] < hi[2]))
    exact = np.full((16, 16), sum(sun.irradiance) * -sun.axis[1])
    assert _agrees(np.where(under, est, 0), np.where(under, count, 0), exact, least=300) >= 6


# ---------------------------------------------------------------- glTF


def _gltf_header(lights: list, nodes: list) -> dict:
    """A glTF of a 4 x 4 floor quad (node 0) with ``lights`` on ``nodes`` (indices from 1), its
    buffer inline."""
    pos = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], dtype=np.float32)
    idx = np.array([0, 2, 1, 0, 3, 2], dtype=np.uint16)  # (facing +y)
    blob = pos.tobytes() + idx.tobytes()
    return {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(len(nodes) + 1))}],
        "nodes": [{"mesh": 0, "name": "floor"}, *nodes],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [-2, 0, -2], "max": [2, 0, 2]},
                      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
    }


def _about_x(degrees: float) -> list[float]:
    h = math.radians(degrees) / 2
    return [math.sin(h), 0.0, 0.0, math.cos(h)]


GLTF_LIGHTS = [{"type": "spot", "name": "beam", "intensity": 10.0, "color": [1.0, 0.5, 0.25],
                "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
               {"type": "directional", "name": "sun", "intensity": 3.0, "color": [1.0, 1.0, 0.5]}]
# the spot 3 above the floor, turned to look straight down; the sun turned 60 degrees down from -z
GLTF_NODES = [{"name": "lamp", "translation": [0.5, 3.0, 0.0], "rotation": _about_x(-90.0),
               "extensions": {"KHR_lights_punctual": {"light": 0}}},
              {"name": "sky", "translation": [9.0, 9.0, 9.0], "rotation": _about_x(-60.0),
               "extensions": {"KHR_lights_punctual": {"light": 1}}}]
GLTF_SCENE = ("materials: {grey: {type: lambertian, albedo: [0.6, 0.6, 0.6]}}\ndefault_material: grey\n"
              "camera: {eye: [0, 4, -6], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n")


def test_a_gltf_s_spot_and_directional_lights_are_imported(tmp_path):
    (tmp_path / "s.gltf").write_text(json.dumps(_gltf_header(GLTF_LIGHTS, GLTF_NODES)))
    (tmp_path / "s.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.gltf}\n")
    scene = load_scene(str(tmp_path / "s.yaml"))
    spot, sun = scene.lights
    assert spot.kind == "spot" and spot.name == "s.gltf KHR_lights_punctual.lights[0] 'beam' at nodes[1]"
    np.testing.assert_allclose(spot.position, (0.5, 3.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(spot.direction, (0.0, -1.0, 0.0), atol=1e-12)  # the node's -z, turned down
    np.testing.assert_allclose(spot.power, 4 * math.pi * 10.0 * np.array([1.0, 0.5, 0.25]), rtol=1e-15)
    np.testing.assert_allclose((spot.inner_angle, spot.outer_angle), (math.degrees(0.2), math.degrees(0.5)))
    assert sun.kind == "directional" and sun.irradiance == (3.0, 3.0, 1.5)  # lux read as W per unit area
    np.testing.assert_allclose(sun.direction, (0.0, -math.sin(math.radians(60)), -0.5), atol=1e-12)
    lo, hi = scene.bounds()
    np.testing.assert_allclose(sun.power, np.array([3.0, 3.0, 1.5]) * math.pi * (np.linalg.norm(hi - lo) / 2) ** 2)
    notes = checks.file_warnings(scene)
    assert (f"{tmp_path / 's.gltf'}: its 2 lights (1 spot and 1 directional: KHR_lights_punctual.lights[0] 'beam' "
            "at nodes[1] and KHR_lights_punctual.lights[1] 'sun' at nodes[2]) are imported as tlm lights of their "
            "kinds (power 4 pi x intensity x color W; irradiance intensity x color W per unit area): the scene "
            "file gives no lights:") in notes
    assert not any("not imported" in n for n in notes)
    # a geometry item's transform turns them (and moves the spot) with the floor
    (tmp_path / "t.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.gltf, transform: {rotate: [0, 0, 90], "
                                     "translate: [0, 1, 0]}}\n")
    spot2, sun2 = load_scene(str(tmp_path / "t.yaml")).lights
    np.testing.assert_allclose(spot2.position, (-3.0, 1.5, 0.0), atol=1e-12)  # Rz(90) (0.5, 3, 0) + (0, 1, 0)
    np.testing.assert_allclose(spot2.direction, (1.0, 0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(sun2.direction, (math.sin(math.radians(60)), 0.0, -0.5), atol=1e-12)
    # a render sees them: the floor lit under the spot and everywhere by the sun
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "s.yaml"), "--out", str(out), "--mode", "rcast", "--outputs", "radiance",
                 "--no-report", "--no-progress", "--no-reference"]) == 0
    image = np.load(out / "radiance" / "composite.npy")
    assert (image.max(axis=2) > 0.0).mean() > 0.25  # (the floor: a 4 x 4 square in the middle of the view)


@pytest.mark.parametrize("spot, said", [
    ({"innerConeAngle": 0.5, "outerConeAngle": 0.5}, "KHR_lights_punctual.lights[0].spot.innerConeAngle: 0.5 must be "
     ">= 0 and less than outerConeAngle (0.5 radians)"),
    ({"outerConeAngle": 1.6}, "KHR_lights_punctual.lights[0].spot.outerConeAngle: 1.6 must be > 0 and <= pi / 2 "
     "(radians)"),
    ({"innerConeAngle": float("nan")}, "KHR_lights_punctual.lights[0].spot.innerConeAngle: nan is not finite"),
    ("wide", "KHR_lights_punctual.lights[0].spot: 'wide' is not an object"),
])
def test_a_malformed_gltf_spot_is_a_one_line_error(tmp_path, spot, said):
    lights = [{**GLTF_LIGHTS[0], "spot": spot}, GLTF_LIGHTS[1]]
    (tmp_path / "s.gltf").write_text(json.dumps(_gltf_header(lights, GLTF_NODES)))
    (tmp_path / "s.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.gltf}\n")
    with pytest.raises(InputError) as got:
        load_scene(str(tmp_path / "s.yaml"))
    assert str(got.value) == f"{tmp_path / 's.gltf'}: {said}"


def test_a_zero_scale_leaves_a_gltf_spot_no_direction(tmp_path):
    nodes = [{**GLTF_NODES[0], "scale": [1.0, 1.0, 0.0]}, GLTF_NODES[1]]
    (tmp_path / "s.gltf").write_text(json.dumps(_gltf_header(GLTF_LIGHTS, nodes)))
    (tmp_path / "s.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.gltf}\n")
    with pytest.raises(InputError, match=r"s\.gltf: nodes\[1\]: its world transform \(with its parents'\) leaves the "
                                         r"spot light lights\[0\] 'beam' no direction \(a zero scale\)$"):
        load_scene(str(tmp_path / "s.yaml"))


def test_an_items_transform_turns_an_imported_lights_direction_by_its_matrix():
    """compose's transform turns a spot's and a directional light's direction by the linear
    part M alone (no translation) and makes it unit again: under a non-uniform scale it turns
    as the triangles' edges do, under a mirroring one it is mirrored; a point light has none."""
    from tlm.scenes.compose import transform_geometry
    from tlm.scenes.model import Geometry, Imported

    r = math.sqrt(0.5)
    lights = (Light("point", (1.0, 1.0, 1.0), position=(1.0, 0.0, 0.0)),
              Light("spot", (4.0, 4.0, 4.0), position=(0.0, 1.0, 0.0), direction=(r, -r, 0.0), inner_angle=10.0,
                    outer_angle=20.0),
              Light("directional", (0.0, 0.0, 0.0), direction=(0.0, -0.6, 0.8), irradiance=(1.0, 1.0, 1.0)))
    geom = Geometry(triangles=np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]]),
                    part=np.zeros(1, dtype=np.int32), part_names=("t",),
                    imports=(Imported(source="x.gltf", lights=lights),))
    moved = transform_geometry(geom, np.diag([3.0, 1.0, -2.0]), np.array([0.0, 0.0, 5.0])).imports[0].lights
    assert [lt.kind for lt in moved] == ["point", "spot", "directional"]
    assert moved[0].position == (3.0, 0.0, 5.0) and moved[0].direction == (0.0, 0.0, 0.0)
    assert moved[1].position == (0.0, 1.0, 5.0) and moved[1].power == (4.0, 4.0, 4.0)
    np.testing.assert_allclose(moved[1].direction, np.array([3.0, -1.0, 0.0]) / math.sqrt(10.0), rtol=1e-15)
    assert (moved[1].inner_angle, moved[1].outer_angle) == (10.0, 20.0)
    np.testing.assert_allclose(moved[2].direction, np.array([0.0, -0.6, -1.6]) / math.sqrt(0.36 + 2.56), rtol=1e-15)
    assert moved[2].irradiance == (1.0, 1.0, 1.0)


def test_a_gltf_s_lights_under_a_non_uniform_scale(tmp_path):
    """The glTF's import holds its two lights and nothing else; a geometry item's scale
    [1, 2, 1] turns the sun's direction (0, -sin 60, -1/2) to (0, -2 sin 60, -1/2) made unit,
    and the straight-down spot's stays straight down."""
    (tmp_path / "s.gltf").write_text(json.dumps(_gltf_header(GLTF_LIGHTS, GLTF_NODES)))
    (imp,) = meshes.load_mesh(tmp_path / "s.gltf").imports
    assert [lt.kind for lt in imp.lights] == ["spot", "directional"]
    (tmp_path / "s.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.gltf, transform: {scale: [1, 2, 1]}}\n")
    spot, sun = load_scene(str(tmp_path / "s.yaml")).lights
    np.testing.assert_allclose(spot.position, (0.5, 6.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(spot.direction, (0.0, -1.0, 0.0), atol=1e-12)
    s60 = math.sin(math.radians(60.0))
    np.testing.assert_allclose(sun.direction, np.array([0.0, -2.0 * s60, -0.5]) / math.hypot(2.0 * s60, 0.5),
                               atol=1e-12)


def _glb(header: dict) -> bytes:
    """``header`` (of :func:`_gltf_header`) as a GLB, its buffer the BIN chunk."""
    blob = base64.b64decode(header["buffers"][0]["uri"].split(",", 1)[1])
    return write_glb({**header, "buffers": [{"byteLength": len(blob)}]}, blob)


def test_a_cached_glb_keeps_its_spot_and_directional_lights(tmp_path, monkeypatch, cache):
    monkeypatch.setattr(scache, "MIN_TRIANGLES", 0)
    parsed = []
    parse = meshes._parse
    monkeypatch.setattr(meshes, "_parse", lambda path: parsed.append(Path(path).name) or parse(path))
    (tmp_path / "s.glb").write_bytes(_glb(_gltf_header(GLTF_LIGHTS, GLTF_NODES)))
    (tmp_path / "s.yaml").write_text(GLTF_SCENE + "geometry: {mesh: s.glb, transform: {rotate: [0, 0, 90]}}\n")
    first = load_scene(str(tmp_path / "s.yaml"))
    again = load_scene(str(tmp_path / "s.yaml"))
    assert parsed == ["s.glb"] and list(cache.glob("scenes/mesh-*.npz"))  # (the second load: from the cache)
    assert [lt.kind for lt in again.lights] == ["spot", "directional"]
    assert [lt.record() for lt in again.lights] == [lt.record() for lt in first.lights]
    assert [lt.name for lt in again.lights] == [lt.name for lt in first.lights]
    np.testing.assert_allclose(again.lights[0].direction, (1.0, 0.0, 0.0), atol=1e-12)


# ---------------------------------------------------------------- export, warnings


def test_the_scene_export_writes_spot_and_directional_lights_back(tmp_path, capsys):
    src = _scene_file(tmp_path)
    (tmp_path / "out").mkdir()
    assert main(["scene", "export", str(src), str(tmp_path / "out" / "x.yaml")]) == 0
    back = load_scene(str(tmp_path / "out" / "x.yaml"))
    scene = load_scene(str(src))
    assert [lt.record() for lt in back.lights] == [lt.record() for lt in scene.lights]


def test_light_warnings_probe_spot_and_directional_lights(tmp_path):
    scene = _stage(tmp_path)
    accel = build_accel(scene.triangles)
    away = replace(scene.lights[0], direction=(0.0, 1.0, 0.0))  # (above the floor, looking up)
    under = replace(scene.lights[1], direction=(0.0, 1.0, 0.0))  # (from below: the floor's back)
    said = checks.light_warnings(replace(scene, lights=(*scene.lights, away, under)), accel)
    assert said == [
        "lights[2] (spot) reaches no surface: none of its 256 probe rays (spread over its outer cone, and aimed at "
        "the scene's triangles on that side) hits the scene (does its direction point away from the scene?)",
        "lights[3] (directional) lights only back faces: all 203 of its 300 probe rays that hit the scene hit the "
        "back of an opaque triangle (is it inside a closed mesh, outside a room whose walls face in, or is the "
        "geometry wound inside out?)"]


# ---------------------------------------------------------------- Mitsuba


def _ours(scene, s: int = 3):
    from tlm.config import config_from_dict
    from tlm.render.frame import Frame, cast
    from tlm.render.passes import rcast_pass

    w, h = scene.camera.width, scene.camera.height
    big = replace(scene, camera=replace(scene.camera, width=w * s, height=h * s))
    frame = Frame.create(big, build_accel(big.triangles), config_from_dict({"scene": "cornell"}))
    radiance, _ = rcast_pass(frame, cast(frame, np.arange(w * h * s * s)))
    return radiance.reshape(h, s, w, s, 3).mean(axis=(1, 3))


def _one_light_class(scene, s: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(height, width) bool: the pixels whose every eye ray (s x s a pixel), and every ray of
    their 8 neighbours, sees one class of light: a spot's inner cone, unshadowed (1); nothing
    (0: shadowed, or outside its outer cone; a directional light: shadowed); or the ring
    between a spot's cones (2, never kept: the falloffs differ there). And where the ring is."""
    from tlm.kernels.camera import primary_rays

    (light,) = scene.lights
    w, h = scene.camera.width, scene.camera.height
    o, d = primary_rays(replace(scene.camera, width=w * s, height=h * s), np.arange(w * h * s * s, dtype=np.int64))
    accel = build_accel(scene.triangles)
    hits = closest_hit(accel, o, d, tmin=0.0, shared_origin=True)
    p = o + hits.t[:, None] * d
    if light.kind == "spot":
        to = p - np.asarray(light.position)
        with np.errstate(invalid="ignore"):
            cos = to @ light.axis / np.linalg.norm(to, axis=1)
        ci, co = light.cone_cosines
        cls = np.where(cos >= ci, 1, np.where(cos <= co, 0, 2))
        seg = np.asarray(light.position) - p
    else:
        cls = np.ones(p.shape[0], dtype=np.int64)
        seg = np.broadcast_to(-light.axis * 20.0, p.shape)
    with np.errstate(invalid="ignore"):
        occ = any_hit(accel, np.nan_to_num(p), np.nan_to_num(seg), tmin=1e-6, tmax=1 - 1e-6,
                      ignore=hits.triangle).occluded
    cls = np.where(occ & (cls != 2), 0, cls)
    cls = np.where(hits.triangle < 0, 3, cls).reshape(h, s, w, s)
    low = ndimage.minimum_filter(cls.min(axis=(1, 3)), size=3, mode="nearest")
    high = ndimage.maximum_filter(cls.max(axis=(1, 3)), size=3, mode="nearest")
    return (low == high) & (low != 2), (cls == 2).any(axis=(1, 3))


@pytest.mark.parametrize("kind", ["spot", "directional"])
def test_spot_and_directional_light_agree_with_mitsuba_direct(tmp_path, kind):
    """Our ray cast (3 x 3 the resolution, averaged down) against Mitsuba's ``direct`` on the
    floor and block at 48 x 48, over the pixels of one material and one plane
    (:func:`~tlm.oracle.masks.smooth_pixels`) that see one class of light (a shadow's edge
    under a point-like light is sharp; the ring between a spot's cones is where Mitsuba's
    falloff, linear in the angle, is not glTF's: there ours is 0.80 of Mitsuba's, summed over
    the ring's smooth pixels). The bar is tests/test_oracle.py's (measured here: spot 0.00053,
    directional 5.6e-7: a point-like light has no sampling noise)."""
    pytest.importorskip("mitsuba")
    from tlm.oracle import mitsuba as om
    from tlm.oracle.masks import smooth_pixels

    from .test_oracle import RCAST_RMSE_BAR

    light = {"spot": {**SPOT, "inner_cone_angle": 30.0, "outer_cone_angle": 40.0}, "directional": SUN}[kind]
    scene = _stage(tmp_path, lights=[light], resolution=[48, 48])
    ours = _ours(scene)
    theirs = om.render(scene, integrator="direct", spp=64)
    one, ring = _one_light_class(scene)
    smooth = smooth_pixels(scene)
    keep = smooth & one
    lit = keep & (theirs.max(axis=2) > 0)
    assert keep.mean() > 0.4 and lit.sum() > 200 and (keep & (theirs.max(axis=2) == 0)).sum() > 20
    err = om.mean_normalised_rel_rmse(ours, theirs, keep)
    assert err < RCAST_RMSE_BAR, err
    assert om.mean_normalised_rel_rmse(1.1 * ours, theirs, keep) > 2 * RCAST_RMSE_BAR  # (a 10% slip shows)
    if kind == "spot":  # the ring between the cones: glTF's falloff is below Mitsuba's linear one
        assert (ring & smooth).sum() > 20 and ours[ring & smooth].sum() < 0.9 * theirs[ring & smooth].sum()


# ---------------------------------------------------------------- threads


def test_spot_and_directional_photon_map_runs_are_bit_identical_on_1_2_3_threads(small_chunks, tmp_path):  # noqa: F811
    """A photon-map run (a mirror and a glass ball beside the block: caustic groups aimed at
    them, parts by parts) lit by a spot and a directional light gives the same bits, photon
    maps and cycles on 1, 2 and 3 threads."""
    geometry = [FLOOR, BLOCK,
                {"shape": "sphere", "name": "chrome", "params": {"center": [1.0, 0.4, 0.8], "radius": 0.4,
                                                                 "segments": 12, "rings": 6}},
                {"shape": "sphere", "name": "glass", "params": {"center": [-1.0, 0.4, 0.8], "radius": 0.4,
                                                                "segments": 12, "rings": 6}}]
    materials = {**STAGE["materials"], "chrome": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]},
                 "glass": {"type": "dielectric", "ior": 1.5}}
    path = _scene_file(tmp_path, geometry=geometry, materials=materials,
                       parts={"floor": "floor", "block": "block", "chrome": "chrome", "glass": "glass"})
    raw = {"scene": str(path), "mode": "pmap", "resolution": [16, 12], "photons": {"count": 3000},
           "render": {"spp": 1, "batch_rays": 120}, "arch": {"frames": 2, "trace": False}}
    one = _render(raw, 1)
    assert one[0].photons is not None and one[0].photons.photons.maps[0].power.shape[0] > 0
    for n in (2, 3):
        _same_render(one, _render(raw, n))

