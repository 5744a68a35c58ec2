"""h438, review of 72d4edc (h435): the warning of a bare built-in scene name with a scene file of that name at
hand says how to give the file (``scene=...``), and that path must name the file where the value is read.

A config's ``scene:`` is looked for in the config's folder first, then the working folder. In a checkout, the
config ``configs/cornell.yaml`` (``scene: cornell``) run from the root where the user keeps a scene file of their
own, ``cornell.yaml`` (``tlm scene export cornell cornell.yaml`` to edit it): the warning said
``scene=./cornell.yaml``, which in the config names ``configs/cornell.yaml``, the run config itself (``is a run
config ..., not a scene file``). It now says ``scene=../cornell.yaml``, which the config's folder leads to the file
from, as ``--set`` does too (not in the working folder: looked for beside the config)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from tlm import storage
from tlm.config import load_config
from tlm.config_paths import builtin_scenes_dir, scene_from


def _said(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if "is the built-in scene" in line]


def _suggested(line: str) -> str:
    m = re.search(r"give it as a path, scene=(\S+)$", line)
    assert m is not None, line
    return m[1]


def test_the_path_the_warning_gives_names_the_file_where_a_configs_folder_holds_a_run_config_of_its_name(
        elsewhere, monkeypatch, capsys):
    monkeypatch.setattr(storage, "SAID", set())
    mine = elsewhere / "cornell.yaml"
    shutil.copy(builtin_scenes_dir() / "ring.yaml", mine)  # (the user's own scene file, not the built-in cornell)
    configs = elsewhere / "configs"
    configs.mkdir()
    (configs / "cornell.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [4, 4]\n")
    assert scene_from("cornell", [configs]) == "cornell"  # (the built-in scene is taken, as before)
    [line] = _said(capsys)
    given = _suggested(line)
    assert given == "../cornell.yaml"
    # as the config's scene: it names the user's file, not configs/cornell.yaml (the config itself)
    assert Path(scene_from(given, [configs])).resolve() == mine.resolve()
    config = configs / "mine.yaml"
    config.write_text(f"scene: {given}\nmode: rcast\nresolution: [4, 4]\n")
    assert Path(load_config(config)[0].scene).resolve() == mine.resolve()
    # and as --set, from the working folder (looked for beside the config there)
    assert Path(load_config(configs / "cornell.yaml", [f"scene={given}"])[0].scene).resolve() == mine.resolve()
    assert not _said(capsys)


def test_a_file_with_no_other_of_its_name_before_it_is_still_given_as_dot_slash(elsewhere, monkeypatch, capsys):
    # (a guard: the cases h435 covers keep their words, ./NAME.yaml naming the file from either folder)
    monkeypatch.setattr(storage, "SAID", set())
    shutil.copy(builtin_scenes_dir() / "ring.yaml", elsewhere / "cornell.yaml")
    cfg = elsewhere / "cfg"
    cfg.mkdir()
    scene_from("cornell", [cfg])
    [line] = _said(capsys)
    assert _suggested(line) == "./cornell.yaml"
    assert Path(scene_from("./cornell.yaml", [cfg])).resolve() == (elsewhere / "cornell.yaml").resolve()


def test_the_path_the_warning_gives_names_the_file_as_set_where_the_working_folder_holds_a_run_config_of_its_name(
        elsewhere, monkeypatch, capsys):
    # (--set scene=cornell from a folder whose cornell.yaml is a run config, the scene file beside the config:
    # --set scene=./cornell.yaml is looked for in the working folder first, and names that run config)
    monkeypatch.setattr(storage, "SAID", set())
    (elsewhere / "cornell.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [4, 4]\n")
    cfg = elsewhere / "cfg"
    cfg.mkdir()
    mine = cfg / "cornell.yaml"
    shutil.copy(builtin_scenes_dir() / "ring.yaml", mine)
    config = cfg / "run.yaml"
    config.write_text("scene: ring\nmode: rcast\nresolution: [4, 4]\n")
    assert Path(load_config(config, ["scene=cornell"])[0].scene).name == "cornell"  # (the built-in, as before)
    [line] = _said(capsys)
    given = _suggested(line)
    assert given == "cfg/cornell.yaml"
    assert Path(load_config(config, [f"scene={given}"])[0].scene).resolve() == mine.resolve()
    config.write_text(f"scene: {given}\nmode: rcast\nresolution: [4, 4]\n")
    assert Path(load_config(config)[0].scene).resolve() == mine.resolve()
