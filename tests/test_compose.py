"""Scene geometry as a list of builders, meshes and shapes, each with its own transform."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.errors import InputError
from tlm.scenes.builders import ring
from tlm.scenes.compose import SHAPES, compose_geometry, item_transform, merge, transform_geometry
from tlm.scenes.loader import list_scenes, load_scene, resolve_scene_path, scenes_dir
from tlm.scenes.meshes import load_mesh
from tlm.scenes.model import Geometry, Material

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "scenes" / "examples" / "mesh_on_floor.yaml"
PAWN = REPO / "scenes" / "examples" / "pawn.obj"
BOX = {"shape": "box", "params": {"min": [0, 0, 0], "max": [1, 2, 3]}}


def geom(raw, path: Path = EXAMPLE) -> Geometry:
    return compose_geometry(raw, str(path), path)


def face_normals(tri: np.ndarray) -> np.ndarray:
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def outward(tri: np.ndarray, centre) -> np.ndarray:
    """Each face normal's dot with the direction from ``centre`` to the face's centroid."""
    return np.sum(face_normals(tri) * (tri.mean(axis=1) - centre), axis=1)


def write_scene(tmp_path: Path, geometry, **extra) -> Path:
    scene = {
        "geometry": geometry,
        "materials": {"w": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "default_material": "w",
        "lights": [{"type": "point", "position": [0, 5, 0], "power": [10, 10, 10]}],
        "camera": {"eye": [0, 2, -6], "target": [0, 0.5, 0], "vfov": 40},
        "resolution": [8, 8],
        **extra,
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(scene))
    return path


def error(raw, path: Path = EXAMPLE) -> str:
    with pytest.raises(InputError) as e:
        geom(raw, path)
    msg = str(e.value)
    assert "\n" not in msg
    return msg


# ---------------------------------------------------------------- merging


def test_the_single_mapping_form_is_unchanged():
    g = geom({"builder": "ring", "params": {}})
    ref = ring()
    np.testing.assert_array_equal(g.triangles, ref.triangles)
    np.testing.assert_array_equal(g.part, ref.part)
    assert g.part_names == ref.part_names


def test_triangle_counts_add_and_order_follows_the_list():
    items = [{"builder": "ring"}, {"mesh": "pawn.obj"}, BOX, {"shape": "plane"}]
    g = geom(items)
    parts = [geom(i) for i in items]
    assert len(g.triangles) == sum(len(p.triangles) for p in parts) == len(g.part)
    np.testing.assert_array_equal(g.triangles, np.concatenate([p.triangles for p in parts]))
    assert g.part_names == ("floor", "ring", "pawn", "box", "plane")
    counts = np.bincount(g.part, minlength=len(g.part_names))
    assert counts.tolist() == [int((p.part == i).sum()) for p in parts for i in range(len(p.part_names))]


def test_translate_moves_a_box():
    g = geom({**BOX, "transform": {"translate": [10, -1, 0.5]}})
    flat = g.triangles.reshape(-1, 3)
    np.testing.assert_allclose(flat.min(axis=0), [10, -1, 0.5])
    np.testing.assert_allclose(flat.max(axis=0), [11, 1, 3.5])


def test_scale_rotate_translate_in_that_order():
    # scale x by 2, turn 90 degrees about y (x -> -z), then move up: [0,2]x[0,2]x[0,3] -> x [0,3], z [-2,0]
    g = geom({**BOX, "transform": {"scale": [2, 1, 1], "rotate": [0, 90, 0], "translate": [0, 5, 0]}})
    flat = g.triangles.reshape(-1, 3)
    np.testing.assert_array_equal(flat.min(axis=0), [0, 5, -2])  # exact at multiples of 90 degrees
    np.testing.assert_array_equal(flat.max(axis=0), [3, 7, 0])
    # rotations about x, then y, then z, right-handed: +y about x by 90 is +z, then about y by 90 is +x
    m, _ = item_transform({"rotate": [90, 90, 0]}, "s.yaml", "transform")
    np.testing.assert_array_equal(m @ [0, 1, 0], [1, 0, 0])
    m, _ = item_transform({"rotate": [0, 0, 90]}, "s.yaml", "transform")
    np.testing.assert_array_equal(m @ [1, 0, 0], [0, 1, 0])
    m, _ = item_transform({"rotate": [0, 0, 45]}, "s.yaml", "transform")
    np.testing.assert_allclose(m @ [1, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0])
    assert item_transform({"scale": 1, "rotate": [0, 360, 0]}, "s.yaml", "transform") is None


def test_mirroring_keeps_outward_normals():
    sphere = {"shape": "sphere", "params": {"segments": 12, "rings": 6}}
    assert (outward(geom(sphere).triangles, [0, 0, 0]) > 0).all()
    for scale in (-1, [-1, 1, 1], [1, 1, -2], [-1, -1, -1]):
        g = geom({**sphere, "transform": {"scale": scale}})
        assert (outward(g.triangles, [0, 0, 0]) > 0).all(), scale
    box = geom({**BOX, "transform": {"scale": -1}})
    assert (outward(box.triangles, [-0.5, -1, -1.5]) > 0).all()


def test_mirroring_file_normals_follow():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=float)
    n = np.array([[[0.0, 0.0, 1.0]] * 3])
    g = Geometry(tri, np.zeros(1, np.int32), ("t",), normals=n)
    m = np.diag([1.0, 1.0, -1.0])
    out = transform_geometry(g, m, np.zeros(3))
    np.testing.assert_allclose(face_normals(out.triangles)[0], [0, 0, -1])
    np.testing.assert_allclose(out.normals[0], [[0, 0, -1]] * 3)
    # a non-uniform scale: normals by the inverse transpose, unit length
    slanted = Geometry(tri, np.zeros(1, np.int32), ("t",), normals=np.array([[[1.0, 1.0, 0.0]] * 3]) / np.sqrt(2))
    out = transform_geometry(slanted, np.diag([2.0, 1.0, 1.0]), np.zeros(3))
    np.testing.assert_allclose(out.normals[0], [[1 / np.sqrt(5), 2 / np.sqrt(5), 0]] * 3)


def test_part_names_stay_unique():
    g = geom([{"mesh": "pawn.obj"}, {"mesh": "pawn.obj"}, {"mesh": "pawn.obj"}])
    assert g.part_names == ("pawn", "pawn_2", "pawn_3")
    assert np.bincount(g.part).tolist() == [512, 512, 512]
    named = geom([{"mesh": "pawn.obj", "name": "a"}, {"builder": "ring", "name": "r"}, {"mesh": "pawn.obj"}])
    assert named.part_names == ("a", "r.floor", "r.ring", "pawn")
    msg = error([{"mesh": "pawn.obj", "name": "x"}, {"shape": "plane", "name": "x"}])
    assert "geometry[1].name" in msg and "'x'" in msg


def test_normals_and_file_materials_merge():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 2, dtype=float)
    n = np.tile(np.array([0.0, 0.0, 1.0]), (2, 3, 1))
    mats = (Material("a", "lambertian"), Material("b", "mirror"))
    a = Geometry(tri, np.zeros(2, np.int32), ("a",), normals=n, materials=mats,
                 face_material=np.array([1, -1], np.int32))
    b = Geometry(tri + 5, np.zeros(2, np.int32), ("b",))
    c = Geometry(tri, np.zeros(2, np.int32), ("c",), materials=(Material("c", "lambertian"),),
                 face_material=np.array([0, 0], np.int32))
    g = merge([a, b, c])
    assert [m.name for m in g.materials] == ["a", "b", "c"]
    assert g.face_material.tolist() == [1, -1, -1, -1, 2, 2]
    # the same file twice shares its materials; another file's "a" that differs is renamed
    d = Geometry(tri, np.zeros(2, np.int32), ("d",), materials=(Material("a", "mirror"), mats[0]),
                 face_material=np.array([0, 1], np.int32))
    g = merge([a, a, d])
    assert [m.name for m in g.materials] == ["a", "b", "a_2"]
    assert g.materials[2] == Material("a_2", "mirror")
    assert g.face_material.tolist() == [1, -1, 1, -1, 2, 0]
    assert g.normals.shape == (6, 3, 3)
    np.testing.assert_allclose(g.normals[2:4], np.tile([0.0, 0.0, 1.0], (2, 3, 1)))  # b: crease normals
    plain = merge([b, b])
    assert plain.normals is None and plain.face_material is None and plain.materials == ()
    assert plain.part_names == ("b", "b_2")


def test_a_mesh_item_in_a_scene(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "pawn.obj").write_text(PAWN.read_text())
    path = write_scene(tmp_path, [{"shape": "plane", "name": "floor", "params": {"size": [4, 4]}},
                                  {"mesh": "m/pawn.obj", "transform": {"scale": 2, "translate": [1, 0, 0]}}],
                       parts={"floor": "w", "pawn": "w"})
    scene = load_scene(str(path))
    assert scene.n_triangles == 2 + 512 and scene.part_names == ("floor", "pawn")
    lo, hi = scene.bounds()
    np.testing.assert_allclose(lo, [-2, 0, -2])
    np.testing.assert_allclose(hi[1], 2 * load_mesh(PAWN).triangles[..., 1].max())
    pawn = scene.triangles[scene.part == 1].reshape(-1, 3)
    np.testing.assert_allclose(pawn.min(axis=0)[[0, 2]], [1 - 0.8, -0.8])
    assert np.isfinite(scene.normals).all()


def test_the_scene_transform_still_moves_everything(tmp_path):
    plain = load_scene(str(write_scene(tmp_path, [BOX])))
    moved = load_scene(str(write_scene(tmp_path, [BOX], transform={"scale": 2, "translate": [1, 2, 3]})))
    np.testing.assert_allclose(moved.triangles, plain.triangles * 2 + [1, 2, 3])
    np.testing.assert_allclose(moved.camera.eye, np.multiply(plain.camera.eye, 2) + [1, 2, 3])
    with pytest.raises(InputError, match=r"transform\.rotate: .*geometry item's transform"):
        load_scene(str(write_scene(tmp_path, [BOX], transform={"rotate": [0, 90, 0]})))


# ---------------------------------------------------------------- shapes


@pytest.mark.parametrize("kind", sorted(SHAPES))
def test_every_shape_builds_with_defaults_or_minimal_params(kind):
    params = {"corner": [0, 0, 0], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1]} if kind == "quad" else {}
    g = geom({"shape": kind, "params": params})
    assert g.part_names == (kind,) and len(g.triangles) > 0 and np.isfinite(g.triangles).all()
    areas = np.linalg.norm(np.cross(g.triangles[:, 1] - g.triangles[:, 0], g.triangles[:, 2] - g.triangles[:, 0]),
                           axis=1)
    assert (areas > 0).all()


def test_a_plane_is_a_floor_facing_up():
    g = geom({"shape": "plane", "params": {"size": [4, 2], "divisions": [2, 3]}})
    assert len(g.triangles) == 12
    np.testing.assert_allclose(face_normals(g.triangles), np.tile([0.0, 1.0, 0.0], (12, 1)))
    flat = g.triangles.reshape(-1, 3)
    np.testing.assert_allclose(flat.min(axis=0), [-2, 0, -1])
    np.testing.assert_allclose(flat.max(axis=0), [2, 0, 1])


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize("raw,key,words", [
    ([], "geometry", "empty list"),
    (5, "geometry", "mapping"),
    ([{"mesh": "pawn.obj"}, 3], "geometry[1]", "mapping"),
    ([{"mesh": "pawn.obj", "builder": "ring"}], "geometry[0]", "exactly one"),
    ([{"name": "x"}], "geometry[0]", "exactly one"),
    ([BOX, {"mesh": "pawn.obj", "transfrom": {}}], "geometry[1].transfrom", "did you mean 'transform'"),
    ([{**BOX, "transform": {"scale": 0}}], "geometry[0].transform.scale", "non-zero"),
    ([{**BOX, "transform": {"scale": [1, 0, 1]}}], "geometry[0].transform.scale", "non-zero"),
    ([{**BOX, "transform": {"scale": "big"}}], "geometry[0].transform.scale", "'big'"),
    ([{**BOX, "transform": {"rotate": [0, 90]}}], "geometry[0].transform.rotate", "3 numbers"),
    ([{**BOX, "transform": {"move": [0, 1, 0]}}], "geometry[0].transform.move", "unknown key"),
    ([{**BOX, "transform": {"translate": [0, float("nan"), 0]}}], "geometry[0].transform.translate", "finite"),
    ([{**BOX, "transform": {"scale": 1e308}}], "geometry[0].transform.scale", "beyond"),
    ([{"shape": "spehre"}], "geometry[0].shape", "did you mean 'sphere'"),
    ([{"shape": "box", "params": {"size": 1}}], "geometry[0].params.size", "unknown key"),
    ([{"shape": "box", "params": {"min": [0, 0, 0], "max": [1, 0, 1]}}], "geometry[0].params", "must exceed"),
    ([{"shape": "quad", "params": {"corner": [0, 0, 0], "edge_u": [1, 0, 0]}}], "geometry[0].params.edge_v",
     "needs edge_v"),
    ([{"shape": "quad", "params": {"corner": [0, 0, 0], "edge_u": [1, 0, 0], "edge_v": [2, 0, 0]}}],
     "geometry[0].params", "no area"),
    ([{"shape": "sphere", "params": {"radius": -1}}], "geometry[0].params.radius", "-1"),
    ([{"shape": "sphere", "params": {"segments": 2}}], "geometry[0].params.segments", ">= 3"),
    ([{"shape": "plane", "params": {"divisions": [1, 0]}}], "geometry[0].params.divisions", ">= 1"),
    ([{"shape": "plane", "params": {"size": [1, -1]}}], "geometry[0].params.size", "positive"),
    ([{"mesh": "pawn.obj", "params": {}}], "geometry[0].params", "transform"),
    ([{"mesh": "nothere.obj"}], "geometry[0].mesh", "not found"),
    ([{"mesh": "pawn.obj", "name": 3}], "geometry[0].name", "3"),
    ([{"builder": "rng"}], "geometry[0].builder", "did you mean 'ring'"),
    ([{"builder": "ring", "params": {"segments": 3}}], "geometry[0].params.segments",
     "unknown parameter of builder ring; its parameters: n_seg, radius, "),
])
def test_errors_name_the_file_and_key(raw, key, words):
    msg = error(raw)
    assert msg.startswith(f"{EXAMPLE}: {key}: "), msg
    assert words in msg, msg


def test_errors_in_a_scene_file_name_it(tmp_path):
    path = write_scene(tmp_path, [BOX, {"shape": "plane", "transform": {"rotate": "x"}}])
    with pytest.raises(InputError, match=r"s\.yaml: geometry\[1\]\.transform\.rotate: 'x'"):
        load_scene(str(path))


# ---------------------------------------------------------------- built-in scenes


def test_builtin_scenes_include_subfolders():
    names = list_scenes()
    assert {"cornell", "ring", "room", "thesis/ring", "thesis/room", "examples/mesh_on_floor"} <= set(names)
    assert names == sorted(names)
    assert not any(n.startswith("meshes/") or n.endswith((".obj", ".ply")) for n in names)
    for n in names:
        assert resolve_scene_path(n) == scenes_dir() / f"{n}.yaml"
    assert resolve_scene_path("thesis/ring.yaml", Path("/nonexistent")) == scenes_dir() / "thesis" / "ring.yaml"


def test_an_unknown_scene_lists_them_all():
    with pytest.raises(InputError) as e:
        resolve_scene_path("thesis_ring")
    assert "thesis/ring" in str(e.value) and "thesis/room" in str(e.value)
    with pytest.raises(InputError, match="did you mean 'thesis/ring'"):
        resolve_scene_path("thesis/rign")


def test_the_example_scene():
    scene = load_scene("examples/mesh_on_floor")
    assert scene.part_names == ("floor", "backdrop", "ivory_pawn", "gold_pawn", "block", "glass_ball")
    assert scene.n_triangles == 2 + 2 + 512 + 512 + 12 + 528
    assert scene.bounds()[0][1] == 0.0  # everything stands on the floor
    for name in ("ivory_pawn", "gold_pawn", "block", "glass_ball"):
        tri = scene.triangles[scene.part == scene.part_names.index(name)]
        assert tri[..., 1].min() >= 0.0
    kinds = {scene.part_names[p]: scene.materials[m].kind for p, m in zip(scene.part, scene.material_index)}
    assert kinds["gold_pawn"] == "mirror" and kinds["glass_ball"] == "dielectric"
