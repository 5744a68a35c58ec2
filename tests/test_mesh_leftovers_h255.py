"""Mesh-file leftovers (h255): a glTF mesh node's singular transform refused only where it
degenerates the mesh's triangles (a flat quad under a scale of 0 along its normal loads, a solid
or an in-plane collapse is still refused: tlm.scenes.meshes._keeps_triangles); a skinned mesh's
node transform ignored, as glTF says, its skin's joint matrix applied where every joint gives the
same one (tlm.scenes.gltf_imports.check_mesh_nodes); crease normals of a pole's welded group by
wide clusters, with the bits of the per-corner loop (tlm.scenes.normals._group_sums)."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes import normals as nm
from tlm.scenes import shapes
from tlm.scenes.meshes import load_mesh

QUAD = [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (2.0, 1.0, 0.0), (0.0, 1.0, 0.0)]  # in the XY plane, facing +z
TETRA = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
S45 = float(np.sin(np.pi / 8))
C45 = float(np.cos(np.pi / 8))


def _gltf(tmp_path: Path, nodes: list, points=QUAD, faces=((0, 1, 2), (0, 2, 3)), normals=None, skins=None,
          matrices=(), roots=(0,), layer=None) -> Path:
    """A .gltf of one mesh (``points``, ``faces``, optional ``NORMAL``s) in one base64 buffer, the
    ``nodes`` given, ``skins`` whose inverse bind matrices (``matrices``, 4x4 row major) follow."""
    pos = struct.pack(f"<{3 * len(points)}f", *np.ravel(points))
    nrm = b"" if normals is None else struct.pack(f"<{3 * len(points)}f", *np.ravel(normals))
    idx = struct.pack(f"<{3 * len(faces)}H", *np.ravel(faces))
    idx += b"\0" * (-len(idx) % 4)
    ibm = b"".join(struct.pack("<16f", *np.asarray(m, dtype=float).T.ravel()) for m in matrices)
    data = pos + nrm + idx + ibm
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)}]
    acc = [{"bufferView": 0, "componentType": 5126, "count": len(points), "type": "VEC3",
            "min": np.min(points, axis=0).tolist(), "max": np.max(points, axis=0).tolist()}]
    attributes = {"POSITION": 0}
    if nrm:
        views.append({"buffer": 0, "byteOffset": len(pos), "byteLength": len(nrm)})
        acc.append({"bufferView": 1, "componentType": 5126, "count": len(points), "type": "VEC3"})
        attributes["NORMAL"] = 1
    views.append({"buffer": 0, "byteOffset": len(pos) + len(nrm), "byteLength": 6 * len(faces)})
    acc.append({"bufferView": len(views) - 1, "componentType": 5123, "count": 3 * len(faces), "type": "SCALAR"})
    prims = [{"attributes": attributes, "indices": len(acc) - 1}]
    if layer is not None:  # (a second primitive: the same corners moved by ``layer``)
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(pos)})
        acc.append({"bufferView": len(views) - 1, "componentType": 5126, "count": len(points), "type": "VEC3",
                    "min": (np.min(points, axis=0) + layer).tolist(), "max": (np.max(points, axis=0) + layer).tolist()})
        data += struct.pack(f"<{3 * len(points)}f", *np.ravel(np.add(points, layer)))
        prims.append({"attributes": {"POSITION": len(acc) - 1}, "indices": prims[0]["indices"]})
    header = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(roots)}], "nodes": nodes,
              "meshes": [{"primitives": prims}],
              "buffers": [{"uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
                           "byteLength": len(data)}], "bufferViews": views, "accessors": acc}
    if matrices:
        views.append({"buffer": 0, "byteOffset": len(pos + nrm + idx), "byteLength": len(ibm)})
        acc.append({"bufferView": len(views) - 1, "componentType": 5126, "count": len(matrices), "type": "MAT4"})
        for skin in skins:
            skin.setdefault("inverseBindMatrices", len(acc) - 1)
    if skins is not None:
        header["skins"] = skins
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "g.gltf"
    path.write_text(json.dumps(header))
    return path


def _triangles(points=QUAD, faces=((0, 1, 2), (0, 2, 3))) -> np.ndarray:
    return np.asarray(points, dtype=np.float32).astype(np.float64)[np.asarray(faces)]


def _refused(path: Path) -> str:
    with pytest.raises(InputError) as info:
        load_mesh(path)
    text = str(info.value)
    assert "\n" not in text
    return text


# ------------------------------------------------------------------ 1. a singular transform, judged by the triangles


def test_a_flat_mesh_under_a_zero_scale_along_its_normal_loads_unchanged(tmp_path, cache):
    """A quad in the XY plane under ``scale: [1, 1, 0]`` (alone, or a parent's under a child's
    turn about z): its triangles are what they are without it (HEAD refused it as singular)."""
    g = load_mesh(_gltf(tmp_path / "a", [{"mesh": 0, "scale": [1.0, 1.0, 0.0]}]))
    assert np.array_equal(g.triangles, _triangles())
    turned = [{"children": [1], "scale": [1.0, 1.0, 0.0]}, {"mesh": 0, "rotation": [0.0, 0.0, S45, C45]}]
    g = load_mesh(_gltf(tmp_path / "b", turned))
    c = np.cos(np.pi / 4)
    want = _triangles() @ np.array([[c, -c, 0.0], [c, c, 0.0], [0.0, 0.0, 1.0]]).T
    assert np.allclose(g.triangles, want, atol=1e-12)
    assert np.allclose(g.triangles[..., 2], 0.0)


def test_a_flat_mesh_flattened_at_a_slant_loads_and_its_normals_follow_its_faces(tmp_path, cache):
    """The quad turned 45 degrees about x, then flattened onto the XY plane by its parent's
    ``scale: [1, 1, 0]``: a slanted projection keeps its triangles (y times cos 45). Its file normals
    (+z) go by the adjugate (the inverse transpose has none): finite, unit, on the faces' side; a
    parent's ``[-1, 1, 0]`` turns no winding (a determinant of 0 is not negative)."""
    up = [(0.0, 0.0, 1.0)] * 4
    nodes = [{"children": [1], "scale": [1.0, 1.0, 0.0]}, {"mesh": 0, "rotation": [S45, 0.0, 0.0, C45]}]
    g = load_mesh(_gltf(tmp_path / "a", nodes, normals=up))
    tri = _triangles()
    assert np.allclose(g.triangles[..., 0], tri[..., 0]) and np.allclose(g.triangles[..., 1], tri[..., 1] * np.cos(
        np.pi / 4))
    assert np.allclose(g.triangles[..., 2], 0.0)
    assert np.isfinite(g.normals).all() and np.allclose(g.normals, [0.0, 0.0, 1.0])
    g = load_mesh(_gltf(tmp_path / "b", [{"mesh": 0, "scale": [-1.0, 1.0, 0.0]}], normals=up))
    assert np.array_equal(g.triangles, tri * [-1.0, 1.0, 0.0])  # (the file's winding kept)
    face = np.cross(g.triangles[:, 1] - g.triangles[:, 0], g.triangles[:, 2] - g.triangles[:, 0])
    assert np.allclose(g.normals, [0.0, 0.0, -1.0]) and (np.sum(face[:, None] * g.normals, axis=2) > 0).all()


