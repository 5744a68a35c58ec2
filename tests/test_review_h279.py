"""Review of da48cd3 (h279): a scene's notes name its files as an error line does (``\\t`` for a tab,
tlm.errors.path_shown), so the frame fingerprint (tlm.experiments.frames.scene_fingerprint) leaves the
scene's folder out of them as a note shows it, and a cached frame's warnings are moved to the folder of
the copy that reads it (frames._here) in that form too: a copy of a scene in another folder with a tab
in its name shares the frame again, its warnings naming its own files. A mesh file given where a scene
goes and not found names the folders looked in as a path is shown (``\\t``, not a space), asks about a
built-in scene's name (``cornell.obj``: ``cornell``), and one that the built-in scenes hold
(``meshes/CornellBox-Original.obj``) is not said not found (tlm.scenes.loader.resolve_scene_path)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.experiments.frames import scene_fingerprint
from tlm.scenes.loader import load_scene

TAB = "t\tab"  # (a folder's name with a tab in it)


def _scene(folder: Path) -> Path:
    """A scene file with a mesh file beside it, and a material no triangle uses (a note naming the file)."""
    folder.mkdir(parents=True)
    (folder / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (folder / "s.yaml").write_text(yaml.safe_dump({
        "geometry": {"mesh": "m.obj"}, "default_material": "m",
        "materials": {"m": {"type": "lambertian", "albedo": [0.5] * 3},
                      "spare": {"type": "lambertian", "albedo": [0.1] * 3}},
        "lights": [{"type": "point", "position": [0.0, 0.0, 10.0], "power": [100.0] * 3}],
        "camera": {"eye": [0.3, 0.3, 5.0], "target": [0.3, 0.3, 0.0], "vfov": 40.0}, "resolution": [4, 4]}))
    return folder / "s.yaml"


def test_a_copy_of_a_scene_in_another_folder_has_the_same_fingerprint(tmp_path, cache):
    """da48cd3 escaped the notes (``t\\tab``) and left the folder out of them as given (``t<TAB>ab``): a
    copy in another folder with a tab in its name had another fingerprint, its frames not shared (a
    backslash, which a note shows as it is, too)."""
    for name in (TAB, "back\\slash"):
        a, b = load_scene(str(_scene(tmp_path / "A" / name))), load_scene(str(_scene(tmp_path / "B" / name)))
        assert any("materials.spare" in n for n in a.extra["notes"]), a.extra["notes"]
        assert scene_fingerprint(a) == scene_fingerprint(b), name


def test_a_sweep_of_a_copy_in_a_folder_with_a_tab_reads_the_frame_and_names_its_own_files(tmp_path, cache,
                                                                                           monkeypatch):
    """The sweep of the copy renders nothing (one frame in the cache) and its point's warning names
    the copy's scene file (``t\\tab/B/s.yaml``), not the first folder's."""
    for folder in ("A", "B"):
        _scene(tmp_path / TAB / folder)
        (tmp_path / TAB / folder / "w.yaml").write_text(yaml.safe_dump({
            "base": {"scene": "s.yaml", "mode": "rcast"}, "grid": {"arch.packet_size": [16]}}))
        monkeypatch.chdir(tmp_path / TAB / folder)
        assert main(["sweep", "w.yaml", "--out", "o", "--no-progress", "--no-report"]) == 0
        assert len(list(cache.rglob("*.npz"))) == 1, folder
    (results,) = (tmp_path / TAB / "B" / "o").rglob("results.json")
    (line,) = [w for w in json.loads(results.read_text())["warnings"] if "materials.spare" in w]
    assert line.startswith(f"{tmp_path}/t\\tab/B/s.yaml: materials.spare: used by no triangle"), line


@pytest.mark.parametrize("name", ["nope.obj", "nope.yaml"])
def test_the_folders_looked_in_show_a_tab_as_backslash_t(tmp_path, monkeypatch, capsys, name):
    """They showed ``t ab`` (the warning line made the tab a space), as the scene's name does not."""
    (tmp_path / TAB).mkdir()
    monkeypatch.chdir(tmp_path / TAB)
    assert main(["scene", "show", name]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert f"not found (looked in {tmp_path}/t\\tab" in line, line


@pytest.mark.parametrize("name", ["cornell.obj", "cornel.obj.gz"])
def test_a_built_in_scenes_name_with_a_mesh_suffix_is_asked_about(tmp_path, monkeypatch, capsys, name):
    monkeypatch.chdir(tmp_path)
    assert main(["scene", "show", name]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"tlm: error: {name}: file not found (looked in {tmp_path}); by its name an OBJ mesh"), line
    assert line.endswith("(did you mean 'cornell'?)"), line


def test_a_mesh_file_of_the_built_in_scenes_is_not_said_not_found(tmp_path, monkeypatch, capsys):
    """``meshes/CornellBox-Original.obj`` (as the built-in scene cornell-box names it) is there, among
    the built-in scenes: what it is, as before da48cd3, which said "file not found"."""
    monkeypatch.chdir(tmp_path)
    assert main(["scene", "show", "meshes/CornellBox-Original.obj"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "not found" not in line
    assert line.startswith("tlm: error: meshes/CornellBox-Original.obj: is an OBJ mesh file, not a scene"), line


def test_a_scene_copied_whole_shares_its_mesh_files_note_too(tmp_path, cache):
    """The mesh file's own note (a glTF's posed skin names its file) is left out with the folder too."""
    from tests.test_newcomer_h276 import _posed
    from tests.test_newcomer_h276 import _scene as _scene_of

    scenes = []
    for folder in ("A", "B"):
        (tmp_path / folder / TAB).mkdir(parents=True)
        _posed(tmp_path / folder / TAB / "m")
        scenes.append(load_scene(str(_scene_of(tmp_path / folder / TAB, "m/g.gltf"))))
    assert any("is posed" in n for n in scenes[0].extra["notes"]), scenes[0].extra["notes"]
    assert scene_fingerprint(scenes[0]) == scene_fingerprint(scenes[1])
