"""Materials from mesh files (tlm/scenes/materials.py through load_mesh): MTL and glTF
mapped to tlm's kinds, per-face material indices, the shipped scenes, PLY triangle
strips, errors, and no library warning reaching the terminal."""

from __future__ import annotations

import lzma
import warnings
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes.materials import glb_chunks, parse_mtl, write_glb
from tlm.scenes.meshes import load_mesh
from tlm.scenes.model import Material

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "scenes" / "meshes"
TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"


def _by_name(g) -> dict[str, Material]:
    return {m.name: m for m in g.materials}


def _usemtl_per_triangle(text: str) -> list[str | None]:
    """The usemtl in force for each triangle (faces fanned), read line by line."""
    out, mat = [], None
    for line in text.splitlines():
        words = line.split()
        if words[:1] == ["usemtl"]:
            mat = line.strip()[6:].strip()
        elif words[:1] == ["f"]:
            out += [mat] * (len(words) - 3)
    return out


# ---------------------------------------------------------------- McGuire's boxes


def test_cornell_sphere_materials_map_to_jensens_scene():
    g = load_mesh(MESHES / "CornellBox-Sphere.obj.xz")
    m = _by_name(g)
    assert list(m) == ["leftSphere", "rightSphere", "floor", "ceiling", "backWall", "rightWall",
                       "leftWall", "light"]
    assert m["leftSphere"] == Material("leftSphere", "mirror", reflectance=(0.95, 0.95, 0.95))
    assert m["rightSphere"] == Material("rightSphere", "dielectric", ior=2.5, transmittance=(1.0, 1.0, 1.0))
    assert m["light"] == Material("light", "lambertian", albedo=(0.78, 0.78, 0.78), emission=(10.0, 10.0, 10.0))
    assert m["light"].emits and not m["floor"].emits
    assert m["leftWall"] == Material("leftWall", "lambertian", albedo=(0.63, 0.065, 0.05))
    assert m["rightWall"] == Material("rightWall", "lambertian", albedo=(0.161, 0.133, 0.427))
    for wall in ("floor", "ceiling", "backWall"):
        assert m[wall] == Material(wall, "lambertian", albedo=(0.725, 0.71, 0.68))


@pytest.mark.parametrize("name", ["CornellBox-Original.obj", "CornellBox-Sphere.obj.xz", "CornellBox-Water.obj.xz"])
def test_face_materials_follow_the_usemtl_runs(name):
    data = (MESHES / name).read_bytes()
    text = (lzma.decompress(data) if name.endswith(".xz") else data).decode()
    g = load_mesh(MESHES / name)
    assert g.face_material.dtype == np.int32 and g.face_material.shape == (g.triangles.shape[0],)
    got = [g.materials[i].name if i >= 0 else None for i in g.face_material]
    assert got == _usemtl_per_triangle(text)
    if name != "CornellBox-Original.obj":  # whose blocks' usemtl comes before their g
        assert [g.part_names[p] for p in g.part] == got  # each group is named after its material


def test_cornell_water_and_original():
    w = _by_name(load_mesh(MESHES / "CornellBox-Water.obj.xz"))
    assert w["water"] == Material("water", "dielectric", ior=1.33, transmittance=(1.0, 1.0, 1.0))
    assert w["leftSphere"].kind == "mirror" and w["rightSphere"].kind == "dielectric"
    o = load_mesh(MESHES / "CornellBox-Original.obj")
    m = _by_name(o)
    assert m["light"].emission == (17.0, 12.0, 4.0) and m["light"].albedo == (0.78, 0.78, 0.78)
    assert {x.kind for x in o.materials} == {"lambertian"}
    assert o.triangles.shape[0] == 36 and o.normals is None


@pytest.mark.slow
def test_the_conference_room():
    g = load_mesh(MESHES / "conference.obj.xz")
    assert g.triangles.shape == (331179, 3, 3)
    assert len(g.materials) == 35 and {m.kind for m in g.materials} == {"lambertian"}
    assert not any(m.emits for m in g.materials)
    assert g.face_material.min() >= 0 and len(np.unique(g.face_material)) == 35
    assert len(g.part_names) == 41 and g.part_names[:3] == ("mesh0", "mesh1", "mesh2")
    assert g.normals is None  # no vn: the scene loader computes crease normals
    # Ks 0.2 over a darker Kd (illum 2) stays Lambertian with Kd
    assert _by_name(g)["mesh4_SG"].albedo == (0.176471, 0.058824, 0.058824)


# ---------------------------------------------------------------- the MTL mapping


