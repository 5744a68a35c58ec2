"""Bad mesh and scene files (h237): a large OBJ polygon's crease normals in linear time with the
same bits (tlm/scenes/normals.py), and a one-line error, naming what is wrong, for a glTF whose
JSON is a list, an absolute buffer URI, a singular node transform on a mesh, an unknown
componentType, a spot light without ``spot``; a NaN vertex numbered as its file numbers it; a
huge OBJ index with its sign; an ASCII PLY whose list counts or element counts do not match its
data; an ASCII STL facet of 2 vertices; a scene path that is a folder or a symbolic-link loop;
an empty scene file; a scene ``name``/``description`` that is not text. A glTF buffer a folder
up (``../bin/data.bin``) loads."""

from __future__ import annotations

import base64
import json
import signal
import struct
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes import normals as nm
from tlm.scenes.loader import load_scene
from tlm.scenes.meshes import load_mesh

# one triangle (0,0,0) (1,0,0) (0,1,0): 36 bytes of float32 positions, then 3 uint16 indices (+2 padding)
TRIANGLE = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3H", 0, 1, 2) + b"\0\0"
SCENE = ("materials: {white: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\ndefault_material: white\n"
         "camera: {eye: [0.0, 0.5, -3.4], target: [0.0, 0.35, 0.0], vfov: 38.0}\nresolution: [8, 8]\n")


def triangle_gltf(uri: str, **fields) -> dict:
    """A glTF of one mesh, the triangle of ``TRIANGLE`` (its buffer at ``uri``), in the one node of
    the one scene; ``fields`` replace its top-level fields (``nodes``, ``scenes``, ...) or add to them
    (tests/test_review_h244.py builds its files with it too)."""
    return {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "buffers": [{"uri": uri, "byteLength": 44}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}], **fields}


def _gltf(uri: str | None = None, **extra) -> dict:
    return triangle_gltf(uri or "data:application/octet-stream;base64," + base64.b64encode(TRIANGLE).decode(), **extra)


def _write(path: Path, content) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def _error(path: Path) -> str:
    with pytest.raises(InputError) as info:
        load_mesh(path)
    text = str(info.value)
    assert "\n" not in text and "Traceback" not in text
    return text


# ------------------------------------------------------------------ 1. crease normals, linear


def _old_crease_normals(tri: np.ndarray, crease_angle: float) -> np.ndarray:
    """The neighbour-rank loop over every group (the code before h237): the reference bits."""
    n = tri.shape[0]
    face = nm._unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    cos_crease = np.cos(np.radians(min(float(crease_angle), 180.0)))
    weight = nm.corner_angles(tri).reshape(-1)
    order, starts, sizes = nm._weld(tri.reshape(-1, 3), np.zeros(3 * n, dtype=np.int64))
    big = np.argsort(-sizes, kind="stable")
    starts, sizes = starts[big], sizes[big]
    new_starts = np.cumsum(sizes) - sizes
    order = order[np.repeat(starts, sizes) + np.arange(3 * n) - np.repeat(new_starts, sizes)]
    head = np.repeat(new_starts, sizes)
    active = np.cumsum((np.bincount(sizes) * np.arange(int(sizes.max()) + 1))[::-1])[::-1]
    f = face[order // 3]
    fx, fy, fz = f[:, 0].copy(), f[:, 1].copy(), f[:, 2].copy()
    w = weight[order]
    ax, ay, az = np.zeros(3 * n), np.zeros(3 * n), np.zeros(3 * n)
    for j in range(1, active.shape[0]):
        m = int(active[j])
        q = head[:m] + (j - 1)
        bx, by, bz = fx[q], fy[q], fz[q]
        ok = (fx[:m] * bx + fy[:m] * by) + fz[:m] * bz >= cos_crease
        wq = np.where(ok, w[q], 0.0)
        ax[:m] += wq * bx
        ay[:m] += wq * by
        az[:m] += wq * bz
    acc = np.empty((3 * n, 3))
    acc[order] = np.stack([ax, ay, az], axis=1)
    out = nm._unit(acc).reshape(n, 3, 3)
    flat = ~np.any(out != 0.0, axis=2)
    out[flat] = np.repeat(face[:, None, :], 3, axis=1)[flat]
    return out


def _fan(k: int, r=None, z=None) -> np.ndarray:
    """The triangles of one k-corner polygon fanned from its first corner (as an OBJ face is)."""
    t = np.linspace(0.0, 2.0 * np.pi, k + 1)[:-1]
    r = np.ones(k) if r is None else r
    p = np.stack([r * np.cos(t), r * np.sin(t), np.zeros(k) if z is None else z(t)], axis=1)
    return np.stack([np.repeat(p[:1], k - 2, axis=0), p[1:-1], p[2:]], axis=1)


def _cone(k: int, h: float) -> np.ndarray:
    t = np.linspace(0.0, 2.0 * np.pi, k + 1)
    p = np.stack([np.cos(t), np.sin(t), np.zeros(k + 1)], axis=1)
    return np.stack([np.repeat([[0.0, 0.0, h]], k, axis=0), p[:-1], p[1:]], axis=1)


def test_a_large_polygon_crease_normals_in_linear_time():
    """A 40,000-corner polygon: its first corner is in every fan triangle (one welded group of
    ~40,000): the old loop ran once per member over every member (quadratic: minutes)."""
    tri = _fan(40_000)

    def too_slow(*_):
        raise TimeoutError("crease_normals of a 40,000-corner fan took over 20 s (quadratic)")

    before = signal.signal(signal.SIGALRM, too_slow)
    signal.alarm(20)
    try:
        out = nm.crease_normals(tri)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, before)
    assert out.shape == (tri.shape[0], 3, 3)
    assert np.allclose(out, [0.0, 0.0, 1.0])


