"""A closed glass part wound inside out (h506, tlm/render/checks.py glass_warnings): glass refracts
into itself from the side ``cross(V1 - V0, V2 - V0)`` points to, so a ball whose faces are reversed
rendered its refract frame 0.02x to 20x per pixel off the right one's, its caustic's peak 3.46 ->
0.075, and no warning said why. Now one line names the part, its material and the fix; open glass
(a water surface, a pane), a sheet of two sides, a hollow body, a body wound both ways, and opaque
parts are not named (h511: a body split over parts is, by all of them), and the built-in scenes with
glass stay silent."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.render import checks
from tlm.scenes.loader import load_scene
from tlm.scenes.shapes import aabox, quad, uv_sphere

REPO = Path(__file__).resolve().parents[1]
SAID = "is a closed surface that faces inwards"
SMALL = ["--set", "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1",
         "--set", "arch.packet_size=16"]


def _obj(path: Path, parts: dict[str, np.ndarray]) -> None:
    """An OBJ of one object per part, each triangle with corners of its own (the check matches
    corners by their coordinates, as an STL's)."""
    lines, k = [], 0
    for name, tri in parts.items():
        lines.append(f"o {name}")
        for t in np.asarray(tri, dtype=np.float64):
            lines += ["v " + " ".join(repr(float(c)) for c in p) for p in t]
            lines.append(f"f {k + 1} {k + 2} {k + 3}")
            k += 3
    path.write_text("\n".join(lines) + "\n")


def _scene(tmp_path: Path, name: str, parts: dict[str, np.ndarray], glass: list[str]) -> Path:
    """A scene of a floor and the OBJ's parts: those in ``glass`` of material 'g', the rest white."""
    _obj(tmp_path / f"{name}.obj", parts)
    materials = "".join(f"  {p}: {'g' if p in glass else 'w'}\n" for p in ["floor", *parts])
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"name: {name}\ngeometry:\n- {{shape: plane, params: {{size: [6, 6]}}, name: floor}}\n"
                    f"- {{mesh: {name}.obj}}\n"
                    "materials:\n  w: {type: lambertian, albedo: [0.7, 0.7, 0.7]}\n  g: {type: dielectric, ior: 1.5}\n"
                    f"parts:\n{materials}"
                    "lights: [{type: point, position: [0.3, 2.5, 0.2], power: [60, 60, 60]}]\n"
                    "camera: {eye: [0, 1.8, -3], target: [0, 0.4, 0], vfov: 40}\nresolution: [16, 16]\n")
    return path


def _reversed(tri: np.ndarray) -> np.ndarray:
    return np.asarray(tri)[:, [0, 2, 1]]


def _ball() -> np.ndarray:
    """A glass ball of 24 x 12 faces with its poles' triangles of zero area (as h500's)."""
    return uv_sphere((0.0, 0.5, 0.0), 0.5, 24, 13)


def test_an_inside_out_glass_ball_is_named_by_the_run(tmp_path, capsys, cache):
    """``tlm run`` of the ball with its faces reversed says so in results.json and on stderr,
    naming the part, its material and the fix; the same ball wound outwards says nothing."""
    lines = {}
    for name, ball in (("ball_in", _reversed(_ball())), ("ball_out", _ball())):
        scene = _scene(tmp_path, name, {"ball": ball}, ["ball"])
        out = tmp_path / f"out_{name}"
        code = main(["run", str(scene), "--out", str(out), "--mode", "refract", "--no-progress", "--no-report",
                     "--no-reference", "--outputs", "images", *SMALL])
        err = capsys.readouterr().err.splitlines()
        said = [w for w in json.loads((out / "results.json").read_text())["warnings"] if SAID in w]
        assert code == 0
        lines[name] = said
        assert [e for e in err if SAID in e] == [f"tlm: warning: {w}" for w in said]
    assert lines["ball_out"] == []
    [line] = lines["ball_in"]
    assert line.startswith("part 'ball' (glass: material 'g') is a closed surface that faces inwards: its "
                           f"{_ball().shape[0]} triangles enclose a volume of -0.5")
    assert "reverse the order of its faces' corners in its mesh file" in line


def test_only_a_closed_glass_part_wound_inwards_is_named(tmp_path):
    """One scene: the inside-out glass box is named; not the same box without its first face (open: a
    water surface), a single pane, a triangle of two sides (closed, enclosing nothing), a hollow box (its
    cavity wound to face into it), the inside-out box with one face turned back (not wound one way), nor an
    inside-out opaque box; the inside-out box split over two parts is named by both (h511: it was not)."""
    cube = aabox((-0.2, 0.0, -0.2), (0.2, 0.4, 0.2))
    at = lambda tri, x: np.asarray(tri) + np.array([x, 0.0, 2.0])  # noqa: E731 (side by side)
    sheet = np.array([[[-0.2, 0.5, -0.2], [0.2, 0.5, -0.2], [0.0, 0.5, 0.2]]])
    one_off = _reversed(at(cube, 2.0))
    one_off[:2] = _reversed(one_off[:2])
    parts = {"inside_out": _reversed(at(cube, -2.0)), "open": _reversed(at(cube, -3.0))[2:],
             "pane": _reversed(at(quad((-0.2, 0.5, -0.2), (0.4, 0.0, 0.0), (0.0, 0.0, 0.4)), -1.0)),
             "two_sided": np.concatenate([at(sheet, 0.0), _reversed(at(sheet, 0.0))]),
             "hollow": np.concatenate([at(cube, 1.0), _reversed(at(aabox((-0.1, 0.1, -0.1), (0.1, 0.3, 0.1)), 1.0))]),
             "one_off": one_off, "half_a": _reversed(at(cube, 3.0))[:6], "half_b": _reversed(at(cube, 3.0))[6:],
             "opaque": _reversed(at(cube, 4.0))}
    scene = load_scene(str(_scene(tmp_path, "many", parts, [p for p in parts if p != "opaque"])))
    said = [w for w in checks.file_warnings(scene) if "a closed surface that faces inwards" in w]
    assert len(said) == 2 and said[0].startswith("part 'inside_out' (glass: material 'g') " + SAID), said
    assert said[1].startswith("parts 'half_a' and 'half_b' (glass: material 'g') are a closed surface"), said


BUILT_IN = {"cornell": ["glass_object"], "cornell-water": ["rightSphere"], "cornell-sphere": ["rightSphere"],
            "room": ["glass"], "thesis/ring": ["glass"], "examples/mesh_on_floor": ["glass_ball"],
            "extreme/cornell_offset_1e6": ["glass_object"], "extreme/cornell_scale_1e-6": ["glass_object"],
            "extreme/cornell_scale_1e6": ["glass_object"], "extreme/cornell_ior10": ["glass_object"]}


@pytest.mark.parametrize("name", sorted(BUILT_IN))
def test_the_built_in_glass_is_silent_and_named_once_reversed(name, cache):
    """Each built-in scene with glass says nothing; with its glass's faces reversed it names each
    closed glass part (cornell-water's water, an open surface, stays unnamed either way), far from
    the origin and at 1e-6 and 1e6 of the box's size too."""
    scene = load_scene(str(REPO / "scenes" / f"{name}.yaml"))
    assert [w for w in checks.file_warnings(scene) if SAID in w] == []
    glass = np.array([m.kind == "dielectric" for m in scene.materials])[scene.material_index]
    tri = scene.triangles.copy()
    tri[glass] = _reversed(tri[glass])
    said = [w for w in checks.file_warnings(replace(scene, triangles=tri)) if SAID in w]
    assert [w.split("'")[1] for w in said] == BUILT_IN[name], said