def _one(text: str) -> Material:
    (m,) = parse_mtl(text, "t.mtl")
    return m


@pytest.mark.parametrize(("text", "expected"), [
    ("newmtl a\nKd 0.5 0.6 0.7\nKs 0.9 0.9 0.9\nillum 2\n", Material("a", "lambertian", albedo=(0.5, 0.6, 0.7))),
    ("newmtl a\nKd 0.1 0.1 0.1\nKs 0.9 0.8 0.7\n", Material("a", "mirror", reflectance=(0.9, 0.8, 0.7))),
    ("newmtl a\nKd 0.5 0.5 0.5\nKs 0.9 0.8 0.7\nillum 3\n", Material("a", "mirror", reflectance=(0.9, 0.8, 0.7))),
    ("newmtl a\nKs 1.5 0.5 0.5\nillum 5\n", Material("a", "mirror", reflectance=(1.0, 0.5, 0.5))),
    ("newmtl a\nKd 0.5 0.5 0.5\nd 0.5\nNi 1.2\n", Material("a", "dielectric", ior=1.2, transmittance=(1.0,) * 3)),
    ("newmtl a\nKd 0.5 0.5 0.5\nTr 0.25\n", Material("a", "dielectric", ior=1.5, transmittance=(1.0,) * 3)),
    ("newmtl a\nd 1\nTr 0.5\n", Material("a", "lambertian", albedo=(0.8, 0.8, 0.8))),  # d wins over Tr
    ("newmtl a\nillum 4\nTf 0.2\nNi 1.7\n", Material("a", "dielectric", ior=1.7, transmittance=(1.0,) * 3)),
    ("newmtl a\nillum 6\n", Material("a", "dielectric", ior=1.5, transmittance=(1.0,) * 3)),
    ("newmtl a\nKd 2 0.5 -0\nKe 3 2 1 # glow\n",
     Material("a", "lambertian", albedo=(1.0, 0.5, 0.0), emission=(3.0, 2.0, 1.0))),
    ("newmtl a\nKd spectral x.rfl\nKd 0.3\nKa 1 1 1\nmap_Kd x.png\nNs 10\n",
     Material("a", "lambertian", albedo=(0.3, 0.3, 0.3))),
    ("newmtl a\nillum 7\nNi 1.33\nKe 1 1 1\n",
     Material("a", "dielectric", ior=1.33, transmittance=(1.0,) * 3, emission=(1.0, 1.0, 1.0))),
])
def test_mtl_mapping_table(text, expected):
    assert _one(text) == expected


def test_mtl_names_order_and_redefinition():
    mats = parse_mtl("Kd 1 0 0\nnewmtl  two words \nKd 0.1 0.2 0.3\nnewmtl b\nnewmtl two words\nKd 1 1 1\n", "t.mtl")
    assert [m.name for m in mats] == ["two words", "b"]
    assert mats[0].albedo == (0.1, 0.2, 0.3)  # the first definition counts


@pytest.mark.parametrize(("text", "words"), [
    ("newmtl glass\nillum 7\nNi 0\n", ["line 3", "'glass'", "Ni", "not positive"]),
    ("newmtl glass\nd 0.5\nNi -1.5\n", ["'glass'", "Ni"]),
    ("newmtl red\nKd 1 nan 0\n", ["line 2", "'red'", "Kd", "not finite"]),
    ("newmtl red\nKe inf 0 0\n", ["'red'", "Ke", "not finite"]),
    ("newmtl red\nKs 0.5 -0.1 0\n", ["'red'", "Ks", "negative"]),
    ("newmtl red\nKd 0.5 0.5\n", ["'red'", "Kd", "3 numbers"]),
    ("newmtl red\nKd 0.5 zero 0.5\n", ["'red'", "Kd", "'zero'"]),
    ("newmtl red\nd 1.5\n", ["'red'", "d", "[0, 1]"]),
    ("newmtl red\nNi nan\n", ["'red'", "Ni", "not finite"]),
    ("newmtl red\nillum\n", ["'red'", "illum", "no value"]),
])
def test_bad_mtl_values_are_one_line_errors(tmp_path, text, words):
    (tmp_path / "m.mtl").write_text(text)
    (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + TRI + "f 1 2 3\n")
    with pytest.raises(InputError) as info:
        load_mesh(tmp_path / "m.obj")
    msg = str(info.value)
    assert "\n" not in msg and str(tmp_path / "m.mtl") in msg
    for w in words:
        assert w in msg


