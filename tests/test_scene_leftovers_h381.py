"""Three scene leftovers (h381).

* A light's name: a glTF's imported light is named ``FILE KHR_lights_punctual.lights[i] 'NAME' at nodes[n]``
  (its ``from`` in ``tlm scene show``, the light warnings); ``tlm scene export`` wrote no key for it, so the
  exported scene loaded back with nameless lights. A scene file's light now takes an optional ``name:`` (a
  string), which the export writes, its ``from`` shows and its record() (references) leaves out.
* The Mitsuba writer's frame (:func:`tlm.oracle.mitsuba._normalised`) moved every light field whatever the
  light's kind, as the loader's transform did before 044a944 (a quad's ``position``, a point's ``corner``):
  now each kind's own points and lengths only (:func:`tlm.scenes.lights.own_points`, the loader's helper).
* ``material_warnings`` said "2 materials of the mesh files" of a single file: now it names the files that
  define them ("of 't.mtl'", "of 'a.mtl' and 'b.mtl'": 74ef2d4, tests/test_material_files_lead66.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from tlm.api_scenes import export_scene, load_scene, scene_info
from tlm.errors import InputError
from tlm.render.checks import material_warnings
from tlm.scenes.model import Light

from .test_gltf_lights import _glb, _on

GLTF_LIGHTS = [{"type": "point", "name": "lamp", "intensity": 5.0, "color": [1.0, 0.5, 0.25]},
               {"type": "spot", "name": "beam", "intensity": 9.0,
                "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
               {"type": "directional", "name": "sun", "intensity": 2.0}]
HEAD = ("materials: {grey: {type: lambertian, albedo: [0.6, 0.6, 0.6]}}\ndefault_material: grey\n"
        "camera: {eye: [0, 0, 6], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")


def _gltf_scene(tmp_path):
    s45 = math.sqrt(0.5)
    nodes = (_on(0, translation=[0.0, 3.0, 0.0]), _on(1, translation=[1.0, 2.0, 3.0], rotation=[s45, 0.0, 0.0, s45]),
             _on(2, rotation=[0.3, 0.1, 0.0, math.sqrt(0.9)]))
    _glb(tmp_path, lights=GLTF_LIGHTS, nodes=nodes, roots=(1, 2, 3))
    (tmp_path / "s.yaml").write_text("geometry: [{mesh: s.glb}]\ntransform: {scale: 0.5, translate: [1, 2, 3]}\n"
                                     + HEAD)
    return load_scene(tmp_path / "s.yaml")


# --- 1. a light's name -----------------------------------------------------------------------------------------

def test_exported_gltf_lights_keep_their_names(tmp_path):
    scene = _gltf_scene(tmp_path)
    names = [f"s.glb KHR_lights_punctual.lights[{i}] '{n}' at nodes[{i + 1}]" for i, n in
             enumerate(("lamp", "beam", "sun"))]
    assert [lt.name for lt in scene.lights] == names
    out = tmp_path / "out.yaml"
    export_scene(scene, out)
    doc = yaml.safe_load(out.read_text())
    assert [e["name"] for e in doc["lights"]] == names
    assert [list(e)[:2] for e in doc["lights"]] == [["type", "name"]] * 3  # (its name after its type)
    again = load_scene(out)
    assert again.lights == scene.lights  # (whole: names included)
    assert [lt.origin for lt in again.lights] == [f"{out}: lights[{i}] {n!r}" for i, n in enumerate(names)]
    assert [lt["from"] for lt in scene_info(again)["lights"]] == [lt.origin for lt in again.lights]
    # exported again: the same lights, names and all
    export_scene(again, tmp_path / "again.yaml")
    assert yaml.safe_load((tmp_path / "again.yaml").read_text())["lights"] == doc["lights"]


POINT = {"type": "point", "position": [0.0, 3.0, 0.0], "power": [1.0, 2.0, 3.0]}
BOX = "geometry: {shape: box, params: {min: [-1, -1, -1], max: [1, 1, 1]}}\n" + HEAD


def _lights(tmp_path, *lights):
    path = tmp_path / "n.yaml"
    path.write_text(BOX + yaml.safe_dump({"lights": list(lights)}, sort_keys=False))
    return path


def test_a_scene_files_light_takes_a_name(tmp_path):
    quad = {"type": "quad", "corner": [-0.5, 2.0, -0.5], "edge_u": [1.0, 0.0, 0.0], "edge_v": [0.0, 0.0, 1.0],
            "power": [5.0, 5.0, 5.0]}
    sun = {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": [1.0, 1.0, 1.0]}
    spot = {"type": "spot", "position": [0.0, 3.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": [1.0, 1.0, 1.0]}
    plain = load_scene(_lights(tmp_path, POINT, quad, sun, spot))
    path = _lights(tmp_path, {**POINT, "name": "key light"}, {**quad, "name": "fill"}, {**sun, "name": "sky"},
                   {**spot, "name": ""})
    named = load_scene(path)
    assert [lt.name for lt in named.lights] == ["key light", "fill", "sky", ""]
    assert [lt.origin for lt in named.lights] == [f"{path}: lights[0] 'key light'", f"{path}: lights[1] 'fill'",
                                                  f"{path}: lights[2] 'sky'", f"{path}: lights[3]"]
    # (a name changes nothing rendered: the same lights but their names, the same record(), so references)
    for a, b in zip(plain.lights, named.lights, strict=True):
        assert a.record() == b.record() and a == Light(**{**b.__dict__, "name": a.name})


@pytest.mark.parametrize("value, said", [(3, "3"), (None, "null"), (["a"], "[a]"), (True, "true")])
def test_a_light_name_that_is_no_string_is_an_error(tmp_path, value, said):
    path = _lights(tmp_path, {**POINT, "name": value})
    with pytest.raises(InputError) as e:
        load_scene(path)
    assert str(e.value) == f"{path}: lights[0].name: {said} is not text (the light's name: quote it, name: \"...\")"


def test_other_keys_of_a_light_are_still_errors(tmp_path):
    path = _lights(tmp_path, {**POINT, "nmae": "key"})
    with pytest.raises(InputError, match=r"lights\[0\]\.nmae: unknown key.*'name'"):
        load_scene(path)


def test_the_cli_refuses_a_bad_name_with_status_2(tmp_path, capsys):
    from tlm.cli import main

    path = _lights(tmp_path, {**POINT, "name": 7})
    assert main(["scene", "show", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tlm: error: {path}: lights[0].name: 7 is not text (the light's name: quote it, name: \"...\")"]


# --- 2. the Mitsuba writer's frame -----------------------------------------------------------------------------

EVERY = {
    "geometry": {"shape": "plane", "params": {"size": [4.0, 4.0], "divisions": [2, 2]}},
    "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}, "default_material": "grey",
    "lights": [POINT,
               {"type": "quad", "corner": [-0.5, 2.5, -0.5], "edge_u": [1.0, 0.0, 0.0], "edge_v": [0.0, 0.0, 1.0],
                "power": [5.0, 5.0, 5.0]},
               {"type": "spot", "position": [1.0, 3.0, 0.5], "direction": [-1.0, -3.0, -0.5],
                "power": [40.0, 41.0, 42.0], "inner_cone_angle": 15.0, "outer_cone_angle": 25.0},
               {"type": "directional", "direction": [0.4, -1.0, 0.3], "irradiance": [1.0, 0.9, 0.8]}],
    "camera": {"eye": [0.5, 3.5, -3.5], "target": [0.0, 0.0, 0.0], "vfov": 50.0},
    "resolution": [8, 8],
    "transform": {"scale": 1.0e-3, "translate": [1.0e3, -2.0e3, 5.0e2]},
}


def _every(tmp_path):
    (tmp_path / "every.yaml").write_text(yaml.safe_dump(EVERY, sort_keys=False))
    return load_scene(tmp_path / "every.yaml")


def _frame(scene):
    """The Mitsuba frame's eye and scale, as the writer takes them (the eye at the origin, the box's diagonal
    MITSUBA_DIAGONAL)."""
    from tlm.oracle import mitsuba as om

    lo, hi = om._extent(scene)
    return np.asarray(scene.camera.eye, dtype=np.float64), om.MITSUBA_DIAGONAL / float(np.linalg.norm(hi - lo))


def test_the_mitsuba_frame_moves_each_kinds_own_points_only(tmp_path):
    """Each light in the writer's frame is the loader's, its kind's own points moved and lengths scaled, its
    power times the square of the scale; a field of another kind stays as the loader left it (a quad's
    position (0, 0, 0), a point's corner), as the loader's transform leaves it (044a944)."""
    from tlm.oracle import mitsuba as om

    scene = _every(tmp_path)
    assert [lt.kind for lt in scene.lights] == ["point", "quad", "spot", "directional"]
    eye, k = _frame(scene)

    def pt(p):
        return tuple(float(x) for x in (np.asarray(p, dtype=np.float64) - eye) * k)

    def vec(v):
        return tuple(float(x) for x in np.asarray(v, dtype=np.float64) * k)

    point, quad, spot, sun = om._normalised(scene).lights
    a, b, c, d = scene.lights
    scaled = {"power": tuple(float(x) * k * k for x in a.power)}
    assert point == Light(**{**a.__dict__, **scaled, "position": pt(a.position)})
    assert quad == Light(**{**b.__dict__, "power": tuple(float(x) * k * k for x in b.power), "corner": pt(b.corner),
                            "edge_u": vec(b.edge_u), "edge_v": vec(b.edge_v)})
    assert spot == Light(**{**c.__dict__, "power": tuple(float(x) * k * k for x in c.power),
                            "position": pt(c.position)})
    assert sun == Light(**{**d.__dict__, "power": tuple(float(x) * k * k for x in d.power)})
    assert quad.position == (0.0, 0.0, 0.0) and point.corner == (0.0, 0.0, 0.0) and sun.position == (0.0, 0.0, 0.0)


def test_the_mitsuba_scene_is_what_the_loaders_lights_imply(tmp_path):
    """The writer's dict for each kind, from the loaded (transformed) scene's lights: a point's position and
    intensity, a quad's rectangle (its centre just off it along its normal), a spot's frame, intensity and
    cones, a directional light's direction and irradiance."""
    pytest.importorskip("mitsuba")
    from tlm.oracle import mitsuba as om

    scene = _every(tmp_path)
    eye, k = _frame(scene)
    doc = om.scene_dict(scene, integrator="path", spp=4)
    a, b, c, d = scene.lights
    close = {"rtol": 1e-9, "atol": 1e-9 * om.MITSUBA_DIAGONAL}
    close32 = {"rtol": 1e-6, "atol": 1e-6 * om.MITSUBA_DIAGONAL}  # (a to_world matrix: float32)

    point = doc["light_0"]
    assert point["type"] == "point"
    np.testing.assert_allclose(point["position"], (np.asarray(a.position) - eye) * k, **close)
    np.testing.assert_allclose(point["intensity"]["value"], np.asarray(a.power) * k * k / (4 * math.pi), rtol=1e-12)

    quad = doc["light_1"]
    m = np.array(quad["to_world"].matrix, dtype=np.float64)
    eu, ev = np.asarray(b.edge_u) * k, np.asarray(b.edge_v) * k
    normal = np.cross(eu, ev) / np.linalg.norm(np.cross(eu, ev))
    centre = (np.asarray(b.corner) - eye) * k + 0.5 * (eu + ev)
    np.testing.assert_allclose(m[:3, 0], 0.5 * eu, **close32)
    np.testing.assert_allclose(m[:3, 1], 0.5 * ev, **close32)
    np.testing.assert_allclose(m[:3, 2], normal, atol=1e-7)
    assert 0.0 < float(np.dot(m[:3, 3] - centre, normal)) < 1e-3 * om.MITSUBA_DIAGONAL  # (just off the quad)
    np.testing.assert_allclose(m[:3, 3], centre, atol=1e-3 * om.MITSUBA_DIAGONAL)
    area = np.linalg.norm(np.cross(eu, ev))
    np.testing.assert_allclose(quad["emitter"]["radiance"]["value"], np.asarray(b.power) * k * k / (math.pi * area),
                               rtol=1e-9)

    spot = doc["light_2"]
    m = np.array(spot["to_world"].matrix, dtype=np.float64)
    np.testing.assert_allclose(m[:3, 3], (np.asarray(c.position) - eye) * k, **close32)
    np.testing.assert_allclose(m[:3, 2], c.axis, atol=1e-4)  # (float32: look_at takes position + axis)
    np.testing.assert_allclose(spot["intensity"]["value"], np.asarray(c.power) * k * k / (4 * math.pi), rtol=1e-12)
    assert (spot["cutoff_angle"], spot["beam_width"]) == (c.outer_angle, c.inner_angle)

    sun = doc["light_3"]
    assert sun["type"] == "directional"
    np.testing.assert_allclose(sun["direction"], d.axis, atol=1e-15)
    assert sun["irradiance"]["value"] == list(d.irradiance)


# --- 3. the files of the materials -----------------------------------------------------------------------------

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
CAMERA = ("lights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]}]\n"
          "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n")


def test_two_materials_of_one_file_are_of_the_mesh_file(tmp_path):
    (tmp_path / "t.obj").write_text("mtllib t.mtl\n" + TRI + "usemtl wood\nf 1 2 3\nusemtl stone\nf 2 4 3\n")
    (tmp_path / "t.mtl").write_text("newmtl wood\nKd 0.5 0.3 0.1\nmap_Kd w.png\nnewmtl stone\nKd 0.5 0.5 0.5\n"
                                    "map_Kd s.png\n")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: t.obj}\n" + CAMERA)
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("2 materials of 't.mtl' ('wood' and 'stone') use what tlm does not render: map_Kd;")


def test_materials_of_two_files_are_of_the_2_mesh_files(tmp_path):
    for stem, name in (("a", "wood"), ("b", "stone")):
        (tmp_path / f"{stem}.obj").write_text(f"mtllib {stem}.mtl\n{TRI}usemtl {name}\nf 1 2 3\n")
        (tmp_path / f"{stem}.mtl").write_text(f"newmtl {name}\nKd 0.5 0.5 0.5\nmap_Kd {name}.png\n")
    (tmp_path / "s.yaml").write_text("geometry: [{mesh: a.obj}, {mesh: b.obj, transform: {translate: [2, 0, 0]}}]\n"
                                     + CAMERA)
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("2 materials of 'a.mtl' and 'b.mtl' ('wood' and 'stone') use what tlm does not "
                           "render:"), line
    # (one of them replaced by the scene file: one material, of its file)
    (tmp_path / "s.yaml").write_text("geometry: [{mesh: a.obj}, {mesh: b.obj, transform: {translate: [2, 0, 0]}}]\n"
                                     + CAMERA + "materials: {wood: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n")
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("1 material of 'b.mtl' ('stone') uses what tlm does not render:"), line
