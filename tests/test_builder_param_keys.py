"""A ``builder:`` item's refusals name the keys the scene file wrote under ``params:``
(``geometry[0].params.glass_seg``), not the shapes' own parameters (``segments``,
``rings``, ``nu``, ``n_seg``): a size too large for the machine, a value that is not a
positive whole number or not a positive number, a radius or position that does not fit."""

from __future__ import annotations

import inspect
import math
import re
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes import shapes
from tlm.scenes.builders import BUILDERS
from tlm.scenes.loader import load_scene

BASE = {
    "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
    "default_material": "grey",
    "lights": [{"type": "point", "position": [0.0, 3.0, 0.0], "power": [10.0, 10.0, 10.0]}],
    "camera": {"eye": [0.0, 1.0, -4.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0},
    "resolution": [8, 8],
}
DEFAULT_COUNT = {"cornell": 2604, "ring": 646, "room": 7812}  # (the thesis's counts: docs, builders.py)
# what the shapes call their sizes, which a scene file's builder params never do
INTERNAL = r"\bsegments =|\brings =|\bnu =|\bnv =|\bn =|n_rings|divisions|a sphere|a cylinder|profile"


def scene_file(tmp_path: Path, builder: str, params: dict) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({**BASE, "geometry": [{"builder": builder, "params": params}]}))
    return path


def refusal(tmp_path: Path, builder: str, params: dict) -> str:
    path = scene_file(tmp_path, builder, params)
    with pytest.raises(InputError) as got:
        load_scene(str(path))
    message = str(got.value)
    assert "\n" not in message
    prefix = f"{path}: "
    assert message.startswith(prefix), message
    return message[len(prefix):]


@pytest.mark.parametrize("builder,params,named", [
    ("cornell", {"wall_div": 7}, "wall_div = 7"),
    ("cornell", {"block_div": 4}, "block_div = 4"),
    ("cornell", {"mirror_seg": 31}, "mirror_seg = 31 and mirror_rings = 15"),
    ("cornell", {"glass_rings": 19}, "glass_seg = 36 and glass_rings = 19"),
    ("ring", {"n_seg": 73}, "n_seg = 73"),
    ("ring", {"floor_nx": 8}, "floor_nx = 8 and floor_nz = 5"),
    ("ring", {"glass_radius": 1.0}, "glass_radius = 1.0, glass_seg = 16 and glass_rings = 9"),
    ("room", {"grid_y": 11}, "grid_x = 20, grid_y = 11 and grid_z = 23"),
    ("room", {"glass_seg": 35}, "glass_seg = 35 and glass_rings = 17"),
    ("room", {"vase_seg": 41}, "vase_seg = 41"),
    ("room", {"leg_seg": 17}, "leg_seg = 17"),
    ("room", {"sofa_div": 4}, "sofa_div = 4"),
    ("room", {"furniture_div": 3}, "furniture_div = 3"),
])
def test_a_builder_too_large_names_the_scene_files_keys(tmp_path, cache, monkeypatch, builder, params, named):
    """On a machine that holds the builder's default scene and not one triangle more, a
    scene file asking for more is refused before anything is made, naming what it changed."""
    fits = DEFAULT_COUNT[builder]
    monkeypatch.setattr(shapes, "machine_memory", lambda: fits * shapes.TRIANGLE_BYTES)
    assert len(BUILDERS[builder]().triangles) == fits
    message = refusal(tmp_path, builder, params)
    assert message.startswith(f"geometry[0].params: {builder} with {named} makes "), message
    assert "more than this machine's" in message
    assert not re.search(INTERNAL, message), message


def test_a_huge_glass_sphere_in_the_cornell_box_is_refused_by_its_keys(tmp_path, cache, capsys):
    """At the machine's own memory: one line, exit 2, and no run folder."""
    params = {"glass_seg": 100000, "glass_rings": 100000}
    message = refusal(tmp_path, "cornell", params)
    assert message.startswith("geometry[0].params: cornell with glass_seg = 100000 and glass_rings = 100000 makes "
                              "19,999,801,380 triangles, about 9,537 GiB to render"), message
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "s.yaml"), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "geometry[0].params: cornell with glass_seg = 100000" in err, err
    assert not out.exists()
    assert main(["scene", "show", str(tmp_path / "s.yaml")]) == 2