def test_an_index_of_refraction_is_checked_only_where_it_is_used():
    assert _one("newmtl wall\nKd 0.5 0.5 0.5\nNi 0\nillum 2\n").kind == "lambertian"


def test_a_missing_mtl_names_the_obj_and_the_mtl(tmp_path):
    (tmp_path / "m.obj").write_text("mtllib gone.mtl\n" + TRI + "f 1 2 3\n")
    with pytest.raises(InputError) as info:
        load_mesh(tmp_path / "m.obj")
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(tmp_path / "m.obj"))
    assert "line 1" in msg and str(tmp_path / "gone.mtl") in msg and "missing" in msg


def test_an_undefined_usemtl_is_named(tmp_path):
    """The mesh loads with a placeholder (the scene file may supply it); a scene that does not
    is the error, naming the OBJ, the line and the library."""
    from tlm import api

    (tmp_path / "m.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + TRI + "usemtl red\nf 1 2 3\nusemtl redd\nf 2 4 3\n")
    placeholder = load_mesh(tmp_path / "m.obj").materials[1]
    assert placeholder.name == "redd" and "line 8" in placeholder.undefined
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\ncamera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], "
                                     "vfov: 40}\nresolution: [8, 8]\n")
    with pytest.raises(InputError) as info:
        api.load_scene(tmp_path / "s.yaml")
    msg = str(info.value)
    assert "\n" not in msg and str(tmp_path / "m.obj") in msg
    assert "line 8" in msg and "'redd'" in msg and "m.mtl" in msg and "did you mean 'red'" in msg


def test_libraries_several_and_with_spaces_and_no_library(tmp_path):
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (tmp_path / "b.mtl").write_text("newmtl blue\nKd 0 0 1\nnewmtl red\nKd 0 1 0\n")
    (tmp_path / "my lib.mtl").write_text("newmtl green\nKd 0 1 0\n")
    (tmp_path / "m.obj").write_text("mtllib a.mtl b.mtl\nmtllib my lib.mtl\n" + TRI +
                                    "f 1 2 3\nusemtl blue\nf 1 2 3\nusemtl red\nf 2 4 3\nusemtl green\nf 1 2 4\n")
    g = load_mesh(tmp_path / "m.obj")
    assert [m.name for m in g.materials] == ["red", "blue", "green"]
    assert g.materials[0].albedo == (1.0, 0.0, 0.0)  # a.mtl's red, named first
    assert g.face_material.tolist() == [-1, 1, 0, 2]
    # no mtllib: no materials, usemtl ignored
    (tmp_path / "n.obj").write_text(TRI + "usemtl whatever\nf 1 2 3\n")
    g = load_mesh(tmp_path / "n.obj")
    assert g.materials == () and g.face_material is None


# ---------------------------------------------------------------- glTF


