"""tlm run on a scene file (tlm/cli.py, /tmp/h210/cli.patch): --set of a scene-file key says where
it goes; --set scene=... says what is rendered."""

from __future__ import annotations

from pathlib import Path

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]


def test_set_of_a_scene_file_key_on_a_scene_file_says_where_it_goes(tmp_path, capsys):
    scene = tmp_path / "cb.yaml"
    scene.write_text((REPO / "scenes" / "cornell.yaml").read_text())
    assert main(["run", str(scene), "--set", "camera.vfov=50", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "with --set: camera: unknown key (camera is a key of the scene file, not a run setting that --set " \
           f"takes: edit {scene}'s camera:, or write a scene file with `extends: {scene}`" in line, line
    assert not (tmp_path / "o").exists()


def test_the_hint_gives_a_path_that_extends_reads_from_the_new_files_folder(tmp_path, capsys, monkeypatch):
    """(h219, 9) ``tlm run big/big.yaml --set camera.vfov=50`` suggested ``extends: big/big.yaml``, which a new
    file elsewhere reads from its own folder: the absolute path."""
    (tmp_path / "big").mkdir()
    (tmp_path / "big" / "big.yaml").write_text((REPO / "scenes" / "cornell.yaml").read_text())
    monkeypatch.chdir(tmp_path)
    assert main(["run", "big/big.yaml", "--set", "camera.vfov=50", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"edit big/big.yaml's camera:, or write a scene file with `extends: {tmp_path / 'big' / 'big.yaml'}` " \
           "(extends: is read from the new file's folder)" in line, line


def test_set_scene_on_a_scene_file_names_what_is_rendered(tmp_path, capsys):
    scene = tmp_path / "cb.yaml"
    scene.write_text((REPO / "scenes" / "cornell.yaml").read_text())
    assert main(["run", str(scene), "--set", "scene=cornell-box", "--mode", "rcast", "--set", "resolution=[8, 8]",
                 "--out", str(tmp_path / "o"), "--no-report", "--no-reference"]) == 0
    out = capsys.readouterr().out
    assert f"{scene} is a scene file, but --set scene=cornell-box replaces it: rendering cornell-box" in out, out
    assert "rendering it with the default settings" not in out
