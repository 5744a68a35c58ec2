"""A run's ``results.json`` records the scene's materials as the renderer used them (each kind's
values, emission, what the MTL gave that tlm does not render, where a scene file's entry came from)
and its lights with where they came from; the report's Provenance section lists them per scene,
and reads a ``results.json`` of an older tlm (each material's kind and triangles only) as before,
saying the values were not recorded."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.experiments.run import scene_stats
from tlm.kernels.traverse import build_accel
from tlm.report.collect import Run, read
from tlm.report.provenance import provenance_section, scene_tables
from tlm.scenes.loader import load_scene

REPO = Path(__file__).resolve().parents[1]

# a floor, a mirror and a glass quad, and a ceiling lamp: each its own usemtl block
MTL = """\
# the test's materials
newmtl floor
  Kd 0.725 0.71 0.68
  map_Kd wood.png
newmtl mirror
  illum 3
  Ks 0.9 0.8 0.7
newmtl glass
  illum 7
  Ni 1.45
newmtl light
  Kd 0.78 0.78 0.78
  Ke 17 12 4
newmtl box
  Kd 0.1 0.2 0.3
"""


def _quad(v0: int, y: float, x0: float, flip: bool = False) -> tuple[list[str], list[str]]:
    vs = [f"v {x0} {y} 0", f"v {x0 + 1} {y} 0", f"v {x0 + 1} {y} 1", f"v {x0} {y} 1"]
    a, b, c, d = (v0 + k for k in range(1, 5))
    fs = [f"f {a} {c} {b}", f"f {a} {d} {c}"] if flip else [f"f {a} {b} {c}", f"f {a} {c} {d}"]
    return vs, fs


def _scene(tmp_path: Path) -> Path:
    """An OBJ of five quads with :data:`MTL`, and a scene file that replaces its ``box`` material."""
    lines = ["mtllib m.mtl"]
    for i, (name, y, x0, flip) in enumerate([("floor", 0.0, 0.0, False), ("mirror", 0.0, 1.0, False),
                                             ("glass", 0.5, 0.0, False), ("light", 2.0, 0.0, True),
                                             ("box", 0.0, -1.0, False)]):
        vs, fs = _quad(4 * i, y, x0, flip)
        lines += [*vs, f"usemtl {name}", *fs]
    (tmp_path / "m.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "m.mtl").write_text(MTL)
    scene = tmp_path / "s.yaml"
    scene.write_text("geometry: {mesh: m.obj}\n"
                     "materials: {box: {type: lambertian, albedo: [0.5, 0.25, 0.125]}}\n"
                     "camera: {eye: [0.5, 1.0, 4.0], target: [0.5, 0.5, 0.5], vfov: 40.0}\n"
                     "resolution: [8, 8]\nphotons: 200\n")
    return scene


def _plain(v) -> bool:
    """Whether ``v`` is JSON's own types all through (no numpy scalar, no tuple)."""
    if isinstance(v, dict):
        return all(isinstance(k, str) and _plain(x) for k, x in v.items())
    if isinstance(v, list):
        return all(_plain(x) for x in v)
    return v is None or (type(v) in (str, int, float, bool) and not isinstance(v, np.generic))


def test_scene_stats_record_the_values_as_the_mtl_says_them(tmp_path):
    scene_file = _scene(tmp_path)
    scene = load_scene(str(scene_file))
    stats = scene_stats(scene, build_accel(scene.triangles, levels=2))
    assert _plain(stats["materials"]) and _plain(stats["lights"])
    mats = stats["materials"]
    # (its "from", the MTL's line, where the mesh loader records it: tlm.scenes.meshes)
    assert {k: v for k, v in mats["floor"].items() if k != "from"} == {
        "kind": "lambertian", "triangles": 2, "albedo": [0.725, 0.71, 0.68], "ignored": ["map_Kd"]}
    assert mats["mirror"]["kind"] == "mirror" and mats["mirror"]["reflectance"] == [0.9, 0.8, 0.7]
    assert mats["glass"]["kind"] == "dielectric" and mats["glass"]["ior"] == 1.45
    assert mats["glass"]["transmittance"] == [1.0, 1.0, 1.0]
    assert mats["light"]["albedo"] == [0.78, 0.78, 0.78] and mats["light"]["emission"] == [17.0, 12.0, 4.0]
    # the scene file's entry replaced the MTL's box: its values, and the file and key that gave them
    assert mats["box"] == {"kind": "lambertian", "triangles": 2, "albedo": [0.5, 0.25, 0.125],
                           "from": f"{scene_file}: materials.box"}
    (mesh,) = stats["lights"]
    assert mesh["type"] == "mesh" and mesh["materials"] == ["light"] and mesh["triangles"] == 2


