"""``tlm scene show`` lists, under ``notes``, the lines a run warns of about what the scene's
mesh files gave: a glTF's lights and camera imported or not used, what was not imported
(lights on no node, orthographic cameras), a PLY's colours; the same text as the run's. It
lists each light with its own kind's fields."""

from __future__ import annotations

import json
import math

import pytest
import yaml

from tests.test_gltf_lights import CAMERA, LAMP, _scene_glb, _yaml
from tlm.cli import main
from tlm.render.checks import file_warnings
from tlm.scenes.loader import load_scene


def _show(capsys, path) -> dict:
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 0
    return json.loads(capsys.readouterr().out)


def test_scene_show_lists_what_a_gltf_gave_and_what_was_left_out(tmp_path, capsys):
    # (the lamp on two nodes, the spot 'beam' on one, the directional 'sky' on none)
    glb = _scene_glb(tmp_path, lights=[LAMP, {"type": "spot", "name": "beam", "intensity": 9.0, "spot": {}},
                                       {"type": "directional", "name": "sky"}])
    scene = _yaml(tmp_path, "geometry: {mesh: s.glb}\n")
    shown = _show(capsys, scene)
    notes = shown["notes"]
    assert notes == [n for n in file_warnings(load_scene(str(scene))) if n.startswith(f"{glb}: ")]
    assert (f"{glb}: not imported from its KHR_lights_punctual lights: lights[2] 'sky' (directional, on no node of "
            "the glTF's scene)") in notes
    assert (f"{glb}: its 3 lights (2 point and 1 spot: KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3] and KHR_lights_punctual.lights[1] 'beam' at nodes[5]) "
            "are imported as tlm lights of their kinds (power 4 pi x intensity x color W): the scene file gives no "
            "lights:") in notes
    assert shown["lights"][2] == {"type": "spot", "power": [4.0 * math.pi * 9.0] * 3, "position": [0.0, 0.0, 0.0],
                                  "direction": [0.0, 0.0, -1.0], "inner_cone_angle": 0.0, "outer_cone_angle": 45.0,
                                  "from": f"{glb} KHR_lights_punctual.lights[1] 'beam' at nodes[5]"}  # (h333)
    assert (f"{glb}: its camera cameras[0] at nodes[4] is the scene's camera (vfov 28.6479 degrees): the "
            "scene file gives no camera:") in notes
    assert (f"{glb}: not imported from its cameras: cameras[1] at nodes[6] (orthographic: tlm's camera is a "
            "pinhole)") in notes


def test_scene_show_says_when_the_scene_file_replaces_them(tmp_path, capsys):
    glb = _scene_glb(tmp_path)
    notes = _show(capsys, _yaml(tmp_path, "geometry: {mesh: s.glb}\nlights: []\n" + CAMERA))["notes"]
    assert (f"{glb}: its 3 lights (2 point and 1 spot: KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3] and KHR_lights_punctual.lights[1] 'beam' at nodes[5]) "
            "are not used: the scene file gives lights: (leave lights: out to import them)") in notes
    assert (f"{glb}: its camera cameras[0] at nodes[4] is not used: the scene file gives camera: (leave camera: out "
            "to import it)") in notes


def test_a_scene_without_such_lines_shows_none(capsys):
    assert _show(capsys, "cornell")["notes"] == []


def test_scene_show_lists_each_light_with_its_own_kinds_fields(tmp_path, capsys):
    """A point light its position, a spot its position, direction and cone angles (degrees),
    a directional light its direction and irradiance (its power: that irradiance over the disc
    covering the scene's bounding sphere), a quad its corner, edges and area; every light its
    power, and no light another kind's fields."""
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({
        "geometry": {"shape": "box", "params": {"min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0]}},
        "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}, "default_material": "grey",
        "camera": {"eye": [0.0, 0.0, 6.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0}, "resolution": [16, 16],
        "lights": [{"type": "point", "position": [0.0, 3.0, 0.0], "power": [1.0, 2.0, 3.0]},
                   {"type": "spot", "position": [2.0, 3.0, 0.0], "direction": [0.0, -2.0, 0.0],
                    "power": [4.0, 4.0, 4.0], "inner_cone_angle": 10.0, "outer_cone_angle": 30.0},
                   {"type": "directional", "direction": [0.0, -1.0, 1.0], "irradiance": [0.5, 0.25, 1.0]},
                   {"type": "quad", "corner": [-0.5, 2.0, -0.5], "edge_u": [1.0, 0.0, 0.0],
                    "edge_v": [0.0, 0.0, 1.0], "power": [5.0, 5.0, 5.0]}],
    }))
    point, spot, sun, quad = _show(capsys, path)["lights"]
    # (h333: each with its from, the scene file's entry)
    assert [lt.pop("from") for lt in (point, spot, sun, quad)] == [f"{path}: lights[{i}]" for i in range(4)]
    assert point == {"type": "point", "power": [1.0, 2.0, 3.0], "position": [0.0, 3.0, 0.0]}
    assert spot == {"type": "spot", "power": [4.0, 4.0, 4.0], "position": [2.0, 3.0, 0.0],
                    "direction": [0.0, -2.0, 0.0], "inner_cone_angle": 10.0, "outer_cone_angle": 30.0}
    assert set(sun) == {"type", "power", "direction", "irradiance"} and sun["type"] == "directional"
    assert sun["direction"] == [0.0, -1.0, 1.0] and sun["irradiance"] == [0.5, 0.25, 1.0]
    # (the box [-1, 1]^3: the sphere around it of radius sqrt(3))
    assert sun["power"] == pytest.approx([e * math.pi * 3.0 for e in (0.5, 0.25, 1.0)], rel=1e-14)
    assert quad == {"type": "quad", "power": [5.0, 5.0, 5.0], "corner": [-0.5, 2.0, -0.5], "edge_u": [1.0, 0.0, 0.0],
                    "edge_v": [0.0, 0.0, 1.0], "area": 1.0}