def _gltf_scene(tmp_path: Path) -> tuple[dict, bytes]:
    """A GLB of four boxes side by side (the last without material), materials patched in."""
    trimesh = pytest.importorskip("trimesh")
    scene = trimesh.Scene()
    for i, name in enumerate(("paint", "chrome", "glass", "lamp", "bare")):
        box = trimesh.creation.box()
        box.visual = trimesh.visual.TextureVisuals(
            material=trimesh.visual.material.PBRMaterial(name=name, baseColorFactor=[200, 100, 50, 255]))
        scene.add_geometry(box, geom_name=name,
                           transform=trimesh.transformations.translation_matrix([3.0 * i, 0.0, 0.0]))
    path = tmp_path / "raw.glb"
    scene.export(path)
    header, binary = glb_chunks(path.read_bytes())
    header["materials"] = [
        {"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 0.125, 1.0], "metallicFactor": 0.0}},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0], "metallicFactor": 0.8}},
        {"name": "glass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 1.0, 0.95, 1.0], "metallicFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_ior": {"ior": 1.45}}},
        {"name": "lamp", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.2, 0.2, 1.0], "metallicFactor": 0.0},
         "emissiveFactor": [1.0, 0.5, 0.25],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
    ]
    order = {m["name"]: i for i, m in enumerate(header["meshes"])}
    for mesh in header["meshes"]:
        for prim in mesh["primitives"]:
            prim.pop("material", None)
            if mesh["name"] != "bare":
                prim["material"] = order[mesh["name"]]
    return header, binary


def test_gltf_materials_and_extensions(tmp_path):
    header, binary = _gltf_scene(tmp_path)
    (tmp_path / "s.glb").write_bytes(write_glb(header, binary))
    g = load_mesh(tmp_path / "s.glb")
    assert g.materials == (
        Material("paint", "lambertian", albedo=(0.5, 0.25, 0.125)),
        Material("material_1", "mirror", reflectance=(0.9, 0.8, 0.7)),
        Material("glass", "dielectric", ior=1.45, transmittance=(0.9, 1.0, 0.95)),
        Material("lamp", "lambertian", albedo=(0.2, 0.2, 0.2), emission=(4.0, 2.0, 1.0)),
    )
    # each box's triangles carry its material (boxes 3 apart in x), the bare one none
    x = g.triangles[:, :, 0].mean(axis=1)
    box = np.round(x / 3.0).astype(int)
    assert g.triangles.shape[0] == 60
    assert g.face_material.tolist() == [[0, 1, 2, 3, -1][b] for b in box]
    assert set(g.part_names) == {"paint", "chrome", "glass", "lamp", "bare"}


def test_gltf_text_file_with_external_buffer(tmp_path):
    import base64
    import json

    header, binary = _gltf_scene(tmp_path)
    header["buffers"] = [{"byteLength": len(binary), "uri": "s.bin"}]
    (tmp_path / "s.bin").write_bytes(binary)
    (tmp_path / "s.gltf").write_text(json.dumps(header))
    a = load_mesh(tmp_path / "s.gltf")
    header["buffers"] = [{"byteLength": len(binary),
                          "uri": "data:application/octet-stream;base64," + base64.b64encode(binary).decode()}]
    (tmp_path / "t.gltf").write_text(json.dumps(header))
    b = load_mesh(tmp_path / "t.gltf")
    (tmp_path / "s.glb").write_bytes(write_glb(*_gltf_scene(tmp_path)))
    c = load_mesh(tmp_path / "s.glb")
    for other in (b, c):
        assert other.materials == a.materials
        np.testing.assert_array_equal(other.face_material, a.face_material)
        np.testing.assert_array_equal(other.triangles, a.triangles)
    assert [m.kind for m in a.materials] == ["lambertian", "mirror", "dielectric", "lambertian"]


@pytest.mark.parametrize("materials", [True, False], ids=["with-materials", "without"])
def test_gltf_buffer_names_are_percent_decoded_and_a_missing_one_is_named(tmp_path, materials):
    """Blender writes 'my%20model.bin' for 'my model.bin' (glTF URIs are RFC 3986)."""
    import json

    header, binary = _gltf_scene(tmp_path)
    if not materials:
        header.pop("materials")
        for mesh in header["meshes"]:
            for prim in mesh["primitives"]:
                prim.pop("material", None)
    (tmp_path / "my model ü.bin").write_bytes(binary)
    header["buffers"] = [{"byteLength": len(binary), "uri": "my%20model%20%C3%BC.bin"}]
    (tmp_path / "s.gltf").write_text(json.dumps(header))
    assert load_mesh(tmp_path / "s.gltf").triangles.shape == (60, 3, 3)
    header["buffers"] = [{"byteLength": len(binary), "uri": "gone%20away.bin"}]
    (tmp_path / "s.gltf").write_text(json.dumps(header))
    with pytest.raises(InputError, match=r"s\.gltf: buffers\[0\]\.uri 'gone%20away\.bin': no file .*gone away\.bin$"):
        load_mesh(tmp_path / "s.gltf")


def test_gltf_metallic_default_and_bad_values(tmp_path):
    header, binary = _gltf_scene(tmp_path)
    header["materials"][0] = {"name": "paint"}  # glTF's defaults: white, metallic 1
    (tmp_path / "d.glb").write_bytes(write_glb(header, binary))
    assert load_mesh(tmp_path / "d.glb").materials[0] == Material("paint", "mirror", reflectance=(1.0, 1.0, 1.0))
    header["materials"][2]["extensions"]["KHR_materials_ior"]["ior"] = 0.0
    (tmp_path / "bad.glb").write_bytes(write_glb(header, binary))
    with pytest.raises(InputError, match=r"bad\.glb.*'glass'.*ior"):
        load_mesh(tmp_path / "bad.glb")
    header["materials"][2]["extensions"]["KHR_materials_ior"]["ior"] = 1.5
    header["materials"][3]["emissiveFactor"] = [1.0, -1.0, 0.0]
    (tmp_path / "bad.glb").write_bytes(write_glb(header, binary))
    with pytest.raises(InputError, match=r"bad\.glb.*'lamp'.*emissiveFactor.*negative"):
        load_mesh(tmp_path / "bad.glb")


def test_broken_gltf_references_and_truncation_are_named(tmp_path):
    """What a library would report as "list index out of range" or a failed reshape is
    named: the reference, the table it misses, the bytes an accessor needs."""
    import copy

    header, binary = _gltf_scene(tmp_path)
    cases = [
        (lambda h: h["meshes"][1]["primitives"][0].update(material=9),
         r"meshes\[1\]\.primitives\[0\]\.material = 9 names no entry of 'materials' \(it has 4\)"),
        (lambda h: h["meshes"][0]["primitives"][0].update(indices=99),
         r"meshes\[0\]\.primitives\[0\]\.indices = 99 names no entry of 'accessors'"),
        (lambda h: h["nodes"][0].update(mesh=42), r"nodes\[0\]\.mesh = 42 names no entry of 'meshes'"),
        (lambda h: h["accessors"][0].update(count=10**9), r"accessors\[0\]\.count = 1000000000 needs [\d,]+ bytes"),
        (lambda h: h.update(meshes=[]), "the glTF has no meshes"),
    ]
    for change, words in cases:
        broken = copy.deepcopy(header)
        change(broken)
        (tmp_path / "b.glb").write_bytes(write_glb(broken, binary))
        with pytest.raises(InputError, match=r"b\.glb: " + words):
            load_mesh(tmp_path / "b.glb")
    whole = write_glb(header, binary)
    for cut in (12, len(whole) // 2):
        (tmp_path / "cut.glb").write_bytes(whole[:cut])
        with pytest.raises(InputError, match=f"cut\\.glb: the binary glTF file is truncated: its header says "
                                             f"{len(whole):,} bytes, the file has {cut:,}"):
            load_mesh(tmp_path / "cut.glb")


def test_meshes_without_materials_have_none(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    for ext in ("ply", "stl"):
        trimesh.creation.box().export(tmp_path / f"b.{ext}")
        g = load_mesh(tmp_path / f"b.{ext}")
        assert g.materials == () and g.face_material is None


def test_compressed_ply_stl_glb_load_like_the_plain_files(tmp_path):
    import bz2
    import gzip

    header, binary = _gltf_scene(tmp_path)
    (tmp_path / "s.glb").write_bytes(write_glb(header, binary))
    trimesh = pytest.importorskip("trimesh")
    trimesh.creation.icosphere(1).export(tmp_path / "s.ply")
    trimesh.creation.box().export(tmp_path / "s.stl")
    for ext, (suffix, pack) in zip(("glb", "ply", "stl"), ((".xz", lzma.compress), (".gz", gzip.compress),
                                                         (".bz2", bz2.compress)), strict=True):
        plain = tmp_path / f"s.{ext}"
        packed = tmp_path / f"s.{ext}{suffix}"
        packed.write_bytes(pack(plain.read_bytes()))
        a, b = load_mesh(plain), load_mesh(packed)
        np.testing.assert_array_equal(a.triangles, b.triangles)
        assert a.part_names == b.part_names and a.materials == b.materials
        if a.face_material is not None:
            np.testing.assert_array_equal(a.face_material, b.face_material)
    (tmp_path / "s.gltf.gz").write_bytes(b"")
    with pytest.raises(InputError, match=r"unsupported mesh extension '\.gltf\.gz'"):
        load_mesh(tmp_path / "s.gltf.gz")


# ---------------------------------------------------------------- PLY triangle strips

STRIP_PLY = """ply
format ascii 1.0
element vertex 8
property float x
property float y
property float z
element tristrips 1
property list int int vertex_indices
end_header
0 0 0
1 0 0
0 1 0
1 1 0
0 2 0
1 2 0
5 5 0
6 5 0
{strip}
"""


def test_ply_triangle_strips_decode_with_one_winding(tmp_path):
    # a strip of 4 triangles, a restart, then a strip with a stitching (degenerate) triangle
    strip = [0, 1, 2, 3, 4, 5, -1, 6, 7, 3, 3, 2]
    path = tmp_path / "strip.ply"
    path.write_text(STRIP_PLY.format(strip=f"{len(strip)} " + " ".join(map(str, strip))))
    g = load_mesh(path)
    faces = [[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5], [6, 7, 3], [3, 7, 3], [3, 3, 2]]
    faces = [f for f in faces if len(set(f)) == 3]  # the stitches go
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0], [1, 2, 0], [5, 5, 0], [6, 5, 0]], float)
    np.testing.assert_array_equal(g.triangles, v[faces])
    first = g.triangles[:4]  # the first strip, a flat ribbon: every triangle faces +z, as its first
    normal = np.cross(first[:, 1] - first[:, 0], first[:, 2] - first[:, 0])
    assert np.all(normal[:, 2] > 0)
    assert g.part_names == ("strip",)


