"""Scene formats and export, leftovers: an ASCII PLY's per-face ``material`` (a scalar that
trimesh keeps as a column), the notes on an OBJ's and a glTF's vertex colours, an export's
refusal of a foreign OBJ or PLY of the target's name, normals that survive an export to the
bit (OBJ, PLY and scene file: the same photon-map work), and a material without ``type``."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

from tlm.errors import InputError

_VIEW = ("lights: [{type: point, position: [0, 3, -1], power: [50, 50, 50]}]\n"
         "camera: {eye: [0, 1.5, -4], target: [0, 0.5, 0], vfov: 45}\nresolution: [8, 8]\n")
_GROUND_GOLD = ("materials:\n  ground: {type: lambertian, albedo: [0.7, 0.7, 0.7]}\n"
                "  gold: {type: mirror, reflectance: [0.9, 0.7, 0.3]}\n")


def _ascii_ply(material: str = "property int material", rows: tuple[str, ...] = ("0", "0", "1", "1")) -> str:
    faces = ["0 2 1", "0 3 2", "4 5 6", "4 6 7"]
    return ("ply\nformat ascii 1.0\ncomment tlm material 0 \"ground\"\ncomment tlm material 1 \"gold\"\n"
            "element vertex 8\nproperty float x\nproperty float y\nproperty float z\nelement face 4\n"
            f"property list uchar int vertex_indices\n{material}\nend_header\n"
            "-2 0 -2\n2 0 -2\n2 0 2\n-2 0 2\n-1 0 1\n1 0 1\n1 1.5 1\n-1 1.5 1\n"
            + "".join(f"3 {f} {m}\n" for f, m in zip(faces, rows, strict=True)))


def test_an_ascii_ply_face_material_reads_as_a_binary_ones(tmp_path):
    """``property int material`` in an ASCII PLY (trimesh gives an (n, 1) column): each face's
    material, named by the header; a negative index other than -1 is still the face's
    error; a list property (even of one number per face) is still refused."""
    from tlm.api import load_scene

    (tmp_path / "m.ply").write_text(_ascii_ply())
    (tmp_path / "s.yaml").write_text(f"geometry: {{mesh: m.ply}}\n{_GROUND_GOLD}{_VIEW}")
    scene = load_scene(tmp_path / "s.yaml")
    assert [scene.materials[i].name for i in scene.material_index] == ["ground", "ground", "gold", "gold"]
    (tmp_path / "m.ply").write_text(_ascii_ply(rows=("0", "-2", "1", "1")))
    with pytest.raises(InputError, match=r"m\.ply: face 1: material -2 names no material"):
        load_scene(tmp_path / "s.yaml")
    (tmp_path / "m.ply").write_text(_ascii_ply("property list uchar int material", ("1 0", "1 0", "1 1", "1 1")))
    with pytest.raises(InputError, match=r"m\.ply: face property 'material' is a list; tlm reads one whole number"):
        load_scene(tmp_path / "s.yaml")


def test_obj_vertex_colours_are_noted_as_a_plys_are():
    """``v x y z r g b``: the reader counts those lines and :func:`colour_notes` says that
    they are not rendered; an OBJ without colours (or with ``w``) has no such line."""
    from tlm.scenes.objfile import colour_notes, parse_obj

    faces = b"f 1 2 3\nf 1 3 4\n"
    coloured = b"v 0 0 0\nv 1 0 0 0.8 0.1 0.1\nv 1 1 0 0.8 0.1 0.1\nv 0 1 0 1\n" + faces
    obj = parse_obj(coloured, "c.obj", "c")
    assert obj.colour_lines == (2, 2)
    assert colour_notes(obj, "c.obj") == ("c.obj: its vertex colours ('v x y z r g b', 2 lines from line 2) are "
                                          "not rendered: a triangle's material is the scene file's or its MTL's "
                                          "(usemtl, parts:, materials:, default_material)",)
    plain = parse_obj(b"v 0 0 0\nv 1 0 0 1\nv 1 1 0\nv 0 1 0\n" + faces, "p.obj", "p")
    assert plain.colour_lines == (0, 0) and colour_notes(plain, "p.obj") == ()


def test_gltf_vertex_colours_are_noted_as_a_plys_are(tmp_path):
    """A glTF whose primitive has ``COLOR_0``: a note in ``tlm scene show``'s notes (and the
    run's warnings), as a PLY's colours get one; none without colours."""
    import trimesh

    from tlm.api import load_scene
    from tlm.render.checks import file_warnings

    box = trimesh.creation.box()
    box.visual.vertex_colors = [200, 30, 30, 255]
    box.export(tmp_path / "c.glb")
    trimesh.creation.box().export(tmp_path / "p.glb")
    for stem in ("c", "p"):
        (tmp_path / f"{stem}.yaml").write_text(f"geometry: {{mesh: {stem}.glb}}\ndefault_material: m\n"
                                               "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
                                               + _VIEW)
    said = [n for n in file_warnings(load_scene(tmp_path / "c.yaml")) if "vertex colours" in n]
    assert said == [f"{tmp_path / 'c.glb'}: its vertex colours (COLOR_0 of meshes[0] 'geometry_0') are not "
                    "rendered: a triangle's material is the glTF's or the scene file's (parts:, materials:, "
                    "default_material)"]
    assert not any("vertex colours" in n for n in file_warnings(load_scene(tmp_path / "p.yaml")))


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_an_export_refuses_a_foreign_mesh_of_the_targets_name(tmp_path, suffix):
    """An existing OBJ or PLY that tlm did not write is refused, one line naming it, nothing
    written (no MTL either); one that tlm wrote is replaced."""
    from tlm.api import load_scene
    from tlm.scenes.export import export_triangles

    scene = load_scene("cornell-box")
    target = tmp_path / f"f{suffix}"
    mine = "ply\nformat ascii 1.0\nend_header\n" if suffix == ".ply" else "# my own mesh\nv 0 0 0\n"
    target.write_text(mine)
    with pytest.raises(InputError, match=rf"^{re.escape(str(target))}: exists and is not a mesh tlm "
                                         rf"wrote; the export would replace it: name another \{suffix} file$"):
        export_triangles(scene, target)
    assert [p.name for p in tmp_path.iterdir()] == [target.name] and target.read_text() == mine
    target.unlink()
    export_triangles(scene, target)
    export_triangles(scene, target)  # (its own: replaced)
    assert target.stat().st_size > 0


def _back(tmp_path, mesh: str) -> str:
    path = tmp_path / f"back_{mesh.replace('.', '_')}.yaml"
    path.write_text(f"geometry: {{mesh: {mesh}}}\ndefault_material: m\n"
                    f"materials: {{m: {{type: lambertian, albedo: [0.5, 0.5, 0.5]}}}}\n{_VIEW}")
    return str(path)


@pytest.mark.parametrize("name", ["examples/mesh_on_floor", "ring"])
def test_exported_normals_read_back_to_the_bit(tmp_path, name):
    """OBJ (``vn``), PLY (``nx ny nz``) and scene-file exports: the loader's normals are the
    original's, bit for bit (a third of them came back an ulp off: renormalized on reading)."""
    from tlm.api import export_scene, load_scene
    from tlm.scenes.export import export_triangles

    a = load_scene(name)
    for suffix in (".obj", ".ply"):
        export_triangles(a, tmp_path / f"t{suffix}")
        b = load_scene(_back(tmp_path, f"t{suffix}"))
        assert b.extra["normals"] == "file" and np.array_equal(a.normals, b.normals), suffix
    ply = trimesh.load(tmp_path / "t.ply", process=False)  # (unit normals, as another tool reads them)
    np.testing.assert_allclose(np.linalg.norm(ply._cache.cache["vertex_normals"], axis=1), 1.0, rtol=0, atol=1e-15)
    export_scene(a, tmp_path / "s.yaml")
    assert np.array_equal(a.normals, load_scene(tmp_path / "s.yaml").normals)


