"""A relative scene file means one file wherever the command runs: a ``scene`` that names a
file is made absolute where the config is read (relative to the file that gave it: a run
config, a sweep file, a base config; on the command line the working folder), so that a
run's or a sweep point's ``config.resolved.yaml`` runs again from any folder, and a remote
worker of another working folder reads the same file. A built-in scene's name stays a name.
A relative scene is looked for from the file that gave it first, the working folder last (a
project's config that names its scene from the project's root, run from there). A scene file
not found names the folders tried, in that order."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tlm.api import load_config
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.frames import render_key
from tlm.experiments.study import read_study, read_study_base
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import load_sweep
from tlm.scenes.loader import resolve_scene_path, scenes_dir

TINY = {"mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False}}
QUIET = ["--no-progress", "--no-report"]


def _box(path: Path, wall_div: int = 1) -> Path:
    """The built-in Cornell box as a scene file of the user's (``wall_div`` changes its mesh)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = (scenes_dir() / "cornell.yaml").read_text()
    assert "params: {}" in text
    path.write_text(text.replace("params: {}", f"params: {{wall_div: {wall_div}}}") if wall_div > 1 else text)
    return path


@pytest.fixture
def study(tmp_path, monkeypatch):
    """``s1/base.yaml`` (``scene: box.yaml``, beside it), ``s2/box2.yaml``, and a working folder
    ``work/`` that holds neither."""
    _box(tmp_path / "s1" / "box.yaml")
    _box(tmp_path / "s2" / "box2.yaml", wall_div=2)
    (tmp_path / "s1" / "base.yaml").write_text(yaml.safe_dump({"scene": "box.yaml", **TINY}))
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    return tmp_path


def _sweep(folder: Path, **body) -> Path:
    path = folder / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": "../s1/base.yaml", **body}, sort_keys=False))
    return path


def test_a_sweeps_scene_files_are_found_from_any_working_folder(study):
    """The grid's box2.yaml is beside the sweep file, box.yaml beside its base config; the
    working folder holds neither (it failed: ``scene file 'box2.yaml' not found``)."""
    sweep = load_sweep(_sweep(study / "s2", grid={"scene": ["box.yaml", "box2.yaml"]}))
    assert [p.config["scene"] for p in sweep.points] == [str(study / "s1" / "box.yaml"),
                                                         str(study / "s2" / "box2.yaml")]
    assert [p.factors for p in sweep.points] == [{"scene": "box.yaml"}, {"scene": "box2.yaml"}]  # (as written)
    assert sweep.points[0].hash != sweep.points[1].hash
    # the base's own scene, and a built-in name, which stays a name
    sweep = load_sweep(_sweep(study / "s2", grid={"seed": [0], "scene": ["cornell", "thesis/ring"]}))
    assert [p.config["scene"] for p in sweep.points] == ["cornell", "thesis/ring"]
    sweep = load_sweep(_sweep(study / "s2", grid={"seed": [0, 1]}))
    assert {p.config["scene"] for p in sweep.points} == {str(study / "s1" / "box.yaml")}


def test_a_scene_file_beside_the_sweep_file_wins_over_the_base_configs(study):
    """A scene the sweep file gives is the sweep file's first (as arch.programs is), then the
    base config's, then the working folder's, last."""
    _box(study / "s2" / "box.yaml", wall_div=3)
    _box(study / "work" / "box.yaml", wall_div=4)
    _box(study / "work" / "box2.yaml", wall_div=4)
    sweep = load_sweep(_sweep(study / "s2", set={"scene": "box.yaml"}, grid={"seed": [0]}))
    assert sweep.points[0].config["scene"] == str(study / "s2" / "box.yaml")
    (study / "s2" / "box.yaml").unlink()
    sweep = load_sweep(_sweep(study / "s2", set={"scene": "box.yaml"}, grid={"seed": [0]}))
    assert sweep.points[0].config["scene"] == str(study / "s1" / "box.yaml")
    (study / "s2" / "box2.yaml").unlink()
    sweep = load_sweep(_sweep(study / "s2", grid={"scene": ["box2.yaml"]}))
    assert sweep.points[0].config["scene"] == str(study / "work" / "box2.yaml")  # (absolute: for any worker)
    (study / "work" / "box2.yaml").unlink()
    with pytest.raises(InputError) as e:
        load_sweep(_sweep(study / "s2", grid={"scene": ["box2.yaml"]}))
    assert str(e.value) == (f"{study / 's2' / 'sw.yaml'} (point 0): scene: scene file 'box2.yaml' not found "
                            f"(looked in {study / 's2'}, {study / 's1'}, {study / 'work'} and among the built-in "
                            "scenes)")