def test_ply_triangle_strips_binary_and_several(tmp_path):
    import struct

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0]], dtype="<f4")
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
            "property float z\nelement tristrips {n}\nproperty list uchar int vertex_indices\nend_header\n")
    for strips, faces in (([[0, 1, 2, 3, -1, 2, 3, 4]], [[0, 1, 2], [2, 1, 3], [2, 3, 4]]),
                          ([[0, 1, 2, 3], [2, 3, 4, 1]], [[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 1]])):
        body = v.tobytes() + b"".join(struct.pack("<B", len(s)) + struct.pack(f"<{len(s)}i", *s) for s in strips)
        (tmp_path / "s.ply").write_bytes(head.format(n=len(strips)).encode() + body)
        g = load_mesh(tmp_path / "s.ply")
        np.testing.assert_array_equal(g.triangles, v.astype(float)[faces])


# ---------------------------------------------------------------- no warnings


def test_no_library_warning_reaches_the_terminal(tmp_path, capfd, monkeypatch):
    trimesh = pytest.importorskip("trimesh")
    (tmp_path / "n.obj").write_text(TRI + "vn 0 0 0\nf 1//1 2//1 3//1\n")  # a zero normal: 0/0
    (tmp_path / "strip.ply").write_text(STRIP_PLY.format(strip="4 0 1 2 3"))
    trimesh.creation.box().export(tmp_path / "b.glb")
    real = trimesh.load

    def noisy(*args, **kwargs):
        warnings.warn("trimesh says something", RuntimeWarning, stacklevel=1)
        np.float64(1.0) / np.float64(0.0)  # numpy's divide warning
        return real(*args, **kwargs)

    monkeypatch.setattr(trimesh, "load", noisy)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for name in ("n.obj", "strip.ply", "b.glb"):
            load_mesh(tmp_path / name)
        load_mesh(MESHES / "CornellBox-Sphere.obj.xz")
    assert caught == []
    out, err = capfd.readouterr()
    assert out == "" and err == ""


