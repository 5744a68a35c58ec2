"""Scene input messages: a mesh file given where a YAML file or a scene goes is told by its
suffix or its first bytes, in one line saying what to write instead; a damaged glTF (a buffer
cut short, a byteLength or a buffer view past its data) is one line naming what is wrong, not
the library's AssertionError; a mesh light's ``materials`` is a list of names."""

from __future__ import annotations

import base64
import json
import struct

import pytest
import yaml

import tlm
from tlm.cli import main
from tlm.config import load_config, read_yaml
from tlm.errors import InputError
from tlm.mesh_files import mesh_file_format
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import write_glb
from tlm.scenes.meshes import load_mesh

OBJ = "# a triangle\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\n"
PLY = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
ASCII_STL = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n" \
            "endsolid t\n"
# one triangle: three float32 positions (36 bytes), then three uint32 indices (12 bytes)
BIN = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3I", 0, 1, 2)


def _gltf(buffer: dict) -> dict:
    return {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
            "buffers": [{"byteLength": len(BIN), **buffer}]}


def _binary_stl() -> bytes:
    return b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<12f", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0) + b"\0\0"


def _mesh_files(tmp_path) -> dict[str, bytes]:
    """Each format's file contents by its name."""
    return {"t.obj": OBJ.encode(), "t.ply": PLY.encode(), "t.stl": ASCII_STL.encode(), "b.stl": _binary_stl(),
            "t.glb": write_glb(_gltf({}), BIN),
            "t.gltf": json.dumps(_gltf({"uri": "data:application/octet-stream;base64,"
                                               + base64.b64encode(BIN).decode()})).encode()}


FORMATS = {"t.obj": "an OBJ", "t.ply": "a PLY", "t.stl": "an STL", "b.stl": "an STL", "t.glb": "a binary glTF (.glb)",
           "t.gltf": "a glTF"}


@pytest.mark.parametrize("name", sorted(FORMATS))
def test_a_mesh_file_read_as_yaml_is_named_with_the_scene_file_to_write(tmp_path, name):
    data = _mesh_files(tmp_path)[name]
    (tmp_path / name).write_bytes(data)
    load_mesh(tmp_path / name)  # (a good mesh file of its format)
    with pytest.raises(InputError) as e:
        load_config(tmp_path / name)
    text = str(e.value)
    assert "\n" not in text and str(tmp_path / name) in text
    assert f"is {FORMATS[name]} mesh file, not a YAML file" in text
    assert f"`geometry: {{mesh: {name}}}`" in text and "tlm run SCENE.yaml" in text
    # by its first bytes alone: the same file under a YAML name, renamed in the hint
    (tmp_path / "m.yaml").write_bytes(data)
    ext = name.rsplit(".", 1)[1]
    if name != "b.stl":  # (a binary STL is told by its size, never under a YAML name)
        with pytest.raises(InputError, match=f"is {FORMATS[name][:5]}.* mesh file.*rename it m.{ext} .*"
                           f"`geometry: {{mesh: m.{ext}}}`"):
            read_yaml(tmp_path / "m.yaml")
    (tmp_path / "noname").write_bytes(data)
    assert mesh_file_format(tmp_path / "noname") == FORMATS[name]
    # while YAML that looks a little like a mesh still reads
    for text in ["v: 1\nf: [1, 2]\n", "scene: cornell\n", "{scene: cornell, asset: 1}\n", "# v 1 2 3\nscene: x\n",
                 "solid: 1\nfacet normal: 2\n", "ply: 1\nformat: 2\n"]:
        (tmp_path / "c.yaml").write_text(text)
        assert isinstance(read_yaml(tmp_path / "c.yaml"), dict) and mesh_file_format(tmp_path / "c.yaml") is None