@pytest.mark.parametrize("nodes, points, faces, layer", [
    ([{"mesh": 0, "scale": [1.0, 1.0, 0.0]}], TETRA, ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)), None),  # a solid
    ([{"mesh": 0, "scale": [1.0, 0.0, 1.0]}], QUAD, ((0, 1, 2), (0, 2, 3)), None),  # flat, collapsed within its plane
    ([{"mesh": 0, "scale": [0.0, 0.0, 1.0]}], QUAD, ((0, 1, 2), (0, 2, 3)), None),  # to a line
    ([{"mesh": 0, "scale": [1.0, 1.0, 0.0]}], QUAD, ((0, 1, 2), (0, 2, 3)), [0.0, 0.0, 1.0]),  # two flat primitives
])
def test_a_singular_transform_that_degenerates_the_triangles_is_still_refused(tmp_path, cache, nodes, points,
                                                                                faces, layer):
    """A solid, a flat mesh collapsed within its plane, and a mesh of two flat primitives in two
    parallel planes (each flat, the mesh not) are still refused, naming the node."""
    text = _refused(_gltf(tmp_path, nodes, points, faces, layer=layer))
    assert ("nodes[0]: its world transform (with its parents') is singular (a zero scale, an all-zero matrix, or "
            "scales whose product is 0 in floating point): it collapses meshes[0] to a plane, a line or a "
            "point") in text
    # the same file with its flat quad under [1, 1, 0] loads (HEAD refused every singular mesh node)
    assert load_mesh(_gltf(tmp_path / "flat", [{"mesh": 0, "scale": [1.0, 1.0, 0.0]}])).triangles.shape == (2, 3, 3)