# ---------------------------------------------------------------- what is not rendered


def test_what_a_file_gives_a_material_and_tlm_does_not_render_is_kept():
    text = ("newmtl wood\nKd 0.5 0.3 0.1\nmap_Kd wood.png\nbump -bm 0.5 n.png\nmap_Kd again.png\nKa 1 1 1\n"
            "newmtl metal\nKd 0.5 0.5 0.5\nPm 1\nPr 0.2\nnewmtl plain\nKd 0.8 0.8 0.8\nNs 10\nKs 0.1 0.1 0.1\n")
    wood, metal, plain = parse_mtl(text, "t.mtl")
    assert wood.ignored == ("map_Kd", "bump") and metal.ignored == ("Pm", "Pr") and plain.ignored == ()
    (xyz,) = parse_mtl("newmtl x\nKd xyz 0.5 0.5 0.5\nKs spectral f.rfl\n", "t.mtl")  # (colours not read either)
    assert xyz.ignored == ("Kd xyz", "Ks spectral") and xyz.albedo == (0.8, 0.8, 0.8)
    assert wood == Material("wood", "lambertian", albedo=(0.5, 0.3, 0.1))  # (not part of the value)


def test_what_a_gltf_material_leaves_unrendered_is_kept():
    from tlm.scenes.materials import gltf_material

    m = gltf_material({"name": "x", "normalTexture": {"index": 1}, "alphaMode": "BLEND",
                       "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.5], "metallicFactor": 0,
                                                "baseColorTexture": {"index": 0}},
                       "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1},
                                      "KHR_materials_transmission": {"transmissionFactor": 0,
                                                                     "transmissionTexture": {"index": 2}}}}, 0)
    assert m.ignored == ("normalTexture", "baseColorTexture", "KHR_materials_clearcoat", "transmissionTexture",
                         "alpha", "alphaMode")
    plain = gltf_material({"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0},
                           "alphaMode": "OPAQUE", "extensions": {"KHR_materials_ior": {"ior": 1.3}}}, 0)
    assert plain.ignored == ()
    with pytest.raises(InputError, match="extensions is not an object"):
        gltf_material({"extensions": [1]}, 0, "f.gltf")


