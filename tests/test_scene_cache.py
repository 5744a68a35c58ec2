"""The scene cache (tlm/scenes/cache.py): parsed meshes and crease normals kept on disk,
the same bits as a fresh parse, and parsed again whenever a file they came from changed,
an entry is damaged or the cache cannot be written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes import cache as scache
from tlm.scenes import meshes
from tlm.scenes.loader import load_scene
from tlm.scenes.normals import crease_normals

REPO = Path(__file__).resolve().parents[1]
OBJ = """mtllib box.mtl
o left
usemtl red
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
f 1 2 3
f 2 4 3
o right
usemtl white
vn 0 0 1
f 1//1 3//1 2//1
"""
MTL = "newmtl red\nKd 0.6 0.1 0.1\nnewmtl white\nKd 0.7 0.7 0.7\n"


@pytest.fixture
def small(monkeypatch, cache):
    """Every mesh and normals cached, however small; returns a counter of the parses."""
    monkeypatch.setattr(scache, "MIN_TRIANGLES", 0)
    calls = []
    parse = meshes._parse

    def counted(path):
        calls.append(Path(path).name)
        return parse(path)

    monkeypatch.setattr(meshes, "_parse", counted)
    return calls


def _box(folder: Path, name: str = "box.obj", mtl: str = MTL) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "box.mtl").write_text(mtl)
    (folder / name).write_text(OBJ)
    return folder / name


def _same(a, b) -> None:
    assert a.triangles.dtype == b.triangles.dtype and np.array_equal(a.triangles, b.triangles)
    assert a.part.dtype == b.part.dtype and np.array_equal(a.part, b.part)
    assert a.part_names == b.part_names and a.materials == b.materials
    assert [m.ignored for m in a.materials] == [m.ignored for m in b.materials]  # (not part of ==)
    assert a.notes == b.notes
    for x, y in ((a.normals, b.normals), (a.face_material, b.face_material)):
        assert (x is None) == (y is None)
        if x is not None:
            assert x.dtype == y.dtype and np.array_equal(x, y)


def test_a_mesh_is_parsed_once_and_read_back_with_the_same_bits(tmp_path, small):
    path = _box(tmp_path / "a")
    first = meshes.load_mesh(path)
    again = meshes.load_mesh(path)
    assert small == ["box.obj"]  # the second load read the cache
    _same(first, again)
    assert again.materials[0].albedo == (0.6, 0.1, 0.1)


def test_what_a_material_leaves_unrendered_is_read_back(tmp_path, small):
    path = _box(tmp_path / "a", mtl=MTL.replace("Kd 0.6 0.1 0.1", "Kd 0.6 0.1 0.1\nmap_Kd red.png\nbump n.png"))
    first = meshes.load_mesh(path)
    again = meshes.load_mesh(path)
    assert small == ["box.obj"]
    assert [m.ignored for m in again.materials] == [("map_Kd", "bump"), ()]
    _same(first, again)


def test_the_shipped_scenes_meshes_read_back_the_same(small):
    for name in ("CornellBox-Sphere.obj.xz", "CornellBox-Water.obj.xz"):
        path = REPO / "scenes" / "meshes" / name
        _same(meshes._parse(path)[0], meshes.load_mesh(path))
        _same(meshes._parse(path)[0], meshes.load_mesh(path))
    assert small.count("CornellBox-Water.obj.xz") == 3  # two direct parses, one load; the other load: cache


def test_a_changed_material_library_is_parsed_again(tmp_path, small):
    path = _box(tmp_path / "a")
    meshes.load_mesh(path)
    (tmp_path / "a" / "box.mtl").write_text(MTL.replace("Kd 0.6 0.1 0.1", "Kd 0.2 0.3 0.4"))
    got = meshes.load_mesh(path)
    assert small == ["box.obj", "box.obj"]
    assert got.materials[0].albedo == (0.2, 0.3, 0.4)


def test_the_same_obj_beside_another_library_or_under_another_name_is_its_own(tmp_path, small):
    meshes.load_mesh(_box(tmp_path / "a"))
    other = meshes.load_mesh(_box(tmp_path / "b", mtl=MTL.replace("Kd 0.7 0.7 0.7", "Kd 0.1 0.9 0.1")))
    assert {m.name: m.albedo for m in other.materials}["white"] == (0.1, 0.9, 0.1)
    gone = tmp_path / "c"
    _box(gone)
    (gone / "box.mtl").unlink()
    with pytest.raises(InputError, match=r"box\.mtl"):  # the missing library is found, not the cached one
        meshes.load_mesh(gone / "box.obj")
    # a file without o/g names its one part after the file: the name is part of the key
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    shutil.copy(tmp_path / "plain.obj", tmp_path / "other.obj")
    assert meshes.load_mesh(tmp_path / "plain.obj").part_names == ("plain",)
    assert meshes.load_mesh(tmp_path / "other.obj").part_names == ("other",)


def _rewrite(npz: Path, **change) -> None:
    """The entry with some members replaced (``meta``: a dict, written as the cache does)."""
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    for k, v in change.items():
        arrays[k] = np.frombuffer(json.dumps(v).encode(), dtype=np.uint8) if k == "meta" else v
    np.savez(npz, **arrays)


def _meta(npz: Path) -> dict:
    with np.load(npz) as z:
        return json.loads(z["meta"].tobytes().decode())


@pytest.mark.parametrize("way", ["cut", "zeroed", "flipped", "meta"])
def test_a_damaged_entry_is_said_once_removed_and_parsed_again(tmp_path, small, cache, capsys, way):
    path = _box(tmp_path / "a")
    first = meshes.load_mesh(path)
    npz = next((cache / "scenes").glob("mesh-*.npz"))
    data = bytearray(npz.read_bytes())
    if way == "cut":
        npz.write_bytes(data[:100])
    elif way == "zeroed":
        npz.write_bytes(b"\0" * len(data))
    elif way == "flipped":  # one byte of the triangles' data: the zip's CRC-32 no longer matches
        at = data.find(np.ascontiguousarray(first.triangles).tobytes()[:24])
        assert at > 0
        data[at + 3] ^= 0x40
        npz.write_bytes(bytes(data))
    else:
        _rewrite(npz, meta={**_meta(npz), "materials": [7]})  # valid JSON, not what an entry holds
    got = meshes.load_mesh(path)
    _same(first, got)
    err = capsys.readouterr().err
    assert "damaged scene cache entry" in err and str(cache / "scenes") in err and "removed" in err
    assert small == ["box.obj", "box.obj"]
    meshes.load_mesh(path)  # the entry written again: no second warning
    assert small == ["box.obj", "box.obj"] and "damaged" not in capsys.readouterr().err


def test_an_entry_with_arrays_that_do_not_match_is_damaged(tmp_path, small, cache, capsys):
    path = _box(tmp_path / "a")
    first = meshes.load_mesh(path)
    npz = next((cache / "scenes").glob("mesh-*.npz"))
    with np.load(npz) as z:
        part = z["part"]
    _rewrite(npz, part=part[:1])  # a whole zip: only the shapes are wrong
    _same(first, meshes.load_mesh(path))
    assert "mismatched shapes" in capsys.readouterr().err


def test_a_library_the_lookup_would_now_find_first_is_parsed_again(tmp_path, small):
    """The lookup of the libraries runs again before an entry is used: a plain library
    beside a compressed OBJ is found before the compressed one, and a ``mtllib`` line read
    as two names becomes one file once a file of the whole line's name exists."""
    import lzma

    folder = tmp_path / "z"
    folder.mkdir()
    (folder / "box.obj.xz").write_bytes(lzma.compress(OBJ.encode()))
    (folder / "box.mtl.xz").write_bytes(lzma.compress(MTL.encode()))
    assert meshes.load_mesh(folder / "box.obj.xz").materials[0].albedo == (0.6, 0.1, 0.1)
    (folder / "box.mtl").write_text(MTL.replace("Kd 0.6 0.1 0.1", "Kd 0.0 0.0 0.9"))
    assert meshes.load_mesh(folder / "box.obj.xz").materials[0].albedo == (0.0, 0.0, 0.9)
    assert small == ["box.obj.xz", "box.obj.xz"]

    two = tmp_path / "two"
    two.mkdir()
    (two / "x").write_text("newmtl red\nKd 0.6 0.1 0.1\n")
    (two / "y.mtl").write_text("newmtl white\nKd 0.7 0.7 0.7\n")
    (two / "m.obj").write_text(OBJ.replace("mtllib box.mtl", "mtllib x y.mtl"))
    assert [m.name for m in meshes.load_mesh(two / "m.obj").materials] == ["red", "white"]
    (two / "x y.mtl").write_text(MTL.replace("Kd 0.6 0.1 0.1", "Kd 0.3 0.3 0.3"))
    assert meshes.load_mesh(two / "m.obj").materials[0].albedo == (0.3, 0.3, 0.3)
    assert small[2:] == ["m.obj", "m.obj"]


