"""h333: scene-file details left from the last stop. An OBJ line that ends with a backslash continues on the next
(the spec's long lines), in the fast and the per-line reader alike, every later line keeping its number; a ``v``'s
4th to 6th number is read as its first three are (``1_0`` refused); a CR alone ends a line in a file of other line
ends too. A material a second MTL library defines again is folded as one library's notes are, saying which
definition is used and recorded. A light's ``from`` names its entry: a scene file's ``FILE: lights[i]`` (the file of
an ``extends:`` chain that gave it), a glTF's its path and ``KHR_lights_punctual.lights[i] ... at nodes[n]``, in
``tlm scene show``, results.json and the report's Provenance lights table."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pytest

from tlm import api
from tlm.errors import InputError
from tlm.experiments.run import light_record
from tlm.render.checks import file_warnings
from tlm.report.provenance import _lights_table
from tlm.scenes.loader import load_scene
from tlm.scenes.objfile import parse_obj

FIELDS = ("vertices", "faces", "face_line", "vertex_normals", "corner_normals", "part", "part_names", "material",
          "material_names", "material_lines", "mtllibs", "colour_lines")
BODY = ["mtllib m.mtl", "o box", "v 0 0 0", "v 1 0 0", "v 1 1 0 0.5 0.5 0.5", "v 0 1 0", "vn 0 0 1", "vn 0 0 1",
        "usemtl red", "f 1//1 2//2 3//1", "g lid", "f 1//1 3//2 4//1", "usemtl blue", "f -4//-1 -3//-2 -1//-1"]


def _same(got, want) -> None:
    for field in FIELDS:
        a, b = getattr(got, field), getattr(want, field)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field)
        else:
            assert a == b, field


def _split(lines: list[str], rng: np.random.Generator, end: str = "\n") -> tuple[str, list[int]]:
    """``lines`` with some of them continued over several lines by a backslash (cut between words, or inside a
    run of spaces), and the physical line number each statement starts on."""
    out, first = [], []
    for line in lines:
        first.append(len(out) + 1)
        words = line.split(" ")
        while len(words) > 1 and rng.random() < 0.5:
            k = int(rng.integers(1, len(words)))
            out.append(" ".join(words[:k]) + rng.choice([" \\", "\\", "  \\"]))
            words = words[k:]
        out.append(" ".join(words))
    return end.join(out) + end, first


def _with_lines(text: str, numbers: list[int]) -> bytes:
    """``text``'s statement i on line ``numbers[i]`` (blank lines between): what a joined file reads as."""
    out: list[str] = []
    for line, at in zip(text.splitlines(), numbers, strict=True):
        out += [""] * (at - 1 - len(out)) + [line]
    return ("\n".join(out) + "\n").encode()


@pytest.mark.parametrize("end", ["\n", "\r\n"])
def test_a_backslash_continues_a_line_in_both_readers(end):
    rng = np.random.default_rng(333)
    plain = "\n".join(BODY) + "\n"
    for _ in range(40):
        text, first = _split(BODY, rng, end)
        want = parse_obj(_with_lines(plain, first), "m.obj", "m")
        got = parse_obj(text.encode(), "m.obj", "m")  # (the fast path: every block reads so)
        _same(got, want)
        assert got.face_line.tolist() == [first[9], first[11], first[13]]
        # an inline comment on the last v, vn and f statement sends their blocks through the per-line reader
        slow = [ln + " # per line" if i in (5, 7, 13) else ln for i, ln in enumerate(BODY)]
        text, first = _split(slow, rng, end)
        _same(parse_obj(text.encode(), "m.obj", "m"), parse_obj(_with_lines(plain, first), "m.obj", "m"))