def test_a_run_warns_of_the_textures_of_the_materials_it_shows(tmp_path):
    """One line, naming the materials on the image's triangles whose file gives them maps;
    a material the scene file replaces, or one no triangle uses, is not named."""
    from tlm import api
    from tlm.render.checks import material_warnings

    (tmp_path / "t.obj").write_text("mtllib t.mtl\n" + TRI + "usemtl wood\nf 1 2 3\nusemtl stone\nf 2 4 3\n")
    (tmp_path / "t.mtl").write_text("newmtl wood\nKd 0.5 0.3 0.1\nmap_Kd w.png\nbump n.png\n"
                                    "newmtl stone\nKd 0.5 0.5 0.5\nmap_Kd s.png\n"
                                    "newmtl unused\nKd 1 1 1\nmap_Ks u.png\n")
    head = ("geometry: {mesh: t.obj}\nlights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]}]\n"
            "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n")
    (tmp_path / "s.yaml").write_text(head)
    (line,) = material_warnings(api.load_scene(tmp_path / "s.yaml"))
    assert line.startswith("2 materials of 't.mtl' ('wood' and 'stone') use what tlm does not render: "
                           "map_Kd, bump;"), line
    (tmp_path / "s.yaml").write_text(head + "materials: {wood: {type: lambertian, albedo: [0.5, 0.3, 0.1]}}\n")
    scene = api.load_scene(tmp_path / "s.yaml")
    assert material_warnings(scene) == ["1 material of 't.mtl' ('stone') uses what tlm does not render: "
                                        "map_Kd; it renders with its constant colour (a scene file's materials: "
                                        "entry of the same name replaces it)"]
    assert api.scene_info(scene)["materials"][1]["ignored"] == ["map_Kd"]
    results = api.run(tmp_path / "s.yaml", tmp_path / "out")
    assert [w for w in results["warnings"] if "does not render" in w] == material_warnings(scene)


def test_items_sharing_a_material_share_what_it_leaves_unrendered():
    from tlm.scenes.compose import merge
    from tlm.scenes.model import Geometry

    tri = np.zeros((1, 3, 3))
    plain = Material("wood", "lambertian", albedo=(0.5, 0.3, 0.1))
    mapped = Material("wood", "lambertian", albedo=(0.5, 0.3, 0.1), ignored=("map_Kd",))
    geoms = [Geometry(tri, np.zeros(1, np.int32), (n,), materials=(m,), face_material=np.zeros(1, np.int32))
             for n, m in (("a", plain), ("b", mapped))]
    g = merge(geoms)
    assert len(g.materials) == 1 and g.materials[0].ignored == ("map_Kd",) and g.face_material.tolist() == [0, 0]


def test_a_materials_entry_replaces_the_material_of_that_name_in_every_mesh_file(tmp_path):
    """Two files both name 'light' (the second is renamed light_2 in the merge): the scene
    file's entry replaces both, as one material; light_2 kept its Ke before."""
    from tlm import api

    (tmp_path / "two.yaml").write_text(
        f"geometry: [{{mesh: {MESHES / 'CornellBox-Original.obj'}}}, {{mesh: {MESHES / 'CornellBox-Sphere.obj.xz'}, "
        "transform: {translate: [3, 0, 0]}}]\n"
        "materials: {light: {type: lambertian, albedo: [0.5, 0.5, 0.5], emission: [1, 1, 1]}}\n"
        "camera: {eye: [1.5, 1, 6], target: [1.5, 1, 0], vfov: 40}\nresolution: [8, 8]\n")
    scene = api.load_scene(tmp_path / "two.yaml")
    names = [m.name for m in scene.materials]
    assert names.count("light") == 1 and "light_2" not in names
    light = scene.materials[names.index("light")]
    assert light.emission == (1.0, 1.0, 1.0)
    emitting = {scene.materials[i].name for i in np.unique(scene.material_index) if scene.materials[i].emits}
    assert emitting == {"light"} and (scene.material_index == names.index("light")).sum() == 4  # 2 + 2 triangles
    assert "rightWall_2" in names  # (a material no entry replaces keeps its renamed name)