# ------------------------------------------------------------------ 2. skinned meshes


def _translate(x, y, z) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = x, y, z
    return m


def test_a_skinned_mesh_nodes_own_transform_is_ignored(tmp_path, cache):
    """glTF: "the transform of the skinned mesh node MUST be ignored". A zero scale on it (HEAD
    refused it as singular) or a move: the mesh stays where its skin at rest puts it (each
    joint's world transform times its inverse bind matrix: here the identity)."""
    points = TETRA
    faces = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))
    for i, own in enumerate([{"scale": [0.0, 0.0, 0.0]}, {"translation": [5.0, 0.0, 0.0]}]):
        nodes = [{"children": [1, 2]}, {"mesh": 0, "skin": 0, **own}, {"translation": [0.0, 2.0, 0.0]}]
        g = load_mesh(_gltf(tmp_path / str(i), nodes, points, faces, skins=[{"joints": [2]}],
                            matrices=[_translate(0.0, -2.0, 0.0)]))
        assert np.array_equal(g.triangles, _triangles(points, faces)), own


def test_a_rigid_skin_moves_its_mesh_and_a_posed_one_is_said(tmp_path, cache):
    """Joints that all give one matrix (a joint moved by (0, 2, 0) from its bind pose) move the
    mesh rigidly by it; joints that give different ones (a posed skin) are not blended: the mesh
    is placed by its node, as before, and a note says so."""
    nodes = [{"children": [1, 2, 3]}, {"mesh": 0, "skin": 0, "translation": [5.0, 0.0, 0.0]},
             {"translation": [0.0, 2.0, 0.0]}, {"translation": [0.0, 0.0, 3.0]}]
    g = load_mesh(_gltf(tmp_path / "rigid", nodes, skins=[{"joints": [2, 3]}],
                        matrices=[np.eye(4), _translate(0.0, 2.0, -3.0)]))
    assert np.array_equal(g.triangles, _triangles() + [0.0, 2.0, 0.0])
    assert not any("skinned" in n for n in g.notes)
    g = load_mesh(_gltf(tmp_path / "posed", nodes, skins=[{"joints": [2, 3]}], matrices=[np.eye(4), np.eye(4)]))
    assert np.array_equal(g.triangles, _triangles() + [5.0, 0.0, 0.0])
    assert any("nodes[1] (skins[0]) is posed (the joints' matrices differ), drawn unposed" in n for n in g.notes)


def test_a_skin_without_inverse_bind_matrices_and_a_bad_skin_index(tmp_path, cache):
    nodes = [{"children": [1, 2]}, {"mesh": 0, "skin": 0, "scale": [0.0, 0.0, 0.0]}, {}]
    g = load_mesh(_gltf(tmp_path / "a", nodes, skins=[{"joints": [2]}]))  # (identity inverse bind matrices)
    assert np.array_equal(g.triangles, _triangles())
    text = _refused(_gltf(tmp_path / "b", [{"mesh": 0, "skin": 3}], skins=[{"joints": [0]}]))
    assert "nodes[0].skin = 3 names no entry of 'skins' (it has 1)" in text


# ------------------------------------------------------------------ 3. crease normals of a pole


def test_a_poles_welded_group_is_summed_by_clusters_with_the_loops_bits(monkeypatch):
    """A sphere's pole of 2,000 segments (its fan's normals ~5.6 degrees off the axis, all within
    the crease angle of each other, but no two within 1e-6 radians): one wide cluster, not the
    quadratic per-corner fallback (HEAD's), with the fallback's bits."""
    tri = shapes.uv_sphere((0.0, 0.0, 0.0), 1.0, 2000, 16)
    decided = []
    real = nm._clusters

    def clusters(*args, **kwargs):
        decided.append(real(*args, **kwargs) is not None)
        return None if forced else real(*args, **kwargs)

    monkeypatch.setattr(nm, "_clusters", clusters)
    forced = True
    want = nm.crease_normals(tri)
    forced = False
    decided.clear()
    got = nm.crease_normals(tri)
    assert decided and any(decided)
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
    for crease in (1.0, 5.0, 11.0, 12.0, 60.0, 179.0):  # (a crease angle below the fan's spread: not clustered)
        forced = True
        want = nm.crease_normals(tri[:4000], None, crease)
        forced = False
        assert np.array_equal(nm.crease_normals(tri[:4000], None, crease).view(np.uint64), want.view(np.uint64))
