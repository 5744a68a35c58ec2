"""A run's ``results.json`` records each light as ``tlm scene show`` lists it: its type and
power (the keys it always had, with the same values) and every field of its kind, so that two
runs differing in a spot's cone or a directional light's direction differ there too; the
report's reader still reads the run folder."""

from __future__ import annotations

import json
import math

import pytest
import yaml

import tlm
from tlm.experiments.run import scene_stats
from tlm.kernels.traverse import build_accel
from tlm.report.collect import read
from tlm.scenes.loader import load_scene

SPOT = {"type": "spot", "position": [2.0, 3.0, 0.0], "direction": [0.0, -2.0, 0.0], "power": [4.0, 4.0, 4.0],
        "inner_cone_angle": 10.0, "outer_cone_angle": 30.0}
SUN = {"type": "directional", "direction": [0.0, -1.0, 1.0], "irradiance": [0.5, 0.25, 1.0]}
POINT = {"type": "point", "position": [0.0, 3.0, 0.0], "power": [1.0, 2.0, 3.0]}
QUAD = {"type": "quad", "corner": [-0.5, 2.0, -0.5], "edge_u": [1.0, 0.0, 0.0], "edge_v": [0.0, 0.0, 1.0],
        "power": [5.0, 5.0, 5.0]}


def _scene(tmp_path, name="s.yaml", lights=(POINT, SPOT, SUN, QUAD)):
    path = tmp_path / name
    path.write_text(yaml.safe_dump({
        "geometry": [{"shape": "plane", "name": "floor", "params": {"size": [4.0, 4.0], "divisions": [2, 2]}},
                     {"shape": "box", "name": "lamp", "params": {"min": [-0.2, 1.0, -0.2], "max": [0.2, 1.2, 0.2]}}],
        "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]},
                      "glow": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5], "emission": [2.0, 2.0, 2.0]}},
        "parts": {"floor": "grey", "lamp": "glow"},
        "camera": {"eye": [0.0, 2.0, 6.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0}, "resolution": [16, 16],
        "lights": [dict(lt) for lt in lights],
    }))
    return path


def _lights(path):
    scene = load_scene(str(path))
    return scene_stats(scene, build_accel(scene.triangles, levels=2))["lights"]


def test_results_lights_are_the_scene_show_lights(tmp_path):
    path = _scene(tmp_path)
    recorded = json.loads(json.dumps(_lights(path)))  # (as results.json holds them)
    assert recorded == json.loads(json.dumps(tlm.scene_info(str(path))["lights"]))
    point, spot, sun, quad, mesh = recorded
    # (h333: each the scene file's entry it came from; the mesh light none, its materials' emission)
    assert [lt.pop("from") for lt in (point, spot, sun, quad)] == [f"{path}: lights[{i}]" for i in range(4)]
    # the keys results.json always had keep their names and values
    assert [lt["type"] for lt in recorded] == ["point", "spot", "directional", "quad", "mesh"]
    assert point == {"type": "point", "power": [1.0, 2.0, 3.0], "position": [0.0, 3.0, 0.0]}
    assert spot == {"type": "spot", "power": [4.0, 4.0, 4.0], "position": [2.0, 3.0, 0.0],
                    "direction": [0.0, -2.0, 0.0], "inner_cone_angle": 10.0, "outer_cone_angle": 30.0}
    assert set(sun) == {"type", "power", "direction", "irradiance"}
    assert sun["direction"] == [0.0, -1.0, 1.0] and sun["irradiance"] == [0.5, 0.25, 1.0]
    assert quad == {"type": "quad", "power": [5.0, 5.0, 5.0], "corner": [-0.5, 2.0, -0.5],
                    "edge_u": [1.0, 0.0, 0.0], "edge_v": [0.0, 0.0, 1.0], "area": 1.0}
    # the emitting box: 12 triangles, 2 * (0.4 * 0.4) + 4 * (0.4 * 0.2) square units, pi * Le * area watts
    assert mesh["materials"] == ["glow"] and mesh["triangles"] == 12
    assert mesh["area"] == pytest.approx(0.64, rel=1e-12)
    assert mesh["power"] == pytest.approx([math.pi * 2.0 * 0.64] * 3, rel=1e-12)


@pytest.mark.parametrize("changed", [{**SPOT, "outer_cone_angle": 20.0}, {**SPOT, "inner_cone_angle": 5.0},
                                     {**SPOT, "direction": [0.5, -2.0, 0.0]}, {**SPOT, "position": [2.0, 3.0, 1.0]}])
def test_spots_that_differ_only_in_their_cone_or_aim_differ_in_results(tmp_path, changed):
    a = _lights(_scene(tmp_path, "a.yaml", lights=[SPOT]))
    b = _lights(_scene(tmp_path, "b.yaml", lights=[changed]))
    a, b = ([{k: v for k, v in lt.items() if k != "from"} for lt in x] for x in (a, b))  # (their files differ)
    assert a[0]["power"] == b[0]["power"] and a != b


def test_suns_that_differ_only_in_direction_differ_in_results(tmp_path):
    a = _lights(_scene(tmp_path, "a.yaml", lights=[SUN]))
    b = _lights(_scene(tmp_path, "b.yaml", lights=[{**SUN, "direction": [1.0, -1.0, 0.0]}]))
    assert a[0]["power"] == b[0]["power"] and a[0]["direction"] != b[0]["direction"]


def test_a_run_folder_records_the_lights_and_the_report_reads_it(tmp_path, cache):
    path = _scene(tmp_path)
    cfg = {"scene": str(path), "mode": "rcast", "render": {"spp": 1, "light_samples": 1}}
    results = tlm.run(cfg, tmp_path / "run", outputs=[])
    written = json.loads((tmp_path / "run" / "results.json").read_text())
    assert written["scene"]["lights"] == results["scene"]["lights"]
    assert written["scene"]["lights"] == json.loads(json.dumps(tlm.scene_info(str(path))["lights"]))
    (run,) = read([tmp_path / "run"]).runs
    assert run.results["scene"]["lights"][1]["outer_cone_angle"] == 30.0