def test_a_light_a_gltf_gave_says_where_it_came_from(tmp_path):
    from tests.test_gltf_lights import _scene_glb, _yaml

    glb = _scene_glb(tmp_path)  # (a lamp on two nodes, a spot 'beam' on one)
    scene = load_scene(str(_yaml(tmp_path, "geometry: {mesh: s.glb}\n")))
    lights = scene_stats(scene, build_accel(scene.triangles, levels=2))["lights"]
    # (h333: its file as a glTF material's from names it, the path, and its key; Light.origin)
    punctual = f"{glb} KHR_lights_punctual.lights"
    assert [lt["from"] for lt in lights if lt["type"] != "mesh"] == [
        f"{punctual}[0] 'lamp' at nodes[2]", f"{punctual}[0] 'lamp' at nodes[3]", f"{punctual}[1] 'beam' at nodes[5]"]


@pytest.fixture(scope="module")
def small_run(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("h318")
    scene = _scene(root)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(root / "run"), "--set",
                     f"scene={scene}", "--set", "arch.frames=2", "--set", "render.light_samples=1", "--set",
                     "mode=rcast", "--set", "arch.trace=false", "--no-report", "--no-progress",
                     "--no-reference"]) == 0
    return root / "run"


def test_a_run_records_what_it_read(small_run):
    scene = json.loads((small_run / "results.json").read_text())["scene"]
    assert scene["materials"]["floor"]["albedo"] == [0.725, 0.71, 0.68]
    assert scene["materials"]["floor"]["ignored"] == ["map_Kd"]
    assert scene["materials"]["glass"]["ior"] == 1.45 and scene["materials"]["light"]["emission"] == [17.0, 12.0, 4.0]
    assert scene["materials"]["box"]["from"].endswith("s.yaml: materials.box")


def _old(results: dict) -> dict:
    """``results`` as a tlm before this record wrote them: each material's kind and triangles."""
    out = json.loads(json.dumps(results))
    out["scene"]["materials"] = {k: {"kind": m["kind"], "triangles": m["triangles"]}
                                 for k, m in out["scene"]["materials"].items()}
    return out


def test_the_provenance_section_lists_them_and_reads_an_old_run(small_run, tmp_path):
    new, old = tmp_path / "runs" / "new", tmp_path / "runs" / "old"
    shutil.copytree(small_run, new)
    shutil.copytree(small_run, old)
    (old / "results.json").write_text(json.dumps(_old(json.loads((small_run / "results.json").read_text()))))
    html = provenance_section(read([new, old]), tmp_path).html
    assert "albedo 0.725 0.71 0.68" in html and "map_Kd" in html and "ior 1.45" in html and "17 12 4" in html
    assert "materials.box" in html
    assert "Material values: not recorded by the tlm of this run (an older one); 5 materials" in html
    # the whole report, of the old run alone, as before
    assert main(["report", str(old), "--out", str(tmp_path / "rep"), "--no-progress"]) == 0
    assert "not recorded by the tlm of this run" in (tmp_path / "rep" / "report.html").read_text()


def test_runs_of_one_scene_are_listed_once(small_run):
    results = json.loads((small_run / "results.json").read_text())
    other = json.loads(json.dumps(results))
    other["scene"]["materials"]["floor"]["albedo"] = [0.5, 0.5, 0.5]
    runs = [Run(Path(f"sw/{i}"), f"sw #{i}", "sweep-point", r, {}) for i, r in enumerate([results, results, other])]
    tables = scene_tables(runs)
    assert len(tables) == 2
    assert "(runs sw #0 and sw #1)" in tables[0] and "(run sw #2)" in tables[1]
    assert "albedo 0.5 0.5 0.5" in tables[1] and "albedo 0.5 0.5 0.5" not in tables[0]
    # none recorded at all (a results.json with no materials or lights): said, no error
    (bare,) = scene_tables([Run(Path("x"), "x", "run", {"scene": {"name": "x"}}, {})])
    assert "not recorded by the tlm of this run" in bare and "Lights: not recorded" in bare


