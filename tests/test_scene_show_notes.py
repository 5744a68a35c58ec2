"""``tlm scene show`` lists, under ``notes``, the lines a run warns of about what the scene's
mesh files gave: a glTF's lights and camera imported or not used, what was not imported
(spot lights, orthographic cameras), a PLY's colours; the same text as the run's."""

from __future__ import annotations

import json

from tests.test_gltf_lights import CAMERA, _scene_glb, _yaml
from tlm.cli import main
from tlm.render.checks import file_warnings
from tlm.scenes.loader import load_scene


def _show(capsys, path) -> dict:
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 0
    return json.loads(capsys.readouterr().out)


def test_scene_show_lists_what_a_gltf_gave_and_what_was_left_out(tmp_path, capsys):
    glb = _scene_glb(tmp_path)
    scene = _yaml(tmp_path, "geometry: {mesh: s.glb}\n")
    notes = _show(capsys, scene)["notes"]
    assert notes == [n for n in file_warnings(load_scene(str(scene))) if n.startswith(f"{glb}: ")]
    assert (f"{glb}: not imported from its KHR_lights_punctual lights: lights[1] 'beam' (spot): tlm has point, quad "
            "and mesh lights (give such a light under lights: in the scene file, or an emissive material)") in notes
    assert (f"{glb}: its 2 point lights (KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3]) are imported as tlm point lights (power 4 pi x "
            "intensity x color W): the scene file gives no lights:") in notes
    assert (f"{glb}: its camera cameras[0] at nodes[4] is the scene's camera (vfov 28.6479 degrees): the "
            "scene file gives no camera:") in notes
    assert (f"{glb}: not imported from its cameras: cameras[1] at nodes[6] (orthographic: tlm's camera is a "
            "pinhole)") in notes


def test_scene_show_says_when_the_scene_file_replaces_them(tmp_path, capsys):
    glb = _scene_glb(tmp_path)
    notes = _show(capsys, _yaml(tmp_path, "geometry: {mesh: s.glb}\nlights: []\n" + CAMERA))["notes"]
    assert (f"{glb}: its 2 point lights (KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3]) are not used: the scene file gives lights: (leave "
            "lights: out to import them)") in notes
    assert (f"{glb}: its camera cameras[0] at nodes[4] is not used: the scene file gives camera: (leave camera: out "
            "to import it)") in notes


def test_a_scene_without_such_lines_shows_none(capsys):
    assert _show(capsys, "cornell")["notes"] == []
