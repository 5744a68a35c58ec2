"""A scene file's identity (:func:`tlm.experiments.provenance.scene_identity`, which eq. 5.2's
groups and the thesis study tell scenes apart by) covers the mesh files its geometry reads:
the same scene file beside other mesh contents (or its mesh changed) is another scene; a copy
of the scene file and its meshes elsewhere is the same one."""

from __future__ import annotations

import re
import shutil

import pytest

from tlm.caches import file_digest
from tlm.experiments.provenance import mesh_paths, scene_identity
from tlm.scenes import cache as scache
from tlm.scenes import meshes
from tlm.scenes.meshes import mesh_files

SCENE = ("geometry: [{mesh: m.obj}, {shape: plane, params: {size: [4, 4]}}]\n"
         "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
         "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n")
OBJ = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl g\nf 1 2 3\n"


def _scene(folder, obj=OBJ, mtl="newmtl g\nKd 0.5 0.5 0.5\n"):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "s.yaml").write_text(SCENE)
    (folder / "m.obj").write_text(obj)
    (folder / "m.mtl").write_text(mtl)
    return folder / "s.yaml"


def test_one_scene_file_beside_two_meshes_is_two_scenes_and_a_copy_is_one(tmp_path):
    a = _scene(tmp_path / "a")
    b = _scene(tmp_path / "b", obj=OBJ.replace("v 0 1 0", "v 0 2 0"))
    assert a.read_bytes() == b.read_bytes()
    assert scene_identity(a) != scene_identity(b)
    copy = tmp_path / "elsewhere" / "deeper"
    shutil.copytree(tmp_path / "a", copy)
    assert scene_identity(copy / "s.yaml") == scene_identity(a)  # (content, not place)
    assert re.fullmatch(r"sha256 [0-9a-f]{16}", scene_identity(a))  # (the label stays short)


def test_the_identity_follows_a_change_of_the_mesh_or_its_library(tmp_path):
    s = _scene(tmp_path)
    first = scene_identity(s)
    (tmp_path / "m.mtl").write_text("newmtl g\nKd 0.9 0.1 0.1\n")
    second = scene_identity(s)
    assert second != first
    (tmp_path / "m.obj").write_text(OBJ + "f 3 2 1\n")
    assert scene_identity(s) not in (first, second)
    (tmp_path / "m.obj").unlink()  # (a mesh that is gone is told apart too)
    assert scene_identity(s) not in (first, second)
    assert [p.name for p in mesh_paths(s)] == ["m.obj"]


def test_a_mesh_named_by_the_base_of_extends_counts(tmp_path):
    _scene(tmp_path / "base")
    (tmp_path / "child.yaml").write_text("extends: base/s.yaml\nname: child\n")
    first = scene_identity(tmp_path / "child.yaml")
    (tmp_path / "base" / "m.obj").write_text(OBJ.replace("v 1 0 0", "v 3 0 0"))
    assert scene_identity(tmp_path / "child.yaml") != first


def test_a_gltf_counts_its_buffer_files(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    for name, data in trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box())).items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "s.yaml").write_text(SCENE.replace("m.obj", "model.gltf"))
    files = mesh_files(tmp_path / "model.gltf")
    assert [f.name for f, _ in files] == ["model.gltf", *sorted(p.name for p in tmp_path.glob("*.bin"))]
    first = scene_identity(tmp_path / "s.yaml")
    buffer = files[1][0]
    buffer.write_bytes(buffer.read_bytes()[:-4] + b"\0\0\0\0")
    assert scene_identity(tmp_path / "s.yaml") != first


def test_an_objs_libraries_are_named_by_its_cache_entry_without_a_parse(tmp_path, cache, monkeypatch):
    monkeypatch.setattr(scache, "MIN_TRIANGLES", 0)  # (every mesh kept)
    _scene(tmp_path)
    obj, mtl = tmp_path / "m.obj", tmp_path / "m.mtl"
    parses = []
    parse = meshes._parse
    monkeypatch.setattr(meshes, "_parse", lambda path: parses.append(path) or parse(path))
    want = [(obj, file_digest(obj)), (mtl, file_digest(mtl))]
    assert mesh_files(obj) == want and parses == [obj]  # (parsed once, and kept)
    assert mesh_files(obj) == want and parses == [obj]  # (the entry names the library)
    meshes.load_mesh(obj)  # (a load reads the entry the identity kept)
    assert parses == [obj]
