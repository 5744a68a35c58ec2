"""A researcher's own scene (probe h202): what loads silently wrong is said. A ``materials:``
entry no triangle can take (a typo of an MTL name) is refused; a light of zero power among
lit ones is warned of; a glTF specular-glossiness material says it is a white mirror; an
MTL's clipped colour and repeated ``newmtl`` are noted; an empty GLB and a glTF 1.0 file
are named as such; docs/scenes.md says how a second file's ``light`` is renamed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm import api
from tlm.config import RunConfig
from tlm.errors import InputError
from tlm.render.checks import material_warnings, zero_power_warnings
from tlm.render.planner import plan
from tlm.scenes.materials import check_gltf, glb_chunks, parse_mtl, write_glb

REPO = Path(__file__).resolve().parents[1]
CAMERA = "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n"
OBJ = ("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
       "usemtl tallBox\nf 1 2 3\nusemtl floor\nf 2 4 3\n")
MTL = "newmtl tallBox\nKd 0.7 0.7 0.7\nnewmtl floor\nKd 0.5 0.5 0.5\n"
LIGHT = "lights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]}]\n"


def _scene(tmp_path: Path, extra: str, mtl: str = MTL) -> Path:
    (tmp_path / "m.obj").write_text(OBJ)
    (tmp_path / "m.mtl").write_text(mtl)
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + extra)
    return tmp_path / "s.yaml"


# ------------------------------------------------------------ 1. a materials: entry no triangle takes


def test_a_materials_entry_named_after_no_file_material_is_refused_with_the_nearest_name(tmp_path):
    path = _scene(tmp_path, LIGHT + "materials: {tallbox: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n")
    with pytest.raises(InputError) as e:
        api.load_scene(path)
    assert str(e.value).startswith(f"{path}: materials.tallbox: used by no triangle (the mesh files' materials: "
                                   "tallBox and floor; did you mean 'tallBox'?)"), e.value
    assert "\n" not in str(e.value)
    path = _scene(tmp_path, LIGHT + "materials: {shiny: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n")
    with pytest.raises(InputError, match=r"materials\.shiny: used by no triangle \(the mesh files' materials: "
                                         r"tallBox and floor\): "):
        api.load_scene(path)
    # an entry a file's material, a part or default_material names loads, and so does every built-in scene
    mirror = "{type: mirror, reflectance: [0.9, 0.9, 0.9]}"
    scene = api.load_scene(_scene(tmp_path, LIGHT + f"materials: {{tallBox: {mirror}}}\n"))
    assert scene.materials[0].kind == "mirror"
    scene = api.load_scene(_scene(tmp_path, LIGHT + f"materials: {{shiny: {mirror}}}\nparts: {{m: shiny}}\n"))
    assert {m.name for m in scene.materials} >= {"shiny"}
    scene = api.load_scene(_scene(tmp_path, LIGHT + f"materials: {{shiny: {mirror}}}\ndefault_material: shiny\n"))
    assert "shiny" in {m.name for m in scene.materials}
    # a palette entry of a scene whose files name no material (a shape's parts): a note, not an error
    (tmp_path / "p.yaml").write_text("geometry: {shape: plane, name: floor, params: {size: [4, 4]}}\n" + CAMERA
                                     + LIGHT + f"materials: {{white: {mirror}, red: {mirror}}}\n"
                                     "parts: {floor: white}\n")
    notes = api.load_scene(tmp_path / "p.yaml").extra["notes"]
    assert f"{tmp_path / 'p.yaml'}: materials.red: used by no triangle (no part under parts: names it and it is " \
           "not default_material): it is not rendered" in notes, notes
    from tlm.scenes.loader import list_scenes, scenes_dir

    for name in list_scenes():
        if not (scenes_dir() / f"{name}.yaml").read_text().startswith("# Bad input"):
            api.load_scene(name)


def test_an_entry_inherited_through_extends_that_a_child_leaves_unused_is_a_note_naming_the_parent(tmp_path):
    """(h219, 1) the check ran on the merged file: a child that moved a part to a material of its own made the
    parent's entry "used by no triangle", exit 2, and the child cannot take an entry out (``glass: null``)."""
    glass = "{type: dielectric, ior: 1.5, transmittance: [0.9, 0.9, 0.9]}"
    parent = _scene(tmp_path, LIGHT + "geometry:\n  - {mesh: m.obj}\n  - {shape: plane, name: ball, params: "
                    f"{{size: [1, 1]}}}}\nmaterials: {{glass: {glass}}}\nparts: {{ball: glass}}\n")
    parent.write_text(parent.read_text().replace("geometry: {mesh: m.obj}\n", ""))
    api.load_scene(parent)
    child = tmp_path / "child.yaml"
    child.write_text("extends: s.yaml\nmaterials: {chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n"
                     "parts: {ball: chrome}\n")
    scene = api.load_scene(child)
    assert [m.kind for m in scene.materials if m.name == "chrome"] == ["mirror"]
    assert f"{child}: materials.glass (given by {parent}, through extends:): used by no triangle here: it is not " \
           "rendered" in scene.extra["notes"], scene.extra["notes"]
    # the child's own entry that no triangle takes is still refused
    child.write_text("extends: s.yaml\nmaterials: {chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n")
    with pytest.raises(InputError, match=r"child\.yaml: materials\.chrome: used by no triangle"):
        api.load_scene(child)


