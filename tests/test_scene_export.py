"""A scene's triangles exported as PLY or OBJ (:mod:`tlm.scenes.export`): face ``i`` is
triangle id ``i`` with the renderer's own vertex positions (and, in PLY, its material)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes.export import export_triangles
from tlm.scenes.model import Camera, Material, Scene


def _scene() -> Scene:
    """Three triangles, two materials; coordinates that a short decimal would round."""
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    [[0.1, 0.2, 0.3], [1 / 3, 2 / 3, 1e-17], [-5.5, 7.25, 1e6]],
                    [[2.0, 2.0, 2.0], [3.0, 2.0, 2.0], [2.0, 3.0, 2.0]]])
    materials = (Material("white", "lambertian", albedo=(0.7, 0.7, 0.7)), Material("mirror", "mirror"))
    camera = Camera((0.0, 0.0, -5.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0, 8, 8)
    return Scene("tiny", tri, np.array([1, 0, 1], dtype=np.int32), materials, np.zeros(3, dtype=np.int32),
                 ("all",), (), camera, 0)


def test_ply_holds_every_triangle_in_id_order_with_its_material(tmp_path):
    scene = _scene()
    export_triangles(scene, tmp_path / "t.PLY")  # the suffix is read case-blind
    data = (tmp_path / "t.PLY").read_bytes()
    head, _, body = data.partition(b"end_header\n")
    lines = head.decode().splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"] and "element vertex 9" in lines
    assert "element face 3" in lines and "property int material" in lines
    verts = np.frombuffer(body[: 9 * 3 * 8], dtype="<f8").reshape(3, 3, 3)
    assert np.array_equal(verts, scene.triangles)  # bit for bit
    faces = np.frombuffer(body[9 * 3 * 8:], dtype=[("k", "u1"), ("v", "<i4", 3), ("m", "<i4")])
    assert faces["k"].tolist() == [3, 3, 3]
    assert faces["v"].tolist() == [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    assert faces["m"].tolist() == [1, 0, 1]


def test_obj_round_trips_the_positions_exactly(tmp_path):
    scene = _scene()
    export_triangles(scene, tmp_path / "t.obj")
    lines = (tmp_path / "t.obj").read_text().splitlines()
    assert lines[0].startswith("# tlm scene tiny")
    v = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("v ")])
    f = [[int(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("f ")]
    assert np.array_equal(v.reshape(3, 3, 3), scene.triangles)
    assert f == [[1, 2, 3], [4, 5, 6], [7, 8, 9]]  # OBJ counts from 1


@pytest.mark.parametrize("name, says", [
    ("t.stl", "unsupported format '.stl': use .ply, .obj, .yaml or .yml"),
    ("t", "unsupported format '(none)'"),
    ("folder.ply", "is a folder; name a .ply, .obj or .yaml file"),
])
def test_a_bad_destination_is_an_input_error_naming_it(tmp_path, name, says):
    (tmp_path / "folder.ply").mkdir()
    with pytest.raises(InputError, match=f"^{re.escape(str(tmp_path / name))}: ") as e:
        export_triangles(_scene(), tmp_path / name)
    assert says in str(e.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.ply"]  # nothing written


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_a_folder_that_takes_no_file_is_one_line(tmp_path, suffix, capsys, monkeypatch):
    """/proc takes no new file (the open fails with ENOENT): one line, exit 1, not an internal error."""
    import tlm.storage as storage
    from tlm.cli import main

    real = open

    def no_file(path, *a, **k):  # (as /proc answers: what is not there cannot be made)
        if str(path).startswith(str(tmp_path)):
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(storage, "open", no_file, raising=False)
    assert main(["scene", "export", "ring", str(tmp_path / f"x{suffix}")]) == 1
    err = capsys.readouterr().err.strip()
    first = tmp_path / ("x.mtl" if suffix == ".obj" else f"x{suffix}")  # (an OBJ's materials are written first)
    assert err == (f"tlm: error: {first}: cannot write: {tmp_path} takes no new files (making one there: no such "
                   "file or directory)")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["cornell", "cornell-box", "cornell-water"])
def test_an_obj_export_reads_back_as_the_same_triangles_parts_and_materials(tmp_path, name, capsys):
    """The OBJ's o / usemtl runs and its MTL library: tlm reads them back as the scene's
    triangles, part names and per-triangle materials (cornell: mirror and glass; cornell-box:
    the Ke light; cornell-water: glass). The lights and camera are the scene file's."""
    from dataclasses import replace

    from tlm.api import load_scene
    from tlm.cli import main

    assert main(["scene", "export", name, str(tmp_path / "s.obj")]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {tmp_path / 's.obj'} (")
    assert (tmp_path / "s.mtl").is_file()
    (tmp_path / "back.yaml").write_text("geometry: {mesh: s.obj}\ncamera: {eye: [0, 1, 5], target: [0, 1, 0], "
                                        "vfov: 40}\nresolution: [8, 8]\n")
    a, b = load_scene(name), load_scene(tmp_path / "back.yaml")
    assert np.array_equal(a.triangles, b.triangles)
    assert [a.part_names[i] for i in a.part] == [b.part_names[i] for i in b.part]
    def clear(m):  # (tlm reads an MTL's glass as clear: Tf is not its colour in the published files)
        return replace(m, transmittance=(1.0, 1.0, 1.0)) if m.kind == "dielectric" else m

    assert [clear(a.materials[i]) for i in a.material_index] == [b.materials[i] for i in b.material_index]
    assert [m.name for m in a.materials] == [m.name for m in b.materials]
    if any(m.emits for m in a.materials):  # (an emissive material's light comes back with it)
        assert [lt.kind for lt in b.lights] == ["mesh"]


def test_an_obj_export_refuses_what_its_mtl_cannot_hold_or_would_overwrite(tmp_path):
    """A material name with '#' (an MTL comment) or spaces at its ends would read back as
    another name; a library tlm did not write (a published scene's, beside its OBJ) would be
    replaced. Both refused, nothing written; tlm's own library is replaced."""
    from dataclasses import replace

    from tlm.api import load_scene

    scene = load_scene("cornell-box")
    for bad in ("m#1", " pad", "two\nlines"):
        odd = replace(scene, materials=(replace(scene.materials[0], name=bad), *scene.materials[1:]))
        with pytest.raises(InputError, match=r"cannot be named in an MTL library"):
            export_triangles(odd, tmp_path / "x.obj")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "x.mtl").write_text("# Morgan McGuire's library\nnewmtl light\n")
    with pytest.raises(InputError, match=r"x\.mtl beside it is not a library tlm wrote"):
        export_triangles(scene, tmp_path / "x.obj")
    assert (tmp_path / "x.mtl").read_text().startswith("# Morgan")
    (tmp_path / "x.mtl").unlink()
    export_triangles(scene, tmp_path / "x.obj")
    export_triangles(scene, tmp_path / "x.obj")  # (its own library: replaced)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mtl", "x.obj"]


@pytest.mark.parametrize("name", ["cornell", "ring", "cornell-box", "cornell-water", "examples/mesh_on_floor",
                                  "extreme/cornell_scale_1e-6"])
def test_a_scene_file_export_loads_as_the_same_scene(tmp_path, name):
    """``.yaml``: the scene file, its OBJ and MTL. tlm reads it back as the scene: the same
    triangles, materials (glass's transmittance too, which the MTL alone loses) and
    per-triangle materials, parts, lights (quad, point, the mesh light of the emitting
    materials), camera, resolution and photons, bit for bit; the shading normals from the
    OBJ's ``vn`` (no crease angle), to within the rounding of their renormalization."""
    from tlm.api import export_scene, load_scene

    a = load_scene(name)
    export_scene(a, tmp_path / "s.yaml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.mtl", "s.obj", "s.yaml"]
    b = load_scene(tmp_path / "s.yaml")
    assert np.array_equal(a.triangles, b.triangles)
    assert a.materials == b.materials and np.array_equal(a.material_index, b.material_index)
    assert a.part_names == b.part_names and np.array_equal(a.part, b.part)
    assert a.lights == b.lights and a.camera == b.camera and a.photons == b.photons
    for la, lb in zip(a.lights, b.lights, strict=True):
        if la.kind == "mesh":
            assert np.array_equal(la.ids, lb.ids) and np.array_equal(la.radiance, lb.radiance)
    assert b.extra["normals"] == "file"
    assert np.abs(a.normals - b.normals).max() <= 4 * np.finfo(float).eps
    assert (a.name, a.extra["description"]) == (b.name, b.extra["description"])


def test_a_scene_file_export_renders_the_original_image(tmp_path, capsys):
    """``tlm scene export cornell s.yaml`` then a photon-map render of each: the same image
    (the normals' last bits aside: within 1e-12 of the brightest pixel)."""
    from tlm.api import render_image
    from tlm.cli import main

    assert main(["scene", "export", "cornell", str(tmp_path / "s.yaml")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"wrote {tmp_path / 's.yaml'} (the scene file: 1 light, the camera, ")  # (none emits)
    assert f"{tmp_path / 's.obj'} (2604 triangles) and {tmp_path / 's.mtl'} (5 materials)" in out
    cfg = {"resolution": [24, 24], "mode": "pmap", "photons": {"count": 2000}}
    a = render_image({**cfg, "scene": "cornell"}).composite
    b = render_image({**cfg, "scene": str(tmp_path / "s.yaml")}).composite
    assert a.max() > 0 and np.abs(a - b).max() <= 1e-12 * a.max()


def test_an_obj_export_carries_the_shading_normals(tmp_path):
    """Every corner's normal as a ``vn`` (faces ``f a//a ...``); read back as the file's
    normals, so a re-read OBJ needs no crease angle to shade as the scene did."""
    from tlm.api import load_scene

    a = load_scene("ring")
    export_triangles(a, tmp_path / "s.obj")
    lines = (tmp_path / "s.obj").read_text().splitlines()
    vn = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("vn ")])
    assert np.array_equal(vn.reshape(-1, 3, 3), a.normals)
    assert next(ln for ln in lines if ln.startswith("f ")) == "f 1//1 2//2 3//3"
    (tmp_path / "back.yaml").write_text("geometry: {mesh: s.obj}\ncamera: {eye: [0, 1, 5], target: [0, 1, 0], "
                                        "vfov: 40}\nresolution: [8, 8]\ndefault_material: m\n"
                                        "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n")
    assert load_scene(tmp_path / "back.yaml").extra["normals"] == "file"


