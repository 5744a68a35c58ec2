"""``tlm scene export NAME OUT.yaml`` writes every light as the loader reads it back (h376):
each built-in scene, exported and loaded again, has the same lights, field by field (the scene's
``transform:`` had moved a quad light's ``position``, a field no quad has and no scene file
gives, so ``extreme/cornell_offset_1e6`` came back with another Light); so does a hand-written
scene of every kind of light the loader knows (point, quad, spot, directional and the mesh light
of its emitting material), transformed, and a glTF's imported point, spot and directional lights."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.api_scenes import export_scene, list_scenes, load_scene
from tlm.scenes.lights import LIGHT_KEYS
from tlm.scenes.model import Light

# the Light fields each kind's scene-file keys give (besides its power)
OWN = {"point": ("position",), "quad": ("corner", "edge_u", "edge_v"),
       "spot": ("position", "direction", "inner_angle", "outer_angle"), "directional": ("direction", "irradiance")}
SLOW = {"conference"}  # (331k triangles: seconds to export and read back)


def _same(a: Light, b: Light) -> None:
    """``b`` (the exported scene's) is ``a``, field by field: kind, power, its kind's own fields, the
    record (scene hashes, references) and ``tlm scene show``'s view of it; and the very same Light (a glTF's
    light too, its name included: the export writes it as the entry's name:, h381)."""
    assert (a.kind, a.power) == (b.kind, b.power)
    for name in OWN.get(a.kind, ()):
        assert getattr(a, name) == getattr(b, name), (a.kind, name)
    if a.kind == "mesh":
        assert (a.name, a.materials) == (b.name, b.materials)
        for name in ("ids", "triangles", "radiance"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.record() == b.record()
    info_a, info_b = a.info(), b.info()
    info_a.pop("from", None)
    info_b.pop("from", None)
    assert info_a == info_b
    assert a == b  # (a glTF's directional light's node position is none of its fields, h379)


def _round_trip(scene, folder: Path, stem: str = "out"):
    out = folder / f"{stem}.yaml"
    export_scene(scene, out)
    return load_scene(out), yaml.safe_load(out.read_text())


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n
                                  for n in list_scenes()])
def test_every_builtin_scene_exports_its_lights(name, tmp_path):
    scene = load_scene(name)
    again, _ = _round_trip(scene, tmp_path)
    assert [lt.kind for lt in again.lights] == [lt.kind for lt in scene.lights]
    for a, b in zip(scene.lights, again.lights, strict=True):
        _same(a, b)


def test_the_offset_cornell_box_keeps_its_quad_light(tmp_path):
    """The case the review found: its quad light has no position (the transform left it (0, 0, 0))."""
    scene = load_scene("extreme/cornell_offset_1e6")
    (quad,) = scene.lights
    assert quad.kind == "quad" and quad.position == (0.0, 0.0, 0.0)
    assert quad.corner[0] > 9e5  # (its corner moved with the box)
    (again,) = _round_trip(scene, tmp_path)[0].lights
    assert again == quad and again.record() == quad.record()


SCENE = {
    "name": "every light",
    "geometry": [{"shape": "plane", "name": "floor", "params": {"size": [4.0, 4.0], "divisions": [2, 2]}},
                 {"shape": "box", "name": "lamp", "params": {"min": [-0.2, 2.0, -0.2], "max": [0.2, 2.1, 0.2]}}],
    "materials": {"floor": {"type": "lambertian", "albedo": [0.7, 0.6, 0.5]},
                  "lamp": {"type": "lambertian", "albedo": [0.1, 0.1, 0.1], "emission": [3.0, 2.5, 2.0]}},
    "parts": {"floor": "floor", "lamp": "lamp"},
    "lights": [
        {"type": "point", "position": [0.1, 1.5, -0.3], "power": [10.0, 20.0, 30.0]},
        {"type": "quad", "corner": [-0.5, 2.5, -0.5], "edge_u": [1.0, 0.0, 0.0], "edge_v": [0.0, 0.0, 1.0],
         "power": [5.0, 5.0, 5.0]},
        {"type": "spot", "position": [1.0, 3.0, 0.5], "direction": [-1.0, -3.0, -0.5], "power": [40.0, 41.0, 42.0],
         "inner_cone_angle": 15.0, "outer_cone_angle": 25.0},
        {"type": "spot", "position": [0.0, 2.0, 0.0], "direction": [0.0, -2.0, 0.0], "intensity": [1.0, 2.0, 3.0]},
        {"type": "directional", "direction": [0.4, -1.0, 0.3], "irradiance": [1.0, 0.9, 0.8]},
    ],
    "camera": {"eye": [0.5, 3.5, -3.5], "target": [0.0, 0.0, 0.0], "vfov": 50.0},
    "resolution": [8, 8],
}


