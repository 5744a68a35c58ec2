"""A whole number past float64 anywhere in a scene file (a light's position, the camera's
field of view, a spot's cone) is one line naming its key, exit 2: ``math.isfinite`` of such
a number raised OverflowError (an internal error, exit 1) outside the geometry items."""

from __future__ import annotations

import json

import pytest

from tlm.cli import main

BIG = 10**400
CAMERA = {"eye": [0, 1, -4], "target": [0, 0, 0], "vfov": 40}
POINT = {"type": "point", "position": [0, 3, 0], "power": [1, 1, 1]}


@pytest.mark.parametrize("key,light,camera", [
    ("lights[0].position: [0, a 401-digit number, 0] is beyond", {**POINT, "position": [0, BIG, 0]}, CAMERA),
    ("camera.vfov: a 401-digit number is beyond", POINT, {**CAMERA, "vfov": BIG}),
    ("lights[0].outer_cone_angle: a 401-digit number is beyond",
     {"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0], "power": [1, 1, 1], "outer_cone_angle": BIG},
     CAMERA),
    ("lights[0].irradiance: [a negative 401-digit number, 1, 1] is beyond",
     {"type": "directional", "direction": [0, -1, 0], "irradiance": [-BIG, 1, 1]}, CAMERA),
])
def test_a_number_past_float64_outside_the_geometry_is_one_line(tmp_path, capsys, key, light, camera):
    doc = {"materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}, "default_material": "grey",
           "lights": [light], "camera": camera, "resolution": [8, 8], "geometry": {"shape": "sphere"}}
    path = tmp_path / "s.yaml"
    path.write_text(json.dumps(doc))  # (JSON is YAML; Python writes the whole number's digits)
    assert main(["scene", "show", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"tlm: error: {path}: {key}"), err
    assert len(err.splitlines()) == 1
