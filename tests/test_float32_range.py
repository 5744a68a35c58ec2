"""The float32 ray-triangle test's range (tlm/scenes/loader.py ``check_float32_range``): a
scene whose final geometry (after its ``transform``) the test cannot handle is refused
with one line naming the file, the key and the scale that brings it in range; one inside
the bounds renders as the unscaled scene does, and a tiny triangle among larger ones is
legal."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.run import render
from tlm.scenes import loader
from tlm.scenes.loader import load_scene

REPO = Path(__file__).resolve().parents[1]
CORNELL = REPO / "scenes" / "cornell.yaml"


def _scaled(tmp_path: Path, scale: str, extra: str = "") -> Path:
    path = tmp_path / f"cornell_{scale}.yaml"
    path.write_text(f"extends: {CORNELL}\nname: c{scale}\ntransform: {{scale: {scale}}}\n{extra}")
    return path


def _refused(path: Path, key: str) -> str:
    with pytest.raises(InputError) as e:
        load_scene(str(path))
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{path}: {key}: "), msg
    return msg


@pytest.mark.parametrize(("scale", "words", "bound"), [
    ("1.0e11", "too large", "scale it down: transform: {scale: 2.9e+09} or less"),
    ("3.0e10", "too large", "scale it down: transform: {scale: 2.9e+09} or less"),
    ("1.0e-16", "too small", "scale it up: transform: {scale: 3.9e-15} or more"),
    ("1.0e-17", "too small", "scale it up: transform: {scale: 3.9e-15} or more"),
])
def test_a_scene_scaled_out_of_the_float32_range_is_refused(tmp_path, scale, words, bound):
    """Before: accepted; at 1e11 the frame was black but the light, at 1e-17 shadows were
    lost. The line names the file, ``transform.scale``, the product and the scale that
    fits, which loads."""
    msg = _refused(_scaled(tmp_path, scale), "transform.scale")
    assert f"the scene is {words} for the float32 ray-triangle test" in msg and msg.endswith(bound), msg
    fit = re.search(r"\{scale: ([^}]+)\}", bound).group(1)
    s = loader.float32_sizes(load_scene(str(_scaled(tmp_path, fit))))
    assert s["extent"] * s["largest"] <= loader.SIZE_HI and s["span"] * s["median"] >= loader.SIZE_LO


def test_the_check_sees_the_geometry_and_camera_the_scene_ends_with(tmp_path):
    """A mesh too large without any transform is refused under ``geometry``; a camera far
    from a scene that fits makes its extent too large; a transform whose scale takes a
    mesh's coordinates past 1e30 is refused under ``transform`` (before: accepted)."""
    (tmp_path / "big.obj").write_text("v 0 0 0\nv 1e13 0 0\nv 0 1e13 0\nf 1 2 3\n")
    big = tmp_path / "big.yaml"
    big.write_text("geometry: {mesh: big.obj}\nmaterials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
                   "default_material: m\nlights: [{type: point, position: [1e12, 1e12, 1e12], power: [1, 1, 1]}]\n"
                   "camera: {eye: [1e12, 1e12, 3e13], target: [1e12, 1e12, 0], vfov: 40}\nresolution: [8, 8]\n")
    assert "too large" in _refused(big, "geometry")
    assert load_scene(str(_scaled(tmp_path, "1.0e9")))  # (the camera 1,073 from the box: in range)
    far = _scaled(tmp_path, "1.0e9", "camera: {eye: [278.0, 273.0, -1.0e5]}\n")
    assert "its extent 1.01e+14 (the diagonal of the box around its triangles, camera eye and lights)" in _refused(
        far, "transform.scale")
    (tmp_path / "wide.obj").write_text("v 0 0 0\nv 1e25 0 0\nv 0 1e25 0\nf 1 2 3\n")
    wide = tmp_path / "wide.yaml"
    wide.write_text(big.read_text().replace("big.obj", "wide.obj") + "transform: {scale: 1.0e6}\n")
    assert "1 triangle(s) have a coordinate beyond +-1e+30" in _refused(wide, "transform")


def test_tiny_triangles_are_legal_among_larger_ones_and_refused_alone(tmp_path, cache):
    """The lower bound takes the triangles' median |E1 x E2|: triangles of edges 1e-14 and
    1e-20 added to the McGuire box load, and the frame is the box's; the same two
    alone, lit and seen from nearby, are refused (before: accepted, and rendered wrong)."""
    (tmp_path / "tiny.obj").write_text("v 0 1e-14 0\nv 1e-14 1e-14 0\nv 0 2e-14 0\nv 0 1e-20 0\nv 1e-20 1e-20 0\n"
                                       "v 0 2e-20 0\nf 1 2 3\nf 4 5 6\n")
    box = REPO / "scenes" / "meshes" / "CornellBox-Original.obj"
    with_tiny = tmp_path / "with_tiny.yaml"
    with_tiny.write_text(f"extends: {REPO / 'scenes' / 'cornell-box.yaml'}\n"
                         f"geometry: [{{mesh: {box}}}, {{mesh: tiny.obj}}]\ndefault_material: floor\n")
    alone = tmp_path / "alone.yaml"
    alone.write_text("geometry: {mesh: tiny.obj}\nmaterials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
                     "default_material: m\nlights: [{type: point, position: [0, 0, -1e-13], power: [1, 1, 1]}]\n"
                     "camera: {eye: [0, 0, -1e-13], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
    assert "too small" in _refused(alone, "geometry")
    frames = []
    for scene in ("cornell-box", str(with_tiny)):
        cfg = config_from_dict({"scene": scene, "mode": "rcast", "resolution": [16, 16],
                                "render": {"spp": 1, "light_samples": 1}})
        frames.append(render(cfg).radiance["rcast"])
    assert np.array_equal(frames[0], frames[1])


def test_the_bounds_lie_inside_the_range_the_cornell_box_renders_exactly(tmp_path, cache):
    """The Cornell box at the largest and smallest scales the loader takes (2.9e9, 3.9e-15)
    renders the unscaled box's ray-cast, reflect and refract frames (to 1e-12); ten times
    past either (3e10, 3e-16: still exact, the margin) is refused."""
    def frames(scene):
        cfg = config_from_dict({"scene": str(scene), "mode": "refract", "resolution": [16, 16],
                                "render": {"spp": 1, "light_samples": 1}})
        return render(cfg).radiance

    base = frames(CORNELL)
    for scale in ("2.9e9", "3.9e-15"):
        got = frames(_scaled(tmp_path, scale))
        for name in ("rcast", "reflect", "refract"):
            np.testing.assert_allclose(got[name], base[name], rtol=1e-12, atol=1e-12 * base[name].max())
    for scale in ("3.0e10", "3.0e-16"):
        _refused(_scaled(tmp_path, scale), "transform.scale")


def test_the_range_check_lives_beside_the_loader_under_its_old_names():
    from tlm.scenes import float32_range

    assert loader.check_float32_range is float32_range.check_float32_range
    assert (loader.SIZE_HI, loader.SIZE_LO) == (float32_range.SIZE_HI, float32_range.SIZE_LO)