def test_a_typo_in_a_parts_value_is_blamed_on_the_value_not_on_the_material_it_leaves_unused(tmp_path):
    """(h219, 2) ``parts: {ball: glas}`` said ``materials.glass: used by no triangle``."""
    path = _scene(tmp_path, LIGHT + "geometry:\n  - {mesh: m.obj}\n  - {shape: plane, name: ball, params: "
                  "{size: [1, 1]}}\nmaterials: {glass: {type: dielectric, ior: 1.5, transmittance: [1, 1, 1]}}\n"
                  "parts: {ball: glas}\n")
    path.write_text(path.read_text().replace("geometry: {mesh: m.obj}\n", ""))
    with pytest.raises(InputError) as e:
        api.load_scene(path)
    assert str(e.value) == f"{path}: parts.ball: 'glas' is not a material (did you mean 'glass'?)"


def test_the_cli_exits_2_on_an_unused_materials_entry(tmp_path, capsys):
    from tlm.cli import main

    path = _scene(tmp_path, LIGHT + "materials: {tallbox: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n")
    assert main(["scene", "show", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "materials.tallbox: used by no triangle" in err[0] and "'tallBox'" in err[0], err


# ------------------------------------------------------------ 2. a light of zero power beside lit ones


def test_a_zero_power_light_among_lit_ones_is_warned_of_once(tmp_path):
    """(h219, 5) a stdout note of the plan said it too, and results.json held both: the warning alone."""
    lights = ("lights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]},\n"
              "         {type: point, position: [0.6, 0.3, 1], power: [0, 0, 0]}]\n")
    scene = api.load_scene(_scene(tmp_path, lights))
    (line,) = zero_power_warnings(scene)
    assert line.startswith("lights[1] (point) has zero power: its shadow rays") and "timing model" in line, line
    assert not [n for n in plan(scene, RunConfig(mode="rcast")).notes if "zero power" in n]
    results = api.run(RunConfig(scene=str(tmp_path / "s.yaml"), mode="rcast"), tmp_path / "out")
    assert line in results["warnings"]
    said = [w for w in [*results["warnings"], *results["plan"].get("notes", [])] if "zero power" in w]
    assert said == [line], said
    # every light off: the black image and the plan's note say so, not a line per light
    off = api.load_scene(_scene(tmp_path, "lights: [{type: point, position: [0.3, 0.3, 1], power: [0, 0, 0]}]\n"))
    assert zero_power_warnings(off) == []
    assert zero_power_warnings(api.load_scene(_scene(tmp_path, LIGHT))) == []


# ------------------------------------------------------------ 3. KHR_materials_pbrSpecularGlossiness


def test_a_specular_glossiness_material_says_it_renders_as_a_white_mirror(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    scene = trimesh.Scene()
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(name="sg", baseColorFactor=[200, 100, 50, 255]))
    scene.add_geometry(box, geom_name="box")
    scene.export(tmp_path / "raw.glb")
    header, binary = glb_chunks((tmp_path / "raw.glb").read_bytes())
    header["materials"] = [{"name": "specgloss_red", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
        "diffuseFactor": [0.8, 0.1, 0.1, 1], "specularFactor": [0, 0, 0], "glossinessFactor": 0.0}}}]
    (tmp_path / "b.glb").write_bytes(write_glb(header, binary))
    (tmp_path / "s.yaml").write_text("geometry: {mesh: b.glb}\ncamera: {eye: [0, 0, 4], target: [0, 0, 0], vfov: 40}"
                                     "\nresolution: [8, 8]\n" + LIGHT.replace("1]", "3]"))
    s = api.load_scene(tmp_path / "s.yaml")
    assert s.materials[0].kind == "mirror" and s.materials[0].reflectance == (1.0, 1.0, 1.0)
    (line,) = material_warnings(s)
    assert "KHR_materials_pbrSpecularGlossiness (read as its fallback pbrMetallicRoughness, whose metallicFactor " \
           "defaults to 1: a mirror)" in line, line
    assert "it renders with its constant colour, as a mirror of reflectance [1, 1, 1] (" in line, line


# ------------------------------------------------------------ 4. MTL colours clipped, newmtl repeated