def test_a_mesh_file_in_a_scene_slot_says_to_write_a_scene_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pawn.glb").write_bytes(write_glb(_gltf({}), BIN))
    (tmp_path / "pawn.obj").write_text(OBJ)
    (tmp_path / "c.yaml").write_text("scene: pawn.obj\n")
    (tmp_path / "e.yaml").write_text("extends: pawn.glb\n")
    for args, said in [(["run", "pawn.glb"], "pawn.glb: is a binary glTF (.glb) mesh file, not a YAML file"),
                       (["run", "c.yaml"], "c.yaml: scene: 'pawn.obj' is an OBJ mesh file, not a scene"),
                       (["run", "c.yaml", "--set", "scene=pawn.glb"], "scene: 'pawn.glb' is a binary glTF"),
                       (["scene", "show", "pawn.glb"], "pawn.glb: is a binary glTF (.glb) mesh file, not a scene"),
                       (["scene", "show", "e.yaml"], "extends: 'pawn.glb' is a binary glTF (.glb) mesh file, "
                                                     "not a scene file to extend")]:
        assert main([*args, "--out", str(tmp_path / "out")] if args[0] == "run" else args) == 2, args
        err = capsys.readouterr().err
        assert said in err and "`geometry: {mesh: pawn." in err, (args, err)
        assert len([ln for ln in err.splitlines() if "error" in ln]) == 1
    assert not (tmp_path / "out").exists()
    # and the scene file it says to write renders the mesh
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "geometry": {"mesh": "pawn.glb"}, "default_material": "white",
        "materials": {"white": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "camera": {"eye": [0.3, 0.3, 3.0], "target": [0.3, 0.3, 0.0], "vfov": 40.0}, "resolution": [8, 8]}))
    assert load_scene(str(tmp_path / "s.yaml")).triangles.shape[0] == 1


def _damaged(tmp_path, name: str) -> object:
    g = _gltf({"uri": "t.bin"})
    (tmp_path / "t.bin").write_bytes(BIN)
    if name == "cut.gltf":  # its buffer file cut short
        (tmp_path / "t.bin").write_bytes(BIN[:30])
    elif name == "long.gltf":  # a byteLength beyond its file
        g["buffers"][0]["byteLength"] = 4096
    elif name == "view.gltf":  # a buffer view past the end of its buffer
        g["bufferViews"][1]["byteLength"] = 4096
    elif name == "nobuf.gltf":
        g["bufferViews"][1]["buffer"] = 3
    elif name == "uri.gltf":
        g["buffers"][0]["uri"] = "data:application/octet-stream;base64,AAAA"
    elif name == "cut.glb":  # the header's length right, its BIN chunk cut short
        data = write_glb(_gltf({}), BIN)[:-8]
        (tmp_path / name).write_bytes(data[:8] + struct.pack("<I", len(data)) + data[12:])
        return tmp_path / name
    (tmp_path / name).write_text(json.dumps(g))
    return tmp_path / name


@pytest.mark.parametrize("name, said", [
    ("cut.gltf", "buffers[0].byteLength = 48 but its file 't.bin' holds 30 bytes"),
    ("long.gltf", "buffers[0].byteLength = 4,096 but its file 't.bin' holds 48 bytes"),
    ("view.gltf", "bufferViews[1] (bytes 36 to 4,132) runs past the end of buffers[0], which holds 48"),
    ("nobuf.gltf", "bufferViews[1].buffer = 3 names no entry of 'buffers' (it has 1)"),
    ("uri.gltf", "buffers[0].byteLength = 48 but its data URI holds 3 bytes"),
    ("cut.glb", "the binary glTF file is truncated: its BIN chunk says 48 bytes, the file holds 40 of them"),
])
def test_a_damaged_gltf_is_one_line_naming_what_is_wrong(tmp_path, name, said):
    path = _damaged(tmp_path, name)
    with pytest.raises(InputError) as e:
        load_mesh(path)
    assert str(e.value).startswith(f"{path}: {said}") and "\n" not in str(e.value)