@pytest.mark.parametrize("crease", [0.5, 30.0, 89.0, 90.0, 120.0, 180.0])
def test_crease_normals_keep_their_bits(crease):
    """Large welded groups (more than ``_SMALL_GROUP`` corners) of flat, concave, wavy and cone
    fans, a degenerate triangle among them: the same bits as the neighbour-rank loop."""
    degenerate = _fan(400)
    degenerate[5, 2] = degenerate[5, 1]
    rng = np.random.default_rng(7)
    assert nm._SMALL_GROUP < 290
    cases = [_fan(600), _fan(700, r=np.where(np.arange(700) % 2, 0.4, 1.0)), _fan(400, z=lambda t: 0.3 * np.sin(3 * t)),
             _cone(300, 0.01), _cone(300, 1.0), degenerate, _fan(40), rng.integers(0, 3, (4000, 3, 3)).astype(float)]
    for tri in cases:
        got, want = nm.crease_normals(tri, None, crease), _old_crease_normals(tri, crease)
        assert np.array_equal(got.view(np.uint64), want.view(np.uint64))


# ------------------------------------------------------------------ 2-4, 6: glTF


def test_a_gltf_whose_json_is_a_list(tmp_path, cache):
    text = _error(_write(tmp_path / "g.gltf", [_gltf()]))
    assert "the glTF JSON is a list, not an object" in text


def test_a_buffer_a_folder_up_loads_and_an_absolute_one_is_named(tmp_path, cache):
    _write(tmp_path / "bin" / "data.bin", TRIANGLE)
    geom = load_mesh(_write(tmp_path / "model" / "m.gltf", _gltf("../bin/data.bin")))
    assert geom.triangles.shape == (1, 3, 3)
    absolute = str(tmp_path / "bin" / "data.bin")
    text = _error(_write(tmp_path / "model" / "a.gltf", _gltf(absolute)))
    assert f"buffers[0].uri {absolute!r} is an absolute path or URL" in text
    assert "FilePathResolver" not in text and "allow_anywhere" not in text
    text = _error(_write(tmp_path / "model" / "b.gltf", _gltf("../bin/nope.bin")))
    assert "buffers[0].uri '../bin/nope.bin': no file" in text


@pytest.mark.parametrize("node", [{"mesh": 0, "matrix": [0.0] * 16}, {"mesh": 0, "scale": [1.0, 0.0, 1.0]}])
def test_a_singular_node_transform_on_a_mesh(tmp_path, cache, node):
    text = _error(_write(tmp_path / "g.gltf", _gltf(nodes=[node])))
    assert "nodes[0]: its world transform (with its parents') is singular" in text
    assert "meshes[0]" in text


def test_an_unknown_component_type(tmp_path, cache):
    g = _gltf()
    g["accessors"][0]["componentType"] = 9999
    assert "accessors[0].componentType = 9999 is not a glTF accessor componentType" in _error(
        _write(tmp_path / "g.gltf", g))


def test_a_spot_light_without_its_spot_object(tmp_path, cache):
    lights = {"KHR_lights_punctual": {"lights": [{"type": "spot"}]}}
    g = _gltf(nodes=[{"mesh": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}}],
              extensionsUsed=["KHR_lights_punctual"], extensions=lights)
    g["scenes"] = [{"nodes": [0, 1]}]
    assert "lights[0]: a spot light needs a 'spot' object" in _error(_write(tmp_path / "g.gltf", g))
    g["extensions"]["KHR_lights_punctual"]["lights"] = [{"type": "spot", "spot": {}}]  # (the defaults)
    assert len(load_mesh(_write(tmp_path / "g2.gltf", g)).imports[0].lights) == 1


# ------------------------------------------------------------------ 5, 6: OBJ, PLY, STL


def test_a_nan_vertex_is_numbered_as_its_file_numbers_it(tmp_path, cache):
    text = _error(_write(tmp_path / "nan2.obj", "v 0 0 0\nv 1 0 0\n# a comment\nv 0 1 nan\nf 1 2 3\n"))
    assert "(first: vertex 3, line 4, [0.0, 1.0, nan])" in text
    ply = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\nnan 1 0\n3 0 1 2\n")
    assert "(first: vertex 2 counting from 0, [nan, 1.0, 0.0])" in _error(_write(tmp_path / "n.ply", ply))