def test_an_mtl_colour_over_1_and_a_repeated_newmtl_are_noted_with_file_line_and_value(tmp_path):
    notes: list[str] = []
    mats = parse_mtl("newmtl floor\nKd 185 181 173\nnewmtl glossy\nillum 3\nKs 1.5 1 1\n"
                     "newmtl floor\nKd 0.1 0.9 0.1\n", "m.mtl", notes)
    assert [m.name for m in mats] == ["floor", "glossy"] and mats[0].albedo == (1.0, 1.0, 1.0)
    assert notes == ["m.mtl: line 2: material 'floor': Kd 185 181 173 is over 1: clipped to albedo [1, 1, 1] "
                     "(0-255 values? divide them by 255)",
                     "m.mtl: line 5: material 'glossy': Ks 1.5 1 1 is over 1: clipped to reflectance [1, 1, 1]",
                     "m.mtl: line 6: newmtl 'floor' again (first defined at line 1): this definition is ignored, "
                     "the first one is used (rename one of them)"]
    clean: list[str] = []
    assert parse_mtl(MTL, "m.mtl", clean) and clean == []
    scene = api.load_scene(_scene(tmp_path, LIGHT, mtl=MTL.replace("Kd 0.5 0.5 0.5", "Kd 128 128 128")
                                  + "newmtl tallBox\nKd 0 0 1\n"))
    said = [n for n in scene.extra["notes"] if "m.mtl" in n]
    assert said == [f"{tmp_path / 'm.mtl'}: line 4: material 'floor': Kd 128 128 128 is over 1: clipped to albedo "
                    "[1, 1, 1] (0-255 values? divide them by 255)",
                    f"{tmp_path / 'm.mtl'}: line 5: newmtl 'tallBox' again (first defined at line 1): this "
                    "definition is ignored, the first one is used (rename one of them)"], said


def test_a_material_a_second_library_defines_again_is_noted_with_both_lines(tmp_path):
    """(h219, 9) the note named the two files and no line."""
    (tmp_path / "m.obj").write_text(OBJ.replace("mtllib m.mtl", "mtllib m.mtl n.mtl"))
    (tmp_path / "m.mtl").write_text(MTL)
    (tmp_path / "n.mtl").write_text("newmtl other\nKd 0 1 0\nnewmtl floor\nKd 0 0 1\n")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + LIGHT)
    said = [n for n in api.load_scene(tmp_path / "s.yaml").extra["notes"] if "n.mtl" in n]
    assert said == [f"{tmp_path / 'n.mtl'}: line 3: newmtl 'floor' is defined by {tmp_path / 'm.mtl'} too (line 3), "
                    "which the mtllib names first: that one is used (results.json's scene.materials, `from`, names "
                    "it), this one is ignored"], said  # (h333: which one is recorded said too)


# ------------------------------------------------------------ 5, 6. an empty GLB, a glTF 1.0 file


@pytest.mark.parametrize("name,data,said", [("e.glb", b"", "the file is empty (0 bytes): no binary glTF to read"),
                                            ("e.gltf", b" \n", "the file is empty (2 bytes, all whitespace)")])
def test_an_empty_gltf_file_is_named_empty(tmp_path, name, data, said):
    (tmp_path / name).write_bytes(data)
    (tmp_path / "s.yaml").write_text(f"geometry: {{mesh: {name}}}\n" + CAMERA)
    with pytest.raises(InputError) as e:
        api.load_scene(tmp_path / "s.yaml")
    assert str(e.value).startswith(f"{tmp_path / name}: {said}"), e.value


def test_a_gltf_1_file_is_named_by_its_version(tmp_path):
    with pytest.raises(InputError, match=r"^v1\.gltf: asset\.version 1\.0: tlm reads glTF 2\.0 "):
        check_gltf({"asset": {"version": "1.0"}, "meshes": {"m": {"primitives": []}}}, "v1.gltf")
    with pytest.raises(InputError, match="the glTF has no meshes"):  # (a 2.0 file: as before)
        check_gltf({"asset": {"version": "2.0"}, "meshes": []}, "v2.gltf")


# ------------------------------------------------------------ 9. docs/scenes.md


def test_a_binary_gltf_1_file_is_named_by_its_version(tmp_path):
    """(h219, 7) a .glb whose header gives version 1 said "first chunk is not its JSON"."""
    import struct

    body = b'{"asset": {"version": "1.0"}, "meshes": {"m": {"primitives": []}}}'
    data = b"glTF" + struct.pack("<III", 1, 20 + len(body), len(body)) + struct.pack("<I", 0) + body
    with pytest.raises(InputError, match=r"^v1\.glb: a binary glTF 1\.0 file \(its header says version 1\): tlm "
                                         r"reads glTF 2\.0 \(convert the file to glTF 2\.0: gltf-pipeline "):
        glb_chunks(data, "v1.glb")
    (tmp_path / "v1.glb").write_bytes(data)
    (tmp_path / "s.yaml").write_text("geometry: {mesh: v1.glb}\n" + CAMERA + LIGHT
                                     + "materials: {w: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
                                     "default_material: w\n")
    with pytest.raises(InputError, match=r"v1\.glb: a binary glTF 1\.0 file"):
        api.load_scene(tmp_path / "s.yaml")


def test_the_docs_say_a_second_files_equal_light_is_shared_not_renamed():
    text = " ".join((REPO / "docs" / "scenes.md").read_text().split())
    assert "a second file's `light` is renamed `light_2` in the scene," not in text
    assert ("a second file's `light` with the same values as the first's is the same material, one with other "
            "values is renamed `light_2`") in text