def test_a_cut_binary_ply_says_so(tmp_path):
    head = PLY.replace("ascii", "binary_little_endian").split("end_header\n")[0] + "end_header\n"
    body = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2)
    (tmp_path / "t.ply").write_bytes(head.encode() + body)
    assert load_mesh(tmp_path / "t.ply").triangles.shape == (1, 3, 3)
    (tmp_path / "t.ply").write_bytes(head.encode() + body[:-6])
    with pytest.raises(InputError) as e:
        load_mesh(tmp_path / "t.ply")
    assert str(e.value).startswith(f"{tmp_path / 't.ply'}: the binary PLY file's data is not the length its header "
                                   "gives (cut short")


def test_a_mesh_lights_materials_are_a_list(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({
        "geometry": [{"shape": "plane", "name": "floor", "params": {"size": [4.0, 4.0]}},
                     {"shape": "box", "name": "lamp", "params": {"min": [-0.2, 1.0, -0.2], "max": [0.2, 1.2, 0.2]}}],
        "materials": {"warm, soft": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5], "emission": [1.0, 1.0, 1.0]},
                      "glow": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5], "emission": [2.0, 2.0, 2.0]}},
        "parts": {"floor": "warm, soft", "lamp": "glow"},
        "camera": {"eye": [0.0, 2.0, 6.0], "target": [0.0, 0.0, 0.0], "vfov": 40.0}, "resolution": [8, 8]}))
    (mesh,) = [lt for lt in tlm.scene_info(str(path))["lights"] if lt["type"] == "mesh"]
    assert mesh["materials"] == ["glow", "warm, soft"]  # (in the scene's order of its materials)
    light = next(lt for lt in load_scene(str(path)).lights if lt.kind == "mesh")
    assert light.name == "glow, warm, soft"  # (the text that names it, and its record, as before)


def test_a_scene_given_as_a_mesh_file_is_named_once_without_a_key_not_written(tmp_path, monkeypatch, capsys):
    (tmp_path / "pawn.obj").write_text(OBJ)
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path / "sub")
    for args in (["scene", "show", "../pawn.obj"], ["scene", "export", "../pawn.obj", "x.ply"]):
        assert main(args) == 2
        (line,) = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
        assert line.startswith("tlm: error: ../pawn.obj: is an OBJ mesh file, not a scene: write "
                               "`geometry: {mesh: pawn.obj}`"), line
        assert line.count("../pawn.obj") == 1 and ": scene: " not in line
        assert line.endswith("name that file in its place")
    assert not (tmp_path / "sub" / "x.ply").exists()
    with pytest.raises(InputError, match=r"^\.\./pawn\.obj: is an OBJ mesh file, not a scene: "):
        tlm.load_scene("../pawn.obj")


def _lines(text: str, width: int, sep: str) -> str:
    return sep.join(text[i:i + width] for i in range(0, len(text), width))


def test_a_base64_data_uri_with_whitespace_loads_and_garbage_is_refused(tmp_path):
    b64 = base64.b64encode(BIN).decode()
    for k, sep in enumerate(["\n", "\r\n", " ", "\n\t "]):  # (MIME breaks lines every 76 characters; here 16)
        path = tmp_path / f"w{k}.gltf"
        path.write_text(json.dumps(_gltf({"uri": "data:application/octet-stream;base64," + _lines(b64, 16, sep)})))
        assert load_mesh(path).triangles.shape == (1, 3, 3), repr(sep)
    for k, bad in enumerate([b64[:10] + "*" + b64[10:], b64[:-4] + "A=AA", b64[:10] + "\u00a0" + b64[10:]]):
        path = tmp_path / f"g{k}.gltf"
        path.write_text(json.dumps(_gltf({"uri": "data:application/octet-stream;base64," + bad})))
        with pytest.raises(InputError) as e:
            load_mesh(path)
        assert str(e.value) == f"{path}: buffers[0].uri: its data URI is not valid base64", bad