@pytest.mark.parametrize("transform", [None, {"scale": 1.0e-3, "translate": [1.0e3, -2.0e3, 5.0e2]},
                                       {"scale": 3.0, "translate": [0.0, 0.0, 0.0]}])
def test_every_kind_of_light_round_trips(tmp_path, transform):
    """Each kind the loader reads (:data:`tlm.scenes.lights.LIGHT_KEYS`, and the mesh light), as given
    and under the scene's transform (which moves each light's own points only), comes back the same;
    the exported file gives each kind every key it reads (a spot's intensity as its power)."""
    raw = dict(SCENE, **({"transform": transform} if transform else {}))
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    scene = load_scene(tmp_path / "s.yaml")
    kinds = [lt.kind for lt in scene.lights]
    assert kinds == ["point", "quad", "spot", "spot", "directional", "mesh"]
    assert set(LIGHT_KEYS) <= set(kinds)  # (a new kind of light: add it above)
    for lt in scene.lights:  # (no field of another kind set: a quad has no position, a point no corner)
        for kind, names in OWN.items():
            if kind != lt.kind and lt.kind != "mesh":
                for name in set(names) - set(OWN.get(lt.kind, ())):
                    assert getattr(lt, name) == getattr(Light("x", (0.0,) * 3), name), (lt.kind, name)
    again, doc = _round_trip(scene, tmp_path)
    for a, b in zip(scene.lights, again.lights, strict=True):
        _same(a, b)
    assert len(again.lights) == len(scene.lights)
    for entry in doc["lights"]:
        assert set(entry) == set(LIGHT_KEYS[entry["type"]]) - {"intensity"}, entry
    assert "mesh" not in [e["type"] for e in doc["lights"]]  # (it is the emitting material's)
    # exported again: the same file
    third, _ = _round_trip(again, tmp_path, "again")
    assert third.lights == again.lights


def test_imported_gltf_lights_round_trip(tmp_path):
    """A glTF's point, spot and directional lights (KHR_lights_punctual), imported where the scene
    file gives no lights:, are written as lights: entries that load to the same lights, whole: their
    names, which say which glTF light each was, too (h381)."""
    from .test_gltf_lights import _glb, _on

    lights = [{"type": "point", "name": "lamp", "intensity": 5.0, "color": [1.0, 0.5, 0.25]},
              {"type": "spot", "name": "beam", "intensity": 9.0,
               "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
              {"type": "directional", "name": "sun", "intensity": 2.0}]
    s45 = math.sqrt(0.5)
    nodes = (_on(0, translation=[0.0, 3.0, 0.0]), _on(1, translation=[1.0, 2.0, 3.0], rotation=[s45, 0.0, 0.0, s45]),
             _on(2, rotation=[0.3, 0.1, 0.0, math.sqrt(0.9)]))
    _glb(tmp_path, lights=lights, nodes=nodes, roots=(1, 2, 3))
    (tmp_path / "s.yaml").write_text(
        "geometry: [{mesh: s.glb, transform: {scale: 2.0, translate: [1.0, 0.0, 0.0]}}]\n"
        "materials: {grey: {type: lambertian, albedo: [0.6, 0.6, 0.6]}}\ndefault_material: grey\n"
        "transform: {scale: 0.5, translate: [10.0, 20.0, 30.0]}\n"
        "camera: {eye: [0, 0, 6], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
    scene = load_scene(tmp_path / "s.yaml")
    assert [lt.kind for lt in scene.lights] == ["point", "spot", "directional"]
    again, _ = _round_trip(scene, tmp_path)
    assert [lt.name for lt in scene.lights] == [f"s.glb KHR_lights_punctual.lights[{i}] '{n}' at nodes[{i + 1}]"
                                                for i, n in enumerate(("lamp", "beam", "sun"))]
    for a, b in zip(scene.lights, again.lights, strict=True):
        _same(a, b)
    assert again.lights == scene.lights
