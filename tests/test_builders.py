"""Built-in scene geometry (exact thesis triangle counts), mesh primitives, mesh loading."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.errors import InputError
from tlm.scenes import shapes
from tlm.scenes.builders import BUILDERS, CORNELL_LIGHT, cornell, ring, room
from tlm.scenes.meshes import load_mesh

SCENES_DIR = Path(__file__).resolve().parents[1] / "scenes"
THESIS_COUNTS = {"ring": 646, "room": 7812, "cornell": 2604}


@pytest.fixture(scope="module", params=sorted(THESIS_COUNTS))
def built(request):
    return request.param, BUILDERS[request.param]()


def _yaml(name: str) -> dict:
    return yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text())


def _bounds(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    flat = tri.reshape(-1, 3)
    return flat.min(axis=0), flat.max(axis=0)


# ---------------------------------------------------------------- builders


def test_builders_registry():
    assert set(BUILDERS) == set(THESIS_COUNTS)


def test_exact_thesis_triangle_counts(built):
    name, g = built
    assert g.triangles.shape == (THESIS_COUNTS[name], 3, 3)


def test_arrays_types_and_finite(built):
    _, g = built
    assert g.triangles.dtype == np.float64
    assert g.part.dtype == np.int32
    assert g.part.shape == (g.triangles.shape[0],)
    assert np.isfinite(g.triangles).all()


def test_no_degenerate_triangles(built):
    _, g = built
    lo, hi = _bounds(g.triangles)
    diag2 = float(np.sum((hi - lo) ** 2))
    assert shapes.triangle_areas(g.triangles).min() > 1e-9 * diag2


def test_parts_valid_and_all_used(built):
    _, g = built
    assert len(set(g.part_names)) == len(g.part_names)
    assert g.part.min() >= 0
    assert g.part.max() < len(g.part_names)
    assert set(np.unique(g.part)) == set(range(len(g.part_names)))


def test_yaml_maps_every_part_to_a_known_material(built):
    name, g = built
    raw = _yaml(name)
    assert raw["geometry"]["builder"] == name
    for part in g.part_names:
        assert part in raw["parts"], f"{name}.yaml does not map part {part!r}"
        assert raw["parts"][part] in raw["materials"]
    assert set(raw["parts"]) <= set(g.part_names)


def test_yaml_camera_looks_into_the_geometry(built):
    name, g = built
    cam = _yaml(name)["camera"]
    lo, hi = _bounds(g.triangles)
    target = np.asarray(cam["target"], dtype=float)
    assert np.all(target >= lo) and np.all(target <= hi)
    assert 10.0 < cam["vfov"] < 120.0


def test_yaml_lights_face_the_scene(built):
    name, g = built
    raw = _yaml(name)
    lo, hi = _bounds(g.triangles)
    assert raw["lights"]
    for light in raw["lights"]:
        assert min(light["power"]) > 0
        if light["type"] == "quad":
            corner = np.asarray(light["corner"], dtype=float)
            eu, ev = np.asarray(light["edge_u"], float), np.asarray(light["edge_v"], float)
            normal = np.cross(eu, ev)
            assert normal[1] < 0, "quad light must emit downwards"
            for p in (corner, corner + eu, corner + ev, corner + eu + ev):
                assert np.all(p >= lo) and np.all(p <= hi)
            assert corner[1] < hi[1], "quad light must sit below the ceiling, not on it"


@pytest.mark.parametrize(
    ("name", "resolution", "photons"),
    [("cornell", [320, 320], 120000), ("ring", [320, 240], 20000), ("room", [320, 240], 80000)],
)
def test_yaml_resolution_and_photons(name, resolution, photons):
    raw = _yaml(name)
    assert raw["resolution"] == resolution
    assert raw["photons"] == photons
    assert raw["name"] == name


def test_material_roles_present():
    kinds = {}
    for name in THESIS_COUNTS:
        raw = _yaml(name)
        kinds[name] = {raw["materials"][m]["type"] for m in raw["parts"].values()}
    assert {"mirror", "dielectric", "lambertian"} <= kinds["cornell"]
    assert {"mirror", "dielectric", "lambertian"} <= kinds["room"]
    assert {"mirror", "lambertian"} <= kinds["ring"]


def test_cornell_matches_published_box():
    g = cornell()
    lo, hi = _bounds(g.triangles)
    np.testing.assert_allclose(lo, [0.0, 0.0, 0.0], atol=1e-9)
    assert 552.0 <= hi[0] <= 556.0
    assert hi[1] == pytest.approx(548.8)
    assert hi[2] == pytest.approx(559.2)
    tri = g.triangles
    verts = {tuple(v) for v in tri.reshape(-1, 3).round(6)}
    for v in [(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114),
              (423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)]:
        assert tuple(float(x) for x in v) in verts
    raw = _yaml("cornell")
    assert raw["camera"]["eye"] == [278.0, 273.0, -800.0]
    (light,) = raw["lights"]
    corner = np.asarray(light["corner"], float)
    quad = [corner, corner + light["edge_u"], corner + light["edge_u"] + light["edge_v"],
            corner + light["edge_v"]]
    np.testing.assert_allclose(np.asarray(quad)[:, [0, 2]],
                               np.asarray(CORNELL_LIGHT)[:, [0, 2]])
    assert corner[1] == 548.8  # the published height, on the ceiling's plane
    assert np.cross(light["edge_u"], light["edge_v"])[1] < 0  # emits down
    assert raw["camera"]["vfov"] == pytest.approx(39.3)


def _part(g, name):
    return g.triangles[g.part == g.part_names.index(name)]


def test_cornell_objects_inside_and_clear():
    g = cornell()
    for name in ("mirror_object", "glass_object"):
        lo, hi = _bounds(_part(g, name))
        assert np.all(lo >= [0.0, 0.0, 0.0]) and np.all(hi <= [549.6, 548.8, 559.2])
    # The spheres' centres are clear of each block's footprint by more than their radius
    # unless they stand on top of it.
    mirror = _part(g, "mirror_object").reshape(-1, 3)
    glass = _part(g, "glass_object").reshape(-1, 3)
    assert mirror[:, 1].min() == pytest.approx(165.0)  # resting on the short block
    assert glass[:, 1].min() == pytest.approx(0.0)  # resting on the floor
    tall = _part(g, "tall_block").reshape(-1, 3)
    for sphere in (mirror, glass):
        c = (sphere.min(0) + sphere.max(0)) / 2
        r = (sphere.max(0) - sphere.min(0))[1] / 2
        assert np.min(np.linalg.norm(tall[:, [0, 2]] - c[[0, 2]], axis=1)) > r
    # Visible: inside the camera's vertical and horizontal field of view.
    eye = np.array([278.0, 273.0, -800.0])
    half = np.tan(np.radians(39.3 / 2))
    for sphere in (mirror, glass):
        d = sphere - eye
        assert np.all(np.abs(d[:, 0] / d[:, 2]) < half)
        assert np.all(np.abs(d[:, 1] / d[:, 2]) < half)


def test_closed_solids_face_outward():
    # Signed volume > 0 for every closed solid part.
    for g, names in ((cornell(), ("mirror_object", "glass_object")), (ring(), ("ring",))):
        for name in names:
            t = _part(g, name)
            vol = np.einsum("ij,ij->i", t[:, 0], shapes.triangle_normals(t)).sum() / 6
            assert vol > 0, name


@pytest.mark.slow
def test_room_surfaces_face_inward():
    g = room()
    lo, hi = _bounds(g.triangles)
    center = (lo + hi) / 2
    for name in ("floor", "ceiling", "walls"):
        t = _part(g, name)
        n = shapes.triangle_normals(t)
        assert np.all(np.einsum("ij,ij->i", n, center - t.mean(axis=1)) > 0), name
    mirror = _part(g, "mirror")
    assert mirror[:, :, 2].max() < hi[2]  # in front of the back wall, not on it


def test_ring_floor_faces_up_and_ring_stands_on_it():
    g = ring()
    floor = _part(g, "floor")
    assert np.all(shapes.triangle_normals(floor)[:, 1] > 0)
    band = _part(g, "ring")
    assert band[:, :, 1].min() == pytest.approx(0.0)


@pytest.mark.parametrize(
    ("builder", "params", "expected"),
    [
        (cornell, {"wall_div": 2, "block_div": 1, "mirror_seg": 8, "mirror_rings": 4,
                   "glass_seg": 10, "glass_rings": 5}, 40 + 20 + 48 + 80),
        (ring, {"n_seg": 10, "floor_nx": 3, "floor_nz": 2}, 12 + 80),
    ],
)
def test_counts_follow_params(builder, params, expected):
    assert builder(**params).triangles.shape[0] == expected


@pytest.mark.slow
def test_room_count_formula():
    p = {"grid_x": 5, "grid_y": 3, "grid_z": 6, "glass_seg": 8, "glass_rings": 4, "vase_seg": 6,
         "leg_seg": 5, "sofa_div": 1, "furniture_div": 1}
    expected = 4 * (5 * 6 + 5 * 3 + 6 * 3) + 2 * 8 * 3 + 24 * 6 + 8 * 5 + 60 + 70 + 1256
    assert room(**p).triangles.shape[0] == expected


def test_bad_builder_params_raise_value_error():
    with pytest.raises(ValueError, match="wall_div"):
        cornell(wall_div=0)
    with pytest.raises(ValueError, match="n_seg"):
        ring(n_seg=2)
    with pytest.raises(ValueError, match="grid_x"):
        room(grid_x=1.5)


# ---------------------------------------------------------------- shapes


def _volume(t):
    return np.einsum("ij,ij->i", t[:, 0], shapes.triangle_normals(t)).sum() / 6


@pytest.mark.parametrize(
    ("tris", "count", "volume"),
    [
        (shapes.uv_sphere((1, 2, 3), 2.0, 12, 6), 2 * 12 * 5, None),
        (shapes.torus((0, 0, 0), 3.0, 1.0, 10, 6, axis=(1, 1, 0)), 2 * 10 * 6, None),
        (shapes.cylinder((0, 0, 0), 1.0, 2.0, 9), 4 * 9, None),
        (shapes.cylinder((0, 0, 0), 1.0, 2.0, 9, bottom=False), 3 * 9, None),
        (shapes.tube((0, 0, 0), 0.5, 1.0, 2.0, 7, axis=(0, 0, 1)), 8 * 7, None),
        (shapes.aabox((0, 0, 0), (1, 2, 3), n=2), 48, 6.0),
        (shapes.oriented_box((1, 0, 1), (1, 2, 3), yaw_deg=33.0), 12, 6.0),
        (shapes.quad((0, 0, 0), (1, 0, 0), (0, 1, 0), nu=3, nv=2), 12, None),
    ],
)
def test_shape_counts_and_orientation(tris, count, volume):
    assert tris.shape == (count, 3, 3)
    assert tris.dtype == np.float64
    assert shapes.triangle_areas(tris).min() > 1e-9
    if volume is not None:
        assert _volume(tris) == pytest.approx(volume)


@pytest.mark.parametrize("make", [
    lambda: shapes.uv_sphere((1, 2, 3), 2.0, 12, 6),
    lambda: shapes.torus((0, 0, 0), 3.0, 1.0, 10, 6),
    lambda: shapes.cylinder((0, 0, 0), 1.0, 2.0, 9),
    lambda: shapes.cylinder((0, 0, 0), 1.0, 2.0, 9, bottom=False),
    lambda: shapes.tube((0, 0, 0), 0.5, 1.0, 2.0, 7),
    lambda: shapes.quad((0, 0, 0), (1, 0, 0), (0, 1, 0), nu=3, nv=2),
    lambda: shapes.aabox((0, 0, 0), (1, 2, 3), n=3),
    lambda: shapes.aabox((0, 0, 0), (1, 2, 3), n=2, omit=("bottom", "top")),
])
def test_a_tessellation_is_checked_against_the_machine_at_its_exact_count(monkeypatch, make):
    """The count checked before anything is allocated is the count made: so a shape of
    exactly what fits passes and one triangle more is refused, naming its size."""
    n = len(make())
    monkeypatch.setattr(shapes, "machine_memory", lambda: n * shapes.TRIANGLE_BYTES)
    assert len(make()) == n
    monkeypatch.setattr(shapes, "machine_memory", lambda: n * shapes.TRIANGLE_BYTES - 1)
    with pytest.raises(ValueError, match=f"makes {n:,} triangles"):
        make()


def test_a_huge_sphere_or_torus_is_refused_before_its_profile_is_made():
    """(np.arange of 10**12 rings would itself need 7 TiB.)"""
    for make in (lambda: shapes.uv_sphere((0, 0, 0), 1.0, 8, 10**12),
                 lambda: shapes.torus((0, 0, 0), 2.0, 1.0, 8, 10**12)):
        with pytest.raises(ValueError, match="more than this machine's"):
            make()


def test_closed_shapes_have_positive_volume():
    assert _volume(shapes.uv_sphere((0, 0, 0), 1.0, 32, 16)) == pytest.approx(
        4 / 3 * np.pi, rel=0.02)
    assert _volume(shapes.torus((0, 0, 0), 2.0, 0.5, 48, 24)) == pytest.approx(
        2 * np.pi**2 * 2.0 * 0.25, rel=0.02)
    assert _volume(shapes.tube((0, 0, 0), 0.5, 1.0, 1.0, 64)) == pytest.approx(
        np.pi * 0.75, rel=0.01)


def test_box_accepts_either_ring_direction():
    ring_ccw = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], dtype=float)
    for r in (ring_ccw, ring_ccw[::-1]):
        t = shapes.box(np.concatenate([r, r + [0, 1, 0]]))
        assert _volume(t) == pytest.approx(1.0)


def test_quad_normal_follows_edges():
    t = shapes.quad((0, 0, 0), (0, 0, 1), (1, 0, 0), nu=2, nv=2)
    n = shapes.triangle_normals(t)
    assert np.all(n[:, 1] > 0) and np.allclose(n[:, [0, 2]], 0)


# ---------------------------------------------------------------- meshes


def _sorted_tris(t: np.ndarray) -> np.ndarray:
    t = np.round(t, 6).reshape(len(t), 9)
    return t[np.lexsort(t.T[::-1])]


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "glb"])
def test_load_mesh_round_trip(tmp_path, ext):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    path = tmp_path / f"box.{ext}"
    box.export(path)
    g = load_mesh(path)
    expected = box.vertices[box.faces]
    assert g.triangles.dtype == np.float64 and g.part.dtype == np.int32
    assert g.triangles.shape == (12, 3, 3)
    assert len(g.part_names) == 1
    np.testing.assert_allclose(_sorted_tris(g.triangles), _sorted_tris(expected), atol=1e-6)
    if ext in ("obj", "ply", "stl"):
        np.testing.assert_allclose(g.triangles, expected, atol=1e-6)
    if ext != "glb":
        assert g.part_names == ("box",)


def test_load_mesh_scene_parts_and_transforms(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), geom_name="cube",
                       transform=trimesh.transformations.translation_matrix([5.0, 0.0, 0.0]))
    scene.add_geometry(trimesh.creation.icosphere(1), geom_name="ball")
    path = tmp_path / "two.glb"
    scene.export(path)
    g = load_mesh(path)
    assert set(g.part_names) == {"cube", "ball"}
    cube = g.triangles[g.part == g.part_names.index("cube")]
    assert cube.shape == (12, 3, 3)
    assert cube[:, :, 0].min() == pytest.approx(4.5)
    assert _volume(cube) == pytest.approx(1.0)


def test_load_mesh_obj_objects_become_parts_in_file_order(tmp_path):
    path = tmp_path / "parts.obj"
    path.write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\n"
        "o first\nf 1 2 3\nf 2 4 3\n"
        "o second\nf 1 2 5\n"
        "o third\nf 1 5 3 4\n"  # a quad: trimesh fan-triangulates it
    )
    g = load_mesh(path)
    assert g.part_names == ("first", "second", "third")
    assert g.part.tolist() == [0, 0, 1, 2, 2]
    np.testing.assert_allclose(g.triangles[0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def _raises_naming(path: Path, match: str | None = None):
    with pytest.raises(InputError) as info:
        load_mesh(path)
    assert path.name in str(info.value)
    assert "\n" not in str(info.value)
    if match:
        assert match in str(info.value)
    return info.value


def test_load_mesh_missing_file(tmp_path):
    _raises_naming(tmp_path / "nothere.obj", "not found")


def test_load_mesh_unknown_extension(tmp_path):
    path = tmp_path / "model.fbx"
    path.write_text("whatever")
    err = _raises_naming(path, ".fbx")
    for ext in (".obj", ".ply", ".stl", ".glb", ".gltf"):
        assert ext in str(err)


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "glb"])
def test_load_mesh_empty_file(tmp_path, ext):
    path = tmp_path / f"empty.{ext}"
    path.write_bytes(b"")
    _raises_naming(path)


_PLY_HEADER = (
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\n"
)


@pytest.mark.parametrize(
    ("name", "text", "first"),
    [
        ("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 nan\nf 1 2 3\nf 2 4 3\n", 4),  # (OBJ numbers vertices from 1)
        ("nan.ply", _PLY_HEADER + "element face 1\nproperty list uchar int vertex_indices\n"
         "end_header\n0 0 0\nnan 0 0\n0 1 inf\n3 0 1 2\n", 1),
    ],
)
def test_load_mesh_non_finite_vertices(tmp_path, name, text, first):
    path = tmp_path / name
    path.write_text(text)
    err = _raises_naming(path, "NaN")
    assert f"vertex {first}" in str(err)


def test_load_mesh_point_cloud_is_an_error(tmp_path):
    path = tmp_path / "points.ply"
    path.write_text(_PLY_HEADER + "end_header\n0 0 0\n1 0 0\n0 1 0\n")
    _raises_naming(path, "faces")


def test_load_mesh_garbage_is_an_error(tmp_path):
    path = tmp_path / "junk.ply"
    path.write_bytes(b"ply\nthis is not a ply header\n\x00\x01")
    _raises_naming(path)


def test_the_thesis_ring_has_the_thesis_counts_a_glass_part_and_rays_that_miss():
    """scenes/thesis/ring.yaml (Fig. 15): 646 triangles, a refractive element (so the
    Refract column runs a pass of its own) and a framing where most eye rays miss."""
    import numpy as np

    from tlm.config import config_from_dict
    from tlm.kernels.camera import primary_rays
    from tlm.kernels.traverse import build_accel, closest_hit
    from tlm.render.planner import plan
    from tlm.scenes.loader import load_scene

    s = load_scene("thesis/ring")
    assert s.n_triangles == 646 and (s.camera.width, s.camera.height) == (320, 240) and s.photons == 20000
    assert any(m.kind == "dielectric" for m in s.materials)
    cfg = config_from_dict({"scene": "thesis/ring", "mode": "refract"}, "t")
    assert "refract" in plan(s, cfg).run_names
    o, d = primary_rays(s.camera, np.arange(320 * 240))
    hit = closest_hit(build_accel(s.triangles), o, d)
    assert np.mean(hit.triangle < 0) > 0.5  # "many ... eye-ray paths do not yield any intersection"
    with pytest.raises(ValueError, match="would touch the ring"):
        from tlm.scenes.builders import ring
        ring(glass_radius=3.0, glass_x=4.0, glass_z=0.0)