def test_a_scene_file_export_replaces_only_files_tlm_wrote(tmp_path):
    """The OBJ and the scene file a ``.yaml`` export writes: a user's file of either name
    is refused, one line naming it, and nothing is written; tlm's own are replaced."""
    from tlm.api import load_scene

    scene = load_scene("cornell-box")
    for mine in ("s.obj", "s.yaml"):
        (tmp_path / mine).write_text("# my own file\n")
        named = "" if mine == "s.yaml" else f"{re.escape(mine)} "  # (the target itself is not named twice)
        with pytest.raises(InputError, match=rf"^{re.escape(str(tmp_path / 's.yaml'))}: {named}exists "
                                             r"and is not a (mesh|scene file) tlm wrote"):
            export_triangles(scene, tmp_path / "s.yaml")
        assert sorted(p.name for p in tmp_path.iterdir()) == [mine]
        assert (tmp_path / mine).read_text() == "# my own file\n"
        (tmp_path / mine).unlink()
    export_triangles(scene, tmp_path / "s.yaml")
    export_triangles(scene, tmp_path / "s.yaml")  # (its own files: replaced)
    assert load_scene(tmp_path / "s.yaml").materials == scene.materials


@pytest.mark.parametrize("name", ["s.yml", "S.YAML"])
def test_a_scene_file_export_takes_every_suffix_a_scene_file_may_have(tmp_path, name, capsys, monkeypatch):
    """``.yml`` as ``.yaml``, and a suffix in capitals, which ``tlm scene show`` then reads as
    a file, not as a built-in scene's name."""
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["scene", "export", "cornell-box", name]) == 0
    capsys.readouterr()
    assert main(["scene", "show", name]) == 0
    assert '"triangles": 36' in capsys.readouterr().out
