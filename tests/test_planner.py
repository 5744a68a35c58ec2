"""The pass planner: which frames a run renders and why the others are left out."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest
import trimesh

from tlm.config import config_from_dict
from tlm.render.planner import PASSES, plan
from tlm.scenes.loader import load_scene

CORNELL_MATERIALS = """
materials:
  white: {type: lambertian, albedo: [0.73, 0.73, 0.73]}
  red: {type: lambertian, albedo: [0.63, 0.065, 0.05]}
  chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}
  glass: {type: dielectric, ior: 1.5}
"""
CAMERA = "camera: {eye: [278, 273, -800], target: [278, 273, 0], up: [0, 1, 0], vfov: 39.3}\nresolution: [16, 16]\n"
QUAD_LIGHT = """
lights:
  - {type: quad, corner: [343, 548, 227], edge_u: [0, 0, 105], edge_v: [-130, 0, 0], power: [1e6, 1e6, 1e6]}
"""


def cornell_yaml(tmp_path: Path, parts: dict[str, str], lights: str = QUAD_LIGHT, name: str = "c") -> Path:
    body = "geometry: {builder: cornell}\n" + CORNELL_MATERIALS
    body += "parts:\n" + "".join(f"  {k}: {v}\n" for k, v in parts.items())
    body += "default_material: white\n" + lights + CAMERA
    path = tmp_path / f"{name}.yaml"
    path.write_text(body)
    return path


def box_scene(tmp_path: Path, material: str, lights: str | None = None) -> Path:
    """A trimesh box exported to OBJ, one part ``box``."""
    trimesh.creation.box(extents=[2.0, 2.0, 2.0]).export(tmp_path / "box.obj")
    mats = {
        "lambertian": "{type: lambertian, albedo: [0.5, 0.5, 0.5]}",
        "mirror": "{type: mirror, reflectance: [0.9, 0.9, 0.9]}",
        "dielectric": "{type: dielectric, ior: 1.33}",
    }
    if lights is None:
        lights = "lights:\n  - {type: point, position: [0, 5, -5], power: [100, 100, 100]}\n"
    text = textwrap.dedent(
        f"""\
        geometry: {{mesh: box.obj}}
        materials:
          m: {mats[material]}
        parts:
          box: m
        camera: {{eye: [0, 0, -6], target: [0, 0, 0], vfov: 40}}
        resolution: [8, 8]
        """
    ) + lights
    path = tmp_path / f"box_{material}.yaml"
    path.write_text(text)
    return path


def decide(scene, **cfg):
    p = plan(scene, config_from_dict(cfg))
    return p, {x.name: x for x in p.passes}


def test_cornell_pmap_runs_everything():
    p, by = decide(load_scene("cornell"), mode="pmap")
    # the frames, then final gathering's rays (traced by the pmap pass; on by default)
    assert p.run_names == ["rcast", "reflect", "refract", "pmap", "fgather"]
    assert all(by[n].run for n in PASSES)
    assert p.notes == ()
    d = p.to_dict()
    assert d["run"] == ["rcast", "reflect", "refract", "pmap", "fgather"] and d["left_out"] == {}
    assert set(d["reasons"]) == {*PASSES, "fgather"}
    off, by = decide(load_scene("cornell"), mode="pmap", estimate={"final_gather": 0})
    assert off.run_names == ["rcast", "reflect", "refract", "pmap"]
    assert "final_gather is 0" in by["fgather"].reason
    json.dumps(d)  # serialisable


def test_ring_has_no_dielectric():
    p, by = decide(load_scene("ring"), mode="refract")
    assert p.run_names == ["rcast", "reflect"]
    assert not by["refract"].run
    assert "no dielectric" in by["refract"].reason
    assert p.to_dict()["left_out"] == {"refract": by["refract"].reason, "pmap": by["pmap"].reason}
    assert "mode 'refract'" in by["pmap"].reason


@pytest.mark.slow
def test_room_runs_everything():
    p, _ = decide(load_scene("room"))  # default mode: refract
    assert p.run_names == ["rcast", "reflect", "refract"]


@pytest.mark.parametrize("mode,runs", [("rcast", ["rcast"]), ("reflect", ["rcast", "reflect"]),
                                       ("refract", ["rcast", "reflect", "refract"]),
                                       ("pmap", ["rcast", "reflect", "refract", "pmap", "fgather"])])
def test_modes_are_cumulative(mode, runs):
    p, by = decide(load_scene("cornell"), mode=mode)
    assert p.run_names == runs
    for name in PASSES:
        if name not in runs:
            assert f"mode {mode!r}" in by[name].reason
            assert name in by[name].reason


def test_mode_reason_wins_over_scene_reason():
    """Ring in rcast mode: refract is left out because of the mode (checked first)."""
    _, by = decide(load_scene("ring"), mode="rcast")
    assert "mode 'rcast'" in by["reflect"].reason
    assert "mode 'rcast'" in by["refract"].reason


@pytest.mark.parametrize("key,name", [("reflect_depth", "reflect"), ("refract_depth", "refract")])
def test_depth_zero_leaves_pass_out(key, name):
    p, by = decide(load_scene("cornell"), render={key: 0})
    assert not by[name].run
    assert f"render.{key} is 0" in by[name].reason
    assert p.runs("rcast")
    other = "refract" if name == "reflect" else "reflect"
    assert by[other].run


def test_lambertian_only_mesh_scene(tmp_path):
    scene = load_scene(str(box_scene(tmp_path, "lambertian")))
    assert scene.n_triangles == 12 and scene.part_names == ("box",)
    p, by = decide(scene, mode="refract")
    assert p.run_names == ["rcast"]
    assert "no mirror" in by["reflect"].reason
    assert "no dielectric" in by["refract"].reason
    assert p.notes == ()


def test_mirror_only_mesh_scene(tmp_path):
    scene = load_scene(str(box_scene(tmp_path, "mirror")))
    p, _by = decide(scene)
    assert p.run_names == ["rcast", "reflect"]
    assert any("no Lambertian surface" in n for n in p.notes)


def test_dielectric_only_mesh_scene(tmp_path):
    scene = load_scene(str(box_scene(tmp_path, "dielectric")))
    p, by = decide(scene)
    assert p.run_names == ["rcast", "refract"]
    assert "no mirror" in by["reflect"].reason


def test_no_lights_note(tmp_path):
    scene = load_scene(str(box_scene(tmp_path, "lambertian", lights="lights: []\n")))
    p, _ = decide(scene)
    assert p.run_names == ["rcast"]
    assert any("no lights" in n for n in p.notes)
    # no lights key at all
    path = box_scene(tmp_path, "lambertian", lights="")
    p, _ = decide(load_scene(str(path)))
    assert any("no lights" in n for n in p.notes)


def test_zero_power_note(tmp_path):
    lights = "lights:\n  - {type: point, position: [0, 5, -5], power: [0, 0, 0]}\n"
    p, _ = decide(load_scene(str(box_scene(tmp_path, "lambertian", lights=lights))))
    assert any("zero power" in n for n in p.notes)
    assert not any("no lights" in n for n in p.notes)


def test_unused_materials_do_not_count(tmp_path):
    """Cornell geometry with the spheres painted white: mirror and glass are defined but
    no triangle uses them, so both specular passes are left out."""
    path = cornell_yaml(tmp_path, {"left_wall": "red", "mirror_object": "white", "glass_object": "white"})
    scene = load_scene(str(path))
    assert scene.n_triangles == 2604
    p, by = decide(scene)
    assert p.run_names == ["rcast"]
    assert by["reflect"].reason == "the scene has no mirror material"
    assert by["refract"].reason == "the scene has no dielectric material"


def test_cornell_with_glass_walls(tmp_path):
    path = cornell_yaml(tmp_path, {"left_wall": "glass", "mirror_object": "white", "glass_object": "white"})
    p, by = decide(load_scene(str(path)), mode="refract")
    assert p.run_names == ["rcast", "refract"]
    p, by = decide(load_scene(str(path)), mode="reflect")
    assert p.run_names == ["rcast"]
    assert "mode 'reflect'" in by["refract"].reason


def test_cornell_no_lights(tmp_path):
    path = cornell_yaml(tmp_path, {"mirror_object": "chrome", "glass_object": "glass"}, lights="")
    p, _ = decide(load_scene(str(path)))
    assert p.run_names == ["rcast", "reflect", "refract"]
    assert len(p.notes) == 1 and "no lights" in p.notes[0]


def test_pmap_left_out_without_lights(tmp_path):
    _p, by = decide(load_scene(str(box_scene(tmp_path, "lambertian", lights=""))), mode="pmap")
    assert not by["pmap"].run and "nothing emits photons" in by["pmap"].reason


def test_pmap_left_out_with_zero_power(tmp_path):
    dark = "lights:\n  - {type: point, position: [0, 5, -5], power: [0, 0, 0]}\n"
    _p, by = decide(load_scene(str(box_scene(tmp_path, "lambertian", lights=dark))), mode="pmap")
    assert not by["pmap"].run and "nothing emits photons" in by["pmap"].reason


@pytest.mark.parametrize("material", ["mirror", "dielectric"])
def test_pmap_left_out_without_a_diffuse_receiver(tmp_path, material):
    _p, by = decide(load_scene(str(box_scene(tmp_path, material))), mode="pmap")
    assert not by["pmap"].run and "no Lambertian surface" in by["pmap"].reason


def test_pmap_left_out_with_no_photons():
    p, by = decide(load_scene("cornell"), mode="pmap", photons={"count": 0})
    assert p.run_names == ["rcast", "reflect", "refract"]
    assert by["pmap"].reason == "photons.count is 0"


def test_pmap_runs_on_a_lit_diffuse_box(tmp_path):
    scene = load_scene(str(box_scene(tmp_path, "lambertian")))  # the file sets no photon count
    assert decide(scene, mode="pmap")[1]["pmap"].reason == "photons.count is 0"
    p, _by = decide(scene, mode="pmap", photons={"count": 1000})
    assert p.run_names == ["rcast", "pmap", "fgather"]


@pytest.mark.parametrize("bounces", [0, 1])
def test_pmap_left_out_when_no_photon_can_be_stored(bounces):
    p, by = decide(load_scene("cornell"), mode="pmap", photons={"max_bounces": bounces})
    assert "pmap" not in p.run_names
    assert f"photons.max_bounces is {bounces}" in by["pmap"].reason
