"""A PLY's per-face material (:mod:`tlm.scenes.plyfile`): ``tlm scene export`` writes each
face's material index and each material's name, and a scene file that names the PLY loads
every face with its material again (the scene file gives the values, by name, or by index
when the file names none); an index naming no material is one line, exit 2. A PLY's
polygons keep the file's face order; its colours are named as not rendered."""

from __future__ import annotations

import gzip
import json
import re

import numpy as np
import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import load_scene
from tlm.scenes.meshes import load_mesh
from tlm.scenes.plyfile import NAME_COMMENT

CAMERA = "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n"
# two parts, three materials: the box's faces split between two of them by the export's face order
SOURCE = """name: two
geometry:
  - {shape: plane, name: floor, params: {size: [4, 4]}}
  - {shape: box, name: block, params: {min: [-0.5, 0, -0.5], max: [0.5, 1, 0.5]}}
materials:
  white: {type: lambertian, albedo: [0.7, 0.7, 0.7]}
  red: {type: lambertian, albedo: [0.7, 0.1, 0.1]}
  gold: {type: mirror, reflectance: [0.9, 0.7, 0.3]}
parts: {floor: white, block: gold}
""" + CAMERA
# a quad (corners 0 1 2 3) of material 7, then a triangle of material 5, then one of none (-1)
QUAD = """ply
format ascii 1.0
{comments}element vertex 5
property float x
property float y
property float z
element face 3
property list uchar int vertex_indices
property {kind} material
end_header
0 0 0
1 0 0
1 1 0
0 1 0
2 0 0
4 0 1 2 3 {a}
3 1 4 2 {b}
3 0 4 1 {c}
"""


def _quad(tmp_path, a="7", b="5", c="-1", kind="int", comments=""):
    path = tmp_path / "q.ply"
    path.write_text(QUAD.format(a=a, b=b, c=c, kind=kind, comments=comments))
    return path


def _exported(tmp_path, capsys):
    (tmp_path / "two.yaml").write_text(SOURCE)
    assert main(["scene", "export", str(tmp_path / "two.yaml"), str(tmp_path / "two.ply")]) == 0
    capsys.readouterr()
    return load_scene(str(tmp_path / "two.yaml"))


