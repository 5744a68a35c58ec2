"""An unknown key under a builder's ``params:`` is named by its key
(``geometry[0].params.wall_dv``), with the parameter it is closest to and all the builder's
parameters, as other unknown keys are; it read ``geometry.params: bad builder parameter
(cornell() got an unexpected keyword argument 'wall_dv')``."""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.compose import compose_geometry

HEAD = """materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}
default_material: grey
lights: [{type: point, position: [0.0, 3.0, 0.0], power: [10.0, 10.0, 10.0]}]
camera: {eye: [0.0, 1.0, -4.0], target: [0.0, 0.0, 0.0], vfov: 40.0}
resolution: [8, 8]
"""
CORNELL = "wall_div, block_div, mirror_radius, mirror_seg, mirror_rings, glass_radius, glass_seg, glass_rings"


def test_tlm_scene_show_names_the_key_and_suggests_the_parameter(tmp_path, cache, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text(HEAD + "geometry: [{builder: cornell, params: {wall_div: 2, wall_dv: 3}}]\n")
    assert main(["scene", "show", str(scene)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"tlm: error: {scene}: geometry[0].params.wall_dv: unknown parameter of builder cornell "
        f"(did you mean 'wall_div'?); its parameters: {CORNELL}"]


@pytest.mark.parametrize("raw,said", [
    ({"builder": "ring", "params": {"n_segs": 8}},
     "geometry.params.n_segs: unknown parameter of builder ring (did you mean 'n_seg'?); its parameters: n_seg, "
     "radius, thickness, height, floor_nx, floor_nz, floor_cell, floor_back, glass_radius, glass_seg, glass_rings, "
     "glass_x, glass_z"),
    ([{"shape": "box"}, {"builder": "room", "params": {"grid_x": 4, "vase": 3}}],
     "geometry[1].params.vase: unknown parameter of builder room (did you mean 'vase_seg'?); its parameters: grid_x, "
     "grid_y, grid_z, glass_seg, glass_rings, vase_seg, leg_seg, sofa_div, furniture_div"),
    ([{"builder": "cornell", "params": {7: 1}}],
     f"geometry[0].params.7: unknown parameter of builder cornell; its parameters: {CORNELL}"),
])
def test_an_unknown_builder_parameter_is_named_by_its_key(raw, said):
    with pytest.raises(InputError) as got:
        compose_geometry(raw, "s.yaml", Path("s.yaml"))
    assert str(got.value) == f"s.yaml: {said}"