def test_a_usemtl_the_library_lacks_takes_the_scene_file_s_material_or_the_default(tmp_path):
    """McGuire's CornellBox-Glossy names a 'light' its MTL does not define: a scene file that
    gives it (materials:, or default_material) loads; one that gives neither is the error."""
    from tlm import api

    (tmp_path / "g.obj").write_text("mtllib g.mtl\n" + TRI + "usemtl floor\nf 1 2 3\nusemtl light\nf 2 4 3\n")
    (tmp_path / "g.mtl").write_text("newmtl floor\nKd 0.5 0.5 0.5\n")
    head = ("geometry: {mesh: g.obj}\ncamera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\n"
            "resolution: [8, 8]\n")
    (tmp_path / "s.yaml").write_text(head)
    with pytest.raises(InputError, match=r"g\.obj: line 8: usemtl 'light': no material of that name in g\.mtl: "
                                         r"give it under materials: in the scene file \(or set default_material\)"):
        api.load_scene(tmp_path / "s.yaml")
    (tmp_path / "s.yaml").write_text(head + "materials: {light: {type: lambertian, albedo: [1, 1, 1], "
                                            "emission: [5, 5, 5]}}\n")
    scene = api.load_scene(tmp_path / "s.yaml")
    assert [m.name for m in scene.materials] == ["floor", "light"] and scene.material_index.tolist() == [0, 1]
    assert scene.materials[1].emission == (5.0, 5.0, 5.0) and scene.lights[0].kind == "mesh"
    (tmp_path / "s.yaml").write_text(head + "default_material: floor\n")
    scene = api.load_scene(tmp_path / "s.yaml")
    assert [m.name for m in scene.materials] == ["floor"] and scene.material_index.tolist() == [0, 0]


def test_a_gltf_s_cameras_punctual_lights_and_double_sided_emission_are_warned_of(tmp_path):
    """tlm imports a glTF's point, spot and directional lights and perspective camera on nodes
    of its scene, and emits from a triangle's front only: what a glTF holds of these that is not
    imported (lights of every kind and cameras on no node) is named in the run's warnings, not
    dropped silently."""
    from tlm import api
    from tlm.render.checks import file_warnings, material_warnings

    header, binary = _gltf_scene(tmp_path)
    header["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}] * 2
    header["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 50},
                                                               {"type": "spot", "intensity": 5, "spot": {}},
                                                               {"type": "point", "intensity": 1},
                                                               {"type": "directional", "intensity": 2}]}}
    header["materials"][3]["doubleSided"] = True  # the emissive "lamp"
    header["materials"][0]["doubleSided"] = True  # not emissive: both sides shade alike, nothing lost
    (tmp_path / "s.glb").write_bytes(write_glb(header, binary))
    g = load_mesh(tmp_path / "s.glb")
    path = str(tmp_path / "s.glb")
    nowhere = "on no node of the glTF's scene"  # (the header's lights and cameras: no node names them)
    assert g.notes == (f"{path}: not imported from its KHR_lights_punctual lights: lights[0] (point, {nowhere}), "
                       f"lights[1] (spot, {nowhere}), lights[2] (point, {nowhere}) and lights[3] (directional, "
                       f"{nowhere})",
                       f"{path}: not imported from its cameras: cameras[0] ({nowhere}) and cameras[1] ({nowhere})")
    assert g.imports == ()  # (nothing placed: nothing imported)
    assert g.materials[3].ignored == ("doubleSided emission",) and g.materials[0].ignored == ()
    (tmp_path / "s.yaml").write_text("geometry: [{mesh: s.glb}, {mesh: s.glb, transform: {translate: [0, 9, 0]}}]\n"
                                     "camera: {eye: [6, 2, 12], target: [6, 0, 0], vfov: 40}\nresolution: [8, 8]\n"
                                     "default_material: grey\n"
                                     "materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n")
    scene = api.load_scene(tmp_path / "s.yaml")
    assert file_warnings(scene) == list(g.notes)  # (two items of one file: said once)
    assert "doubleSided emission" in material_warnings(scene)[0]
    (tmp_path / "plain.glb").write_bytes(write_glb(*_gltf_scene(tmp_path)))
    assert load_mesh(tmp_path / "plain.glb").notes == ()


def test_malformed_punctual_lights_and_dark_double_sided_emitters(tmp_path):
    """KHR_lights_punctual that is not an object is no note (it was an internal error); a
    doubleSided material whose emission is 0 (emissive strength 0) is nothing lost."""
    for bad in ([{"type": "point"}], "x"):
        header, binary = _gltf_scene(tmp_path)
        header["extensions"] = {"KHR_lights_punctual": bad}
        (tmp_path / "s.glb").write_bytes(write_glb(header, binary))
        assert load_mesh(tmp_path / "s.glb").notes == ()
    header, binary = _gltf_scene(tmp_path)
    lamp = header["materials"][3]
    lamp["doubleSided"] = True
    lamp["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = 0.0
    (tmp_path / "s.glb").write_bytes(write_glb(header, binary))
    assert load_mesh(tmp_path / "s.glb").materials[3].ignored == ()
