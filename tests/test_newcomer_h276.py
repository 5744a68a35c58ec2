"""A newcomer's findings (h276): a path in a scene's notes shows a tab as ``\\t`` and an escape
sequence escaped, as an error line names a path (tlm.scenes.loader.load_scene: ``extra["notes"]``
through tlm.errors.path_shown), where a ``tlm: warning:`` line made the tab a space; the posed-skin
note says the mesh is posed and drawn unposed (tlm.scenes.gltf_imports.check_mesh_nodes); a mesh
file given where a scene goes that is not there is said not found first, what its name makes it
after (tlm.scenes.loader.resolve_scene_path, tlm.mesh_files.mesh_file_missing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import tlm
from tests.test_mesh_leftovers_h255 import _gltf
from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import load_scene
from tlm.scenes.meshes import load_mesh

ODD = "t\tab\x1b[31m"  # (a folder's name with a tab and an escape sequence in it)
SHOWN = "t\\tab\\x1b[31m"  # (as an error line names it)
POSED = [{"mesh": 0, "skin": 0}, {"translation": [0.0, 0.0, 5.0]}, {"translation": [0.0, 1.0, 0.0]}]


def _posed(folder: Path) -> Path:
    """A .gltf in ``folder`` whose one mesh's skin is posed (its two joints' matrices differ)."""
    return _gltf(folder, POSED, skins=[{"joints": [1, 2]}], matrices=[np.eye(4), np.eye(4)], roots=(0, 1, 2))


def _scene(folder: Path, mesh: str, **more) -> Path:
    (folder / "s.yaml").write_text(yaml.safe_dump({
        "geometry": {"mesh": mesh}, "default_material": "m",
        "materials": {"m": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}, **more},
        "lights": [{"type": "point", "position": [0.0, 0.0, 10.0], "power": [100.0, 100.0, 100.0]}],
        "camera": {"eye": [1.0, 0.5, 20.0], "target": [1.0, 0.5, 0.0], "vfov": 40.0}, "resolution": [4, 4]}))
    return folder / "s.yaml"


# ------------------------------------------------------------------ the posed-skin note


def test_the_posed_skin_note_says_the_mesh_is_posed_and_drawn_unposed(tmp_path, cache):
    """HEAD said the mesh "is not posed" (it is: its joints' matrices differ; tlm does not apply the pose)."""
    (note,) = [n for n in load_mesh(_posed(tmp_path / "g")).notes if "skinned" in n]
    assert note.endswith("g.gltf: its skinned mesh nodes[0] (skins[0]) is posed (the joints' matrices differ), drawn "
                         "unposed: tlm does not apply a skin's pose (it does not blend the joints by their weights); "
                         "placed by the node's world transform"), note
    assert "not posed" not in note


# ------------------------------------------------------------------ a tab in a note's path


def test_a_scenes_notes_show_a_tab_and_an_escape_in_a_path_as_an_error_line_does(tmp_path, cache):
    """The mesh file's note (the posed skin) and the scene file's own (an unused material) name
    their file with its control characters escaped: ``t\\tab\\x1b[31m``, not a tab (which a warning
    line made a space) or the escape sequence itself."""
    folder = tmp_path / ODD
    folder.mkdir()
    _posed(folder / "m")
    scene = _scene(folder, "m/g.gltf", spare={"type": "lambertian", "albedo": [0.1, 0.1, 0.1]})
    notes = load_scene(str(scene)).extra["notes"]
    shown = str(tmp_path).replace("\t", "\\t") + "/" + SHOWN
    assert any(n.startswith(f"{shown}/m/g.gltf: its skinned mesh nodes[0] (skins[0]) is posed") for n in notes), notes
    assert any(n.startswith(f"{shown}/s.yaml: materials.spare: used by no triangle") for n in notes), notes
    assert not any("\t" in n or "\x1b" in n for n in notes), notes


def test_a_runs_warning_line_shows_the_tab_of_a_mesh_files_folder(tmp_path, cache, monkeypatch, capsys):
    """The probe's case: ``tlm run`` of a scene whose mesh lies in ``t<TAB>ab<ESC>[31m/``: its
    warning line said ``t ab\\x1b[31m`` (the tab a space), as docs/usage.md says it does not."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / ODD
    folder.mkdir()
    _posed(folder)
    _scene(tmp_path, f"{ODD}/g.gltf")
    assert main(["run", "s.yaml", "--out", "r", "--no-report", "--no-progress", "--outputs", "images"]) == 0
    warnings = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("tlm: warning: ")]
    (line,) = [ln for ln in warnings if "skinned mesh" in ln]
    assert f"/{SHOWN}/g.gltf: its skinned mesh nodes[0] (skins[0]) is posed" in line, line
    assert "t ab" not in line


# ------------------------------------------------------------------ a mesh file that is not there


@pytest.mark.parametrize("name", ["pawn.glb", "sub/pawn.obj.gz"])
def test_a_mesh_file_given_as_the_scene_that_is_not_there_is_said_not_found_first(tmp_path, monkeypatch, capsys,
                                                                                  name):
    """``tlm scene show pawn.glb`` of no such file said it "is a binary glTF (.glb) mesh file, not a
    scene: write ...", where ``tlm scene show nosuch.yaml`` says not found."""
    monkeypatch.chdir(tmp_path)
    assert main(["scene", "show", name]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"tlm: error: {name}: file not found (looked in {tmp_path}); by its name "), line
    assert "mesh file, not a scene: a scene file names it under `geometry:`" in line
    with pytest.raises(InputError, match=rf"^{name}: file not found "):
        tlm.load_scene(name)
    (tmp_path / "sub").mkdir()
    (tmp_path / name).write_text("v 0 0 0\n")  # (there: the hint as before)
    assert main(["scene", "show", name]) == 2
    assert "not found" not in capsys.readouterr().err


def test_a_mesh_file_named_by_a_config_or_by_extends_and_not_there_is_said_not_found(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text("scene: pawn.obj\n")
    (tmp_path / "e.yaml").write_text("extends: pawn.glb\n")
    assert main(["run", "c.yaml", "--out", "o", "--no-report"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"tlm: error: c.yaml: scene: 'pawn.obj' not found (looked in {tmp_path}); by its name an "
                           "OBJ mesh file, not a scene"), line
    assert main(["scene", "show", "e.yaml"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert f"e.yaml: extends: 'pawn.glb' not found (looked in {tmp_path}); by its name a binary glTF" in line, line
    assert not (tmp_path / "o").exists()
    with pytest.raises(InputError, match=r"^/nowhere/x\.mtl: file not found; by its name a Wavefront MTL"):
        tlm.load_scene("/nowhere/x.mtl")
