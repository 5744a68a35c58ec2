"""A glTF's KHR_lights_punctual point, spot and directional lights and its first perspective
camera become the scene's lights and camera when the scene file gives no lights: / camera: (tlm/scenes/meshes.py
and tlm/scenes/gltf_imports.py read them, tlm/scenes/compose.py moves them with the item's
transform, tlm/scenes/loader.py decides which are used, tlm/scenes/cache.py keeps them); what
is not imported, and what is, is named in the run's warnings; a malformed light or camera is
a one-line error."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.render.checks import file_warnings
from tlm.scenes import cache as scache
from tlm.scenes import meshes
from tlm.scenes.gltf_imports import gltf_imports
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import glb_chunks, write_glb

S45 = math.sqrt(0.5)  # sin and cos of 45 degrees: a quaternion of 90 degrees about an axis
GREY = "materials: {grey: {type: lambertian, albedo: [0.6, 0.6, 0.6]}}\ndefault_material: grey\n"
CAMERA = "camera: {eye: [0, 0, 6], target: [0, 0, 0], vfov: 40}\n"
LAMP = {"type": "point", "name": "lamp", "intensity": 5.0, "color": [1.0, 0.5, 0.25]}


def _header(folder: Path) -> tuple[dict, bytes]:
    """The JSON and binary of a GLB of one unit box (node 0) centred on the origin."""
    trimesh = pytest.importorskip("trimesh")
    raw = folder / "raw.glb"
    trimesh.creation.box().export(raw)
    return glb_chunks(raw.read_bytes())


def _glb(folder: Path, lights: list | None = None, cameras: list | None = None, nodes: tuple = (),
         roots: tuple = (), name: str = "s.glb") -> Path:
    """A GLB of the unit box with ``lights`` (KHR_lights_punctual), ``cameras`` and more
    ``nodes`` (indices from 1), ``roots`` of them added to the scene."""
    header, binary = _header(folder)
    if lights is not None:
        header["extensions"] = {"KHR_lights_punctual": {"lights": lights}}
        header["extensionsUsed"] = ["KHR_lights_punctual"]
    if cameras is not None:
        header["cameras"] = cameras
    header["nodes"] += list(nodes)
    header["scenes"][0]["nodes"] += list(roots)
    path = folder / name
    path.write_bytes(write_glb(header, binary))
    return path


def _on(light: int, **node) -> dict:
    return {**node, "extensions": {"KHR_lights_punctual": {"light": light}}}


def _perspective(yfov: float = 0.5, **more) -> dict:
    return {"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.01, **more}}


# node 1: a parent moved by (1, 2, 3), turned 90 degrees about z and scaled 2; node 2, its child,
# 1 along its x, holds the lamp: at (1, 2, 3) + Rz(90) (2, 0, 0) = (1, 4, 3)
PARENT = {"name": "arm", "translation": [1.0, 2.0, 3.0], "rotation": [0.0, 0.0, S45, S45], "scale": [2.0, 2.0, 2.0],
          "children": [2]}
# node 3: the lamp again, by a column-major matrix moving it to (0, 5, 0)
MATRIX = _on(0, matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 5, 0, 1])
# node 4: a camera at (0, 1, 10) turned 90 degrees about y: it looks down -x, +y up
VIEW = {"name": "view", "translation": [0.0, 1.0, 10.0], "rotation": [0.0, S45, 0.0, S45], "camera": 0}


def _scene_glb(folder: Path, **kw) -> Path:
    lights = kw.pop("lights", [LAMP, {"type": "spot", "name": "beam", "intensity": 9.0, "spot": {}}])
    cameras = kw.pop("cameras", [_perspective(), {"type": "orthographic", "orthographic": {
        "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}])
    nodes = kw.pop("nodes", (PARENT, _on(0, name="bulb", translation=[1.0, 0.0, 0.0]), MATRIX, VIEW,
                             _on(1, name="spot"), {"camera": 1}))
    return _glb(folder, lights, cameras, nodes, kw.pop("roots", (1, 3, 4, 5, 6)), **kw)


def _yaml(folder: Path, body: str, name: str = "s.yaml") -> Path:
    path = folder / name
    path.write_text(GREY + "resolution: [16, 16]\n" + body)
    return path


def test_point_lights_take_their_nodes_world_positions_and_4_pi_intensity_color(tmp_path):
    glb = _scene_glb(tmp_path)
    scene = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n")))
    power = tuple(4.0 * math.pi * 5.0 * c for c in (1.0, 0.5, 0.25))
    assert [lt.kind for lt in scene.lights] == ["point", "point", "spot"]  # (the lamp on two nodes, the spot)
    assert np.allclose(scene.lights[0].position, (1.0, 4.0, 3.0)) and np.allclose(scene.lights[0].power, power)
    assert np.allclose(scene.lights[1].position, (0.0, 5.0, 0.0)) and np.allclose(scene.lights[1].power, power)
    assert scene.lights[0].name == "s.glb KHR_lights_punctual.lights[0] 'lamp' at nodes[2]"
    # the spot (white, intensity 9, glTF's default cones 0 and pi / 4) on an unmoved node: at the
    # origin, shining down the node's -z
    spot = scene.lights[2]
    assert spot.name == "s.glb KHR_lights_punctual.lights[1] 'beam' at nodes[5]"
    assert spot.position == (0.0, 0.0, 0.0) and spot.direction == (0.0, 0.0, -1.0)
    assert spot.power == pytest.approx((4.0 * math.pi * 9.0,) * 3, rel=1e-15)
    assert (spot.inner_angle, spot.outer_angle) == (0.0, 45.0)
    notes = file_warnings(scene)
    assert not any("not imported from its KHR_lights_punctual lights" in n for n in notes)
    assert (f"{glb}: its 3 lights (2 point and 1 spot: KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3] and KHR_lights_punctual.lights[1] 'beam' at nodes[5]) "
            "are imported as tlm lights of their kinds (power 4 pi x intensity x color W): the scene file gives no "
            "lights:") in notes


def test_the_first_perspective_camera_looks_down_its_nodes_minus_z(tmp_path):
    glb = _scene_glb(tmp_path)
    scene = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n")))
    cam = scene.camera
    assert np.allclose(cam.eye, (0.0, 1.0, 10.0)) and np.allclose(cam.target, (-1.0, 1.0, 10.0))
    assert np.allclose(cam.up, (0.0, 1.0, 0.0)) and cam.vfov == pytest.approx(math.degrees(0.5))
    assert (cam.width, cam.height) == (16, 16)  # (the scene file's resolution)
    notes = file_warnings(scene)
    assert (f"{glb}: its camera cameras[0] at nodes[4] is the scene's camera (vfov 28.6479 degrees): the "
            "scene file gives no camera:") in notes
    assert (f"{glb}: not imported from its cameras: cameras[1] at nodes[6] (orthographic: tlm's camera is a "
            "pinhole)") in notes


def test_a_camera_node_keeps_its_mesh(tmp_path):
    """trimesh leaves out the mesh of a node with a camera (tlm reads the cameras itself)."""
    glb = _glb(tmp_path, None, [_perspective()], ({"mesh": 0, "translation": [5.0, 0.0, 0.0], "camera": 0},), (1,))
    g = meshes.load_mesh(glb)
    x = g.triangles[:, :, 0].mean(axis=1)
    assert g.triangles.shape[0] == 24 and (x > 4.0).sum() == 12 and (x < 1.0).sum() == 12  # (both boxes)
    assert g.imports[0].camera.eye == (5.0, 0.0, 0.0)


def test_a_scene_file_without_a_camera_needs_one_from_its_meshes(tmp_path):
    _glb(tmp_path, [LAMP], None, (_on(0, translation=[0, 2, 0]),), (1,))
    with pytest.raises(InputError, match=r"s\.yaml: camera: missing: give camera: \{eye, target, vfov\} \(no mesh "
                                         r"file of the geometry has a perspective camera to import\)"):
        load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n")))


def test_the_items_transform_moves_lights_and_camera_and_the_scenes_scales_power(tmp_path):
    """p' = Ry(90) 2 p + (0, 0, 1): the lamp (1, 4, 3) to (6, 8, -1), the spot (0, 0, 0) to
    (0, 0, 1) and its direction -z to -x, the eye (0, 1, 10) to (20, 2, 1), the view direction -x
    to +z; the power stays (a glTF node's scale leaves its light's intensity). The scene's
    transform scales power by scale^2, as for every light, and turns no direction."""
    _scene_glb(tmp_path)
    item = "geometry: {mesh: s.glb, transform: {scale: 2, rotate: [0, 90, 0], translate: [0, 0, 1]}}\n"
    scene = load_scene(str(_yaml(tmp_path, item)))
    plain = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n", "plain.yaml")))
    assert np.allclose(scene.lights[0].position, (6.0, 8.0, -1.0))
    assert scene.lights[0].power == plain.lights[0].power
    assert np.allclose(scene.lights[2].position, (0.0, 0.0, 1.0)) and scene.lights[2].power == plain.lights[2].power
    np.testing.assert_allclose(scene.lights[2].direction, (-1.0, 0.0, 0.0), atol=1e-15)
    assert np.allclose(scene.camera.eye, (20.0, 2.0, 1.0)) and np.allclose(scene.camera.target, (20.0, 2.0, 2.0))
    assert np.allclose(scene.camera.up, (0.0, 1.0, 0.0))
    whole = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\ntransform: {scale: 3, translate: [1, 0, 0]}\n",
                                 "whole.yaml")))
    assert np.allclose(whole.lights[0].position, (4.0, 12.0, 9.0))
    assert np.allclose(whole.lights[0].power, np.multiply(plain.lights[0].power, 9.0))
    assert whole.lights[2].direction == (0.0, 0.0, -1.0) and np.allclose(whole.lights[2].position, (1.0, 0.0, 0.0))
    assert np.allclose(whole.camera.eye, (1.0, 3.0, 30.0))
    two = load_scene(str(_yaml(tmp_path, "geometry: [{mesh: s.glb}, {mesh: s.glb, transform: {translate: [0, 0, 50]}}]"
                                         "\n", "two.yaml")))
    assert [lt.position[2] for lt in two.lights] == pytest.approx([3.0, 0.0, 0.0, 53.0, 50.0, 50.0])
    assert np.allclose(two.camera.eye, plain.camera.eye)  # (the first item's camera)
    assert any("its 6 lights (4 point and 2 spot: " in n and ", in each of its 2 geometry items)" in n
               for n in file_warnings(two))


def test_the_scene_files_lights_and_camera_come_first(tmp_path):
    """lights: (even []) and camera: given, by the file or through extends: the glTF's are not
    used, and a line says so."""
    glb = _scene_glb(tmp_path)
    own = "lights: [{type: point, position: [0, 9, 0], power: [1, 1, 1]}]\n" + CAMERA
    scene = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n" + own)))
    assert [lt.position for lt in scene.lights] == [(0.0, 9.0, 0.0)] and scene.camera.eye == (0.0, 0.0, 6.0)
    notes = file_warnings(scene)
    assert (f"{glb}: its 3 lights (2 point and 1 spot: KHR_lights_punctual.lights[0] 'lamp' at nodes[2], "
            "KHR_lights_punctual.lights[0] 'lamp' at nodes[3] and KHR_lights_punctual.lights[1] 'beam' at nodes[5]) "
            "are not used: the scene file gives lights: (leave lights: out to import them)") in notes
    assert (f"{glb}: its camera cameras[0] at nodes[4] is not used: the scene file gives camera: (leave "
            "camera: out to import it)") in notes
    assert not any("imported as" in n or "is the scene's camera" in n for n in notes)
    dark = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\nlights: []\n", "dark.yaml")))
    assert dark.lights == () and np.allclose(dark.camera.eye, (0.0, 1.0, 10.0))  # (lights only: camera imported)
    (tmp_path / "child.yaml").write_text(f"extends: {tmp_path / 's.yaml'}\nname: child\n")
    child = load_scene(str(tmp_path / "child.yaml"))
    assert child.lights == scene.lights and child.camera == scene.camera


def test_range_aspect_ratio_and_unplaced_entries_are_named(tmp_path):
    ranged = {**LAMP, "range": 4.0}
    glb = _glb(tmp_path, [ranged, {"type": "point"}, {"type": "directional"},
                          {"type": "spot", "range": 2.0, "spot": {}}, {"type": "spot", "spot": {}}],
               [_perspective(aspectRatio=1.5), _perspective(0.9)],
               (_on(0, translation=[0, 2, 0]), {"camera": 0, "translation": [0, 0, 5]}, {"camera": 1},
                _on(2), _on(3, translation=[0, 3, 0])), (1, 2, 3, 4, 5))
    scene = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n")))
    assert [lt.kind for lt in scene.lights] == ["point", "directional", "spot"]
    sun = scene.lights[1]
    assert sun.direction == (0.0, 0.0, -1.0) and sun.irradiance == (1.0, 1.0, 1.0)  # (a node's -z; 1 lux, white)
    notes = file_warnings(scene)
    assert (f"{glb}: not imported from its KHR_lights_punctual lights: lights[1] (point, on no node of the glTF's "
            "scene) and lights[4] (spot, on no node of the glTF's scene)") in notes
    assert (f"{glb}: the range of its point and spot lights lights[0] 'lamp' (range 4) and lights[3] (range 2) is not "
            "modelled: a tlm point or spot light reaches every distance (falling off as 1/d^2)") in notes
    assert f"{glb}: not imported from its cameras: cameras[1] at nodes[3] (a perspective camera after the first)" \
        in notes
    assert (f"{glb}: its camera cameras[0] at nodes[2] has aspectRatio 1.5, not the resolution's 1 (16x16): the "
            "horizontal field of view follows the resolution") in notes


def test_imported_lights_and_camera_survive_a_cache_hit(tmp_path, monkeypatch, cache):
    """The parsed GLB is cached (however small, here): the second load, of a copy in another
    folder, parses nothing and has the same lights and camera, named after the copy."""
    monkeypatch.setattr(scache, "MIN_TRIANGLES", 0)
    parsed = []
    parse = meshes._parse
    monkeypatch.setattr(meshes, "_parse", lambda path: parsed.append(Path(path).name) or parse(path))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _scene_glb(tmp_path / "a")
    (tmp_path / "b" / "s.glb").write_bytes((tmp_path / "a" / "s.glb").read_bytes())
    first = meshes.load_mesh(tmp_path / "a" / "s.glb")
    again = meshes.load_mesh(tmp_path / "b" / "s.glb")
    assert parsed == ["s.glb"] and list(cache.glob("scenes/mesh-*.npz"))
    (a,), (b,) = first.imports, again.imports
    assert a.source == str(tmp_path / "a" / "s.glb") and b.source == str(tmp_path / "b" / "s.glb")
    assert b.lights == a.lights and [lt.kind for lt in b.lights] == ["point", "point", "spot"]
    assert b.lights[2].direction == (0.0, 0.0, -1.0) and b.camera == a.camera is not None
    assert (b.camera_name, b.aspect) == (a.camera_name, a.aspect) == ("cameras[0] at nodes[4]", None)
    assert again.notes == tuple(n.replace(str(tmp_path / "a"), str(tmp_path / "b")) for n in first.notes)
    scene = load_scene(str(_yaml(tmp_path / "b", "geometry: {mesh: s.glb}\n")))
    assert parsed == ["s.glb"] and np.allclose(scene.lights[0].position, (1.0, 4.0, 3.0))
    assert np.allclose(scene.camera.eye, (0.0, 1.0, 10.0))


def test_tlm_run_renders_a_gltf_by_its_own_light_and_camera(tmp_path, capsys):
    """The box seen from (0, 0.5, 4) by its camera, lit by its lamp at (0, 2, 3) through a parent."""
    glb = _glb(tmp_path, [{"type": "point", "intensity": 20.0}], [_perspective(0.6)],
               ({"translation": [0.0, 1.0, 3.0], "children": [2]}, _on(0, translation=[0.0, 1.0, 0.0]),
                {"translation": [0.0, 0.5, 4.0], "camera": 0}), (1, 3))
    scene = _yaml(tmp_path, "geometry: {mesh: s.glb}\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--mode", "rcast", "--outputs", "radiance", "--no-report",
                 "--no-progress", "--no-reference"]) == 0
    composite = np.load(out / "radiance" / "composite.npy")
    assert composite.shape == (16, 16, 3) and composite.max() > 0.0
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    assert not any("black" in w for w in warnings)
    assert f"{glb}: its point light (KHR_lights_punctual.lights[0] at nodes[2]) is imported as a tlm point light " \
           "(power 4 pi x intensity x color W): the scene file gives no lights:" in warnings
    assert any(w.startswith(f"{glb}: its camera cameras[0] at nodes[3] is the scene's camera") for w in warnings)


# ---------------------------------------------------------------- malformed entries


MALFORMED = {
    "intensity 'bright'": ({"lights": [{**LAMP, "intensity": "bright"}]},
                           r"KHR_lights_punctual\.lights\[0\]\.intensity: 'bright' is not a number"),
    "intensity -1": ({"lights": [{**LAMP, "intensity": -1}]},
                     r"KHR_lights_punctual\.lights\[0\]\.intensity: -1 is negative"),
    "intensity NaN": ({"lights": [{**LAMP, "intensity": float("nan")}]},
                      r"KHR_lights_punctual\.lights\[0\]\.intensity: nan is not finite"),
    "colour negative": ({"lights": [{**LAMP, "color": [1, -0.5, 0]}]},
                        r"KHR_lights_punctual\.lights\[0\]\.color: \[1, -0\.5, 0\] has a negative value"),
    "type": ({"lights": [{"type": "area"}]},
             r"KHR_lights_punctual\.lights\[0\]\.type: 'area' is not 'point', 'spot' or 'directional'"),
    "range 0": ({"lights": [{**LAMP, "range": 0}]}, r"KHR_lights_punctual\.lights\[0\]\.range: 0 must be > 0"),
    "NaN position": ({"nodes": ({**PARENT, "translation": [1.0, float("nan"), 3.0]},
                                 _on(0, translation=[1.0, 0.0, 0.0]))},
                     r"nodes\[1\]\.translation: \[1\.0, nan, 3\.0\] is not finite"),
    "zero quaternion": ({"nodes": ({**PARENT, "rotation": [0, 0, 0, 0]}, _on(0))},
                        r"nodes\[1\]\.rotation: \[0, 0, 0, 0\] is no rotation \(a zero quaternion\)"),
    "light index": ({"nodes": (_on(7),), "roots": (1,)},
                    r"nodes\[1\]\.extensions\.KHR_lights_punctual\.light = 7 names no entry of "
                    r"KHR_lights_punctual\.lights \(it has 2\)"),
    "camera index": ({"nodes": ({"camera": 5},), "roots": (1,)},
                     r"nodes\[1\]\.camera = 5 names no entry of 'cameras' \(it has 2\)"),
    "child index": ({"nodes": ({"children": [40]}, _on(0)), "roots": (1,)},
                    r"nodes\[1\]\.children names 40, no entry of 'nodes' \(it has 3\)"),
    "zero yfov": ({"cameras": [_perspective(0.0)]},
                  r"cameras\[0\]\.perspective\.yfov: 0\.0 must be > 0 and < pi \(radians\)"),
    "no yfov": ({"cameras": [{"type": "perspective", "perspective": {"znear": 0.1}}]},
                r"cameras\[0\]\.perspective\.yfov: missing"),
    "yfov 'wide'": ({"cameras": [_perspective("wide")]}, r"cameras\[0\]\.perspective\.yfov: 'wide' is not a number"),
    "zero scale": ({"nodes": (PARENT, _on(0), {**VIEW, "scale": [0, 0, 0]})},
                   r"nodes\[3\]: its world transform \(with its parents'\) leaves the camera no view direction"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_a_malformed_light_or_camera_is_a_one_line_error(tmp_path, capsys, case):
    spec, message = MALFORMED[case]
    spec = dict(spec)
    if "nodes" in spec and "roots" not in spec:
        spec["roots"] = (1,) if len(spec["nodes"]) < 3 else (1, 3)
    glb = _scene_glb(tmp_path, **spec)
    scene = _yaml(tmp_path, "geometry: {mesh: s.glb}\n" + CAMERA)
    with pytest.raises(InputError, match=rf"^{glb}: {message}"):
        load_scene(str(scene))
    capsys.readouterr()
    assert main(["scene", "show", str(scene)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tlm: error: {glb}: ")


def test_an_imported_camera_wider_than_179_degrees_is_an_error(tmp_path):
    glb = _glb(tmp_path, None, [_perspective(3.13)], ({"camera": 0},), (1,))
    with pytest.raises(InputError, match=rf"^{glb}: cameras\[0\] at nodes\[1\]: its yfov \(179\.3 degrees\) is over "
                                         r"tlm's 179 degrees"):
        load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\nlights: []\n")))
    assert load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n" + CAMERA, "own.yaml"))).camera.vfov == 40.0


def test_gltf_imports_reads_a_header_without_a_mesh():
    """The import from the JSON alone: a point light two nodes down (the parent's scale moves
    it, leaves its power), a spot light at the origin (white, intensity 1 by default) shining
    down its node's -z, and a perspective camera turned 90 degrees about y (it looks down the
    world's -x); nothing is left out, so there are no notes."""
    header = {
        "extensions": {"KHR_lights_punctual": {"lights": [LAMP, {"type": "spot", "name": "cone", "spot": {}}]}},
        "cameras": [{"type": "perspective", "perspective": {"yfov": math.pi / 2}}],
        "nodes": [{"children": [1], "scale": [2.0, 2.0, 2.0], "translation": [1.0, 0.0, 0.0]},
                  _on(0, translation=[0.0, 3.0, 0.0]), _on(1), {"camera": 0, "rotation": [0.0, S45, 0.0, S45]}],
        "scenes": [{"nodes": [0, 2, 3]}], "scene": 0,
    }
    imp, notes = gltf_imports(header, "h.gltf")
    light, spot = imp.lights  # (and nothing else: no entry but the lights themselves)
    assert light.kind == "point" and light.position == pytest.approx((1.0, 6.0, 0.0))
    assert light.power == pytest.approx(tuple(4 * math.pi * 5.0 * c for c in (1.0, 0.5, 0.25)))
    assert spot.kind == "spot" and spot.name == "h.gltf KHR_lights_punctual.lights[1] 'cone' at nodes[2]"
    assert spot.position == (0.0, 0.0, 0.0) and spot.direction == (0.0, 0.0, -1.0)
    assert spot.power == pytest.approx((4 * math.pi,) * 3) and (spot.inner_angle, spot.outer_angle) == (0.0, 45.0)
    assert imp.camera.vfov == pytest.approx(90.0)
    assert np.subtract(imp.camera.target, imp.camera.eye) == pytest.approx((-1.0, 0.0, 0.0))
    assert notes == ()
