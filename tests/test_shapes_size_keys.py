"""A ``shape:`` item too large for the machine is refused naming the keys the scene file
gave (``segments``, ``rings``, ``divisions``: docs/scenes.md), not the builder's internal
parameters (``n_seg``, ``n_rings``, ``nu``, ``nv``, ``n``)."""

from __future__ import annotations

import json

import pytest

from tlm.errors import InputError
from tlm.scenes import shapes
from tlm.scenes.loader import load_scene

BASE = {
    "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
    "default_material": "grey",
    "lights": [{"type": "point", "position": [0.0, 3.0, 0.0], "power": [10.0, 10.0, 10.0]}],
    "camera": {"eye": [0.0, 1.0, -4.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0},
    "resolution": [8, 8],
}


@pytest.mark.parametrize("shape,params,said", [
    ("cylinder", {"segments": 1000},
     "a cylinder of segments = 1000 (4 triangles a segment) makes 4,000 triangles"),
    ("sphere", {"segments": 100, "rings": 40}, "a sphere of segments = 100 and rings = 40 makes 7,800 triangles"),
    ("box", {"divisions": 30}, "divisions = 30 (a side, on each of 6 faces) makes 10,800 triangles"),
    ("plane", {"divisions": [40, 50]}, "divisions = [40, 50] makes 4,000 triangles"),
    ("quad", {"corner": [0, 0, 0], "edge_u": [1, 0, 0], "edge_v": [0, 1, 0], "divisions": [50, 40]},
     "divisions = [50, 40] makes 4,000 triangles"),
])
def test_a_shape_too_large_names_the_scene_files_keys(tmp_path, cache, monkeypatch, shape, params, said):
    monkeypatch.setattr(shapes, "machine_memory", lambda: 2000 * shapes.TRIANGLE_BYTES)  # (2,000 triangles fit)
    scene = tmp_path / "s.yaml"
    floor = {"shape": "plane", "params": {"size": [4.0, 4.0]}}
    scene.write_text(json.dumps({**BASE, "geometry": [floor, {"shape": shape, "params": params}]}))
    with pytest.raises(InputError) as got:
        load_scene(str(scene))
    message = str(got.value)
    assert message.startswith(f"{scene}: geometry[1].params: {said}, about ")
    assert "more than this machine's" in message
    for internal in ("n_seg", "n_rings", "nu =", "nv =", "n ="):
        assert internal not in message


def test_a_cylinder_is_checked_at_the_count_it_makes():
    """The cylinder's own check counts what lathe makes, caps or not: one triangle more than fits is refused."""
    for bottom, top in ((True, True), (True, False), (False, False)):
        n = len(shapes.cylinder((0, 0, 0), 1.0, 2.0, 9, bottom=bottom, top=top))
        assert n == (2 + bottom + top) * 9
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(shapes, "machine_memory", lambda n=n: n * shapes.TRIANGLE_BYTES - 1)
            with pytest.raises(ValueError, match=rf"^a cylinder of segments = 9 \({2 + bottom + top} triangles a "
                                                 rf"segment\) makes {n} triangles"):
                shapes.cylinder((0, 0, 0), 1.0, 2.0, 9, bottom=bottom, top=top)