def test_a_unit_normal_is_read_as_written():
    """A ``vn`` of unit length (to its rounding) comes out of the loader's normalization as
    written, for many random unit vectors; a longer one is still normalized."""
    from tlm.scenes.objfile import _unit, unit_as_written

    v = np.random.default_rng(7).normal(size=(20000, 3))
    v = _unit(v)
    v[:10] = _unit(np.c_[np.ones(10), np.zeros(10), np.arange(10.0)])
    assert not np.array_equal(_unit(v), v)  # (what the reader did: a third an ulp off)
    assert np.array_equal(_unit(unit_as_written(v)), v)
    assert np.array_equal(unit_as_written(np.array([[0.0, 0.0, 2.0]])), [[0.0, 0.0, 2.0]])


def test_a_scene_file_export_does_the_same_photon_map_work(tmp_path):
    """``tlm scene export examples/mesh_on_floor s.yaml``, then a photon-map render of each:
    the same image and the same work, count for count (so the same cycles)."""
    from tlm.api import export_scene, load_scene, render_image

    export_scene(load_scene("examples/mesh_on_floor"), tmp_path / "s.yaml")
    cfg = {"resolution": [16, 12], "mode": "pmap", "photons": {"count": 1500}}
    a = render_image({**cfg, "scene": "examples/mesh_on_floor"})
    b = render_image({**cfg, "scene": str(tmp_path / "s.yaml")})
    assert np.array_equal(a.composite, b.composite)
    assert a.work_totals() == b.work_totals()


@pytest.mark.parametrize("entry, says", [
    ("{albedo: [0.6, 0.6, 0.6]}", "materials.grey.type: missing; give one of lambertian, mirror, dielectric"),
    ("{type: null, albedo: [0.6, 0.6, 0.6]}",
     "materials.grey.type: missing; give one of lambertian, mirror, dielectric"),
    ("{type: true}", "materials.grey: type true is not one of lambertian, mirror, dielectric"),
])
def test_a_material_without_a_type_is_said_in_yaml_words(tmp_path, entry, says):
    from tlm.api import load_scene

    (tmp_path / "s.yaml").write_text(f"geometry: {{shape: plane, params: {{size: [2, 2]}}}}\ndefault_material: grey\n"
                                     f"materials: {{grey: {entry}}}\n{_VIEW}")
    with pytest.raises(InputError) as err:
        load_scene(tmp_path / "s.yaml")
    assert str(err.value) == f"{tmp_path / 's.yaml'}: {says}"


def test_obj_vertex_colours_reach_the_scenes_notes(tmp_path):
    from tlm.api import load_scene
    from tlm.render.checks import file_warnings

    (tmp_path / "c.obj").write_text("v 0 0 0 0.8 0.1 0.1\nv 1 0 0 0.8 0.1 0.1\nv 1 1 0 0.8 0.1 0.1\nf 1 2 3\n")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: c.obj}\ndefault_material: m\n"
                                     "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n" + _VIEW)
    assert any("c.obj: its vertex colours ('v x y z r g b', 3 lines from line 1) are not rendered" in n
               for n in file_warnings(load_scene(tmp_path / "s.yaml")))