def test_an_exported_ply_loads_back_with_each_faces_material(tmp_path, capsys):
    orig = _exported(tmp_path, capsys)
    head = (tmp_path / "two.ply").read_bytes().partition(b"end_header")[0].decode()
    assert f'{NAME_COMMENT}0 "white"' in head.splitlines() and f'{NAME_COMMENT}2 "gold"' in head.splitlines()
    # the scene file gives the values by name; no parts:, no default_material
    (tmp_path / "back.yaml").write_text("geometry: {mesh: two.ply}\nmaterials:\n"
                                        "  white: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n"
                                        "  gold: {type: mirror, reflectance: [1, 1, 1]}\n" + CAMERA)
    back = load_scene(str(tmp_path / "back.yaml"))
    assert np.array_equal(back.triangles, orig.triangles)
    names = [back.materials[i].name for i in back.material_index]
    assert names == [orig.materials[i].name for i in orig.material_index]
    assert {"white", "gold"} == set(names) and back.materials[back.material_index[-1]].kind == "mirror"
    assert main(["scene", "show", str(tmp_path / "back.yaml")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert {m["name"]: m["triangles"] for m in info["materials"]} == {"white": 2, "gold": 12}


def test_a_material_the_scene_file_does_not_give_is_one_line_naming_the_face(tmp_path, capsys):
    _exported(tmp_path, capsys)
    (tmp_path / "back.yaml").write_text("geometry: {mesh: two.ply}\nmaterials:\n"
                                        "  white: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n" + CAMERA)
    assert main(["scene", "show", str(tmp_path / "back.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert (f"{tmp_path / 'two.ply'}: face 2: material 2 (named 'gold' by the header): a PLY file gives no "
            "material's values: give it under materials: in the scene file (or set default_material)") in err
    # default_material covers it, as it covers an OBJ's usemtl that no MTL defines
    (tmp_path / "back.yaml").write_text("geometry: {mesh: two.ply}\ndefault_material: white\nmaterials:\n"
                                        "  white: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n" + CAMERA)
    assert [m.name for m in load_scene(str(tmp_path / "back.yaml")).materials] == ["white"]


def test_a_ply_without_names_has_its_materials_named_by_index_and_polygons_in_file_order(tmp_path):
    _quad(tmp_path)
    (tmp_path / "s.yaml").write_text("geometry: {mesh: q.ply}\nmaterials:\n"
                                     "  5: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n"
                                     "  '7': {type: mirror, reflectance: [1, 1, 1]}\n"
                                     "  grey: {type: lambertian, albedo: [0.2, 0.2, 0.2]}\n"
                                     "default_material: grey\n" + CAMERA)
    scene = load_scene(str(tmp_path / "s.yaml"))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    # the quad fanned from its first corner, then the triangles: the file's order
    np.testing.assert_array_equal(scene.triangles, v[[[0, 1, 2], [0, 2, 3], [1, 4, 2], [0, 4, 1]]])
    assert [scene.materials[i].name for i in scene.material_index] == ["7", "7", "5", "grey"]  # -1: none


@pytest.mark.parametrize("values, comments, says", [
    (("7", "2", "-1"), f'{NAME_COMMENT}0 "a"\n{NAME_COMMENT}1 "b"\n{NAME_COMMENT}2 "c"\n',
     r"face 0: material 7 names no material: the file's 'comment tlm material' lines name materials 0 to 2 "
     r"\(-1: none\)$"),
    (("1", "1", "2"), f'{NAME_COMMENT}1 "b"\n', r"face 2: material 2 names no material: the file's 'comment tlm "
                                                  r"material' lines name material 1 \(-1: none\)$"),
    (("7", "-2", "-1"), "", r"face 1: material -2 is negative: a material index is 0 or more \(-1: none\)$"),
    (("7", "5", "-1"), f'{NAME_COMMENT}x "a"\n', r"header line 'comment tlm material x \"a\"': expected"),
    (("7", "5", "-1"), f'{NAME_COMMENT}1 "a"\n{NAME_COMMENT}2 "a"\n',
     r"header line 'comment tlm material 2 \"a\"': material 'a' is named twice$"),
])
def test_an_index_naming_no_material_is_one_line_exit_2(tmp_path, capsys, values, comments, says):
    path = _quad(tmp_path, *values, comments=comments)
    with pytest.raises(InputError, match=rf"^{re.escape(str(path))}: " + says):
        load_mesh(path)
    (tmp_path / "s.yaml").write_text("geometry: {mesh: q.ply}\ndefault_material: g\n"
                                     "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n" + CAMERA)
    assert main(["scene", "show", str(tmp_path / "s.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tlm: error: {path}: ")


def test_a_fraction_is_no_material_index(tmp_path):
    path = _quad(tmp_path, "7", "5.5", kind="float")
    with pytest.raises(InputError, match=rf"^{re.escape(str(path))}: face 1: material 5\.5 is not a whole number"):
        load_mesh(path)
    g = load_mesh(_quad(tmp_path, "7.0", "5", kind="float"))  # (a whole number written as a float is one)
    assert [m.name for m in g.materials] == ["5", "7"] and g.face_material.tolist() == [1, 1, 0, -1]


def test_a_compressed_ply_keeps_its_names(tmp_path, capsys):
    _exported(tmp_path, capsys)
    (tmp_path / "z.ply.gz").write_bytes(gzip.compress((tmp_path / "two.ply").read_bytes()))
    a, b = load_mesh(tmp_path / "two.ply"), load_mesh(tmp_path / "z.ply.gz")
    assert [m.name for m in a.materials] == [m.name for m in b.materials] == ["white", "gold"]
    np.testing.assert_array_equal(a.face_material, b.face_material)


def test_colours_a_ply_gives_are_named_as_not_rendered(tmp_path):
    path = tmp_path / "c.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 255 0 0\n"
                    "0 1 0 255 0 0\n3 0 1 2\n")
    assert load_mesh(path).notes == (f"{path}: its vertex colours (red, green, blue) are not rendered: a triangle's "
                                     "material is the scene file's (parts:, materials:, default_material)",)


def test_a_material_property_of_triangle_strips_is_named_as_not_read(tmp_path):
    path = tmp_path / "s.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "element tristrips 1\nproperty list int int vertex_indices\nproperty int material\nend_header\n"
                    "0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3 5\n")
    g = load_mesh(path)
    assert g.triangles.shape == (2, 3, 3) and g.materials == ()
    assert g.notes == (f"{path}: its triangle strips' material property is not read (tlm reads a face element's): "
                       "a triangle's material is the scene file's (parts:, materials:, default_material)",)
