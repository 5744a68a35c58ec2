"""Review of ef5e115 (h244): a glTF mesh node with a small but non-zero scale is no singular
transform (tlm.scenes.gltf_imports.check_mesh_nodes), and the noting resolver of a glTF's
buffers works with trimesh 4, which pyproject allows and whose FilePathResolver takes no
``allow_anywhere`` (tlm.scenes.mesh_checks)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from tests.test_bad_meshes_h237 import TRIANGLE, triangle_gltf
from tlm.errors import InputError
from tlm.scenes import mesh_checks
from tlm.scenes.meshes import load_mesh


def _write(folder: Path, nodes: list, roots: list | None = None, uri: str = "data.bin") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "data.bin").write_bytes(TRIANGLE)
    path = folder / "g.gltf"
    path.write_text(json.dumps(triangle_gltf(uri, nodes=nodes, scenes=[{"nodes": [0] if roots is None else roots}])))
    return path


_QUARTER = [0.0, 0.0, float(np.sin(np.pi / 8)), float(np.cos(np.pi / 8))]  # 45 degrees about z


@pytest.mark.parametrize("nodes", [
    [{"mesh": 0, "scale": [1e-9, 1e-9, 1.0]}],  # a thin sheet, not a flat one (ef5e115 refused it)
    [{"mesh": 0, "scale": [1.0, 1.0, 1e-16]}],
    [{"children": [1], "scale": [1e-8, 1.0, 1.0]}, {"mesh": 0, "scale": [1.0, 1e-8, 1.0]}],
])
def test_a_small_but_non_zero_scale_is_no_singular_transform(tmp_path, cache, nodes):
    g = load_mesh(_write(tmp_path, nodes))
    assert g.triangles.shape == (1, 3, 3)
    assert np.abs(g.triangles).max() > 0.0


@pytest.mark.parametrize("nodes", [
    [{"mesh": 0, "scale": [1.0, 0.0, 1.0]}],
    [{"mesh": 0, "matrix": [0.0] * 16}],
    # a parent's zero scale under a rotated child: no zero column, but the columns dependent to rounding
    [{"children": [1], "scale": [1.0, 0.0, 3.0], "rotation": _QUARTER},
     {"mesh": 0, "rotation": _QUARTER, "scale": [2.0, 5.0, 7.0]}],
    [{"children": [1], "scale": [1e-200] * 3}, {"mesh": 0, "scale": [1e-200] * 3}],  # a product 0 in floats
])
def test_a_singular_transform_is_still_refused(tmp_path, cache, nodes):
    with pytest.raises(InputError) as info:
        load_mesh(_write(tmp_path, nodes))
    assert (f"nodes[{len(nodes) - 1}]: its world transform (with its parents') is singular (a zero scale, an all-zero "
            "matrix, or scales whose product is 0 in floating point): it collapses meshes[0] to a plane, a line or a "
            "point") in str(info.value)


class _Trimesh4Resolver:
    """trimesh 4's FilePathResolver, as far as tlm uses it: ``__init__(source)`` (no
    ``allow_anywhere``), no ``absolute``, ``get`` joining the name to the folder."""

    def __init__(self, source: str):
        clean = os.path.expanduser(os.path.abspath(str(source)))
        self.parent = clean if os.path.isdir(clean) else os.path.split(clean)[0]

    def get(self, name: str) -> bytes:
        path = os.path.join(self.parent, name.strip())
        if not os.path.exists(path):
            path = os.path.join(self.parent, os.path.split(name)[-1])
        with open(path, "rb") as f:
            return f.read()

    def __getitem__(self, name: str) -> bytes:
        return self.get(name)


def test_the_noting_resolver_under_trimesh_4(tmp_path, monkeypatch):
    import trimesh.resolvers

    folder = tmp_path / "model"
    path = _write(folder, [{"mesh": 0}])
    (tmp_path / "bin").mkdir()
    (tmp_path / "bin" / "up.bin").write_bytes(b"up")
    monkeypatch.setattr(trimesh.resolvers, "FilePathResolver", _Trimesh4Resolver)
    mesh_checks.noting_resolver_class.cache_clear()
    try:
        resolver = mesh_checks.noting_resolver(str(path))  # (ef5e115: TypeError, allow_anywhere)
        assert resolver.get("data.bin") == TRIANGLE
        assert resolver.get("../bin/up.bin") == b"up"
        assert resolver.absolute("../bin/up.bin") == folder / "../bin/up.bin"
        with pytest.raises(ValueError, match="absolute path"):
            resolver.absolute("/etc/passwd")
    finally:
        mesh_checks.noting_resolver_class.cache_clear()  # (the next caller gets trimesh's own class)


# ------------------------------------------------------------------ scene files: what a message says

_SCENE = ("geometry: {shape: plane}\nmaterials: {white: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\n"
          "default_material: white\ncamera: {eye: [0.0, 0.5, -3.4], target: [0.0, 0.35, 0.0], vfov: 38.0}\n"
          "resolution: [8, 8]\n")


@pytest.mark.parametrize("text", ["null\n", "~\n"])
def test_a_scene_file_of_a_bare_null_is_not_called_only_comments(tmp_path, cache, text):
    from tlm.scenes.loader import load_scene

    path = tmp_path / "n.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"n\.yaml: is empty \(nothing but comments or blanks\) or a bare null"):
        load_scene(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_scene_path_that_is_a_pipe_is_named_a_special_file(tmp_path, cache):
    from tlm.scenes.loader import load_scene

    os.mkfifo(tmp_path / "pipe.yaml")
    with pytest.raises(InputError) as info:
        load_scene(tmp_path / "pipe.yaml")  # (not opened: a pipe with no writer would block)
    assert "pipe.yaml' is a special file (a device, a pipe or a socket), not a scene file" in str(info.value)
    (tmp_path / "real.yaml").write_text(_SCENE)
    (tmp_path / "link.yaml").symlink_to("real.yaml")  # a link to a good file is that file
    assert load_scene(tmp_path / "link.yaml").triangles.shape[1:] == (3, 3)