def test_a_copy_s_cached_frame_names_the_copy_s_files(tmp_path, cache):
    """A cached frame is shared by a copy of its project in another folder (its key is the scene's content): the
    copy's ``scene.materials`` say its own scene file gave its material."""
    from tlm.config import config_from_dict
    from tlm.experiments import frames

    got = []
    for p in ("p1", "deeper/p2"):
        scene = tmp_path / p / "s.yaml"
        scene.parent.mkdir(parents=True)
        scene.write_text("geometry: {shape: plane, name: floor, params: {size: [2.0, 2.0]}}\n"
                         "materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\nparts: {floor: grey}\n"
                         "lights: [{type: point, position: [0.0, 1.0, 0.0], power: [1.0, 1.0, 1.0]}]\n"
                         "camera: {eye: [0.0, 2.0, 3.0], target: [0.0, 0.0, 0.0], vfov: 40.0}\n")
        got.append(frames.cached_render(config_from_dict({"scene": str(scene), "mode": "rcast",
                                                          "resolution": [8, 8]})))
    assert [g.cached for g in got] == [False, True]
    assert [g.summary["scene"]["materials"]["grey"]["from"] for g in got] == [
        f"{tmp_path}/{p}/s.yaml: materials.grey" for p in ("p1", "deeper/p2")]


def test_a_material_of_an_mtl_says_its_line(tmp_path):
    """(with tlm/scenes/meshes.py setting Material.origin: /tmp/h318/origin_h316.patch)"""
    scene_file = _scene(tmp_path)
    scene = load_scene(str(scene_file))
    mats = scene_stats(scene, build_accel(scene.triangles, levels=2))["materials"]
    mtl = tmp_path / "m.mtl"
    assert {k: m["from"] for k, m in mats.items()} == {
        "floor": f"{mtl}:2", "mirror": f"{mtl}:5", "glass": f"{mtl}:8", "light": f"{mtl}:11",
        "box": f"{scene_file}: materials.box"}


def test_a_mesh_cache_entry_keeps_the_mtl_line_for_each_copy(tmp_path, cache):
    """A mesh large enough for the scene cache (tlm.scenes.cache.MIN_TRIANGLES) shared by two copies of its folder:
    each copy's material names its own MTL."""
    side = 101  # (2 x 100 x 100 triangles)
    verts = [f"v {i * 0.01} 0 {j * 0.01}" for i in range(side) for j in range(side)]
    faces = [f"f {a} {a + 1} {a + side + 1}\nf {a} {a + side + 1} {a + side}"
             for a in (i * side + j + 1 for i in range(side - 1) for j in range(side - 1))]
    for p in ("a", "b"):
        (tmp_path / p).mkdir()
        (tmp_path / p / "big.obj").write_text("\n".join(["mtllib m.mtl", "usemtl grey", *verts, *faces]) + "\n")
        (tmp_path / p / "m.mtl").write_text("# the test's\nnewmtl grey\nKd 0.25 0.5 0.75\n")
        (tmp_path / p / "s.yaml").write_text(
            "geometry: {mesh: big.obj}\nresolution: [8, 8]\n"
            "camera: {eye: [0.5, 2, 0.5], target: [0.5, 0, 0.5], up: [0, 0, 1], vfov: 40}\n"
            "lights: [{type: point, position: [0.5, 1, 0.5], power: [1, 1, 1]}]\n")
    for p in ("a", "b", "a"):
        (grey,) = load_scene(str(tmp_path / p / "s.yaml")).materials
        assert grey.info() == {"kind": "lambertian", "albedo": [0.25, 0.5, 0.75], "from": f"{tmp_path / p}/m.mtl:2"}
    assert list((cache / "scenes").glob("mesh-*"))  # (the parse was kept, and served the copies)
