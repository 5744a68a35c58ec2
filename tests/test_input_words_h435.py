"""h435 (probe h409's leftovers): input said in one go.

1. ``--set scene=NAME`` (or ``scene: NAME`` in a config) names a built-in scene, which is taken, while a
   scene file ``NAME.yaml`` is in the working folder or beside the config: one warning line names both and
   how to give the file (``scene=./NAME.yaml``); before, the built-in was taken unsaid. A run config of
   that name (``configs/room.yaml`` beside ``configs/cornell.yaml``) is no scene file: nothing said.
2. ``tlm granularity`` with ``packet_sizes: [4, 4.0]`` said the float first and, once that was fixed,
   ``4 given twice``: now both in the one line.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.config_paths import builtin_scenes_dir

RUN = "mode: rcast\nresolution: [4, 4]\n"
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [4, 4]}


def _scene_file(path: Path) -> Path:
    """A scene file of the user's own, not the built-in scene ``cornell`` (another scene's copy)."""
    shutil.copy(builtin_scenes_dir() / "ring.yaml", path)
    return path


def _run(args: list[str], capsys) -> tuple[list[str], dict]:
    out = Path(args[args.index("--out") + 1])
    assert main(["run", *args, "--no-report"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if line.startswith("tlm: warning:")]
    return warned, json.loads((out / "results.json").read_text())


def test_set_scene_of_a_builtin_name_with_a_scene_file_of_it_here_is_warned_of(tmp_path, elsewhere, cache, capsys):
    _scene_file(elsewhere / "cornell.yaml")
    config = tmp_path / "cfg" / "run.yaml"
    config.parent.mkdir()
    config.write_text("scene: ring\n" + RUN)
    warned, results = _run([str(config), "--set", "scene=cornell", "--out", str(tmp_path / "o")], capsys)
    assert [w for w in warned if "cornell.yaml" in w] == [
        "tlm: warning: scene 'cornell' is the built-in scene of that name, not the file cornell.yaml: "
        "to run the file, give it as a path, scene=./cornell.yaml"]
    # (which one is taken is not changed: the built-in scene)
    assert Path(results["scene"]["source"]).resolve() == (builtin_scenes_dir() / "cornell.yaml").resolve()


def test_a_configs_scene_of_a_builtin_name_with_a_scene_file_beside_it_is_warned_of(tmp_path, elsewhere, cache,
                                                                                      capsys):
    folder = elsewhere / "cfg"
    folder.mkdir()
    _scene_file(folder / "cornell.yml")
    (folder / "run.yaml").write_text("scene: cornell\n" + RUN)
    warned, results = _run(["cfg/run.yaml", "--out", str(tmp_path / "o")], capsys)
    assert [w for w in warned if "cornell.yml" in w] == [
        "tlm: warning: scene 'cornell' is the built-in scene of that name, not the file cfg/cornell.yml: "
        "to run the file, give it as a path, scene=./cornell.yml"]
    assert Path(results["scene"]["source"]).resolve() == (builtin_scenes_dir() / "cornell.yaml").resolve()


def test_the_way_the_warning_names_takes_the_file_unsaid(tmp_path, elsewhere, cache, capsys):
    mine = _scene_file(elsewhere / "cornell.yaml")
    config = tmp_path / "run.yaml"
    config.write_text(RUN)
    warned, results = _run([str(config), "--set", "scene=./cornell.yaml", "--out", str(tmp_path / "o")], capsys)
    assert not [w for w in warned if "built-in scene" in w]
    assert Path(results["scene"]["source"]).resolve() == mine.resolve()


def test_a_run_config_named_as_the_builtin_scene_beside_the_config_is_no_scene_file(tmp_path, elsewhere, cache,
                                                                                     capsys):
    # (configs/cornell.yaml --set scene=room: configs/room.yaml runs the built-in room, no scene of its own;
    # a guard: the old code said nothing either)
    folder = elsewhere / "configs"
    folder.mkdir()
    (folder / "cornell.yaml").write_text("scene: cornell\n" + RUN)
    (folder / "run.yaml").write_text("scene: ring\n" + RUN)
    warned, _ = _run(["configs/run.yaml", "--set", "scene=cornell", "--out", str(tmp_path / "o")], capsys)
    assert not [w for w in warned if "built-in scene" in w]


def _refused(tmp_path: Path, sizes: str, capsys) -> str:
    study = tmp_path / "g.yaml"
    study.write_text(f"base: {json.dumps(BASE)}\npacket_sizes: {sizes}\n")
    out = tmp_path / "o"
    assert main(["granularity", str(study), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert not out.exists()
    assert err[0].startswith(f"tlm: error: {study}: packet_sizes: {sizes} must be a non-empty list of whole numbers")
    return err[0]


def test_a_packet_size_as_a_float_and_given_twice_is_said_in_one_line(tmp_path, capsys):
    said = _refused(tmp_path, "[4, 4.0]", capsys)
    assert said.endswith(": 4.0 reads as a float (a number written with an exponent or a decimal point); write 4; "
                         "and 4 is given twice (as 4 and 4.0): list it once")


@pytest.mark.parametrize("sizes, twice", [("[4.0, 4.0]", "4 is given twice"), ("[4, 4, 0]", "4 is given twice"),
                                          ("[16, 2.5, 16.0]", "16 is given twice (as 16 and 16.0)")])
def test_a_packet_size_given_twice_is_said_with_the_lists_other_error(tmp_path, capsys, sizes, twice):
    assert _refused(tmp_path, sizes, capsys).endswith(f"; and {twice}: list it once")


def test_a_list_without_a_number_given_twice_says_nothing_of_it(tmp_path, capsys):
    assert "twice" not in _refused(tmp_path, "[4, '4', 8.0]", capsys)