def test_another_numpy_or_trimesh_is_another_entry(tmp_path, small, monkeypatch):
    path = _box(tmp_path / "a")
    meshes.load_mesh(path)
    meshes.load_mesh(path)
    monkeypatch.setattr(scache, "parse_versions", lambda: "numpy=0 trimesh=0")
    meshes.load_mesh(path)
    assert small == ["box.obj", "box.obj"]


def test_a_cache_that_cannot_be_written_only_costs_speed(tmp_path, small, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("TLM_CACHE", str(blocker))  # (mkdir under a file fails, as read-only does)
    path = _box(tmp_path / "a")
    _same(meshes.load_mesh(path), meshes.load_mesh(path))
    assert small == ["box.obj", "box.obj"]


def test_small_meshes_and_gltf_with_outside_buffers_are_not_kept(tmp_path, cache, monkeypatch):
    meshes.load_mesh(_box(tmp_path / "a"))  # 3 triangles: under MIN_TRIANGLES
    assert not (cache / "scenes").exists() or not any((cache / "scenes").iterdir())
    monkeypatch.setattr(scache, "MIN_TRIANGLES", 0)
    import trimesh

    trimesh.creation.box().export(tmp_path / "cube.gltf")  # a .gltf and its .bin
    meshes.load_mesh(tmp_path / "cube.gltf")
    assert not list((cache / "scenes").glob("mesh-*")) if (cache / "scenes").exists() else True
    trimesh.creation.box().export(tmp_path / "cube.glb")
    meshes.load_mesh(tmp_path / "cube.glb")
    assert len(list((cache / "scenes").glob("mesh-*.npz"))) == 1


def test_crease_normals_are_kept_per_triangles_parts_and_angle(small, cache):
    tri = load_scene("cornell-sphere").triangles
    part = np.arange(tri.shape[0]) % 3
    computed = []

    def compute(t, p, a):
        computed.append(a)
        return crease_normals(t, p, a)

    a = scache.crease_normals(tri, part, 30.0, compute)
    b = scache.crease_normals(tri, part, 30.0, compute)
    assert computed == [30.0] and a.dtype == b.dtype and np.array_equal(a, b)
    assert np.array_equal(a, crease_normals(tri, part, 30.0))
    scache.crease_normals(tri, part, 60.0, compute)  # another angle
    scache.crease_normals(tri, part // 2, 30.0, compute)  # other parts
    moved = tri + 1.0
    c = scache.crease_normals(moved, part, 30.0, compute)  # other triangles
    assert computed == [30.0, 60.0, 30.0, 30.0]
    assert np.array_equal(c, crease_normals(moved, part, 30.0))


def test_a_large_scene_loads_from_the_cache_with_the_same_bits(cache):
    """The conference room (331k triangles, 35 materials): the second load reads both entries."""
    first = load_scene("conference")
    kinds = sorted(p.name.split("-")[0] for p in (cache / "scenes").glob("*.npz"))
    assert kinds == ["mesh", "normals"]
    again = load_scene("conference")
    for name in ("triangles", "normals", "material_index", "part"):
        x, y = getattr(first, name), getattr(again, name)
        assert x.dtype == y.dtype and np.array_equal(x, y), name
    assert first.materials == again.materials and first.part_names == again.part_names
    assert first.lights == again.lights


def test_a_glb_s_notes_are_read_back(tmp_path, small):
    import trimesh

    from tlm.scenes.materials import glb_chunks, write_glb

    box = trimesh.creation.box()
    path = tmp_path / "b.glb"
    box.export(path)
    header, binary = glb_chunks(path.read_bytes())
    header["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}]
    path.write_bytes(write_glb(header, binary))
    first = meshes.load_mesh(path)
    again = meshes.load_mesh(path)
    assert small == ["b.glb"] and again.notes == (f"{path}: not imported from its cameras: cameras[0] (on no node "
                                                  "of the glTF's scene)",)
    _same(first, again)


def test_a_cached_note_names_the_file_it_is_read_for(tmp_path, small):
    """The entry is keyed by the file's name and bytes, not its folder: a copy elsewhere reads
    it back, and its notes (and an undefined usemtl's line) name the copy, not the first file."""
    u = "mtllib box.mtl\nv 0 0 0\nv 3 0 0\nv 3 2 0\nv 2 2 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n"
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "box.mtl").write_text(MTL)
        (tmp_path / folder / "u.obj").write_text(u + "usemtl red\nf 1 2 3 4 5 6 7 8\nusemtl gone\nf 1 2 3\n")
    first = meshes.load_mesh(tmp_path / "a" / "u.obj")
    again = meshes.load_mesh(tmp_path / "b" / "u.obj")
    assert small == ["u.obj"]  # (the second from the cache)
    (note,) = again.notes
    assert note.startswith(f"{tmp_path / 'b' / 'u.obj'}: 1 polygon is not convex") and "/a/" not in note
    assert again.materials[-1].undefined.startswith(f"{tmp_path / 'b' / 'u.obj'}: line 12: usemtl 'gone'")
    assert first.notes[0].startswith(str(tmp_path / "a" / "u.obj"))
