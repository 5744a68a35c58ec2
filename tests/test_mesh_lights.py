"""Emitting triangles as lights (a ``mesh`` light): built from materials with emission,
sampled for direct light in proportion to power, emitting photons, seen by eye rays, and
agreeing with the quad light they replace and with Mitsuba 3."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.kernels.emission import emit, photon_key
from tlm.kernels.photons import trace_photons
from tlm.kernels.shade import face_normals, triangle_choice
from tlm.kernels.traverse import build_accel
from tlm.render.frame import Frame, cast
from tlm.render.passes import rcast_pass
from tlm.scenes.builders import cornell
from tlm.scenes.lights import with_mesh_light
from tlm.scenes.loader import load_scene, transform_scene
from tlm.scenes.model import Camera, Light, Material, Scene

LIGHT_Y = 548.3  # half a millimetre below the ceiling: the emitter is geometry, it must not z-fight
CORNER = np.array([343.0, LIGHT_Y, 227.0])
EDGE_U = np.array([0.0, 0.0, 105.0])
EDGE_V = np.array([-130.0, 0.0, 0.0])
POWER = (1.1e6, 0.95e6, 0.75e6)


def _box(width: int, height: int, emitter: bool) -> Scene:
    """The Cornell box without spheres, lit by the published light as a quad light or,
    with ``emitter``, as two emitting triangles in the same place (60 or 62 triangles)."""
    geo = cornell(wall_div=2, block_div=1)
    names = geo.part_names
    keep = ~np.isin(geo.part, [names.index("mirror_object"), names.index("glass_object")])
    area = float(np.linalg.norm(np.cross(EDGE_U, EDGE_V)))
    le = tuple(p / (math.pi * area) for p in POWER)
    materials = (
        Material("white", "lambertian", albedo=(0.73, 0.73, 0.73)),
        Material("red", "lambertian", albedo=(0.63, 0.065, 0.05)),
        Material("green", "lambertian", albedo=(0.14, 0.45, 0.09)),
        Material("lamp", "lambertian", albedo=(0.0, 0.0, 0.0), emission=le),
    )
    part_material = np.array([{"left_wall": 1, "right_wall": 2}.get(n, 0) for n in names], dtype=np.int32)
    tri, part = geo.triangles[keep], geo.part[keep]
    index = part_material[part]
    camera = Camera((278.0, 273.0, -800.0), (278.0, 273.0, 0.0), (0.0, 1.0, 0.0), 39.3, width, height)
    if not emitter:
        light = Light("quad", power=POWER, corner=tuple(CORNER), edge_u=tuple(EDGE_U), edge_v=tuple(EDGE_V))
        return Scene("box", tri, index, materials, part, names, (light,), camera, 0)
    a, b, c, d = CORNER, CORNER + EDGE_U, CORNER + EDGE_U + EDGE_V, CORNER + EDGE_V
    lamp = np.array([[a, b, c], [a, c, d]])  # cross(b - a, c - a) = cross(edge_u, edge_v): down
    tri = np.concatenate([tri, lamp])
    part = np.concatenate([part, np.zeros(2, dtype=part.dtype)])
    index = np.concatenate([index, np.full(2, 3, dtype=np.int32)])
    return with_mesh_light(Scene("box", tri, index, materials, part, names, (), camera, 0))


def _rcast(scene: Scene, **render) -> tuple[np.ndarray, np.ndarray]:
    cfg = config_from_dict({"scene": "cornell", "render": render})
    frame = Frame.create(scene, build_accel(scene.triangles), cfg)
    w, h = scene.camera.width, scene.camera.height
    g = cast(frame, np.arange(w * h))
    radiance, _ = rcast_pass(frame, g)
    seen = g.every(~g.sees_emitter)
    return radiance.reshape(h, w, 3), seen.reshape(h, w)


def test_emitting_triangles_become_one_mesh_light_with_their_power():
    scene = _box(8, 8, emitter=True)
    (light,) = scene.lights
    assert light.kind == "mesh" and light.name == "lamp"
    assert light.ids.tolist() == [scene.n_triangles - 2, scene.n_triangles - 1]
    np.testing.assert_allclose(light.power, POWER, rtol=1e-12)
    assert light.record() == {"kind": "mesh", "power": list(light.power), "name": "lamp", "triangles": 2}
    # scaling the scene scales the power by the square (radiance, the image, unchanged)
    moved = transform_scene(scene, 1e-3, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(moved.lights[0].power, np.asarray(POWER) * 1e-6, rtol=1e-9)
    np.testing.assert_allclose(moved.lights[0].triangles, scene.lights[0].triangles * 1e-3 + [1.0, 2.0, 3.0])


def test_triangle_choice_follows_power():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [2, 0, 0], [0, 2, 0]],
                    [[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=np.float64)
    le = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    light = Light("mesh", (1.0, 1.0, 1.0), ids=np.arange(3), triangles=tri, radiance=le)
    u = (np.arange(10000) + 0.5) / 10000
    j, prob = triangle_choice(light, u)
    counts = np.bincount(j, minlength=3)
    assert counts[2] == 0  # a triangle of zero power is never picked
    assert abs(counts[1] / counts[0] - 4.0) < 0.01  # four times the area, four times the power
    np.testing.assert_allclose(prob[j == 1], 0.8)


def test_mesh_light_photons_carry_its_power_from_its_front():
    scene = _box(8, 8, emitter=True)
    (light,) = scene.lights
    o, d, power, _, source = emit(scene.lights, 20000, photon_key(1), with_source=True)
    np.testing.assert_allclose(power.sum(axis=0), POWER, rtol=1e-9)
    assert set(np.unique(source)) <= set(light.ids.tolist())
    assert np.all(d[:, 1] < 0)  # the emitter faces down: every photon leaves below it
    np.testing.assert_allclose(o[:, 1], LIGHT_Y)
    assert np.all((o[:, 0] >= 213.0 - 1e-9) & (o[:, 0] <= 343.0 + 1e-9))
    # cosine-weighted: E[cos] = 2/3
    cos = -d[:, 1]
    assert abs(cos.mean() - 2.0 / 3.0) < 0.01


@pytest.mark.slow
def test_mesh_light_photon_map_matches_the_quad_lights():
    quad, mesh = _box(8, 8, emitter=False), _box(8, 8, emitter=True)
    stored = []
    for scene in (quad, mesh):
        traced = trace_photons(scene, build_accel(scene.triangles), 20000, seed=2)
        stored.append(traced.photons.power.sum(axis=0))
    # the same light, the same flux reaching the walls after a bounce (Monte Carlo: 3 %)
    np.testing.assert_allclose(stored[1], stored[0], rtol=0.03)


@pytest.mark.slow
def test_mesh_light_renders_as_the_quad_light_it_replaces():
    quad, quad_light = _rcast(_box(32, 32, emitter=False), light_samples=16)
    mesh, mesh_light = _rcast(_box(32, 32, emitter=True), light_samples=16)
    assert quad_light.sum() == mesh_light.sum() > 0  # the same pixels see the light
    keep = quad_light & mesh_light
    # the same light: the same image up to the light sampling's noise
    assert abs(mesh[keep].mean() / quad[keep].mean() - 1.0) < 0.01
    blocks = lambda im: im.reshape(4, 8, 4, 8, 3).mean(axis=(1, 3))  # noqa: E731
    np.testing.assert_allclose(blocks(np.where(keep[..., None], mesh, 0)),
                               blocks(np.where(keep[..., None], quad, 0)), rtol=0.05, atol=1e-3)
    # seen directly, the emitter shows its radiance
    le = np.asarray(POWER) / (math.pi * np.linalg.norm(np.cross(EDGE_U, EDGE_V)))
    inside = ~mesh_light
    assert inside.sum() >= 2
    # a pixel wholly inside the emitter: its radiance, plus the black lamp's reflection (none)
    full = np.all(np.isclose(mesh, le), axis=2)
    assert full.sum() >= 1


def test_a_back_facing_emitter_lights_only_what_its_front_faces():
    scene = _box(16, 16, emitter=True)
    light = scene.lights[0]
    flipped = scene.triangles.copy()
    flipped[light.ids] = flipped[light.ids][:, [0, 2, 1]]  # now facing up, at the ceiling
    up = with_mesh_light(replace(scene, triangles=flipped))
    image, _ = _rcast(up, light_samples=4)
    assert image[8:].max() == 0.0  # the floor, the blocks and the walls' lower halves: black
    assert image[:2].max() > 0.0  # the ceiling, half a millimetre above it, is lit
    down, _ = _rcast(scene, light_samples=4)
    assert image.sum() < 0.05 * down.sum()


def test_yaml_emission_and_file_material_override(tmp_path):
    (tmp_path / "lamp.yaml").write_text(
        "extends: cornell\n"
        "materials:\n"
        "  lamp: {type: lambertian, albedo: [0.5, 0.5, 0.5], emission: [2.0, 1.0, 0.5]}\n"
        "parts: {ceiling: lamp}\n"
        "lights: []\n"
    )
    scene = load_scene(str(tmp_path / "lamp.yaml"))
    (light,) = scene.lights
    ceiling = scene.part == scene.part_names.index("ceiling")
    assert sorted(light.ids.tolist()) == np.flatnonzero(ceiling).tolist()
    area = light.areas.sum()
    np.testing.assert_allclose(light.power, np.pi * area * np.array([2.0, 1.0, 0.5]), rtol=1e-12)
    np.testing.assert_allclose(face_normals(light.triangles)[:, 1], -1.0)  # the ceiling faces down


def test_negative_emission_is_a_one_line_error(tmp_path):
    from tlm.errors import InputError

    (tmp_path / "bad.yaml").write_text(
        "extends: cornell\nmaterials:\n  lamp: {type: lambertian, albedo: [0.5, 0.5, 0.5], emission: [1, -1, 0]}\n"
    )
    with pytest.raises(InputError, match=r"materials\.lamp\.emission"):
        load_scene(str(tmp_path / "bad.yaml"))


@pytest.mark.slow
def test_mesh_light_against_mitsuba_direct():
    pytest.importorskip("mitsuba")
    from tlm.oracle import mitsuba as om
    from tlm.oracle.masks import smooth_pixels

    scene = _box(48, 48, emitter=True)
    s = 3
    big = replace(scene, camera=replace(scene.camera, width=144, height=144))
    ours, _ = _rcast(big, light_samples=16)
    ours = ours.reshape(48, s, 48, s, 3).mean(axis=(1, 3))
    theirs = om.render(scene, integrator="direct", spp=256)
    smooth = smooth_pixels(scene)
    assert smooth.mean() > 0.35
    # the bar of tests/test_oracle.py's quad-light check: unbiased renderers differ by their noise
    assert om.mean_normalised_rel_rmse(ours, theirs, smooth) < 0.02
