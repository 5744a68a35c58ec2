"""Review of the published scenes (551231d), mended (h251): a mesh given as a symbolic link to a
published mesh has that mesh's notice in an export (a LICENSE beside the link or not); an MTL's
OBJ is found where its ``mtllib`` writes ``./NAME.mtl``; an MTL named under a scene file's
``extends`` is hinted at with the OBJ beside it, found from the scene file's folder (not the
working folder), as the scene names it; a statement given three times in one MTL material is
one note naming the line used (not two, the first of which called its second line "the last")."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tlm.errors import InputError
from tlm.mesh_files import mtl_user
from tlm.scenes import export
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import parse_mtl

MESHES = Path(__file__).resolve().parents[1] / "scenes" / "meshes"
CAMERA = "camera: {eye: [0, 1, 3.9], target: [0, 1, 0], vfov: 39}\nresolution: [8, 8]\n"


def test_a_symbolic_link_to_a_published_mesh_carries_its_notice(tmp_path, capsys):
    published, mine = tmp_path / "meshes", tmp_path / "mine"
    published.mkdir()
    mine.mkdir()
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl", "COPYRIGHT-cornellbox.txt"):
        shutil.copy(MESHES / name, published / name)
    try:
        (mine / "box.obj").symlink_to(published / "CornellBox-Original.obj")
    except OSError:  # (a file system without symbolic links)
        pytest.skip("no symbolic links here")
    (mine / "CornellBox-Original.mtl").symlink_to(published / "CornellBox-Original.mtl")
    assert export.notice_files(mine / "box.obj") == [published / "COPYRIGHT-cornellbox.txt"]
    (mine / "box.yaml").write_text(f"geometry: {{mesh: box.obj}}\n{CAMERA}")
    export.export_triangles(load_scene(str(mine / "box.yaml")), tmp_path / "out.obj")
    lines = (tmp_path / "out.obj").read_text().splitlines()
    assert "# Notice of the mesh box.obj (its COPYRIGHT-cornellbox.txt), to keep with every copy:" in lines
    assert "licence notice" not in capsys.readouterr().err
    (mine / "LICENSE").write_text("my own scenes' licence\n")  # (the link's folder's notice: not instead of the mesh's)
    assert export.notice_files(mine / "box.obj") == [mine / "LICENSE", published / "COPYRIGHT-cornellbox.txt"]
    export.export_triangles(load_scene(str(mine / "box.yaml")), tmp_path / "out.obj")
    text = (tmp_path / "out.obj").read_text()
    assert "my own scenes' licence" in text and "Attribution 3.0 Unported (CC BY 3.0)" in text


@pytest.mark.parametrize("written", ["./box.mtl", ".\\box.mtl", "sub/../box.mtl"])
def test_an_mtl_is_found_from_an_mtllib_written_with_a_dot(tmp_path, written):
    (tmp_path / "box.mtl").write_text("newmtl a\nKd 1 0 0\n")
    (tmp_path / "scene.obj").write_text(f"mtllib {written}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n")
    assert mtl_user(tmp_path / "box.mtl") == "scene.obj"
    (tmp_path / "other.obj").write_text("mtllib ../elsewhere/box.mtl\nv 0 0 0\n")  # (another folder's: not it)
    assert mtl_user(tmp_path / "box.mtl") == "scene.obj"


def test_an_mtl_extended_by_a_scene_is_hinted_with_the_obj_beside_it(tmp_path, monkeypatch):
    (tmp_path / "cb" / "sc").mkdir(parents=True)
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl"):
        shutil.copy(MESHES / name, tmp_path / "cb" / name)
    scene = tmp_path / "cb" / "sc" / "s.yaml"
    scene.write_text("extends: ../CornellBox-Original.mtl\n")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # (the working folder is not the scene file's)
    with pytest.raises(InputError) as e:
        load_scene(str(scene))
    message = str(e.value)
    assert "names it: CornellBox-Original.obj, beside it)" in message, message
    assert "`geometry: {mesh: ../CornellBox-Original.obj}`" in message and "THE.obj" not in message


def test_a_statement_given_three_times_is_one_note_naming_the_line_used():
    notes: list[str] = []
    (red,) = parse_mtl("newmtl red\nKd 1 0 0\nKd 0 1 0\nKa 0 0 0\nKd 0 0 1\nKa 0 0 0\n", "t.mtl", notes)
    assert red.albedo == (0.0, 0.0, 1.0)
    assert notes == ["t.mtl: line 5: material 'red': Kd given 3 times, line 2 `Kd 1 0 0`, line 3 `Kd 0 1 0` and "
                     "line 5 `Kd 0 0 1`: the last is used, as OBJ readers (trimesh, tinyobjloader) take it (another "
                     "value: a scene file's `materials: {red: ...}` entry, the MTL file left as it is)"]
    # (Ka given twice alike: not noted)