@pytest.mark.parametrize("builder,params", [
    ("cornell", {"wall_div": 2, "block_div": 1, "mirror_seg": 5, "mirror_rings": 3, "glass_seg": 4, "glass_rings": 2}),
    ("cornell", {}),
    ("ring", {"n_seg": 5, "floor_nx": 3, "floor_nz": 4, "glass_radius": 1.0, "glass_seg": 3, "glass_rings": 2}),
    ("ring", {}),
    ("room", {"grid_x": 1, "grid_y": 2, "grid_z": 3, "glass_seg": 3, "glass_rings": 2, "vase_seg": 3, "leg_seg": 3,
              "sofa_div": 1, "furniture_div": 1}),
])
def test_a_builder_is_checked_against_the_machine_at_the_count_it_makes(monkeypatch, builder, params):
    """The whole builder's count, not each of its pieces': what fits exactly is made, one
    triangle more is refused."""
    make = BUILDERS[builder]
    n = len(make(**params).triangles)
    monkeypatch.setattr(shapes, "machine_memory", lambda: n * shapes.TRIANGLE_BYTES)
    assert len(make(**params).triangles) == n
    monkeypatch.setattr(shapes, "machine_memory", lambda: n * shapes.TRIANGLE_BYTES - 1)
    with pytest.raises(ValueError, match=rf"^{builder} with .* makes {n:,} triangles"):
        make(**params)


def _refused(builder: str, key: str) -> list:
    """Values of ``key`` each refused on its own: a string, NaN, and a negative number
    where one is no position."""
    bad = ["x", math.nan, True]
    if key not in ("glass_x", "glass_z"):
        bad.append(-1)
    return bad


@pytest.mark.parametrize("builder,key", [(b, k) for b, f in BUILDERS.items() for k in inspect.signature(f).parameters])
def test_every_parameter_is_refused_by_its_own_key(tmp_path, cache, builder, key):
    for value in _refused(builder, key):
        message = refusal(tmp_path, builder, {key: value})
        assert message.startswith(f"geometry[0].params.{key}: {value!r} must "), message


@pytest.mark.parametrize("builder,params,key,says", [
    ("cornell", {"wall_div": 2.5}, "wall_div", "2.5 must be a whole number >= 1"),
    ("cornell", {"mirror_seg": 2}, "mirror_seg", "2 must be a whole number >= 3"),
    ("cornell", {"glass_rings": 1}, "glass_rings", "1 must be a whole number >= 2"),
    ("cornell", {"mirror_radius": 150}, "mirror_radius", "150 must be at most 140 mm"),
    ("cornell", {"glass_radius": 120}, "glass_radius", "120 must be at most 110 mm"),
    ("ring", {"radius": 0}, "radius", "0 must be a positive number"),
    ("ring", {"floor_back": 1.0}, "floor_back", "1.0 must lie in (0, 1)"),
    ("ring", {"glass_seg": 2}, "glass_seg", "2 must be a whole number >= 3"),  # (checked without the sphere too)
    ("ring", {"glass_radius": 1.0, "glass_x": ".5"}, "glass_x", "'.5' must be a finite number"),
    ("room", {"sofa_div": 0}, "sofa_div", "0 must be a whole number >= 1"),
    # (a Python int beyond int64 and float)
    ("room", {"leg_seg": 10**400}, None, "room with leg_seg = a 401-digit number makes a 401-digit number"),
    # a length or a place that no float can hold: one line (was an OverflowError, exit 1)
    ("ring", {"radius": 10**400}, "radius", "a 401-digit number is too large"),
    ("ring", {"thickness": 10**400}, "thickness", "a 401-digit number is too large"),
    ("ring", {"glass_radius": 1.0, "glass_x": -10**400}, "glass_x", "a negative 401-digit number is too large"),
    ("cornell", {"mirror_radius": 10**400}, "mirror_radius", "a 401-digit number is too large"),
])
def test_a_refusal_says_the_value_as_written(tmp_path, cache, builder, params, key, says):
    message = refusal(tmp_path, builder, params)
    where = f"geometry[0].params.{key}" if key else "geometry[0].params"
    assert message.startswith(f"{where}: {says}"), message


@pytest.mark.parametrize("params,keys", [
    ({"thickness": 6.0}, ("thickness = 6.0", "radius = 5.0")),
    ({"floor_nx": 1, "floor_cell": 8.0},
     ("floor_nx * floor_cell = 8.0 cm", "floor_back * floor_nz * floor_cell = 16.0 cm", "radius = 5.0")),
    ({"floor_back": 0.05}, ("floor_back * floor_nz * floor_cell = 2.5 cm", "radius = 5.0")),
    ({"glass_radius": 3.0, "glass_x": 4.0, "glass_z": 0.0},
     ("glass_radius = 3.0", "glass_x = 4.0", "glass_z = 0.0", "would touch the ring of radius = 5.0")),
    ({"glass_radius": 3.0, "glass_x": 40.0}, ("glass_radius = 3.0", "glass_x = 40.0", "does not stand on the floor")),
])
def test_a_ring_that_does_not_fit_names_the_keys_that_place_it(tmp_path, cache, params, keys):
    message = refusal(tmp_path, "ring", params)
    assert message.startswith("geometry[0].params: "), message
    for k in keys:
        assert k in message, message
