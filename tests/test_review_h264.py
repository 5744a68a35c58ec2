"""Review of 7a6576d (h264): a skin's inverse bind matrices that name no accessor, or whose
buffer view's byteStride or accessor's byteOffset is no count of bytes, are one line naming
them (7a6576d: an IndexError or a ValueError out of tlm.scenes.gltf_imports._accessor_mat4); a
skin that is not an object is said to be one; a glTF buffer is read once however many nodes one
skin skins (tlm.scenes.mesh_checks.buffer_reader: 7a6576d decoded a 40 MB data URI again for
each, 49 s against 3.6 s for 40 nodes); a NaN corner of a mesh under a singular transform is
named as a NaN corner, not as a collapse (tlm.scenes.meshes._load_trimesh); a skin whose joint
matrix collapses its mesh is named, not its node's world transform, which glTF ignores."""

from __future__ import annotations

import base64
import json
import pathlib
from pathlib import Path

import numpy as np
import pytest

from tests.test_mesh_leftovers_h255 import QUAD, _gltf, _refused, _translate, _triangles
from tlm.scenes.meshes import load_mesh

_SKINNED = [{"children": [1, 2]}, {"mesh": 0, "skin": 0, "translation": [5.0, 0.0, 0.0]},
            {"translation": [0.0, 2.0, 0.0]}]


def _edited(path: Path, edit) -> Path:
    header = json.loads(path.read_text())
    edit(header)
    path.write_text(json.dumps(header))
    return path


# ------------------------------------------------------------------ 1. a skin's accessor, named in one line


def test_inverse_bind_matrices_that_name_no_accessor_are_one_line(tmp_path, cache):
    for i, k in enumerate((99, True, -1)):
        text = _refused(_gltf(tmp_path / str(i), _SKINNED, skins=[{"joints": [2], "inverseBindMatrices": k}]))
        assert f"skins[0].inverseBindMatrices = {k!r} names no entry of 'accessors' (it has 2)" in text


@pytest.mark.parametrize("key, value, said", [
    ("byteStride", "z", "bufferViews[2].byteStride = 'z' is not a count of bytes of at least 64 (a MAT4 of floats)"),
    ("byteStride", 16, "bufferViews[2].byteStride = 16 is not a count of bytes of at least 64"),
    ("byteOffset", "x", "accessors[2].byteOffset = 'x' is not a count of bytes"),
    ("byteOffset", -64, "accessors[2].byteOffset = -64 is not a count of bytes"),
])
def test_a_stride_or_offset_that_is_no_count_of_bytes_is_one_line(tmp_path, cache, key, value, said):
    path = _gltf(tmp_path, _SKINNED, skins=[{"joints": [2]}], matrices=[_translate(0.0, -2.0, 0.0)])
    assert np.array_equal(load_mesh(path).triangles, _triangles())  # (as written: placed by its skin)

    def edit(header):
        table = "bufferViews" if key == "byteStride" else "accessors"
        header[table][-1][key] = value

    text = _refused(_edited(path, edit))
    assert f"skins[0].inverseBindMatrices = 2: {said}" in text


def test_a_skin_that_is_not_an_object_is_said_to_be_one(tmp_path, cache):
    text = _refused(_gltf(tmp_path, _SKINNED, skins=[5]))
    assert "skins[0]: 5 is not an object" in text and "names no entry" not in text


# ------------------------------------------------------------------ 2. a buffer read once


def test_a_buffer_is_read_once_for_every_node_one_skin_skins(tmp_path, cache, monkeypatch):
    """Three nodes skinned by one skin whose matrices are in an external .bin: the file is read
    once (7a6576d read it again for each node: a big data URI decoded again, seconds each)."""
    nodes = [{"children": [1, 2, 3, 4]}, {"translation": [0.0, 2.0, 0.0]}] + [{"mesh": 0, "skin": 0}] * 3
    path = _gltf(tmp_path, nodes, skins=[{"joints": [1]}], matrices=[_translate(0.0, -2.0, 0.0)])
    header = json.loads(path.read_text())
    (tmp_path / "data.bin").write_bytes(base64.b64decode(header["buffers"][0]["uri"].split(",", 1)[1]))
    header["buffers"][0]["uri"] = "data.bin"
    path.write_text(json.dumps(header))
    reads: list[str] = []
    real = pathlib.Path.read_bytes

    def read_bytes(self):
        reads.append(self.name)
        return real(self)

    monkeypatch.setattr(pathlib.Path, "read_bytes", read_bytes)
    g = load_mesh(path)
    assert np.array_equal(g.triangles, np.concatenate([_triangles()] * 3))
    assert reads.count("data.bin") == 1, reads