def test_a_byte_length_short_of_the_bytes_its_data_holds_loads_with_a_note(tmp_path):
    """The spec calls it invalid, but glTF libraries read the data's bytes: read so, and named
    in the notes; a view past the bytes really there is still refused."""
    said = "buffers[0].byteLength = 40 is less than bufferViews[1] reaches (bytes 36 to 48): read from the 48 bytes "
    uri = "data:application/octet-stream;base64," + base64.b64encode(BIN).decode()
    for name, buffer, what in [("f.gltf", {"uri": "t.bin"}, "its file 't.bin'"),
                               ("u.gltf", {"uri": uri}, "its data URI"), ("b.glb", {}, "the BIN chunk")]:
        (tmp_path / "t.bin").write_bytes(BIN)
        g = _gltf(buffer)
        g["buffers"][0]["byteLength"] = 40
        path = tmp_path / name
        path.write_bytes(write_glb(g, BIN) if name.endswith(".glb") else json.dumps(g).encode())
        geom = load_mesh(path)
        assert geom.triangles.shape == (1, 3, 3) and geom.triangles[0, 1].tolist() == [1.0, 0.0, 0.0]
        (note,) = geom.notes
        assert note.startswith(f"{path}: {said}{what} holds") and "byteLength to be the buffer's length" in note
    # the scene's notes say it (tlm scene show, a run's warnings)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "geometry": {"mesh": "f.gltf"}, "default_material": "white",
        "materials": {"white": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "camera": {"eye": [0.3, 0.3, 3.0], "target": [0.3, 0.3, 0.0], "vfov": 40.0}, "resolution": [8, 8]}))
    assert [n for n in tlm.scene_info(str(tmp_path / "s.yaml"))["notes"] if said in n]
    # a view past the bytes the data holds: refused, by those bytes
    g = _gltf({"uri": "t.bin"})
    g["buffers"][0]["byteLength"] = 40
    g["bufferViews"][1]["byteLength"] = 16
    (tmp_path / "p.gltf").write_text(json.dumps(g))
    with pytest.raises(InputError) as e:
        load_mesh(tmp_path / "p.gltf")
    assert str(e.value) == f"{tmp_path / 'p.gltf'}: bufferViews[1] (bytes 36 to 52) runs past the end of buffers[0], " \
                           "which holds 48"


def test_a_json_config_is_not_called_a_gltf_while_a_gltf_under_a_yaml_name_still_is(tmp_path):
    for k, text in enumerate([
            '{"scene": "cornell", "resolution": [32, 24], "mode": "rcast", "asset": 1, "version": 2}\n',
            '{"scene": "cornell", "asset": {"version": "2.0"}, "meshes": []}\n',  # (glTF's scene is an index)
            '{"asset": {"version": "2.0"}, "meshes": [], "mode": "rcast"}\n',  # (a key glTF has not)
            '{"asset": {"version": "2.0"}, "note": "version"}\n', '{"asset": "x", "version": 1, "meshes": []}\n']):
        path = tmp_path / f"j{k}.yaml"
        path.write_text(text)
        assert mesh_file_format(path) is None, text
        assert isinstance(read_yaml(path), dict)
    with pytest.raises(InputError) as e:
        load_config(tmp_path / "j0.yaml")
    assert str(e.value).startswith(f"{tmp_path / 'j0.yaml'}: asset: unknown key")
    g = _gltf({"uri": "data:application/octet-stream;base64," + base64.b64encode(BIN).decode()})
    big = {**g, "extras": {"pad": "x" * 5000}}  # ('asset' past the first 4 KB: sorted after 'accessors', 'extras')
    cut = json.dumps(g, indent=1)
    huge = dict(g, buffers=[{"byteLength": 1 << 20, "uri": "data:application/octet-stream;base64," + "A" * (1 << 21)}])
    for name, text in [("g.yaml", json.dumps(g)), ("sorted.yaml", json.dumps(big, sort_keys=True)),
                       ("cut.yaml", cut[: len(cut) // 2]), ("huge.yaml", json.dumps(huge))]:
        (tmp_path / name).write_text(text)
        assert mesh_file_format(tmp_path / name) == "a glTF", name
        with pytest.raises(InputError, match=r"is a glTF mesh file, not a YAML file: rename it"):
            read_yaml(tmp_path / name)