def test_a_continued_statement_and_the_lines_after_it_keep_their_numbers():
    text = "v 0 0 0\nv 1 0 \\\n  0\nv 0 1 0\nf 1 2 \\\n\\\n 3\nf 1 2 q\n"
    with pytest.raises(InputError) as e:
        parse_obj(text.encode(), "m.obj", "m")
    assert str(e.value) == "m.obj: line 8: cannot read the face corner 'q' (indices are integers)"
    with pytest.raises(InputError) as e:  # (an error in a continued statement names its first line)
        parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 \\\n 2 \\\n 9\n", "m.obj", "m")
    assert str(e.value) == "m.obj: line 4: a face references vertex 9: there are only 3 vertices"
    got = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n 3", "m.obj", "m")  # (the last line, no newline)
    assert got.faces.tolist() == [[0, 1, 2]] and got.face_line.tolist() == [4]
    got = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 \\\n", "m.obj", "m")  # (a backslash on the last line)
    assert got.faces.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize(("line", "word"), [("v 1 0 0 1_0", "1_0"), ("v 1 0 0 1 1 1_0", "1_0"),
                                            ("v 1 0 0 0.5 0_5 0.5", "0_5"), ("v 1 0 0 w", "w"),
                                            ("v 1 0 0 1 x 1", "x")])
def test_a_vertex_s_fourth_to_sixth_number_is_read_as_a_number(line, word):
    for tail in ("", " # per line"):  # (the fast path, and the per-line reader)
        with pytest.raises(InputError) as e:
            parse_obj(f"v 0 0 0\n{line}{tail}\nv 0 1 0\nf 1 2 3\n".encode(), "m.obj", "m")
        assert str(e.value) == f"m.obj: line 2: cannot read {word!r} as a number in a 'v' statement"
    got = parse_obj(b"v 0 0 0\nv 1 0 0 1 0.5 0.25 # rgb\nv 0 1 0 1.0\nf 1 2 3\n", "m.obj", "m")
    assert got.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]] and got.colour_lines == (1, 2)


def test_a_cr_alone_ends_a_line_in_a_file_with_other_line_ends():
    for data in (b"v 0 0 0\rv 1 0 0\rv 0 1 0\n\rf 1 2 3\r", b"v 0 0 0\r\nv 1 0 0\rv 0 1 0\r\n\rf 1 2 3\r\n"):
        got = parse_obj(data, "m.obj", "m")
        assert got.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
        assert got.faces.tolist() == [[0, 1, 2]] and got.face_line.tolist() == [5]


# ---------------------------------------------------------------- a material a second library defines again


CAMERA = "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n"
LIGHTS = ("lights: [{type: point, position: [0.5, 0.5, 1], power: [10, 10, 10]}, "
          "{type: point, position: [0.5, 0.5, 2], power: [1, 1, 1]}]\n")


def _two_libraries(folder: Path, mtllib: str) -> Path:
    names = ["red", "green", "blue", "grey"]
    out = mtllib.split("\n")
    for i, n in enumerate(names):
        out += [f"v {i} 0 0", f"v {i + 1} 0 0", f"v {i} 1 0", f"usemtl {n}", f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}"]
    (folder / "m.obj").write_text("\n".join(out) + "\n")
    (folder / "a.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl green\nKd 0 1 0\nnewmtl blue\nKd 0 0 1\n")
    (folder / "b.mtl").write_text("newmtl red\nKd 0.5 0 0\nnewmtl green\nKd 0 0.5 0\nnewmtl blue\nKd 0 0 0.5\n"
                                  "newmtl grey\nKd 0.5 0.5 0.5\n")
    (folder / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + LIGHTS)
    return folder / "s.yaml"


@pytest.mark.parametrize("mtllib", ["mtllib a.mtl b.mtl", "mtllib a.mtl\nmtllib b.mtl"])
def test_a_material_a_second_library_defines_again_is_folded_and_its_winner_recorded(tmp_path, mtllib):
    scene = load_scene(str(_two_libraries(tmp_path, mtllib)))
    a, b = tmp_path / "a.mtl", tmp_path / "b.mtl"
    each = [n for n in scene.extra["notes"] if n.startswith(str(b))]
    assert each == [f"{b}: line {k}: newmtl {name!r} is defined by {a} too (line {k}), which the mtllib names first: "
                    "that one is used (results.json's scene.materials, `from`, names it), this one is ignored"
                    for k, name in ((1, "red"), (3, "green"), (5, "blue"))]
    assert [w for w in file_warnings(scene) if str(b) in w] == [
        f"{b}: 3 newmtl names that {a} defines too, which the mtllib names first: the first at line 1, material "
        f"'red' ({a} line 1), and 2 more at lines 3, 5: the definitions in {a} are used (results.json's "
        "scene.materials, `from`, names them), these are ignored (`tlm scene show` lists each)"]
    info = {m["name"]: m for m in api.scene_info(scene)["materials"]}
    assert {k: (m["albedo"], m["from"]) for k, m in info.items()} == {
        "red": ([1.0, 0.0, 0.0], f"{a}:1"), "green": ([0.0, 1.0, 0.0], f"{a}:3"), "blue": ([0.0, 0.0, 1.0], f"{a}:5"),
        "grey": ([0.5, 0.5, 0.5], f"{b}:7")}


