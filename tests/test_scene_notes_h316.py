"""A published scene's material and light notes (probe h314): one mistake an MTL repeats over its
materials is one warning line (each note still listed by ``tlm scene show``); an MTL given as a
scene names the OBJs whose ``mtllib`` reads it, not one of its stem that reads another; an
``mtllib`` name with a space, or of another letter case, is named whole; bytes that are not UTF-8
are noted; a light whose face is wound into the surface it hangs under is warned of."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tlm import api
from tlm.cli import main
from tlm.errors import InputError
from tlm.kernels.traverse import build_accel
from tlm.render import checks

REPO = Path(__file__).resolve().parents[1]
CAMERA = "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n"
LIGHT = "lights: [{type: point, position: [0.5, 0.5, 1], power: [10, 10, 10]}]\n"


def _obj(names: list[str], mtllib: str = "m.mtl") -> str:
    """An OBJ of one triangle per material of ``names``."""
    out = [f"mtllib {mtllib}"]
    for i, name in enumerate(names):
        out += [f"v {i} 0 0", f"v {i + 1} 0 0", f"v {i} 1 0", f"usemtl {name}",
                f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}"]
    return "\n".join(out) + "\n"


def _scene(tmp_path: Path, mtl: str, names: list[str]) -> Path:
    (tmp_path / "m.obj").write_text(_obj(names))
    (tmp_path / "m.mtl").write_text(mtl)
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + LIGHT)
    return tmp_path / "s.yaml"


# ------------------------------------------------------------ 1. one mistake repeated: one line


def test_kd_in_0_255_over_many_materials_is_one_warning_line_and_every_note_is_shown(tmp_path):
    names = ["a", "b", "c", "d"]
    mtl = "".join(f"newmtl {n}\nKd {100 + i} 50 50\n" for i, n in enumerate(names))
    path = _scene(tmp_path, mtl, names)
    scene = api.load_scene(path)
    lib = tmp_path / "m.mtl"
    clipped = [n for n in scene.extra["notes"] if "is over 1" in n]
    assert len(clipped) == 4 and len(api.scene_info(scene)["notes"]) == 4  # (every fact: tlm scene show)
    lines = [w for w in checks.file_warnings(scene) if str(lib) in w]
    assert lines == [f"{lib}: 4 materials whose Kd is over 1, each clipped to albedo [0, 1]: the first at line 2, "
                     "material 'a' (Kd 100 50 50 -> [1, 1, 1]), and 3 more at lines 4, 6, 8 (0-255 values? divide "
                     "them by 255) (`tlm scene show` lists each)"], lines


def test_repeated_statements_and_newmtl_names_fold_per_file_and_kind(tmp_path):
    mtl = ("newmtl a\nKd 0.1 0.1 0.1\nKd 0.2 0.2 0.2\nnewmtl b\nKs 0 0 0\nKs 0.5 0.5 0.5\n"
           "newmtl a\nKd 0 0 1\nnewmtl b\nKd 0 1 0\nnewmtl c\nKd 3 3 3\n")
    scene = api.load_scene(_scene(tmp_path, mtl, ["a", "b", "c"]))
    lib = tmp_path / "m.mtl"
    assert len([n for n in scene.extra["notes"] if str(lib) in n]) == 5
    lines = [w for w in checks.file_warnings(scene) if str(lib) in w]
    assert lines == [
        f"{lib}: 2 statements given again in one material with another value: the first at line 3, material 'a' "
        "(Kd given twice, line 2 `Kd 0.1 0.1 0.1` and line 3 `Kd 0.2 0.2 0.2`), and 1 more at line 6: the last is "
        "used, as OBJ readers (trimesh, tinyobjloader) take it (another value: a scene file's `materials:` entry "
        "of each, the MTL file left as it is) (`tlm scene show` lists each)",
        f"{lib}: 2 newmtl names defined again, each later definition ignored: the first at line 7, material 'a' "
        "(first defined at line 1), and 1 more at line 9: the first definitions are used (rename them) "
        "(`tlm scene show` lists each)",
        f"{lib}: line 12: material 'c': Kd 3 3 3 is over 1: clipped to albedo [1, 1, 1] (0-255 values? divide them "
        "by 255)"], lines  # (one of its kind: as it was)


# ------------------------------------------------------------ 2. the OBJs whose mtllib names an MTL


def test_an_mtl_given_as_a_scene_names_the_objs_whose_mtllib_reads_it(tmp_path, capsys):
    """As McGuire publishes them: CornellBox-Glossy-Floor.obj reads CornellBox-Glossy.mtl, and
    CornellBox-Glossy-Floor.mtl is read by no OBJ (the hint named the OBJ of its stem as its reader)."""
    (tmp_path / "Glossy.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\n")
    (tmp_path / "Glossy-Floor.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\n")
    for obj in ("Glossy.obj", "Glossy-Floor.obj"):
        (tmp_path / obj).write_text(_obj(["a"], "Glossy.mtl"))
    assert main(["scene", "show", str(tmp_path / "Glossy-Floor.mtl")]) == 2
    err = capsys.readouterr().err
    assert "read with the OBJ whose `mtllib` names it; no OBJ beside it names it: Glossy-Floor.obj, of its stem, " \
           "reads Glossy.mtl instead)" in err, err
    assert main(["scene", "show", str(tmp_path / "Glossy.mtl")]) == 2
    err = capsys.readouterr().err
    assert "read with the OBJs whose `mtllib` names it: Glossy.obj and Glossy-Floor.obj, beside it)" in err, err
    assert "`geometry: {mesh: Glossy.obj}`" in err, err


# ------------------------------------------------------------ 3. an mtllib name with a space


def test_a_missing_mtllib_with_a_space_is_named_whole_with_what_was_tried_and_its_letter_case(tmp_path):
    (tmp_path / "m.obj").write_text(_obj(["a"], "my lib.mtl"))
    (tmp_path / "My Lib.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\n")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + LIGHT)
    with pytest.raises(InputError) as got:
        api.load_scene(tmp_path / "s.yaml")
    said = str(got.value)
    assert said.startswith(f"{tmp_path / 'm.obj'}: line 1: the material library 'my lib.mtl' (mtllib) is missing: "
                           f"no file {tmp_path / 'my lib.mtl'}, nor {tmp_path / 'my'} and {tmp_path / 'lib.mtl'} "
                           "(of the names its spaces separate"), said
    assert "('My Lib.mtl' is there: the name differs in letter case" in said, said
    (tmp_path / "My Lib.mtl").rename(tmp_path / "my lib.mtl")  # (its whole text, one file: read)
    assert [m.name for m in api.load_scene(tmp_path / "s.yaml").materials] == ["a"]


# ------------------------------------------------------------ 4. bytes that are not UTF-8


def test_a_latin_1_mtl_and_obj_are_noted_with_file_line_and_the_latin_1_reading(tmp_path):
    (tmp_path / "m.obj").write_bytes(_obj(["Fu\xdfboden"]).encode("latin-1"))
    (tmp_path / "m.mtl").write_bytes("newmtl Fu\xdfboden\nKd 0.5 0.5 0.5\n".encode("latin-1"))
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + LIGHT)
    scene = api.load_scene(tmp_path / "s.yaml")
    assert [m.name for m in scene.materials] == ["Fu\ufffdboden"]  # (the OBJ's and the MTL's names still match)
    notes = scene.extra["notes"]
    assert f"{tmp_path / 'm.mtl'}: line 1: bytes that are not UTF-8 ('newmtl Fu\ufffdboden'): read as U+FFFD, so a " \
           "name there matches no scene file's `materials:` entry spelled otherwise; read as Latin-1 the line is " \
           "'newmtl Fußboden' (save the file as UTF-8)" in notes, notes
    assert any(n.startswith(f"{tmp_path / 'm.obj'}: line 5: usemtl 'Fu\ufffdboden': bytes that are not UTF-8")
               for n in notes), notes


# ------------------------------------------------------------ 5. a light wound into its ceiling

ROOM = ("v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\n"
        "v 0.4 0.99 0.4\nv 0.6 0.99 0.4\nv 0.6 0.99 0.6\nv 0.4 0.99 0.6\n"
        "usemtl wall\nf 1 2 3 4\nf 5 6 7 8\nusemtl light\n")
ROOM_MTL = "newmtl wall\nKd 0.7 0.7 0.7\nnewmtl light\nKd 0.8 0.8 0.8\nKe 10 10 10\n"


def test_a_ceiling_light_wound_to_face_its_ceiling_is_warned_of_and_one_facing_the_room_is_not(tmp_path):
    said = {}
    for face in ("f 9 10 11 12", "f 12 11 10 9"):  # (the first: cross(V1 - V0, V2 - V0) = -y, down into the room)
        (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + ROOM + face + "\n")
        (tmp_path / "m.mtl").write_text(ROOM_MTL)
        (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA)
        scene = api.load_scene(tmp_path / "s.yaml")
        said[face] = checks.light_warnings(scene, build_accel(scene.triangles))
    assert said["f 9 10 11 12"] == [], said
    (line,) = said["f 12 11 10 9"]
    assert re.match(r"lights\[0\] \(mesh 'light'\) sends (9\d|100)% of its power into a surface within 0\.0346 of "
                    r"it \(the smaller of 0\.02 of the scene's diagonal and 0\.5 of its size; at 0\.01", line), line
    assert "is its face wound the wrong way? reverse the order of its faces' corners" in line, line


def test_a_quad_light_facing_its_ceiling_is_warned_of_and_the_built_in_scenes_are_not(tmp_path):
    (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + ROOM.replace("usemtl light\n", ""))
    (tmp_path / "m.mtl").write_text(ROOM_MTL)
    quad = ("lights: [{type: quad, corner: [0.4, 0.99, 0.4], edge_u: [0, 0, 0.2], edge_v: [0.2, 0, 0], "
            "power: [5, 5, 5]}]")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: m.obj}\n" + CAMERA + quad + "\n")
    scene = api.load_scene(tmp_path / "s.yaml")  # (cross(edge_u, edge_v) = +y: into the ceiling)
    (line,) = checks.light_warnings(scene, build_accel(scene.triangles))
    assert "swap edge_u and edge_v" in line, line
    for name in ("cornell-box", "cornell", "cornell-sphere", "cornell-water", "ring", "room"):
        s = api.load_scene(REPO / "scenes" / f"{name}.yaml")
        accel = build_accel(s.triangles)
        assert all(checks.blocked_share(s, accel, lt)[0] == 0.0 for lt in s.lights), name