def test_a_run_configs_missing_scene_names_the_folder_tried(study):
    (study / "s2" / "run.yaml").write_text(yaml.safe_dump({"scene": "nope.yaml"}))
    cfg = load_config(str(study / "s2" / "run.yaml"))
    with pytest.raises(InputError) as e:
        render_key(cfg.settings, cfg.base, cfg.source)
    assert str(e.value).endswith(f"scene file 'nope.yaml' not found (looked in {study / 's2'}, {study / 'work'} "
                                 "and among the built-in scenes)")


def test_the_loader_looks_in_the_files_folder_then_the_working_folder_then_the_built_ins(study):
    """A file's relative scene (or ``extends``) is relative to that file's folder first: a
    file of that name in the working folder is not taken instead; it is found there where the
    file's folder holds none, before the built-in scenes (a project's own ``ring.yaml`` is not
    replaced by the built-in ring, as before absolute paths)."""
    _box(study / "work" / "box2.yaml")
    assert resolve_scene_path("box2.yaml") == Path("box2.yaml")  # (no base: the working folder)
    assert resolve_scene_path("box2.yaml", study / "s2") == study / "s2" / "box2.yaml"  # (the file's folder wins)
    assert resolve_scene_path("box2.yaml", study / "s1") == study / "work" / "box2.yaml"  # (then the cwd)
    (study / "work" / "box2.yaml").unlink()
    with pytest.raises(InputError, match=r"scene file 'box2\.yaml' not found \(looked in .*s1, .*work and among "
                                         r"the built-in scenes\)"):
        resolve_scene_path("box2.yaml", study / "s1")
    assert resolve_scene_path("thesis/ring.yaml", study / "s1") == scenes_dir() / "thesis" / "ring.yaml"
    _box(study / "work" / "ring.yaml", wall_div=2)  # (the project's own ring.yaml wins over the built-in ring)
    assert resolve_scene_path("ring.yaml", study / "s1") == study / "work" / "ring.yaml"
    (study / "s1" / "mine.yaml").write_text(yaml.safe_dump({"scene": "ring.yaml", **TINY}))
    assert load_config(str(study / "s1" / "mine.yaml")).settings.scene == str(study / "work" / "ring.yaml")
    assert resolve_scene_path("thesis/ring", study / "s1") == scenes_dir() / "thesis" / "ring.yaml"  # (a name)
    assert load_config(str(study / "s1" / "base.yaml")).settings.scene == str(study / "s1" / "box.yaml")


def test_a_config_files_scene_is_absolute_and_the_command_lines_is_the_working_folders(study):
    cfg = load_config(str(study / "s1" / "base.yaml"))
    assert cfg.settings.scene == str(study / "s1" / "box.yaml")
    _box(study / "work" / "box.yaml", wall_div=2)
    assert load_config(str(study / "s1" / "base.yaml"), ["scene=box.yaml"]).settings.scene == str(
        study / "work" / "box.yaml")
    # a --set scene that is no file in the working folder is still looked for beside the config
    assert load_config(str(study / "s1" / "base.yaml"), ["scene=../s2/box2.yaml"]).settings.scene == str(
        study / "s2" / "box2.yaml")
    for name in ("cornell", "thesis/ring", "thesis/ring.yaml"):
        assert load_config(str(study / "s1" / "base.yaml"), [f"scene={name}"]).settings.scene == name


def test_two_box_yaml_of_other_folders_are_two_scenes(study):
    """Each config names its own folder's box.yaml: other strings, other frame keys."""
    _box(study / "a" / "box.yaml")
    _box(study / "b" / "box.yaml", wall_div=2)
    for name in ("a", "b"):
        (study / name / "run.yaml").write_text(yaml.safe_dump({"scene": "box.yaml", **TINY}))
    a, b = (load_config(str(study / name / "run.yaml")) for name in ("a", "b"))
    assert (a.settings.scene, b.settings.scene) == (str(study / "a" / "box.yaml"), str(study / "b" / "box.yaml"))
    assert render_key(a.settings, a.base) != render_key(b.settings, b.base)


def test_a_studys_base_scene_is_absolute(study):
    (study / "s2" / "g.yaml").write_text(yaml.safe_dump({"base": "../s1/base.yaml", "packet_sizes": [1]}))
    _, base, _, _ = read_study_base(study / "s2" / "g.yaml", ("packet_sizes",))
    assert base["scene"] == str(study / "s1" / "box.yaml")
    (study / "s2" / "e.yaml").write_text(yaml.safe_dump({"base": {"scene": "box2.yaml"}, "cases": []}))
    _, base, _ = read_study(study / "s2" / "e.yaml", ("cases",))
    assert base["scene"] == str(study / "s2" / "box2.yaml")