@pytest.mark.parametrize("index", ["99999999999999999999999", "-99999999999999999999999"])
def test_a_huge_obj_index_keeps_its_sign(tmp_path, cache, index):
    text = _error(_write(tmp_path / "h.obj", f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {index}\n"))
    assert f"line 4: a face references vertex {index}:" in text
    assert "9223372036854775807" not in text


_PLY = ("ply\nformat ascii 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
        "element face {nf}\nproperty list uchar int vertex_indices\nend_header\n")


@pytest.mark.parametrize("body, nv, nf, expect", [
    ("0 0 0\n1 0 0\n0 1 0\n255 0 1 2\n", 3, 1, "line 13: element 'face' row 0 (from 0) holds 4 numbers"),
    ("0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2\n3 1 3 2\n", 4, 2, "line 14: element 'face' row 0 (from 0) holds 4"),
    ("0 0 0\n1 0 0\n", 5, 1, "the ASCII PLY's data holds 6 numbers, fewer than its header's elements need"),
    ("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 10 ** 12, 1, "cut short, or a count in the header too large"),
])
def test_an_ascii_ply_whose_data_does_not_match_its_header(tmp_path, cache, body, nv, nf, expect):
    assert expect in _error(_write(tmp_path / "p.ply", _PLY.format(nv=nv, nf=nf) + body))


def test_an_ascii_ply_that_matches_loads(tmp_path, cache):
    geom = load_mesh(_write(tmp_path / "p.ply", _PLY.format(nv=4, nf=2) + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n"
                            "3 0 1 2\n4 1 3 2 0\n"))
    assert geom.triangles.shape == (3, 3, 3)


def test_an_ascii_stl_facet_of_two_vertices(tmp_path, cache):
    stl = ("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n"
           "endsolid x\n")
    assert "line 3: facet 0 (from 0) has 2 vertices" in _error(_write(tmp_path / "s.stl", stl))


def test_the_file_checks_in_mesh_checks_are_the_objects_meshes_calls(tmp_path, cache, monkeypatch):
    """The checks before trimesh reads a file (tlm/scenes/mesh_checks.py, out of meshes.py: h240): the same
    objects meshes.py holds by their old private names, doing as they did; a patch of the old name in
    meshes takes effect in a load."""
    from tlm.scenes import mesh_checks, meshes

    for name in mesh_checks.__all__:
        assert getattr(meshes, "_" + name) is getattr(mesh_checks, name), name
    assert mesh_checks.absolute_uri("C:/x.bin") and mesh_checks.absolute_uri("file:///x.bin")
    assert not mesh_checks.absolute_uri("../bin/x.bin") and not mesh_checks.absolute_uri("my%20model.bin")
    stl = _write(tmp_path / "s.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                 "vertex 0 1 0\nvertex 1 1 0\nendloop\nendfacet\nendsolid x\n")
    with pytest.raises(InputError, match=r"line 3: facet 0 \(from 0\) has 4 vertices"):
        mesh_checks.check_ascii_stl(stl, None, str(stl))
    assert isinstance(mesh_checks.noting_resolver(str(stl)), mesh_checks.noting_resolver_class())
    assert mesh_checks.noting_resolver_class() is mesh_checks.noting_resolver_class()

    def refuse(path, data, src):
        raise InputError("patched", source=src)

    monkeypatch.setattr(meshes, "_check_ascii_stl", refuse)
    good = _write(tmp_path / "t.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                  "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n")
    assert "patched" in _error(good)


# ------------------------------------------------------------------ 6: scene files


def test_a_scene_path_that_is_a_folder_or_a_link_loop(tmp_path, cache):
    (tmp_path / "adir.yaml").mkdir()
    (tmp_path / "l1.yaml").symlink_to("l2.yaml")
    (tmp_path / "l2.yaml").symlink_to("l1.yaml")
    with pytest.raises(InputError, match=r"adir\.yaml'? is a folder, not a scene file"):
        load_scene(tmp_path / "adir.yaml")
    with pytest.raises(InputError, match=r"l1\.yaml'? is a symbolic link that leads round in a loop"):
        load_scene(tmp_path / "l1.yaml")
    _write(tmp_path / "ext.yaml", "extends: l1.yaml\ngeometry: {shape: plane}\n" + SCENE)
    with pytest.raises(InputError, match=r"extends: .*l1\.yaml'? is a symbolic link that leads round in a loop"):
        load_scene(tmp_path / "ext.yaml")


def test_an_empty_scene_file(tmp_path, cache):
    with pytest.raises(InputError, match=r"empty\.yaml: is empty \(nothing but comments or blanks\)"):
        load_scene(_write(tmp_path / "empty.yaml", "# nothing\n"))


@pytest.mark.parametrize("line, key", [("name: [1]", "name"), ("description: 5", "description")])
def test_a_scene_name_or_description_that_is_not_text(tmp_path, cache, line, key):
    path = _write(tmp_path / "s.yaml", f"{line}\ngeometry: {{shape: plane}}\n" + SCENE)
    with pytest.raises(InputError, match=f"{key}: .* is not text"):
        load_scene(path)
