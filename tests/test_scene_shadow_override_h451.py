"""h451: h435's warning of a built-in scene's bare name (``scene: cornell``) while a scene file ``cornell.yaml``
lies in the config's or the working folder is said only of the scene used, after every override.

Before, it was said of a config's (a sweep's base, a study's base, an API mapping's) scene that a ``--set
scene=...`` (or ``scene.file=...``), a sweep's ``set:``, ``--set`` or factor, or the API's overrides replace:
a warning about a scene that no run used. And a bare name that is no built-in scene (``scene: myroom``) while
a scene file ``myroom.yaml`` lies there: the error line now says how to give the file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tlm import storage
from tlm.cli import main
from tlm.config_paths import builtin_scenes_dir

RUN = "mode: rcast\nresolution: [4, 4]\n"
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [4, 4]}
SHADOWED = "scene 'cornell' is the built-in scene of that name"


@pytest.fixture(autouse=True)
def _fresh_said(monkeypatch):
    """Nothing said yet (an earlier test's warning would keep this one's unsaid: said once)."""
    monkeypatch.setattr(storage, "SAID", set())


def _scene_file(path: Path) -> Path:
    """A scene file of the user's own (another built-in scene's copy)."""
    shutil.copy(builtin_scenes_dir() / "ring.yaml", path)
    return path


@pytest.fixture
def here(elsewhere):
    """The working folder, with a scene file cornell.yaml (shadowed by the built-in cornell) and other.yaml."""
    _scene_file(elsewhere / "cornell.yaml")
    _scene_file(elsewhere / "other.yaml")
    return elsewhere


def _shadow_lines(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if SHADOWED in line]


@pytest.mark.parametrize("sets", [["scene=./other.yaml"], ["scene=ring"], ["scene=cornell", "scene=ring"]])
def test_a_set_scene_that_replaces_the_configs_is_not_warned_of(here, tmp_path, cache, capsys, sets):
    (here / "run.yaml").write_text("scene: cornell\n" + RUN)
    out = tmp_path / "o"
    args = [a for s in sets for a in ("--set", s)]
    assert main(["run", "run.yaml", *args, "--out", str(out), "--no-report"]) == 0
    assert _shadow_lines(capsys) == []
    source = Path(json.loads((out / "results.json").read_text())["scene"]["source"]).resolve()
    assert source == ((here / "other.yaml") if "other" in sets[-1] else builtin_scenes_dir() / "ring.yaml").resolve()


def test_a_set_scene_file_key_says_its_error_alone(here, capsys):
    (here / "run.yaml").write_text("scene: cornell\n" + RUN)
    assert main(["run", "run.yaml", "--set", "scene.file=./other.yaml", "--out", "o", "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: run.yaml, with --set: scene:"), err


@pytest.mark.parametrize("sweep, sets", [
    ("grid: {scene: [./other.yaml, ring]}\n", ()),
    ("set: {scene: ./other.yaml}\ngrid: {seed: [0, 1]}\n", ()),
    ("grid: {seed: [0, 1]}\n", ("scene=./other.yaml",)),
    ("set: {scene: cornell}\ngrid: {seed: [0, 1]}\n", ("scene=ring",)),
])
def test_a_sweeps_scene_replaced_by_its_set_a_factor_or_a_set_is_not_warned_of(here, capsys, sweep, sets):
    from tlm.experiments.sweep_file import load_sweep

    (here / "sw.yaml").write_text(f"base: {json.dumps(BASE)}\n{sweep}")
    load_sweep(here / "sw.yaml", sets)
    assert _shadow_lines(capsys) == []


def test_a_sweeps_factor_that_gives_the_name_is_warned_of_once(here, capsys):
    # (the base's ring is replaced; the factor's cornell is run: said once; before, ring.yaml here was said too)
    _scene_file(here / "ring.yaml")
    (here / "sw.yaml").write_text(f"base: {json.dumps({**BASE, 'scene': 'ring'})}\n"
                                  "grid: {scene: [./other.yaml, cornell]}\n")
    from tlm.experiments.sweep_file import load_sweep

    load_sweep(here / "sw.yaml")
    err = capsys.readouterr().err
    assert "scene 'ring'" not in err
    assert [line for line in err.splitlines() if SHADOWED in line] == [
        f"tlm: warning: {SHADOWED}, not the file cornell.yaml: to run the file, give it as a path, "
        "scene=./cornell.yaml"]


def _granularity(here: Path, sets: tuple[str, ...]):
    from tlm.experiments.granularity import load_granularity

    (here / "g.yaml").write_text(f"base: {json.dumps(BASE)}\npacket_sizes: [1, 4]\n")
    assert load_granularity(here / "g.yaml", sets)[0].scene == str(here / "other.yaml")


def _extreme(here: Path, sets: tuple[str, ...]):
    from tlm.experiments.extreme import load_cases

    case = {"name": "a", "category": "c", "expect": "e", "config": {"seed": 1}, "checks": ["finite"]}
    (here / "x.yaml").write_text(f"base: {json.dumps(BASE)}\ncases: [{json.dumps(case)}]\n")
    assert load_cases(here / "x.yaml", sets)[0]["scene"] == str(here / "other.yaml")


def _error_vs_cost(here: Path, sets: tuple[str, ...]):
    from tlm.experiments.error_cost import load_experiment

    (here / "e.yaml").write_text(f"base: {json.dumps({**BASE, 'mode': 'pmap'})}\npoints: [{{photons.count: [1000]}}]\n")
    assert load_experiment(here / "e.yaml", sets)[0]["scene"] == str(here / "other.yaml")


@pytest.mark.parametrize("load", [_granularity, _extreme, _error_vs_cost])
def test_a_studys_base_scene_replaced_by_its_set_is_not_warned_of(here, capsys, load):
    load(here, ("scene=./other.yaml",))
    assert _shadow_lines(capsys) == []


@pytest.mark.parametrize("overrides", [{"scene": "./other.yaml"}, ["scene=ring"]])
def test_the_apis_mapping_whose_scene_an_override_replaces_is_not_warned_of(here, capsys, overrides):
    from tlm import load_config

    load_config(dict(BASE), overrides)
    assert _shadow_lines(capsys) == []


def test_a_bare_name_that_is_no_builtin_scene_with_a_scene_file_of_it_here_says_how_to_give_it(tmp_path, elsewhere,
                                                                                                capsys):
    folder = elsewhere / "cfg"
    folder.mkdir()
    _scene_file(folder / "myroom.yml")
    (folder / "run.yaml").write_text("scene: myroom\n" + RUN)
    assert main(["run", "cfg/run.yaml", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: cfg/run.yaml: scene: 'myroom' is not a built-in scene")
    assert err[0].endswith("; a scene file of that name lies at cfg/myroom.yml: to run it, give it as a path, "
                           "scene=./myroom.yml")
    # (--set scene=myroom: the working folder's file; a run config of that name is no scene file: nothing of it)
    (folder / "myroom.yml").unlink()
    _scene_file(elsewhere / "myroom.yaml")
    (folder / "ring.yaml").write_text("scene: ring\n" + RUN)
    assert main(["run", "cfg/ring.yaml", "--set", "scene=myroom", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    assert capsys.readouterr().err.strip().endswith("; a scene file of that name lies at myroom.yaml: to run it, "
                                                    "give it as a path, scene=./myroom.yaml")
    (elsewhere / "myroom.yaml").write_text("scene: room\n" + RUN)
    assert main(["run", "cfg/run.yaml", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    assert "lies at" not in capsys.readouterr().err
