"""The published scenes' materials and licences (h249): a statement given twice in one MTL
material is noted (the last is used, as OBJ readers take it: the conference room's table); an
export of a scene whose mesh's notice is McGuire's ``copyright.txt`` (or a LICENSE) carries it,
and one of a mesh with none says so; the conference room's licence wording is what its files
say; the wheel carries the meshes' notices; an MTL given where a scene goes gets the hint an
OBJ gets; a ``parts:`` entry naming a material says so; docs/usage.md's MTL summary is the
code's; a mesh path is named without its ``..``."""

from __future__ import annotations

import glob
import os
import re
import shutil
import tomllib
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.mesh_files import mesh_file_format
from tlm.scenes import export
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import GLASS_ILLUM, MIRROR_ILLUM, parse_mtl

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "scenes" / "meshes"
MTL_FORMAT = "a Wavefront MTL material library"
CAMERA = "camera: {eye: [0, 1, 3.9], target: [0, 1, 0], vfov: 39}\nresolution: [8, 8]\n"


def _box(folder: Path, notice: str | None = None) -> Path:
    """A copy of CornellBox-Original (OBJ and MTL) in ``folder``, with the Cornell boxes' notice
    as ``notice`` beside it (none: no notice file), and a scene file of it in ``folder``/sc."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl"):
        shutil.copy(MESHES / name, folder / name)
    if notice is not None:
        shutil.copy(MESHES / "COPYRIGHT-cornellbox.txt", folder / notice)
    (folder / "sc").mkdir(exist_ok=True)
    scene = folder / "sc" / "box.yaml"
    scene.write_text(f"geometry: {{mesh: ../CornellBox-Original.obj}}\n{CAMERA}")
    return scene


# ---------------------------------------------------------------- 1. a key given twice in one MTL material


def test_a_statement_given_twice_in_a_material_is_the_last_and_noted():
    notes: list[str] = []
    (wood, same) = parse_mtl("newmtl wood\nKd 0.286 0.149 0.129\nKs 0.2\nKd 1 1 1\nnewmtl same\nNi 1.5\nNi 1.5\n",
                             "t.mtl", notes)
    assert wood.albedo == (1.0, 1.0, 1.0) and same.kind == "lambertian"  # (last-wins, as trimesh reads it)
    assert notes == ["t.mtl: line 4: material 'wood': Kd given twice, line 2 `Kd 0.286 0.149 0.129` and line 4 "
                     "`Kd 1 1 1`: the last is used, as OBJ readers (trimesh, tinyobjloader) take it (another value: "
                     "a scene file's `materials: {wood: ...}` entry, the MTL file left as it is)"]


def test_the_conference_table_s_two_kd_are_noted_with_the_one_used():
    mtl = MESHES / "conference.mtl"
    notes: list[str] = []
    table = {m.name: m for m in parse_mtl(mtl.read_text(), str(mtl), notes)}["mesh29_SG"]
    assert table.albedo == (1.0, 1.0, 1.0)
    (note,) = [n for n in notes if "mesh29_SG" in n]
    assert note.startswith(f"{mtl}: line 315: material 'mesh29_SG': Kd given twice, line 314 `Kd 0.286275 0.149020 "
                           "0.129412` and line 315 `Kd 1 1 1`: the last is used")
    for text in ((REPO / "scenes" / "conference.yaml").read_text(), (MESHES / "README.md").read_text()):
        flat = " ".join(text.replace("#", " ").split())
        assert "mesh29_SG" in flat and "0.286275 0.149020 0.129412" in flat and "the last" in flat


def test_scene_show_lists_the_note_of_a_key_given_twice(tmp_path, capsys):
    (tmp_path / "t.obj").write_text("mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 1\nusemtl wood\nf 1 2 3\n")
    (tmp_path / "t.mtl").write_text("newmtl wood\nKd 0.286 0.149 0.129\nKd 1 1 1\n")
    (tmp_path / "t.yaml").write_text("geometry: {mesh: t.obj}\nlights: [{type: point, position: [0.3, 1, 0.3], "
                                     "power: [10, 10, 10]}]\n" + CAMERA)
    assert main(["scene", "show", str(tmp_path / "t.yaml")]) == 0
    out = capsys.readouterr().out
    assert f"{tmp_path / 't.mtl'}: line 3: material 'wood': Kd given twice, line 2 `Kd 0.286 0.149 0.129`" in out


# ---------------------------------------------------------------- 2. the export's notices


@pytest.mark.parametrize("notice", ["copyright.txt", "COPYRIGHT", "LICENSE", "licence.md"])
def test_an_export_carries_the_notice_beside_the_mesh_as_published(tmp_path, capsys, notice):
    scene = load_scene(str(_box(tmp_path / "cb", notice)))
    export.export_triangles(scene, tmp_path / "out.obj")
    lines = (tmp_path / "out.obj").read_text().splitlines()
    assert f"# Notice of the mesh CornellBox-Original.obj (its {notice}), to keep with every copy:" in lines
    assert "#   Attribution 3.0 Unported (CC BY 3.0) License" in lines
    assert "licence notice" not in capsys.readouterr().err


def test_a_notice_naming_another_mesh_is_not_this_one_s(tmp_path, capsys):
    """``COPYRIGHT-conference.txt`` beside a Cornell box is the conference room's: not the box's."""
    path = _box(tmp_path / "cb")
    (tmp_path / "cb" / "conference.obj").write_text("v 0 0 0\n")
    (tmp_path / "cb" / "COPYRIGHT-conference.txt").write_text("the room's notice\n")
    assert export.notice_files(tmp_path / "cb" / "CornellBox-Original.obj") == []
    export.export_triangles(load_scene(str(path)), tmp_path / "out.obj")
    assert "the room's notice" not in (tmp_path / "out.obj").read_text()
    err = capsys.readouterr().err
    assert err == (f"tlm: warning: {tmp_path / 'out.obj'}: the export carries no licence notice for the mesh "
                   f"{tmp_path / 'cb' / 'CornellBox-Original.obj'}: there is no notice file of it beside it "
                   "(COPYRIGHT*, LICENSE*, LICENCE*) and none in its header; if its licence asks for one with every "
                   "copy, add it beside the exported files\n")


def test_an_export_of_a_mesh_with_no_notice_says_so_in_one_line(tmp_path, capsys):
    path = _box(tmp_path / "cb")
    assert main(["scene", "export", str(path), str(tmp_path / "out.yaml")]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(err) == 1 and err[0].startswith("tlm: warning: ") and "carries no licence notice" in err[0]
    assert f"{tmp_path / 'cb' / 'CornellBox-Original.obj'}:" in err[0] and "/../" not in err[0]
    assert (tmp_path / "out.yaml").is_file()  # (written all the same)


# ---------------------------------------------------------------- 3. the conference room's licence wording


def test_the_conference_room_s_licence_is_what_its_files_say():
    notice = (MESHES / "COPYRIGHT-conference.txt").read_text()
    assert "licen" not in notice.lower()  # (it states none: only the wood texture's image is public domain)
    row = next(line for line in (MESHES / "README.md").read_text().splitlines()
               if line.startswith("| `conference.obj.xz`"))
    cell = row.rstrip(" |").rsplit("|", 1)[1]
    assert "no licence in the shipped files" in cell and "archive's listing" in cell
    ladder = next(line for line in (REPO / "README.md").read_text().splitlines() if line.startswith("| `conference`"))
    assert "Public Domain)" not in ladder and "no licence in its shipped notice" in ladder
    conf = (REPO / "scenes" / "conference.yaml").read_text()
    assert "(Public Domain;" not in conf and "states no" in conf


# ---------------------------------------------------------------- 4. the wheel's licence files


def test_the_wheel_s_licence_files_take_in_the_shipped_meshes_notices():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    named = {os.path.relpath(f, REPO) for pattern in project["license-files"]
             for f in glob.glob(str(REPO / pattern))}
    notices = {os.path.relpath(f, REPO) for f in MESHES.glob("COPYRIGHT*")}
    assert notices and notices <= named and "LICENSE" in named


# ---------------------------------------------------------------- 5. an MTL given where a scene goes


def test_an_mtl_given_as_a_scene_is_said_to_be_one_with_its_obj(tmp_path, capsys):
    shutil.copy(MESHES / "CornellBox-Original.mtl", tmp_path / "box.mtl")
    shutil.copy(MESHES / "CornellBox-Original.obj", tmp_path / "box.obj")
    mtl = str(tmp_path / "box.mtl")
    assert mesh_file_format(mtl) == MTL_FORMAT
    for command in (["scene", "show", mtl], ["run", mtl]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"tlm: error: {mtl}: is {MTL_FORMAT} (the materials of an OBJ mesh"), err
        assert "`geometry: {mesh: box.obj}`" in err and "YAML syntax" not in err
    (tmp_path / "lib.yaml").write_text((MESHES / "CornellBox-Original.mtl").read_text())  # (by its content)
    with pytest.raises(InputError, match=r"is a Wavefront MTL material library .*not a YAML file"):
        load_scene(str(tmp_path / "lib.yaml"))


def test_an_mtl_named_by_an_obj_of_another_name_is_found_by_its_mtllib(tmp_path):
    from tlm.mesh_files import mtl_user

    shutil.copy(MESHES / "CornellBox-Original.mtl", tmp_path / "CornellBox-Original.mtl")
    shutil.copy(MESHES / "CornellBox-Original.obj", tmp_path / "box.obj")
    assert mtl_user(tmp_path / "CornellBox-Original.mtl") == "box.obj"
    (tmp_path / "other.mtl").write_text("newmtl x\nKd 1 1 1\n")
    assert mtl_user(tmp_path / "other.mtl") is None


# ---------------------------------------------------------------- 6. parts: naming a material


def test_a_part_that_is_a_material_of_the_mesh_says_to_replace_it_under_materials(tmp_path):
    (tmp_path / "s.yaml").write_text("extends: cornell-box\nmaterials: {chrome: {type: mirror, reflectance: [1, 1, 1]}}"
                                     "\nparts: {tallBox: chrome}\n")
    with pytest.raises(InputError) as e:
        load_scene(str(tmp_path / "s.yaml"))
    assert str(e.value).endswith("; 'tallBox' is a material of the mesh file, not a part: to change the triangles "
                                 "that take it, replace it under materials: (`materials: {tallBox: ...}` with the "
                                 "fields of 'chrome')")
    (tmp_path / "t.yaml").write_text("extends: cornell-box\nparts: {tallbox: grey}\n")  # (no material: as before)
    with pytest.raises(InputError, match=r"no part 'tallbox' \(parts: [^)]*\)$"):
        load_scene(str(tmp_path / "t.yaml"))


# ---------------------------------------------------------------- 7. docs/usage.md's MTL summary


def test_usage_md_s_mtl_summary_is_the_code_s():
    text = " ".join((REPO / "docs" / "usage.md").read_text().split())
    summary = text[text.index("**Materials from mesh files.**"):text.index("glTF: baseColor")]
    glass = re.search(r"`illum ([0-9/]+)` or `d` < 1 \(`Tr` > 0\) -> `dielectric`", summary)
    mirror = re.search(r"`illum ([0-9/]+)`, or no `illum` and a `Ks` whose largest component exceeds `Kd`'s -> "
                       r"`mirror`", summary)
    assert glass and mirror, summary
    assert tuple(map(int, glass.group(1).split("/"))) == GLASS_ILLUM
    assert tuple(map(int, mirror.group(1).split("/"))) == MIRROR_ILLUM


# ---------------------------------------------------------------- 8. a mesh path named without its ..


def test_a_mesh_s_path_is_named_without_its_dot_dot(tmp_path, capsys):
    (tmp_path / "cb").mkdir()
    (tmp_path / "cb" / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 1\nusemtl light\nf 1 2 3\n")
    (tmp_path / "cb" / "m.mtl").write_text("newmtl wall\nKd 1 1 1\n")
    (tmp_path / "sc").mkdir()
    (tmp_path / "sc" / "s.yaml").write_text("geometry: {mesh: ../cb/m.obj}\n" + CAMERA)
    assert main(["scene", "show", str(tmp_path / "sc" / "s.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"tlm: error: {tmp_path / 'cb' / 'm.obj'}: line 5: usemtl 'light': no material"), err


def test_a_shown_path_keeps_a_symbolic_link_s_name_and_a_dot_dot_after_one(tmp_path):
    from tlm.scenes.meshes import shown_path

    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "m.obj").write_text("v 0 0 0\n")
    (tmp_path / "link").symlink_to(tmp_path / "a")
    assert shown_path(tmp_path / "link" / "x" / ".." / "m.obj") == tmp_path / "link" / "x" / ".." / "m.obj"  # (none)
    assert shown_path(Path(f"{tmp_path}/link/./m.obj")) == tmp_path / "link" / "m.obj"  # (the link's name kept)
    (tmp_path / "deep").symlink_to(tmp_path / "a" / "b")
    given = tmp_path / "deep" / ".." / "m.obj"  # (deep/.. is a/, where m.obj is; normpath would say tmp/m.obj)
    assert given.is_file() and shown_path(given) == given