# ------------------------------------------------------------------ 3. a NaN corner under a singular transform


def test_a_nan_corner_under_a_singular_transform_is_named_as_such(tmp_path, cache):
    """A flat quad with a NaN corner under ``scale: [1, 1, 0]``: the NaN vertex is named (as it
    is without the scale), not a collapse the transform does not make (7a6576d said "singular
    ... collapses meshes[0]")."""
    points = [*QUAD[:3], (float("nan"), 1.0, 0.0)]
    plain = _refused(_gltf(tmp_path / "plain", [{"mesh": 0}], points))
    text = _refused(_gltf(tmp_path / "flat", [{"mesh": 0, "scale": [1.0, 1.0, 0.0]}], points))
    assert "vertex with NaN or infinite coordinates (first: vertex 3" in plain
    assert "vertex with NaN or infinite coordinates (first: vertex 3" in text and "singular" not in text
    # a solid under the same scale is still refused as a collapse
    tetra = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    faces = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))
    assert "is singular" in _refused(_gltf(tmp_path / "solid", [{"mesh": 0, "scale": [1.0, 1.0, 0.0]}], tetra,
                                          faces))


def test_a_skin_whose_joint_matrix_collapses_a_solid_names_the_skin(tmp_path, cache):
    """A skinned tetrahedron whose node is the identity and whose one joint has ``scale: [1, 1,
    0]``: the joint matrix collapses it, and the error says so (7a6576d blamed the node's own
    world transform, which glTF ignores for a skinned mesh and which is not singular)."""
    tetra = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    faces = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))
    nodes = [{"children": [1, 2]}, {"mesh": 0, "skin": 0}, {"scale": [1.0, 1.0, 0.0]}]
    text = _refused(_gltf(tmp_path, nodes, tetra, faces, skins=[{"joints": [2]}]))
    assert ("nodes[1]: its skin's joint matrix (skins[0]: a joint's world transform times its inverse bind matrix) "
            "is singular (a zero scale, an all-zero matrix, or scales whose product is 0 in floating point): it "
            "collapses meshes[0] to a plane, a line or a point") in text


def test_a_deep_rig_is_walked_once_however_many_nodes_its_skin_skins(tmp_path, cache, monkeypatch):
    """Three nodes skinned by one skin of a chain of 50 joints at rest: each node's local
    transform composed once, not once per joint per skinned node (7a6576d: 3 x 1,275 for this
    rig; 5 s against 0.6 s for a chain of 1,000), and the mesh where the rest pose puts it."""
    from tlm.scenes import gltf_imports

    depth = 50
    nodes = [{"children": [1, depth + 1, depth + 2, depth + 3]}]
    nodes += [{"translation": [0.0, 0.01, 0.0], **({"children": [j + 2]} if j < depth - 1 else {})}
              for j in range(depth)]
    nodes += [{"mesh": 0, "skin": 0}] * 3
    rest = [_translate(0.0, -0.01 * (j + 1), 0.0) for j in range(depth)]
    path = _gltf(tmp_path, nodes, skins=[{"joints": list(range(1, depth + 1))}], matrices=rest)
    calls = []
    real = gltf_imports._node_matrix

    def node_matrix(node, i, src):
        calls.append(i)
        return real(node, i, src)

    monkeypatch.setattr(gltf_imports, "_node_matrix", node_matrix)
    g = load_mesh(path)
    assert np.allclose(g.triangles, np.concatenate([_triangles()] * 3), atol=1e-5)
    assert not any("skinned" in n for n in g.notes)  # (no note: the skin is at rest)
    assert len(calls) <= 2 * len(nodes), len(calls)