# ---------------------------------------------------------------- a light's from


def test_a_scene_file_s_light_says_its_entry(tmp_path):
    scene_file = _two_libraries(tmp_path, "mtllib a.mtl b.mtl")
    want = [f"{scene_file}: lights[0]", f"{scene_file}: lights[1]"]
    assert [lt["from"] for lt in api.scene_info(scene_file)["lights"]] == want  # (tlm scene show)
    scene = load_scene(str(scene_file))
    assert [light_record(lt)["from"] for lt in scene.lights if lt.kind != "mesh"] == want  # (results.json)
    table = html.unescape(_lights_table([light_record(lt) for lt in scene.lights], {"red": {"kind": "lambertian"}}))
    assert f"{scene_file}: lights[1]" in table and "the scene file's lights:" not in table
    # given through extends: the file that gave lights:
    (tmp_path / "child.yaml").write_text("extends: s.yaml\nresolution: [4, 4]\n")
    assert [lt["from"] for lt in api.scene_info(tmp_path / "child.yaml")["lights"]] == want
    own = tmp_path / "own.yaml"
    own.write_text("extends: s.yaml\nlights: [{type: point, position: [0, 1, 1], power: [1, 1, 1]}]\n")
    assert [lt["from"] for lt in api.scene_info(own)["lights"]] == [f"{own}: lights[0]"]


def test_a_gltf_light_says_its_file_and_entry_as_its_materials_do(tmp_path):
    from tests.test_gltf_lights import _scene_glb, _yaml

    glb = _scene_glb(tmp_path)
    info = api.scene_info(_yaml(tmp_path, "geometry: {mesh: s.glb}\n"))
    punctual = f"{glb} KHR_lights_punctual.lights"
    assert [lt["from"] for lt in info["lights"]] == [
        f"{punctual}[0] 'lamp' at nodes[2]", f"{punctual}[0] 'lamp' at nodes[3]", f"{punctual}[1] 'beam' at nodes[5]"]


def test_a_copy_s_cached_frame_names_the_copy_s_lights(tmp_path, cache):
    """A cached frame is shared by a copy of its project in another folder (the lights' from is no part of the
    scene's value, and is said from its folder in the frame's key), and names the copy's scene file."""
    from tlm.config import config_from_dict
    from tlm.experiments import frames

    got = []
    for p in ("p1", "deeper/p2"):
        scene = tmp_path / p / "s.yaml"
        scene.parent.mkdir(parents=True)
        scene.write_text("geometry: {shape: plane, name: floor, params: {size: [2.0, 2.0]}}\n"
                         "materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\nparts: {floor: grey}\n"
                         "lights: [{type: point, position: [0.0, 1.0, 0.0], power: [1.0, 1.0, 1.0]}]\n"
                         "camera: {eye: [0.0, 2.0, 3.0], target: [0.0, 0.0, 0.0], vfov: 40.0}\n")
        got.append(frames.cached_render(config_from_dict({"scene": str(scene), "mode": "rcast",
                                                          "resolution": [8, 8]})))
    assert [g.cached for g in got] == [False, True]
    assert [g.summary["scene"]["lights"][0]["from"] for g in got] == [
        f"{tmp_path}/{p}/s.yaml: lights[0]" for p in ("p1", "deeper/p2")]
