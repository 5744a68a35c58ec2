"""A scene file's material without the key its type cannot do without (``albedo``,
``reflectance``, ``ior``) is refused saying that the key is required for that type, whether
the material is new or ``extends:`` gave a base's material another type (which takes none
of the base's fields); it said ``None is not a list of 3 numbers``."""

from __future__ import annotations

import json

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import load_scene

BASE = {
    "geometry": [{"shape": "plane", "name": "floor", "params": {"size": [4.0, 4.0]}},
                 {"shape": "sphere", "name": "ball", "params": {"center": [0.0, 0.5, 0.0], "radius": 0.5,
                                                                "segments": 8, "rings": 4}}],
    "materials": {"floor": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]},
                  "glass": {"type": "dielectric", "ior": 1.5}},
    "parts": {"floor": "floor", "ball": "glass"},
    "lights": [{"type": "point", "position": [0.0, 3.0, 0.0], "power": [10.0, 10.0, 10.0]}],
    "camera": {"eye": [0.0, 1.0, -4.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0},
    "resolution": [8, 8],
}
SAID = {"mirror": "reflectance: required for type mirror: [r, g, b] in [0, 1]",
        "lambertian": "albedo: required for type lambertian: [r, g, b] in [0, 1]",
        "dielectric": "ior: required for type dielectric: a number > 0"}


@pytest.mark.parametrize("kind,name", [("mirror", "glass"), ("lambertian", "glass"), ("dielectric", "floor")])
def test_extends_giving_a_material_another_type_needs_its_fields(tmp_path, cache, capsys, kind, name):
    (tmp_path / "base.yaml").write_text(json.dumps(BASE))
    scene = tmp_path / "s.yaml"
    scene.write_text(json.dumps({"extends": "base.yaml", "materials": {name: {"type": kind}}}))
    assert main(["scene", "show", str(scene)]) == 2
    assert capsys.readouterr().err.strip() == f"tlm: error: {scene}: materials.{name}.{SAID[kind]}"


@pytest.mark.parametrize("kind", ["mirror", "lambertian", "dielectric"])
def test_a_new_material_without_its_types_key_says_it_is_required(tmp_path, kind):
    scene = tmp_path / "s.yaml"
    scene.write_text(json.dumps({**BASE, "materials": {**BASE["materials"], "new": {"type": kind,
                                                                                   "emission": [1.0, 1.0, 1.0]}}}))
    with pytest.raises(InputError) as got:
        load_scene(str(scene))
    assert str(got.value) == f"{scene}: materials.new.{SAID[kind]}"
    # a key given with a bad value is still that value's error
    bad = {"mirror": {"reflectance": None}, "lambertian": {"albedo": [1, 2]}, "dielectric": {"ior": None}}[kind]
    scene.write_text(json.dumps({**BASE, "materials": {**BASE["materials"], "new": {"type": kind, **bad}}}))
    with pytest.raises(InputError, match=r"is not a (list of 3 numbers|finite number)$"):
        load_scene(str(scene))