def test_a_runs_resolved_config_runs_again_from_another_folder(study, cache, monkeypatch):
    """``tlm run s1/base.yaml`` from s1, then its config.resolved.yaml from work/: the same
    scene file (it failed: ``scene file 'box.yaml' not found``)."""
    monkeypatch.chdir(study / "s1")
    assert main(["run", "base.yaml", "--out", str(study / "r1"), *QUIET]) == 0
    resolved = yaml.safe_load((study / "r1" / "config.resolved.yaml").read_text())
    assert resolved["scene"] == str(study / "s1" / "box.yaml")
    monkeypatch.chdir(study / "work")
    assert main(["run", str(study / "r1" / "config.resolved.yaml"), "--out", str(study / "r2"), *QUIET]) == 0
    assert yaml.safe_load((study / "r2" / "config.resolved.yaml").read_text())["scene"] == resolved["scene"]


def test_a_sweep_points_resolved_config_runs_again_from_another_folder(study, cache, monkeypatch):
    monkeypatch.chdir(study / "s2")
    run_sweep(_sweep(study / "s2", grid={"scene": ["box2.yaml"]}), study / "o", jobs=1)
    (point,) = (study / "o" / "points").iterdir()
    resolved = yaml.safe_load((point / "config.resolved.yaml").read_text())
    assert resolved["scene"] == str(study / "s2" / "box2.yaml")
    monkeypatch.chdir(study / "work")
    assert main(["run", str(point / "config.resolved.yaml"), "--out", str(study / "r"), *QUIET]) == 0


def test_a_mappings_scene_and_table_are_absolute_from_its_base(study):
    """A Python mapping (``tlm.load_config({...}, base=...)``) names its files from ``base`` as a
    file names them from its folder: absolute in the config, so its ``config.resolved.yaml`` runs
    again from anywhere."""
    (study / "s1" / "t.yaml").write_text((Path(__file__).parents[1] / "tlm" / "arch" / "programs.yaml").read_text())
    cfg = load_config({**TINY, "scene": "box.yaml", "arch": {**TINY.get("arch", {}), "programs": "t.yaml"}},
                      base=study / "s1")
    assert cfg.settings.scene == str(study / "s1" / "box.yaml")
    assert cfg.settings.arch.programs == str(study / "s1" / "t.yaml")
    assert load_config({"scene": "cornell", **TINY}).settings.scene == "cornell"  # (a built-in name stays a name)


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A project whose config names its scene from the project's root (``configs/x.yaml``:
    ``scene: myscenes/box.yaml``), a sweep whose base is that config, run from the root."""
    root = tmp_path / "proj"
    _box(root / "myscenes" / "box.yaml")
    (root / "configs").mkdir()
    (root / "configs" / "x.yaml").write_text(yaml.safe_dump({"scene": "myscenes/box.yaml", **TINY}))
    (root / "study").mkdir()
    (root / "study" / "sw.yaml").write_text(yaml.safe_dump({"base": "../configs/x.yaml",
                                                            "grid": {"arch.fifo_depth": [1, 2]}}))
    monkeypatch.chdir(root)
    return root


def test_a_scene_from_the_working_folder_is_found_last_and_made_absolute(project, cache):
    """``tlm run configs/x.yaml`` from the project's root, and a sweep of that base: the scene
    is the working folder's (nothing beside the config holds it), absolute in the config so that
    a worker and a rerun elsewhere read the same file (it failed: ``scene file
    'myscenes/box.yaml' not found (looked in .../configs ...)``)."""
    box = str(project / "myscenes" / "box.yaml")
    assert load_config("configs/x.yaml").settings.scene == box
    assert main(["run", "configs/x.yaml", "--out", str(project / "r1"), *QUIET]) == 0
    assert yaml.safe_load((project / "r1" / "config.resolved.yaml").read_text())["scene"] == box
    assert {p.config["scene"] for p in load_sweep(Path("study/sw.yaml")).points} == {box}
    # a file of that path beside the config wins over the working folder's
    _box(project / "configs" / "myscenes" / "box.yaml", wall_div=2)
    assert load_config("configs/x.yaml").settings.scene == str(project / "configs" / "myscenes" / "box.yaml")


def test_an_old_resolved_config_runs_again_from_the_folder_its_scene_was_relative_to(project, cache, monkeypatch):
    """A ``config.resolved.yaml`` of an older tlm holds the scene as its config wrote it
    (relative to the config's folder): run again from that folder, it finds the scene there."""
    old = project.parent / "runs" / "r3" / "config.resolved.yaml"  # (../myscenes/box.yaml is no file from there)
    old.parent.mkdir(parents=True)
    old.write_text(yaml.safe_dump({"scene": "../myscenes/box.yaml", **TINY}))
    monkeypatch.chdir(project / "configs")
    assert main(["run", str(old), "--out", str(project / "r2"), *QUIET]) == 0
    assert yaml.safe_load((project / "r2" / "config.resolved.yaml").read_text())["scene"] == str(
        project / "myscenes" / "box.yaml")
