"""Review h324 of 3415b80: a light's "faces the surface it lies against" warning in a scene with a wide
ground (near is the smaller of 0.02 of the scene's diagonal and half the light's size, not the diagonal's
share alone); a cached frame whose material a copy's MTL defines on another line (its origin in
frame_scenes' scene fingerprint); the report's Provenance of a sweep over one material (the scene once,
then only what differs; no more than MAX_CONFIGS records)."""

from __future__ import annotations

from pathlib import Path

from tlm import api
from tlm.kernels.traverse import build_accel
from tlm.render import checks

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "scenes" / "meshes"

# McGuire's box (about 2 units wide, its ceiling light facing down, 1.98 over the floor) on a ground 1000 wide:
# 0.02 of the scene's diagonal is 28, over ten times the room's height
GROUND = """\
geometry:
  - mesh: {mesh}
  - shape: quad
    name: ground
    params: {{corner: [-500.0, -0.01, 500.0], edge_u: [1000.0, 0.0, 0.0], edge_v: [0.0, 0.0, -1000.0]}}
materials:
  grass: {{type: lambertian, albedo: [0.3, 0.5, 0.2]}}
parts: {{ground: grass}}
camera: {{eye: [0.0, 1.0, 3.92], target: [0.0, 1.0, 0.0], up: [0.0, 1.0, 0.0], vfov: 39.3}}
resolution: [8, 8]
"""


def test_a_ceiling_light_facing_its_floor_is_not_warned_of_in_a_scene_on_a_wide_ground(tmp_path):
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GROUND.format(mesh=MESHES / "CornellBox-Original.obj"))
    scene = api.load_scene(scene_file)
    accel = build_accel(scene.triangles)
    (light,) = scene.lights
    assert checks.blocked_share(scene, accel, light)[0] == 0.0
    assert checks.light_warnings(scene, accel) == []


def test_a_quad_light_facing_its_ceiling_is_still_warned_of_on_a_wide_ground(tmp_path):
    """The same box with a quad light 2 cm under its ceiling (its corner at y 1.97) facing it: near is half its size."""
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GROUND.format(mesh=MESHES / "CornellBox-Original.obj") + (
        "lights: [{type: quad, corner: [-0.2, 1.97, -0.2], edge_u: [0.0, 0.0, 0.4], edge_v: [0.4, 0.0, 0.0], "
        "power: [5, 5, 5]}]\n"))
    scene = api.load_scene(scene_file)
    accel = build_accel(scene.triangles)
    said = [w for w in checks.light_warnings(scene, accel) if "quad" in w]
    assert len(said) == 1 and "swap edge_u and edge_v" in said[0], said
    assert "within 0.2 of it (the smaller of 0.02 of the scene's diagonal and 0.5 of its size;" in said[0], said


def test_a_copy_whose_mtl_defines_the_material_on_another_line_says_its_own_line(tmp_path, cache):
    from tlm.config import config_from_dict
    from tlm.experiments import frames

    said = []
    for p, head in (("p1", ""), ("p2", "# a comment\n# another\n")):
        d = tmp_path / p
        d.mkdir()
        (d / "m.obj").write_text("mtllib m.mtl\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nusemtl grey\nf 1 2 3 4\n")
        (d / "m.mtl").write_text(head + "newmtl grey\nKd 0.5 0.5 0.5\n")
        (d / "s.yaml").write_text("name: s\ngeometry: {mesh: m.obj}\n"
                                  "lights: [{type: point, position: [0.0, 1.0, 0.0], power: [1.0, 1.0, 1.0]}]\n"
                                  "camera: {eye: [0.0, 2.0, 3.0], target: [0.0, 0.0, 0.0], vfov: 40.0}\n")
        got = frames.cached_render(config_from_dict({"scene": str(d / "s.yaml"), "mode": "rcast",
                                                     "resolution": [8, 8]}))
        said.append(got.summary["scene"]["materials"]["grey"]["from"])
    assert said == [f"{tmp_path / 'p1' / 'm.mtl'}:1", f"{tmp_path / 'p2' / 'm.mtl'}:3"]


def _point(k: int, mats: dict, lights: list):
    from tlm.report.collect import Run

    return Run(Path(f"sw/{k}"), f"sw #{k}", "sweep-point",
               {"scene": {"name": "conference", "source": "/p/conference.yaml", "materials": mats, "lights": lights}},
               {})


def test_a_sweep_over_one_material_lists_the_scene_once_and_then_the_material_that_differs():
    from tlm.report import provenance

    mats = {f"mesh{i}_SG": {"kind": "lambertian", "triangles": 100, "albedo": [0.5, 0.5, 0.5],
                            "from": f"/p/conference.mtl:{9 * i}"} for i in range(36)}
    lights = [{"type": "point", "power": [1.0, 1.0, 1.0], "position": [0.0, 1.0, 0.0]}]
    runs = [_point(k, {**mats, "mesh29_SG": {**mats["mesh29_SG"], "albedo": [k / 4, 0.5, 0.5]}}, lights)
            for k in range(4)]
    runs.append(_point(4, mats, [{**lights[0], "power": [2.0, 2.0, 2.0]}]))
    tables = provenance.scene_tables(runs)
    assert len(tables) == 5
    assert tables[0].count("<tr>") == 1 + 36 + 1 + 1  # (its materials' and its lights' heads and rows)
    for k in (1, 2, 3):
        assert f"as for run sw #0, but 1 material (run sw #{k})" in tables[k], tables[k]
        assert tables[k].count("<tr>") == 2 and f"albedo {k / 4:g} 0.5 0.5" in tables[k], tables[k]
    assert "as for run sw #0, but 1 material and its lights (run sw #4)" in tables[4], tables[4]
    assert "<td class=\"l\">2 2 2</td>" in tables[4]
    # a sweep of more records than the report lists: the first MAX_CONFIGS, the rest counted
    many = [_point(k, {**mats, "mesh29_SG": {**mats["mesh29_SG"], "albedo": [k / 200, 0.5, 0.5]}}, lights)
            for k in range(200)]
    tables = provenance.scene_tables(many)
    assert len(tables) == provenance.MAX_CONFIGS + 1
    assert tables[-1] == (f"<p>The materials and lights of {200 - provenance.MAX_CONFIGS} more scene records "
                          f"({200 - provenance.MAX_CONFIGS} runs) are not listed: each run's results.json holds "
                          "them (scene.materials, scene.lights).</p>")
    assert sum(map(len, tables)) < 100_000
